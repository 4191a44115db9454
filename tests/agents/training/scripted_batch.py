"""A scripted two-row SB3 batch for the training wrappers' tests (ActionRatePenalty, PrecisionReward):
reward 1 every step, the dones and infos set by the test, the last actions kept."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env import VecEnv


class ScriptedBatch(VecEnv):
    """Two rows of two action components in [-1, 1], reward 1 every step, the dones and infos given
    by the test; ``received`` the last actions."""

    def __init__(self):
        super().__init__(2, spaces.Box(-1.0, 1.0, (1,)), spaces.Box(-1.0, 1.0, (2,)))
        self.infos = [{}, {}]
        self.dones = np.zeros(2, dtype=bool)
        self.received = None

    def reset(self):
        return np.zeros((2, 1), np.float32)

    def step_async(self, actions):
        self.received = np.array(actions)

    def step_wait(self):
        return np.zeros((2, 1), np.float32), np.ones(2, np.float32), self.dones.copy(), [dict(i) for i in self.infos]

    def close(self):
        pass

    def get_attr(self, attr_name, indices=None):
        return [None, None]

    def set_attr(self, attr_name, value, indices=None):
        pass

    def env_method(self, method_name, *args, indices=None, **kwargs):
        return [None, None]

    def env_is_wrapped(self, wrapper_class, indices=None):
        return [False, False]
