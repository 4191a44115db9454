"""A reward for the last millimetres of a set point, for training only.

:class:`PrecisionReward` is a stable-baselines3 ``VecEnvWrapper``: each step it adds
``weight * (exp(-|e_p| / position_scale) + exp(-|e_o| / orientation_scale))`` to every row's
reward, ``|e_p|`` (m) and ``|e_o|`` (rad) the step's position and orientation errors the
environment reports in its info (``position_error``, ``orientation_error``, the errors of the
success criterion).  The task's reward, ``exp(-|e| / scale)`` at a scale of centimetres to
decimetres so that a distant target still has a slope, barely changes within the success band
(2 mm, 10 mrad); this second pair of terms at the band's scale rewards closing it.  The
environment's reward and its contract stay as they are: the terms live in the training batch only
(a config names the wrapper under rl-baselines3-zoo's ``vec_env_wrapper`` key), and evaluation
runs the environment itself.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from stewart_env.tasks.base import ORIENTATION_TOLERANCE, POSITION_TOLERANCE
from stewart_env.validation import real

__all__ = ["PrecisionReward", "precision_reward"]


def precision_reward(
    position_error: np.ndarray,
    orientation_error: np.ndarray,
    weight: float,
    position_scale: float,
    orientation_scale: float,
) -> np.ndarray:
    """Each row's ``weight * (exp(-|e_p| / position_scale) + exp(-|e_o| / orientation_scale))``;
    a row whose error is not finite (no error reported) gets 0 for that term.

    Args:
        position_error: the rows' position errors |e_p|, m, shape (rows,).
        orientation_error: the rows' orientation errors |e_o|, rad, shape (rows,).
        weight: the weight of each term, at least 0.
        position_scale: m, positive.
        orientation_scale: rad, positive.

    Returns:
        The rewards, shape (rows,), float64.
    """
    terms = np.zeros(np.shape(position_error))
    for error, scale in ((position_error, position_scale), (orientation_error, orientation_scale)):
        e = np.abs(np.asarray(error, dtype=np.float64))
        finite = np.isfinite(e)
        terms += np.exp(-np.where(finite, e, 0.0) / scale) * finite
    return weight * terms


class PrecisionReward(VecEnvWrapper):
    """The training batch with ``weight * (exp(-|e_p| / position_scale) + exp(-|e_o| /
    orientation_scale))`` added to each row's reward (see the module's docstring).

    It sits between VecMonitor and VecNormalize, where rl-baselines3-zoo puts a
    ``vec_env_wrapper``: the monitor's episode returns are the environment's reward, the agent
    learns from the sum.  A step whose info lacks an error (a batch that does not report it) adds
    nothing for it.

    Args:
        venv: the vector environment.
        weight: the weight of each of the two terms, a finite number at least 0 (0: no reward).
        position_scale: the position term's scale, m, a finite positive number (default the
            success band's 2 mm).
        orientation_scale: the orientation term's scale, rad, a finite positive number (default
            the success band's 0.01 rad).

    Raises:
        UsageError: an option out of its range (the message names it).
    """

    def __init__(
        self,
        venv: VecEnv,
        weight: float = 0.5,
        position_scale: float = POSITION_TOLERANCE,
        orientation_scale: float = ORIENTATION_TOLERANCE,
    ):
        super().__init__(venv)
        options = self.check_options(weight, position_scale, orientation_scale)
        self.weight = options["weight"]
        self.position_scale = options["position_scale"]
        self.orientation_scale = options["orientation_scale"]

    @staticmethod
    def check_options(
        weight: float = 0.5,
        position_scale: float = POSITION_TOLERANCE,
        orientation_scale: float = ORIENTATION_TOLERANCE,
    ) -> dict[str, Any]:
        """The wrapper's keyword arguments, checked (what a config's ``vec_env_wrapper`` may give).

        Args:
            weight: the weight of each term, a finite number at least 0.
            position_scale: m, a finite positive number.
            orientation_scale: rad, a finite positive number.

        Returns:
            The keyword arguments as floats.

        Raises:
            UsageError: an option out of its range (the message names it).
        """
        return {
            "weight": real("weight", weight, 0.0),
            "position_scale": real("position_scale", position_scale, 0.0, low_open=True),
            "orientation_scale": real("orientation_scale", orientation_scale, 0.0, low_open=True),
        }

    def reset(self) -> Any:
        """Reset every row.

        Returns:
            The batch's first observations.
        """
        return self.venv.reset()

    def step_wait(self):
        """The batch's step with each row's precision reward added.

        Returns:
            Observations, rewards, dones and infos, as the wrapped batch gives them.
        """
        observations, rewards, dones, infos = self.venv.step_wait()
        position = np.array([info.get("position_error", math.nan) for info in infos], dtype=np.float64)
        orientation = np.array([info.get("orientation_error", math.nan) for info in infos], dtype=np.float64)
        bonus = precision_reward(position, orientation, self.weight, self.position_scale, self.orientation_scale)
        rewards = (np.asarray(rewards, dtype=np.float64) + bonus).astype(np.asarray(rewards).dtype, copy=False)
        return observations, rewards, dones, infos
