"""SIGINT and SIGTERM during training: the first stops training at the next step (a checkpoint is
saved), a second exits at once."""

from __future__ import annotations

import contextlib
import os
import signal
import threading
from collections.abc import Iterator

__all__ = ["StopRequest", "stop_on_signals"]


class StopRequest:
    """The first SIGINT/SIGTERM received while training, or None."""

    signum: int | None = None


@contextlib.contextmanager
def stop_on_signals(stop: StopRequest) -> Iterator[None]:
    """Inside the block, SIGINT and SIGTERM set ``stop.signum`` (training then stops at the next
    step and saves a checkpoint); a second signal exits at once with 128 + its number.  Only the
    main thread can own signal handlers: elsewhere the block changes nothing.

    Args:
        stop: the request the handler sets ``signum`` of.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        name = signal.Signals(signum).name
        if stop.signum is not None:
            os.write(2, f"stewart-env train: second signal ({name}); exiting now without saving\n".encode())
            os._exit(128 + signum)
        stop.signum = signum
        os.write(
            2, f"stewart-env train: {name} received; saving a checkpoint (send it again to exit at once)\n".encode()
        )

    previous = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
