"""``python -m stewart_env.mujoco``: see :mod:`stewart_env.mujoco.cli`."""

from stewart_env.mujoco.cli import main

raise SystemExit(main())
