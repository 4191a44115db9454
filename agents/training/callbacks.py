"""The stable-baselines3 callbacks of training: checkpoints and the stop on a signal
(:func:`checkpoint_callback`, for :func:`~stewart_env.agents.training.train`), and the timer of
collection and learning with its points (:func:`timer_callback`, for time-to-agent).

stable-baselines3 is imported inside the functions, so that importing this module does not load
torch.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

from stewart_env.agents.training.rundir import log_progress, save_checkpoint
from stewart_env.agents.training.signals import StopRequest

__all__ = ["checkpoint_callback", "timer_callback"]


def checkpoint_callback(directory: Path, algo: str, freq: int, keep: int, wall_offset: float, stop: StopRequest):
    """An SB3 callback that stops training once ``stop`` holds a signal, and otherwise calls
    :func:`~stewart_env.agents.training.save_checkpoint` at the first rollout end ``freq``
    environment steps after the last checkpoint (0: never), logging each checkpoint's step count
    and training wall time (s, ``wall_offset`` plus the time since this call started) to
    DIR/checkpoints/progress.csv, so that a point of the learning curve can be matched to its budget.

    Args:
        directory: the run directory.
        algo: the algorithm's name, one of :data:`~stewart_env.agents.training.ALGORITHMS`.
        freq: environment steps between checkpoints (0: none).
        keep: how many of the newest checkpoints to keep.
        wall_offset: the training wall time of earlier segments of the run, s.
        stop: the signal request that stops training.

    Returns:
        The callback; its ``last`` is the step count of the last checkpoint it saved (or of the
        start).
    """
    from stable_baselines3.common.callbacks import BaseCallback

    class Checkpoints(BaseCallback):
        def _on_training_start(self) -> None:
            self.last = self.model.num_timesteps
            self.start = time.perf_counter() - wall_offset

        def _on_step(self) -> bool:
            return stop.signum is None

        def _on_rollout_end(self) -> None:
            # at the end of a rollout, not in _on_step: off-policy, SB3 stores a step's transition
            # after the step's callback, so a checkpoint taken there would miss it
            steps = self.model.num_timesteps
            if freq and steps - self.last >= freq and stop.signum is None:
                self.last = steps
                save_checkpoint(self.model, directory, algo, keep)
                log_progress(directory, steps, time.perf_counter() - self.start)

    return Checkpoints()


def timer_callback(clock: Callable[[], float], on_point: Callable[[], bool]):
    """An SB3 callback that times collection (``_on_rollout_start`` to ``_on_rollout_end``) and
    learning (``_on_rollout_end`` to the next ``_on_rollout_start``: the update), and at every
    rollout start after the first calls ``on_point``; training stops at the next step once it
    returns True.

    Args:
        clock: the training wall time, s (pauses excluded by the caller).
        on_point: called between an update and the next rollout; True stops training.

    Returns:
        The callback: ``collection_time``, ``collection_steps``, ``learning_time`` and
        ``learning_steps`` so far, ``stop``, and ``finish()``, which counts an update that ended
        after the last rollout.
    """
    from stable_baselines3.common.callbacks import BaseCallback

    class Timer(BaseCallback):
        def _on_training_start(self) -> None:
            self.collection_time = self.learning_time = 0.0
            self.collection_steps = self.learning_steps = 0
            self.rollout_start = self.rollout_end = None
            self.steps_at_start = 0
            self.stop = False

        def finish(self) -> bool:
            """Count the update that just ended (if any); whether there was one."""
            if self.rollout_end is None:
                return False
            self.learning_time += clock() - self.rollout_end
            self.learning_steps += self.last_rollout
            self.rollout_end = None
            return True

        def _on_rollout_start(self) -> None:
            if self.finish():  # the update of the previous rollout just ended
                self.stop = on_point()
            self.rollout_start = clock()
            self.steps_at_start = self.model.num_timesteps

        def _on_step(self) -> bool:
            return not self.stop

        def _on_rollout_end(self) -> None:
            self.rollout_end = clock()
            self.collection_time += self.rollout_end - self.rollout_start
            self.last_rollout = self.model.num_timesteps - self.steps_at_start
            self.collection_steps += self.last_rollout

    return Timer()
