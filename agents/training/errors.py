"""The errors of training and loading agents, and the check that the ``rl`` extra is installed."""

from __future__ import annotations

import signal
from pathlib import Path

from stewart_env.errors import UsageError
from stewart_env.extras import require

__all__ = ["TrainingError", "TrainingInterrupted", "check_rl_installed"]


class TrainingError(UsageError):
    """A training or loading request that cannot be carried out; the message says why."""


class TrainingInterrupted(KeyboardInterrupt):
    """Training stopped by SIGINT or SIGTERM after saving ``checkpoint``; ``exit_code`` is the
    shell's 128 + signal number (130 for SIGINT, 143 for SIGTERM)."""

    def __init__(self, signum: int, checkpoint: Path):
        super().__init__(signal.Signals(signum).name, str(checkpoint))
        self.signum = signum
        self.checkpoint = checkpoint
        self.exit_code = 128 + signum


def check_rl_installed() -> None:
    """:class:`stewart_env.extras.MissingExtra` with the install command unless stable-baselines3
    and torch are importable.  Looks them up without importing them, so it is cheap and runs
    before anything is written."""
    require("rl", "training and loading agents")
