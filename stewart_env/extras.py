"""The optional extras of ``pyproject.toml`` and the one-line error when one is missing.

Each extra brings the libraries of one kind of work: ``rl`` (training and loading agents),
``mujoco`` (the MuJoCo twin), ``distributed`` (the study on a Ray cluster), ``laws`` (a user's own
control laws as numba cfuncs), ``logs`` (drive logs in HDF5), ``jsbsim`` (flight references for the cueing task),
``casadi`` (the symbolic model) and ``mpc`` (the model-predictive controller's QP solver).  :func:`require` looks the libraries
up without importing them, so a command checks its extras before it does any work; :func:`extra_of` names the extra a failed
import belongs to, so that the command line turns any such ``ImportError`` into one line.

The install hints work from a clone of the repository (``pip install -e ".[rl]"``): the package
is installed from its source, not by name from a package index.

This module imports nothing from the rest of the package but its errors: it sits below every layer.
"""

from __future__ import annotations

import importlib.util

from stewart_env.errors import UsageError

__all__ = ["EXTRAS", "MissingExtra", "extra_of", "install_hint", "missing", "require"]

#: Every optional extra and the top-level modules it installs that the package imports.
EXTRAS: dict[str, tuple[str, ...]] = {
    "rl": ("torch", "stable_baselines3", "sb3_contrib"),
    "mujoco": ("mujoco",),
    "distributed": ("ray",),
    "laws": ("numba",),
    "logs": ("h5py",),
    "jsbsim": ("jsbsim",),
    "casadi": ("casadi",),
    "mpc": ("osqp",),
}
#: What an extra asks of the user before ``pip install`` (torch's CPU build for ``rl``: the
#: default index serves the CUDA build, gigabytes this package does not use).
_BEFORE = {
    "rl": "first torch==2.13.0 (the CPU build: pip install torch==2.13.0 --index-url "
    "https://download.pytorch.org/whl/cpu), then "
}


class MissingExtra(UsageError, ImportError):
    """An optional extra is not installed; the message names it and the command installing it.
    An ``ImportError`` too, so that code catching a failed import keeps catching it."""

    def __init__(self, message: str, extra: str):
        super().__init__(message)
        self.extra = extra


def install_hint(extra: str) -> str:
    """How to install ``extra`` from a clone: ``install the extra 'rl': pip install -e ".[rl]"``.

    Args:
        extra: the extra's name.
    """
    return f'install the extra {extra!r}: {_BEFORE.get(extra, "")}pip install -e ".[{extra}]"'


def missing(extra: str) -> list[str]:
    """The modules of ``extra`` that cannot be imported (looked up, not imported).

    Args:
        extra: the extra's name, a key of ``EXTRAS``.
    """
    found = []
    for name in EXTRAS[extra]:
        try:
            spec = importlib.util.find_spec(name)
        except (ImportError, ValueError):  # a module set to None in sys.modules, a broken package
            spec = None
        if spec is None:
            found.append(name)
    return found


def require(extra: str, what: str) -> None:
    """Raise :class:`MissingExtra` unless every module of ``extra`` can be imported.

    Args:
        extra: the extra's name, a key of ``EXTRAS`` (``"rl"``, ``"mujoco"``, ...).
        what: what needs the extra, the subject of the message "``what`` needs <modules>, which is
            not installed; install the extra ...".

    Raises:
        MissingExtra: a module of the extra is not installed.
    """
    absent = missing(extra)
    if absent:
        verb = "is" if len(absent) == 1 else "are"
        raise MissingExtra(
            f"{what} needs {' and '.join(absent)}, which {verb} not installed; {install_hint(extra)}", extra
        )


def extra_of(error: BaseException | None) -> str | None:
    """The extra whose module ``error`` failed to import, or None (a module of no extra).

    Args:
        error: an exception, followed through the errors it was raised from; or None.
    """
    while error is not None:  # the import that failed, through errors raised from it
        if isinstance(error, MissingExtra):
            return error.extra
        top = (getattr(error, "name", None) or "").split(".")[0]
        found = next((extra for extra, modules in EXTRAS.items() if top in modules), None)
        if found is not None:
            return found
        error = error.__cause__
    return None
