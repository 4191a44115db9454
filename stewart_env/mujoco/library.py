"""The one door to the MuJoCo library: every module of the package reaches ``mujoco`` through here.

Without the optional extra the package still imports; the first call that needs MuJoCo raises
:class:`~stewart_env.extras.MissingExtra`, an ImportError that says how to install it.
"""

from __future__ import annotations

import contextlib

from stewart_env.extras import MissingExtra, install_hint

try:
    import mujoco as _mj
except ImportError:  # the optional extra is missing
    _mj = None

__all__ = ["quiet_mujoco", "require_mujoco", "require_rollout"]


def require_mujoco():
    """The ``mujoco`` module.  Raises ``stewart_env.extras.MissingExtra`` (an ImportError)
    naming the extra when it is not installed."""
    if _mj is None:
        raise MissingExtra(
            f"stewart_env.mujoco: the package 'mujoco' is not installed; {install_hint('mujoco')}", "mujoco"
        )
    return _mj


def require_rollout():
    """The ``mujoco.rollout`` module (batched stepping in MuJoCo's thread pool)."""
    require_mujoco()
    from mujoco import rollout

    return rollout


@contextlib.contextmanager
def quiet_mujoco():
    """MuJoCo's default log handler neither prints nor writes MUJOCO_LOG.TXT into the current
    directory while the plant steps: a diverging row is reported as NaN instead (the previous
    configuration is restored afterwards)."""
    mj = require_mujoco()
    before = mj.MjLogConfig.get()
    quiet = mj.MjLogConfig.get()
    quiet.logto_console = quiet.logto_file = False
    quiet.set()
    try:
        yield
    finally:
        before.set()
