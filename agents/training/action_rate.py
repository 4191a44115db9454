"""A penalty on the change of the action between control steps, for training only.

:class:`ActionRatePenalty` is a stable-baselines3 ``VecEnvWrapper``: each step it subtracts
``weight * mean((a_t - a_{t-1})**2)`` (the mean over the action's components) from every row's
reward, as legged-robot reinforcement learning penalises the action rate, so that an agent learns
commands that do not jump from step to step.  The environment's reward and its contract stay as
they are: the penalty lives in the training batch only (a config names it under rl-baselines3-zoo's
``vec_env_wrapper`` key), and evaluation runs the environment itself.

Each row keeps its own previous action.  A row's first step after a reset (of the whole batch or
of that row, which the vector environment resets by itself when its episode ends) has no previous
action and no penalty: the episode's first command is free to jump to wherever the task asks.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from stewart_env.errors import UsageError
from stewart_env.validation import real

__all__ = ["ActionRatePenalty", "action_rate_penalty"]


def action_rate_penalty(
    actions: np.ndarray, previous: np.ndarray, has_previous: np.ndarray, weight: float
) -> np.ndarray:
    """Each row's penalty on its action's change: ``weight * mean((a_t - a_{t-1})**2)``, 0 where
    the row has no previous action.

    Args:
        actions: the step's actions, shape (rows, components).
        previous: each row's previous action, the same shape.
        has_previous: shape (rows,), whether the row has a previous action in its episode.
        weight: the penalty's weight, at least 0.

    Returns:
        The penalties, shape (rows,), float64.
    """
    change = np.asarray(actions, dtype=np.float64) - np.asarray(previous, dtype=np.float64)
    return np.where(has_previous, weight * np.mean(change * change, axis=1), 0.0)


class ActionRatePenalty(VecEnvWrapper):
    """The training batch with ``weight * mean((a_t - a_{t-1})**2)`` subtracted from each row's
    reward (see the module's docstring).

    It sits between VecMonitor and VecNormalize, where rl-baselines3-zoo puts a
    ``vec_env_wrapper``: the monitor's episode returns are the environment's reward, the agent
    learns from the penalised one.  The actions are clipped to the action space first, as the
    environment receives them.

    Args:
        venv: the vector environment (a Box action space).
        weight: the penalty's weight, a finite number at least 0 (0: no penalty).

    Raises:
        UsageError: ``weight`` not a finite number at least 0, or an action space that is not a Box
            (the message names it).
    """

    def __init__(self, venv: VecEnv, weight: float = 0.1):
        super().__init__(venv)
        weight = self.check_options(weight)["weight"]
        space = venv.action_space
        if getattr(space, "shape", None) is None or len(space.shape) != 1 or not hasattr(space, "low"):
            raise UsageError.about(
                "venv", f"the action-rate penalty needs a one-dimensional Box action space, got {space}"
            )
        self.weight = weight
        self._low, self._high = np.asarray(space.low, np.float64), np.asarray(space.high, np.float64)
        self._previous = np.zeros((self.num_envs, space.shape[0]))
        self._has_previous = np.zeros(self.num_envs, dtype=bool)
        self._actions = self._previous.copy()

    @staticmethod
    def check_options(weight: float = 0.1) -> dict[str, Any]:
        """The wrapper's keyword arguments, checked (what a config's ``vec_env_wrapper`` may give).

        Args:
            weight: the penalty's weight, a finite number at least 0.

        Returns:
            The keyword arguments, ``weight`` as a float.

        Raises:
            UsageError: ``weight`` not a finite number at least 0 (the message names it).
        """
        return {"weight": real("weight", weight, 0.0)}

    def reset(self) -> Any:
        """Reset every row; none has a previous action.

        Returns:
            The batch's first observations.
        """
        self._has_previous[:] = False
        return self.venv.reset()

    def step_async(self, actions: np.ndarray) -> None:
        """Keep the step's actions (clipped to the action space) and send them on.

        Args:
            actions: the rows' actions, shape (rows, components).
        """
        self._actions = np.clip(
            np.asarray(actions, dtype=np.float64).reshape(self._previous.shape), self._low, self._high
        )
        self.venv.step_async(actions)

    def step_wait(self):
        """The batch's step with each row's reward penalised; a row whose episode ended (and which
        the batch reset) forgets its previous action.

        Returns:
            Observations, penalised rewards, dones and infos, as the wrapped batch gives them.
        """
        observations, rewards, dones, infos = self.venv.step_wait()
        penalty = action_rate_penalty(self._actions, self._previous, self._has_previous, self.weight)
        rewards = (np.asarray(rewards, dtype=np.float64) - penalty).astype(np.asarray(rewards).dtype, copy=False)
        self._previous = self._actions
        self._has_previous = ~np.asarray(dones, dtype=bool)
        return observations, rewards, dones, infos
