"""``python -m stewart_env``: the ``stewart-env`` command."""

import sys

from stewart_env.cli import main

sys.exit(main())
