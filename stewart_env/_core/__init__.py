"""The compiled kernels, in the build the processor runs fastest.

The C++ kernels (``stewart_env/_core/cpp/``, by layer: ``physics/``, ``identification/``,
``tasks/``, ``env/``) are compiled once per instruction-set target into
an extension of their own: ``_core_baseline`` (the architecture's baseline, which any processor of
it runs) and, on x86-64, ``_core_x86_64_v3`` (AVX2, FMA, BMI2) and ``_core_x86_64_v4``
(AVX-512).  On import this module takes the most demanding target the processor runs, or the one
the environment variable ``STEWART_ENV_CPU`` names (``baseline``, ``x86-64-v3`` or
``x86-64-v4``; a value that cannot be had is a RuntimeWarning naming it, and the fastest target
is used), imports its extension and re-exports its names, so that ``from
stewart_env import _core`` reaches the kernels whichever was chosen.  Every target
computes the same numbers bit for bit (no fused multiply-adds on any target); they differ in speed
only.  This package is the lowest layer: it imports nothing of ``stewart_env`` but
``stewart_env.errors``, and every layer may import it.

Attributes:
    TARGET: the name of the target imported, e.g. ``"x86-64-v4"``.
"""

# Every name of this module that is not the kernels' is private (a leading _): its namespace is
# theirs, as the extension's was.
import importlib as _importlib
import importlib.util as _importlib_util
import os as _os
import warnings as _warnings

from stewart_env._core import _cpu_features
from stewart_env.errors import UsageError as _UsageError

_VARIABLE = "STEWART_ENV_CPU"


def _module_name(target: str) -> str:
    """The extension of the kernels compiled for ``target``: ``x86-64-v3`` -> ``_core_x86_64_v3``."""
    return "_core_" + target.replace("-", "_")


def _built_targets() -> list[str]:
    """The targets this installation holds an extension of, from the least to the most demanding."""
    return [t for t in _cpu_features.TARGETS if _importlib_util.find_spec(f"{__package__}.{_module_name(t)}")]


def _choose(requested: str | None, built: list[str], runnable: list[str]) -> str:
    """The target to import: ``requested`` (the value of ``STEWART_ENV_CPU``; unset or empty for the
    most demanding target that is both built and runnable).

    Args:
        requested: a target's name, or None or "" to choose.
        built: the targets this installation holds, from the least to the most demanding.
        runnable: the targets the processor runs, likewise.

    Returns:
        The target's name.

    Raises:
        UsageError: ``requested`` names no target, one this installation did not build, or one the
            processor cannot run.
        ImportError: the installation holds no extension of the kernels the processor runs.
    """
    if not requested:
        usable = [t for t in built if t in runnable]
        if not usable:
            raise ImportError(
                f"stewart_env._core: no compiled kernels this processor runs (built: "
                f"{', '.join(built) or 'none'}); reinstall the package to compile them"
            )
        return usable[-1]
    if requested not in _cpu_features.TARGETS:
        raise _UsageError(
            f"{_VARIABLE}={requested!r}: not a target; choose one of "
            f"{', '.join(_cpu_features.TARGETS)}, or unset it for the fastest this processor runs"
        )
    if requested not in built:
        raise _UsageError(f"{_VARIABLE}={requested!r}: not built in this installation (built: {', '.join(built)})")
    if requested not in runnable:
        raise _UsageError(f"{_VARIABLE}={requested!r}: this processor cannot run it (it runs: {', '.join(runnable)})")
    return requested


def _target() -> str:
    """The target to import: ``STEWART_ENV_CPU``'s if it can be had; otherwise, with a warning naming
    the variable, the fastest this processor runs (the variable is read on import, before any caller
    could catch an error, and a job script copied to another machine should still run)."""
    built, runnable = _built_targets(), list(_cpu_features.runnable())
    try:
        return _choose(_os.environ.get(_VARIABLE, "").strip(), built, runnable)
    except _UsageError as err:
        fallback = _choose(None, built, runnable)
        _warnings.warn(f"{err}; using {fallback}", RuntimeWarning, stacklevel=2)
        return fallback


TARGET = _target()

_kernels = _importlib.import_module(f"{__package__}.{_module_name(TARGET)}")
globals().update({name: value for name, value in vars(_kernels).items() if not name.startswith("__")})
