"""The training wrapper that rewards the last millimetres (PrecisionReward) and its config hook."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from scripted_batch import ScriptedBatch  # noqa: E402
from stable_baselines3.common.vec_env import VecMonitor, VecNormalize  # noqa: E402

from stewart_env.agents.training import TrainingError, make_training_env, parse_hyperparameters  # noqa: E402
from stewart_env.agents.training.precision import PrecisionReward, precision_reward  # noqa: E402
from stewart_env.errors import UsageError  # noqa: E402

WRAPPER = "stewart_env.agents.training.precision.PrecisionReward"


def step(env: PrecisionReward, infos) -> np.ndarray:
    env.venv.infos = infos
    env.step_async(np.zeros((2, 2), np.float32))
    return env.step_wait()[1]


def test_reward_by_hand():
    env = PrecisionReward(ScriptedBatch(), weight=0.5, position_scale=0.002, orientation_scale=0.01)
    env.reset()
    rewards = step(
        env,
        [
            {"position_error": 0.0, "orientation_error": 0.0},  # in the band's middle: 1 + 0.5 * 2
            {"position_error": 0.002, "orientation_error": 0.02},  # 1 + 0.5 * (e^-1 + e^-2)
        ],
    )
    np.testing.assert_allclose(rewards, [2.0, 1.0 + 0.5 * (math.exp(-1) + math.exp(-2))], rtol=1e-6)
    assert rewards.dtype == np.float32  # as SB3's batches give


def test_a_missing_or_non_finite_error_adds_nothing_for_its_term():
    env = PrecisionReward(ScriptedBatch(), weight=1.0)
    env.reset()
    rewards = step(env, [{}, {"position_error": math.nan, "orientation_error": 0.0}])
    np.testing.assert_allclose(rewards, [1.0, 2.0], rtol=1e-6)


def test_reward_function_is_the_sum_of_two_exponentials():
    r = precision_reward(np.array([0.001, 0.004]), np.array([0.0, 0.05]), 2.0, 0.002, 0.01)
    np.testing.assert_allclose(r, [2.0 * (math.exp(-0.5) + 1.0), 2.0 * (math.exp(-2.0) + math.exp(-5.0))])


def test_defaults_are_the_success_band():
    env = PrecisionReward(ScriptedBatch())
    assert (env.weight, env.position_scale, env.orientation_scale) == (0.5, 0.002, 0.01)


@pytest.mark.parametrize(
    "options, name",
    [
        ({"weight": -0.1}, "weight"),
        ({"weight": math.nan}, "weight"),
        ({"weight": True}, "weight"),
        ({"position_scale": 0.0}, "position_scale"),
        ({"position_scale": math.inf}, "position_scale"),
        ({"orientation_scale": -1.0}, "orientation_scale"),
        ({"orientation_scale": "0.01"}, "orientation_scale"),
    ],
)
def test_bad_options_are_refused_naming_them(options, name):
    with pytest.raises(UsageError, match=rf"^{name}: expected a finite number"):
        PrecisionReward(ScriptedBatch(), **options)


def test_training_env_puts_the_wrapper_between_monitor_and_normalisation():
    env = make_training_env(2, {"action_mode": "pose"}, 0, {}, wrappers=((PrecisionReward, {"weight": 0.3}),))
    try:
        assert isinstance(env, VecNormalize)
        assert isinstance(env.venv, PrecisionReward) and env.venv.weight == 0.3
        assert isinstance(env.venv.venv, VecMonitor)  # the monitor records the environment's own reward
        env.reset()
        # the environment reports the errors the wrapper reads
        _, _, _, infos = env.venv.step(np.zeros((2, 6), np.float32))
        assert all(np.isfinite(i["position_error"]) and np.isfinite(i["orientation_error"]) for i in infos)
    finally:
        env.close()


def entry(wrapper) -> dict:
    return {"n_timesteps": 1000, "policy": "MlpPolicy", "vec_env_wrapper": wrapper}


def test_config_names_the_wrapper():
    hp = parse_hyperparameters("ppo", entry({WRAPPER: {"weight": 0.5, "position_scale": 0.003}}))
    assert hp.vec_env_wrappers == ((PrecisionReward, {"weight": 0.5, "position_scale": 0.003}),)


def test_config_errors_name_the_key():
    with pytest.raises(TrainingError, match=r"^hyperparameter vec_env_wrapper: PrecisionReward: position_scale"):
        parse_hyperparameters("ppo", entry({WRAPPER: {"position_scale": 0}}))
