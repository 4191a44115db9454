"""The base class of every error a user's request can cause.

:class:`UsageError` is a ``ValueError``: a bad argument, config, file or folder. The command line
prints such an error as one line naming the argument or path and exits with status 2; every other
exception is a bug and keeps its traceback. The errors of the parts of the package
(:class:`stewart_env.files.FileError`, :class:`stewart_env.params.ConfigError`, the commands' own
errors) derive from it.
"""

from __future__ import annotations

__all__ = ["UsageError"]


class UsageError(ValueError):
    """A request the user can correct: the message names the argument, config or path, and why."""
