"""Progress reporting that suits both terminals and logs.

On a terminal (stderr is a TTY), :func:`progress` is a tqdm bar. Elsewhere (CI logs, files,
notebooks' captured stderr) a bar would write a line per refresh; there :func:`progress`
returns a quiet stand-in with the same methods that writes at most one line per minute to
stderr, and nothing at all for runs shorter than that.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Iterable, Iterator

__all__ = ["on_terminal", "progress", "LOG_INTERVAL"]

#: Seconds between two progress lines when stderr is not a terminal.
LOG_INTERVAL = 60.0


def on_terminal() -> bool:
    """Whether stderr is an interactive terminal (where progress bars belong)."""
    isatty = getattr(sys.stderr, "isatty", None)
    try:
        return bool(isatty and isatty())
    except ValueError:  # a closed stream
        return False


class QuietProgress:
    """The subset of tqdm's interface used here (iteration, ``update``, ``set_postfix_str``,
    ``close``, context manager); writes ``desc: n/total unit (postfix), elapsed s`` to stderr
    at most once per ``interval`` seconds, or never if ``disable``."""

    def __init__(
        self,
        iterable: Iterable | None = None,
        total: float | None = None,
        desc: str = "",
        unit: str = "it",
        disable: bool = False,
        interval: float = LOG_INTERVAL,
    ):
        self.iterable = iterable
        if total is None and iterable is not None and hasattr(iterable, "__len__"):
            total = len(iterable)
        self.total, self.desc, self.unit = total, desc, unit
        self.disable = disable
        self.interval = interval
        self.n = 0
        self.postfix = ""
        self._start = self._last = time.monotonic()

    def __iter__(self) -> Iterator:
        for item in self.iterable:
            yield item
            self.update()

    def __enter__(self) -> QuietProgress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def set_postfix_str(self, text: str = "", refresh: bool = True) -> None:
        """As tqdm's ``set_postfix_str``: the text shown after the count from the next line on.

        Args:
            text: the text.
            refresh: tqdm's argument, ignored (a line is printed at most once a minute).
        """
        self.postfix = str(text)

    def update(self, n: float = 1) -> None:
        """As tqdm's ``update``: advance the count, printing a line if a minute has passed since the last.

        Args:
            n: the increment, in ``unit``.
        """
        self.n += n
        now = time.monotonic()
        if self.disable or now - self._last < self.interval:
            return
        self._last = now
        count = f"{self.n:g}/{self.total:g}" if self.total else f"{self.n:g}"
        postfix = f" ({self.postfix})" if self.postfix else ""
        label = f"{self.desc}: " if self.desc else ""
        print(f"{label}{count} {self.unit}{postfix}, {now - self._start:.0f} s", file=sys.stderr, flush=True)

    def close(self) -> None:
        """As tqdm's ``close``: nothing to do (no line is left open)."""


def progress(
    iterable: Iterable | None = None,
    total: float | None = None,
    desc: str = "",
    unit: str = "it",
    disable: bool = False,
    leave: bool = True,
):
    """A tqdm bar over ``iterable`` (or advanced by ``update``) when stderr is a terminal, else a
    :class:`QuietProgress` (at most one line per minute); ``disable`` silences both.

    Args:
        iterable: what the bar iterates over, or None for a bar advanced by ``update``.
        total: the expected count, or None (the length of ``iterable`` if it has one, for tqdm).
        desc: the label before the count.
        unit: the unit of the count (``"it"``, ``"step"``, ...).
        disable: show nothing.
        leave: tqdm's: keep the bar on the terminal when it is done.
    """
    if on_terminal():
        from tqdm.auto import tqdm

        return tqdm(iterable, total=total, desc=desc, unit=unit, disable=disable, leave=leave)
    return QuietProgress(iterable, total=total, desc=desc, unit=unit, disable=disable)
