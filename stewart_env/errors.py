"""The base class of every error a user's request can cause.

:class:`UsageError` is a ``ValueError``: a bad argument, config, file or folder. The command line
prints such an error as one line naming the argument or path and exits with status 2; every other
exception is a bug and keeps its traceback. The errors of the parts of the package
(:class:`stewart_env.files.FileError`, :class:`stewart_env.params.ConfigError`, the commands' own
errors) derive from it.

An error about one argument carries that argument's name as data (:attr:`UsageError.argument`)
and what is wrong with it (:attr:`UsageError.problem`), so a caller that must say it in its own
terms (the command line names the flag, ``--model``) reads the two fields and never the message's
text.
"""

from __future__ import annotations

__all__ = ["UsageError"]


class UsageError(ValueError):
    """A request the user can correct: the message names the argument, config or path, and why.

    Args:
        message: the whole one-line message; with ``argument`` and no message, it is
            ``"<argument>: <problem>"``.
        argument: the name of the argument refused (a keyword such as ``"model"``), or None when
            the error is not about one argument.
        problem: what is wrong with the argument, without its name (defaults to ``message``).

    Attributes:
        argument: the refused argument's name, or None.
        problem: what is wrong with it.

    Examples:
        >>> from stewart_env.errors import UsageError
        >>> err = UsageError.about("model", "unknown model 'newton'")
        >>> err.argument, err.problem, str(err)
        ('model', "unknown model 'newton'", "model: unknown model 'newton'")
    """

    def __init__(self, message: str = "", *args, argument: str | None = None, problem: str | None = None):
        if not message and argument is not None and problem is not None:
            message = f"{argument}: {problem}"
        super().__init__(message, *args)
        self.argument = argument
        self.problem = message if problem is None else problem

    @classmethod
    def about(cls, argument: str, problem: str, **extra) -> UsageError:
        """The error ``"<argument>: <problem>"`` about the argument named ``argument``.

        Args:
            argument: the argument's name.
            problem: what is wrong with it.
            **extra: further keyword arguments of the subclass.

        Returns:
            The error (not raised).
        """
        return cls(f"{argument}: {problem}" if argument else problem, argument=argument, problem=problem, **extra)
