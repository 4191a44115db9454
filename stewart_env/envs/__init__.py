"""The Gymnasium environments: the single env, the native vector env and the SB3 VecEnv adapter.

``StewartPlatformSB3VecEnv`` is imported on first use, so this package imports without
stable-baselines3 (and torch).  The three are faces of one batch of platforms
(:mod:`~stewart_env.envs.core`), which a plant simulates (:mod:`~stewart_env.envs.plant`) and
an observation pipeline observes (:mod:`~stewart_env.envs.observation`); their keyword
arguments are the configuration records' (:mod:`~stewart_env.envs.config`,
:mod:`~stewart_env.envs.keywords`).
"""

from stewart_env.envs.config import EnvConfig
from stewart_env.envs.core import TERMINATION_REASONS
from stewart_env.envs.keywords import DEFAULTS
from stewart_env.envs.stewart_platform import StewartPlatformEnv, holding_action
from stewart_env.envs.vector import StewartPlatformVectorEnv

__all__ = [
    "DEFAULTS",
    "EnvConfig",
    "TERMINATION_REASONS",
    "StewartPlatformEnv",
    "StewartPlatformSB3VecEnv",
    "StewartPlatformVectorEnv",
    "holding_action",
]


def __getattr__(name: str):
    if name == "StewartPlatformSB3VecEnv":
        from stewart_env.envs.sb3 import StewartPlatformSB3VecEnv

        return StewartPlatformSB3VecEnv
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
