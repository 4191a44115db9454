"""Where numba keeps the kernels it compiles, chosen so that ``import stewart_env`` works from any
install, read-only ones included.

The physics is compiled when the package is installed (the extension
``stewart_env.dynamics._core``); numba compiles the tasks' and the environment's own kernels
(``stewart_env.tasks``, ``stewart_env.envs``) on their first call and caches them on disk.

numba picks the cache directory of a ``@njit(cache=True)`` function when the function is
decorated, that is when its module is imported.  ``numba.core.caching.CacheImpl`` tries its
locators in order: ``numba.config.CACHE_DIR`` (the ``NUMBA_CACHE_DIR`` variable), a
``__pycache__`` directory beside the source file, then the user-wide cache directory
(``~/.cache/numba`` on Linux); each must be creatable and writable.  When none is, the import
fails with ``RuntimeError: cannot cache function ...: no locator available``.

:func:`configure` runs before any module with kernels is imported (``stewart_env/__init__.py``
calls it first).  It asks numba's own locators whether every directory of the package has a
cache location; if one has none, it points ``numba.config.CACHE_DIR`` at a private temporary
directory, ``<tempdir>/stewart_env-numba-cache-<uid>``, and if even that is impossible it
compiles the package's kernels in memory on every run.  Either fallback warns once.
:func:`is_warm` tells whether the kernels are already compiled in the cache in use.
"""

from __future__ import annotations

import os
import stat
import tempfile
import warnings
from collections.abc import Iterable
from pathlib import Path

__all__ = ["CacheWarning", "configure", "is_warm"]

_PACKAGE = __name__.partition(".")[0]
_PACKAGE_DIR = Path(__file__).resolve().parent
_configured = False


class CacheWarning(UserWarning):
    """numba cannot cache the kernels where it would by itself (see the module docstring)."""


def _probe() -> None:
    """Stands in for a kernel when asking numba's locators about a source file."""


def _source_dirs() -> list[str]:
    """Every directory of the package that holds modules (each is located separately)."""
    found = []
    for directory, subdirs, files in os.walk(_PACKAGE_DIR):
        subdirs[:] = [d for d in subdirs if d != "__pycache__"]
        if "__init__.py" in files:
            found.append(directory)
    return found


def _dirs_without_cache() -> list[str]:
    """Package directories for which no numba locator finds a writable cache location; numba's
    locators create the directory and write a probe file, exactly as at decoration time."""
    from numba.core.caching import CacheImpl

    missing = []
    for directory in _source_dirs():
        source = os.path.join(directory, "__init__.py")
        if all(cls.from_function(_probe, source) is None for cls in CacheImpl._locator_classes):
            missing.append(directory)
    return missing


def _private_temp_dir() -> str | None:
    """``<tempdir>/stewart_env-numba-cache-<uid>``, created if needed, or None when it cannot be
    created or is not ours alone: numba unpickles what it finds in its cache, so a directory that
    another user can write must not be used."""
    uid = os.getuid() if hasattr(os, "getuid") else None
    try:
        path = os.path.join(tempfile.gettempdir(), f"{_PACKAGE}-numba-cache-{uid if uid is not None else 'user'}")
        os.makedirs(path, mode=0o700, exist_ok=True)
        info = os.lstat(path)
    except OSError:  # includes gettempdir() finding no usable temporary directory
        return None
    if not stat.S_ISDIR(info.st_mode):
        return None
    if uid is not None and (info.st_uid != uid or info.st_mode & 0o022):
        return None
    return path


def _compile_in_memory() -> None:
    """Leave the package's kernels without a cache: numba then compiles them on first call in
    every process.  Only this package's functions are affected."""
    from numba.core.dispatcher import Dispatcher

    enable_caching = Dispatcher.enable_caching

    def enable_caching_outside_package(self) -> None:
        if getattr(self.py_func, "__module__", "").partition(".")[0] == _PACKAGE:
            return  # keeps the NullCache the dispatcher starts with
        enable_caching(self)

    Dispatcher.enable_caching = enable_caching_outside_package


def configure() -> None:
    """Make sure numba can cache (or, failing that, at least compile) the package's kernels.

    Idempotent; must run before the first module with ``@njit(cache=True)`` kernels is imported.
    Warns (:class:`CacheWarning`) when it has to move the cache or give it up.
    """
    global _configured
    if _configured:
        return
    _configured = True
    from numba.core import config

    if not _dirs_without_cache():
        return
    # Only the attribute, not os.environ: a changed NUMBA_* variable makes numba re-read its
    # whole configuration at the next compile, undoing settings made in code.
    chosen = config.CACHE_DIR
    fallback = _private_temp_dir()
    if fallback is not None:
        config.CACHE_DIR = fallback
        if not _dirs_without_cache():
            warnings.warn(
                f"{_PACKAGE}: numba cannot cache compiled kernels beside the package, in NUMBA_CACHE_DIR "
                f"or in the user's cache directory (none is writable); caching them in {fallback}. "
                "Set NUMBA_CACHE_DIR to a writable directory to choose another place.",
                CacheWarning, stacklevel=2)
            return
        config.CACHE_DIR = chosen
    _compile_in_memory()
    warnings.warn(
        f"{_PACKAGE}: no writable directory for numba's cache (package, user cache directory and "
        "temporary directory); kernels are compiled in memory, on first use in every process. "
        "Set NUMBA_CACHE_DIR to a writable directory to keep them.",
        CacheWarning, stacklevel=2)


def is_warm(names: Iterable[str] | None = None) -> bool:
    """Whether the numba kernels of the package's modules imported so far (import
    ``stewart_env.envs`` first for the environment's and the tasks') are compiled in the cache in
    use, so that calling them loads machine code instead of compiling.

    Args:
        names: kernel names (e.g. ``("_error_rows",)``); True only if every one has a cache index
            for the current source.  None: True if any kernel has one, i.e. the package has
            compiled and cached kernels before.
    """
    import sys

    from numba.core.dispatcher import Dispatcher

    modules = [m for name, m in list(sys.modules.items()) if name.startswith(_PACKAGE + ".") and m is not None]
    found = {name: obj for module in modules for name, obj in vars(module).items()
             if isinstance(obj, Dispatcher) and obj.py_func.__module__ == module.__name__}
    if names is None:
        return any(_has_fresh_index(obj) for obj in found.values())
    names = list(names)
    unknown = [name for name in names if name not in found]
    if unknown:
        raise ValueError(f"is_warm: unknown kernel(s) {', '.join(map(repr, unknown))}")
    return all(_has_fresh_index(found[name]) for name in names)


def _has_fresh_index(dispatcher) -> bool:
    """The dispatcher's cache index exists, is of this numba version and matches the source."""
    cache_file = getattr(dispatcher._cache, "_cache_file", None)  # absent for the in-memory NullCache
    if cache_file is None:
        return False
    try:
        return bool(cache_file._load_index())
    except Exception:  # an unreadable or corrupt index: numba will recompile too
        return False
