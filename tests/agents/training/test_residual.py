"""PPO as a residual on the washout: a zero residual is the washout, the batch's observation ends
with the washout's command, a trained agent loads back, and bad settings are named."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from stewart_env.agents.controllers.washout import WashoutPolicy  # noqa: E402
from stewart_env.agents.training import TrainingError  # noqa: E402
from stewart_env.agents.training.residual import (  # noqa: E402
    MANIFEST,
    MODEL_FILE,
    ResidualFilter,
    ResidualSettings,
    ResidualWashoutPolicy,
    ResidualWashoutVecEnv,
    combine,
    load_residual,
    residual_settings,
    train_residual,
)
from stewart_env.envs import StewartPlatformSB3VecEnv, StewartPlatformVectorEnv  # noqa: E402

CUEING = {"task": "cueing", "action_mode": "pose", "task_options": {"preview": 2}}


class ConstantModel:
    """A stand-in for an SB3 model whose residual is one constant."""

    def __init__(self, value: float):
        self.value = value

    def predict(self, observation, deterministic=True):
        return np.full((len(observation), 6), self.value, dtype=np.float32), None


def test_combine_scales_the_residual_and_clips_the_command():
    washout = np.array([[0.0, 0.5, -0.95, 0.9, 0.0, 0.0]])
    residual = np.array([[1.0, -1.0, -1.0, 1.0, 0.5, 0.0]])
    # float32 commands: 1e-7 is their rounding
    assert combine(washout, residual, 0.2)[0] == pytest.approx([0.2, 0.3, -1.0, 1.0, 0.1, 0.0], abs=1e-7)


def test_the_residuals_filter_is_a_first_order_lag_started_at_zero():
    lag = ResidualFilter(tau=0.09, dt=0.01)  # a = dt / (tau + dt) = 0.1
    outputs = [lag.step(np.full((2, 6), 3.0))[0, 0] for _ in range(3)]  # 3.0: clipped to 1 first
    assert outputs == pytest.approx([0.1, 0.19, 0.271], abs=1e-12)  # 1 - 0.9^k; 1e-12: rounding
    lag.reset(np.array([True, False]))
    assert lag.step(np.zeros((2, 6)))[:, 0] == pytest.approx([0.0, 0.2439], abs=1e-12)  # row 1: 0.271 * 0.9
    assert np.array_equal(ResidualFilter(0.0, 0.01).step(np.full((1, 6), 0.5)), np.full((1, 6), 0.5))


def test_a_zero_residual_drives_the_platform_as_the_washout_does():
    runs = []
    for make in (
        lambda env: WashoutPolicy(env, "washout"),
        lambda env: ResidualWashoutPolicy(env, ConstantModel(0.0), None, ResidualSettings("washout", 0.2, 0.5)),
    ):
        env = StewartPlatformVectorEnv(num_envs=2, max_episode_steps=None, **CUEING)
        policy = make(env)
        obs, _ = env.reset(seed=3)
        steps = []
        for _ in range(300):
            action, _ = policy.predict(obs)
            obs, reward, *_ = env.step(action)
            steps.append(np.concatenate([action, reward[:, None]], axis=1))
        env.close()
        runs.append(np.array(steps))
    assert np.array_equal(runs[0], runs[1])  # bit for bit: the same commands and rewards
    assert np.ptp(runs[0][:, :, :6]) > 0.05  # the washout moved the platform: not two idle runs compared


def test_the_batch_observes_the_washouts_command_and_steps_its_residual():
    raw = StewartPlatformSB3VecEnv(num_envs=2, max_episode_steps=None, **CUEING)
    raw.seed(0)
    env = ResidualWashoutVecEnv(raw, ResidualSettings("washout", 0.5, 0.09))  # the lag's a: 0.1
    assert env.observation_space.shape == (raw.observation_space.shape[0] + 12,)
    reference = StewartPlatformSB3VecEnv(num_envs=2, max_episode_steps=None, **CUEING)
    reference.seed(0)
    washout = WashoutPolicy(reference.venv, "washout")
    obs, ref_obs = env.reset(), reference.reset()
    lag = ResidualFilter(0.09, 0.01)
    filtered = np.zeros((2, 6))
    for _ in range(20):
        command, _ = washout.predict(ref_obs)
        assert np.array_equal(obs[:, :-12], ref_obs) and np.array_equal(obs[:, -12:-6], command)
        assert np.allclose(obs[:, -6:], filtered, atol=1e-7)  # float32 observations: 1e-7 their rounding
        residual = np.full((2, 6), 0.4, dtype=np.float32)
        filtered = lag.step(residual)
        obs, reward, *_ = env.step(residual)
        ref_obs, ref_reward, *_ = reference.step(combine(command, filtered, 0.5))
        assert np.array_equal(reward, ref_reward)
    assert filtered[0, 0] == pytest.approx(0.4 * (1 - 0.9**20), abs=1e-7)  # the lag's step response; float32 input
    env.close()
    reference.close()


def test_bad_residual_settings_are_named():
    with pytest.raises(TrainingError, match=r"residual_washout: scale must be a number in \(0, 2\], got 0"):
        residual_settings({"residual_washout": {"washout": "washout", "scale": 0}})
    with pytest.raises(TrainingError, match=r"smoothing must be a number in \[0, 10\] s, got -1"):
        residual_settings({"residual_washout": {"smoothing": -1}})
    with pytest.raises(TrainingError, match="unknown key\\(s\\) gain; valid: washout, scale, smoothing"):
        residual_settings({"residual_washout": {"gain": 1.0}})
    with pytest.raises(TrainingError, match="needs a mapping residual_washout"):
        residual_settings({"n_timesteps": 1})


@pytest.mark.extra("rl")
def test_a_trained_agent_loads_back_and_refuses_a_changed_file(tmp_path):
    config = tmp_path / "residual.yml"
    config.write_text(
        "StewartPlatform-v1:\n  n_timesteps: 64\n  residual_washout: {washout: washout, scale: 0.2}\n"
        "  env_kwargs: {action_mode: pose, max_episode_steps: 200, task_options: {training_seeds: 2}}\n"
        "  n_envs: 2\n  n_steps: 32\n  batch_size: 32\n  n_epochs: 1\n  normalize: true\n"
    )
    manifest = train_residual(tmp_path / "agent", config, seed=1)
    assert manifest["num_timesteps"] == 64  # 2 platforms x 32 steps a rollout, one rollout
    assert manifest["cpu_seconds"] > 0.0
    assert manifest["residual"] == {"washout": "washout", "scale": 0.2, "smoothing": 0.0}
    env = StewartPlatformVectorEnv(num_envs=1, max_episode_steps=None, **CUEING | {"task_options": {}})
    policy = load_residual(tmp_path / "agent", env)
    obs, _ = env.reset(seed=0)
    action, _ = policy.predict(obs)
    assert action.shape == (1, 6) and np.all(np.abs(action) <= 1.0)
    env.close()
    model = tmp_path / "agent" / MODEL_FILE
    model.write_bytes(model.read_bytes() + b"\0")
    with pytest.raises(TrainingError, match=f"its sha256 does not match {MANIFEST}: the file was changed"):
        load_residual(tmp_path / "agent", env)
    # a file the manifest lists but the folder lost: a named error, not a raw OSError
    model.unlink()
    with pytest.raises(TrainingError, match=f"{MODEL_FILE}: missing \\({MANIFEST} lists it\\)"):
        load_residual(tmp_path / "agent", env)
