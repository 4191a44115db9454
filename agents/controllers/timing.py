"""A controller's compute time per control step, measured against the control period (real time)."""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import Any, NamedTuple

import gymnasium as gym
import numpy as np

__all__ = ["ComputeTime", "control_step_times"]


class ComputeTime(NamedTuple):
    """The wall time of a policy's ``predict`` per control step of one platform.

    Attributes:
        mean: the mean over the steps, s.
        max: the longest step, s.
        period: the control period it must fit in, s (the environment's ``dt``).
        steps: the steps timed.
    """

    mean: float
    max: float
    period: float
    steps: int

    @property
    def real_time_factor(self) -> float:
        """The mean over the period (below 1 the controller keeps up with real time on average)."""
        return self.mean / self.period

    def __str__(self) -> str:
        return (
            f"{1e3 * self.mean:.3g} ms mean, {1e3 * self.max:.3g} ms max per control step of "
            f"{1e3 * self.period:.3g} ms ({self.steps} steps)"
        )


def control_step_times(
    policy: Callable[[Any], Any] | Any,
    env_kwargs: Mapping[str, Any] | None = None,
    steps: int = 100,
    seed: int = 0,
) -> ComputeTime:
    """Time a policy's ``predict`` on every control step of one ``StewartPlatform-v1`` episode.

    The first call is not timed (a controller may set itself up on it, e.g. an MPC's solver).
    Under load the figures grow with the other work on the machine: measure on an idle one.

    Args:
        policy: a policy (with SB3's ``predict``) or a factory env -> policy, as
            :func:`~stewart_env.agents.evaluation.evaluate` takes them.
        env_kwargs: the environment's keywords (``observation_mode`` is set to ``"pose"``).
        steps: the control steps to time (>= 1); fewer if the episode ends first.
        seed: the episode's seed.

    Returns:
        The :class:`ComputeTime`.

    Raises:
        ValueError: ``steps`` not a positive integer, or a bad environment keyword.
    """
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise ValueError(f"steps: expected a positive integer, got {steps!r}")
    env = gym.make("StewartPlatform-v1", **{**dict(env_kwargs or {}), "observation_mode": "pose"})
    try:
        if not hasattr(policy, "predict") or isinstance(policy, type):  # a factory, as evaluate takes it
            policy = policy(env)
        observation, _ = env.reset(seed=seed)
        policy.predict(observation)
        times = []
        for _ in range(steps):
            start = time.perf_counter()
            action, _ = policy.predict(observation)
            times.append(time.perf_counter() - start)
            observation, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                break
        return ComputeTime(float(np.mean(times)), float(np.max(times)), float(env.unwrapped.dt), len(times))
    finally:
        env.close()
