"""The training wrapper that penalises the action's change (ActionRatePenalty) and its config hook."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from scripted_batch import ScriptedBatch  # noqa: E402
from stable_baselines3.common.vec_env import VecMonitor, VecNormalize  # noqa: E402

from stewart_env.agents.training import (  # noqa: E402
    TrainingError,
    make_training_env,
    parse_hyperparameters,
    read_hyperparameters,
)
from stewart_env.agents.training.action_rate import ActionRatePenalty, action_rate_penalty  # noqa: E402
from stewart_env.errors import UsageError  # noqa: E402

WRAPPER = "stewart_env.agents.training.action_rate.ActionRatePenalty"


def step(env: ActionRatePenalty, actions) -> np.ndarray:
    env.step_async(np.asarray(actions, dtype=np.float32))
    return env.step_wait()[1]


def test_penalty_by_hand():
    env = ActionRatePenalty(ScriptedBatch(), weight=0.5)
    env.reset()
    # the first step has no previous action: no penalty
    np.testing.assert_array_equal(step(env, [[0.0, 0.0], [1.0, 1.0]]), [1.0, 1.0])
    # row 0: 0.5 * mean(0.2^2, 0.4^2) = 0.05; row 1: 0.5 * mean(0, 1^2) = 0.25
    rewards = step(env, [[0.2, -0.4], [1.0, 0.0]])
    np.testing.assert_allclose(rewards, [0.95, 0.75], rtol=1e-6)  # float32 rewards, as SB3's batches give
    assert rewards.dtype == np.float32
    # the same action again: no change, no penalty
    np.testing.assert_array_equal(step(env, [[0.2, -0.4], [1.0, 0.0]]), [1.0, 1.0])


def test_a_row_reset_forgets_its_previous_action_only():
    batch = ScriptedBatch()
    env = ActionRatePenalty(batch, weight=1.0)
    env.reset()
    step(env, [[0.0, 0.0], [0.0, 0.0]])
    batch.dones[:] = [True, False]  # row 0's episode ends on this step; the batch resets that row
    # this step's change is penalised in both rows (row 0's last step of its episode): mean(1, 1) = 1
    np.testing.assert_allclose(step(env, [[1.0, 1.0], [1.0, 1.0]]), [0.0, 0.0], atol=1e-7)
    batch.dones[:] = False
    # row 0 starts a new episode: its jump to -1 is free; row 1's is penalised: mean(2^2, 2^2) = 4
    np.testing.assert_allclose(step(env, [[-1.0, -1.0], [-1.0, -1.0]]), [1.0, -3.0], rtol=1e-6)


def test_reset_forgets_every_previous_action():
    env = ActionRatePenalty(ScriptedBatch(), weight=1.0)
    env.reset()
    step(env, [[1.0, 1.0], [1.0, 1.0]])
    env.reset()
    np.testing.assert_array_equal(step(env, [[-1.0, -1.0], [-1.0, -1.0]]), [1.0, 1.0])


def test_actions_are_clipped_to_the_action_space_and_sent_on_unchanged():
    batch = ScriptedBatch()
    env = ActionRatePenalty(batch, weight=1.0)
    env.reset()
    step(env, [[0.0, 0.0], [0.0, 0.0]])
    # 3 is clipped to 1 (what the environment receives): mean(1, 0) = 0.5, not mean(9, 0) = 4.5
    np.testing.assert_allclose(step(env, [[3.0, 0.0], [0.0, 0.0]]), [0.5, 1.0], rtol=1e-6)
    np.testing.assert_array_equal(batch.received, [[3.0, 0.0], [0.0, 0.0]])


def test_penalty_function_rows():
    penalties = action_rate_penalty(np.array([[1.0, 3.0]] * 2), np.zeros((2, 2)), np.array([True, False]), 2.0)
    np.testing.assert_array_equal(penalties, [10.0, 0.0])  # 2 * mean(1, 9) = 10; row 1 has no previous


@pytest.mark.parametrize("weight", [-0.1, math.nan, math.inf, True, "1"])
def test_bad_weight_is_refused_naming_it(weight):
    with pytest.raises(UsageError, match=r"^weight: expected a finite number >= 0"):
        ActionRatePenalty(ScriptedBatch(), weight=weight)


def test_training_env_puts_the_wrapper_between_monitor_and_normalisation():
    env = make_training_env(2, {"action_mode": "pose"}, 0, {}, wrappers=((ActionRatePenalty, {"weight": 0.3}),))
    try:
        assert isinstance(env, VecNormalize)
        assert isinstance(env.venv, ActionRatePenalty) and env.venv.weight == 0.3
        assert isinstance(env.venv.venv, VecMonitor)  # the monitor records the environment's own reward
    finally:
        env.close()


def test_shipped_pose_config_trains_with_the_penalty_and_the_precision_reward():
    from stewart_env.agents.training.precision import PrecisionReward

    hp = parse_hyperparameters("ppo", read_hyperparameters("ppo", "ppo_pose"))
    assert [(cls, options) for cls, options in hp.vec_env_wrappers] == [
        (ActionRatePenalty, {"weight": 2.0}),
        (PrecisionReward, {"weight": 0.5, "position_scale": 0.01, "orientation_scale": 0.02}),
    ]
    assert "vec_env_wrapper" not in hp.algorithm_kwargs


def entry(wrapper) -> dict:
    return {"n_timesteps": 1000, "policy": "MlpPolicy", "vec_env_wrapper": wrapper}


@pytest.mark.parametrize(
    "wrapper, expected",
    [
        (WRAPPER, ((ActionRatePenalty, {}),)),
        ({WRAPPER: {"weight": 0.5}}, ((ActionRatePenalty, {"weight": 0.5}),)),
        ([{WRAPPER: None}], ((ActionRatePenalty, {}),)),
        (None, ()),
    ],
)
def test_config_forms(wrapper, expected):
    assert parse_hyperparameters("ppo", entry(wrapper)).vec_env_wrappers == expected


@pytest.mark.parametrize(
    "wrapper, message",
    [
        ("os.system", r"'os.system' is not a wrapper stewart-env trains with"),
        ({WRAPPER: {"wieght": 1}}, r"ActionRatePenalty: unknown keyword argument\(s\) wieght; valid: weight"),
        ({WRAPPER: {"weight": -1}}, r"ActionRatePenalty: weight: expected a finite number >= 0"),
        ({WRAPPER: [1]}, r"expected a class path or a mapping of one class path"),
        (3, r"expected a class path or a mapping of one class path"),
    ],
)
def test_config_errors_name_the_key(wrapper, message):
    with pytest.raises(TrainingError, match=r"^hyperparameter vec_env_wrapper: " + message):
        parse_hyperparameters("ppo", entry(wrapper))
