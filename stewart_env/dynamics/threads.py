"""The threads of the compiled batches: how many there are, and how to set their number.

A batch call of the compiled kernels (a forward or inverse call on many platforms, a rollout, an
environment's step of many rows) shares its blocks of platforms between the calling thread and
helper threads, when the batch is large enough to pay for waking them (512 platform-evaluations
or more).  The numbers never depend on the thread count: each platform is computed by one thread
with the same arithmetic, so a batch gives the same bits on 1, 2 or 256 threads.

How many threads:

* by default one per processor core this process may run on (its CPU affinity: ``taskset`` or a
  container's CPU set count, not the machine's), the calling thread included;
* the environment variable ``STEWART_ENV_THREADS``, read when the package is imported: a whole
  number from 1 to ``MAX_THREADS`` (256).  1 keeps the calling thread alone.  Empty is the same as
  unset; any other value (``0``, ``-2``, ``four``, ``1.5``) is ignored with a RuntimeWarning that
  names the variable, and the default used; a number above ``MAX_THREADS`` (256) is capped at it,
  with a warning;
* :func:`set_num_threads`, at any time between calls.

Processes that run side by side each have their own threads: with W worker processes running
batches on C cores, ``set_num_threads(max(1, C // W))`` in each keeps them from competing for the
cores (the mismatch study's Ray jobs run on the CPUs Ray gave them; a batch of one platform, such
as each environment of SB3's ``SubprocVecEnv``, never uses helper threads).  When the operating system refuses to
start a thread (a capped address space, ``ulimit -v``, or process count, ``ulimit -u``), the
batches use the threads it did start: :func:`get_num_threads` tells how many.
"""

from __future__ import annotations

import os
import re
import warnings

from stewart_env import _core, validation

__all__ = ["MAX_THREADS", "THREADS_VARIABLE", "get_num_threads", "set_num_threads"]

#: The most threads a batch may use, the calling thread included.
MAX_THREADS: int = _core.MAX_THREADS
#: The environment variable that sets the thread count when the package is imported.
THREADS_VARIABLE = "STEWART_ENV_THREADS"


def set_num_threads(n: int) -> int:
    """Use ``n`` threads (the calling thread included) for the compiled batches from now on.

    Safe between calls from any thread: a batch running on another thread finishes first.  The
    numbers of every call are the same whatever ``n``.

    Args:
        n: the thread count, 1 (the calling thread alone) to ``MAX_THREADS`` (256).

    Returns:
        The threads the batches now use, ``n`` or fewer when the operating system refused to
        start some (a capped address space or process count).

    Raises:
        ValueError: ``n`` not an integer from 1 to ``MAX_THREADS`` (256); the message names ``n``.
    """
    return _core.set_num_threads(validation.integer("n", n, 1, MAX_THREADS))


def get_num_threads() -> int:
    """The threads the compiled batches use, the calling thread included.

    Starts the helper threads if no batch has yet, so the answer is what the operating system
    gave: see the module docstring for the default and ``STEWART_ENV_THREADS``.

    Returns:
        The thread count, 1 to ``MAX_THREADS`` (256).
    """
    return _core.get_num_threads()


def threads_from_environment(value: str | None) -> tuple[int | None, str | None]:
    """The thread count a value of ``STEWART_ENV_THREADS`` asks for, and a warning when it is not one.

    Args:
        value: the variable's value, or None when it is not set.

    Returns:
        The pair (threads, warning): threads None for the default (unset, empty or not a
        count); the warning None when the value is one.
    """
    if value is None or not value.strip():
        return None, None
    if not re.fullmatch(r"\s*\d+\s*", value) or int(value) < 1:
        return None, (
            f"{THREADS_VARIABLE}: expected a whole number of threads from 1 to {MAX_THREADS}, got "
            f"{value[:40]!r}; using the default, one thread per processor core"
        )
    if int(value) > MAX_THREADS:
        return (
            MAX_THREADS,
            f"{THREADS_VARIABLE}: {int(value)} threads is above the most, {MAX_THREADS}; using {MAX_THREADS}",
        )
    return int(value), None


def _apply_environment() -> None:
    """Set the count the threads start with from ``STEWART_ENV_THREADS`` (none starts here)."""
    threads, warning = threads_from_environment(os.environ.get(THREADS_VARIABLE))
    if warning is not None:
        warnings.warn(warning, RuntimeWarning, stacklevel=2)
    if threads is not None:
        _core.set_default_threads(threads)


_apply_environment()
