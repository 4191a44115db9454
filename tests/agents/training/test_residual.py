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
    residual = np.array([[1.0, -1.0, -1.0, 1.0, 3.0, 0.0]])  # 3.0: clipped to 1 first, as SB3 clips a Box action
    # float32 commands: 1e-7 is their rounding
    assert combine(washout, residual, 0.2)[0] == pytest.approx([0.2, 0.3, -1.0, 1.0, 0.2, 0.0], abs=1e-7)


def test_a_zero_residual_drives_the_platform_as_the_washout_does():
    runs = []
    for make in (
        lambda env: WashoutPolicy(env, "washout"),
        lambda env: ResidualWashoutPolicy(env, ConstantModel(0.0), None, ResidualSettings("washout", 0.2)),
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
    env = ResidualWashoutVecEnv(raw, ResidualSettings("washout", 0.5))
    assert env.observation_space.shape == (raw.observation_space.shape[0] + 6,)
    reference = StewartPlatformSB3VecEnv(num_envs=2, max_episode_steps=None, **CUEING)
    reference.seed(0)
    washout = WashoutPolicy(reference.venv, "washout")
    obs, ref_obs = env.reset(), reference.reset()
    for _ in range(20):
        command, _ = washout.predict(ref_obs)
        assert np.array_equal(obs[:, :-6], ref_obs) and np.array_equal(obs[:, -6:], command)
        residual = np.full((2, 6), 0.1, dtype=np.float32)
        obs, reward, *_ = env.step(residual)
        ref_obs, ref_reward, *_ = reference.step(combine(command, residual, 0.5))
        assert np.array_equal(reward, ref_reward)
    env.close()
    reference.close()


def test_bad_residual_settings_are_named():
    with pytest.raises(TrainingError, match=r"residual_washout: scale must be a number in \(0, 2\], got 0"):
        residual_settings({"residual_washout": {"washout": "washout", "scale": 0}})
    with pytest.raises(TrainingError, match="unknown key\\(s\\) gain; valid: washout, scale"):
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
    assert manifest["cpu_seconds"] > 0.0 and manifest["residual"] == {"washout": "washout", "scale": 0.2}
    env = StewartPlatformVectorEnv(num_envs=1, max_episode_steps=None, **CUEING | {"task_options": {}})
    policy = load_residual(tmp_path / "agent", env)
    obs, _ = env.reset(seed=0)
    action, _ = policy.predict(obs)
    assert action.shape == (1, 6) and np.all(np.abs(action) <= 1.0)
    env.close()
    model = tmp_path / "agent" / MODEL_FILE
    model.write_bytes(model.read_bytes() + b"\0")
    with pytest.raises(TrainingError, match=f"its sha256 is not the one {MANIFEST} records"):
        load_residual(tmp_path / "agent", env)
