"""``python -m stewart_env.mujoco``: the accuracy report of MuJoCo's twin
(:mod:`stewart_env.cli.mujoco_accuracy`)."""

from stewart_env.cli.mujoco_accuracy import main

raise SystemExit(main())
