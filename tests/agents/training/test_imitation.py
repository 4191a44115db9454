"""PPO from an imitation of the cueing MPC: the settings are checked and named, the
standardisation round-trips, the fit learns a known map, the MPC's own inputs reproduce its
actions through the agent's path, and a trained agent loads back and refuses a changed file."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from stewart_env.agents.training import TrainingError  # noqa: E402
from stewart_env.agents.training.imitation import (  # noqa: E402
    ACTION_BOUND,
    FEATURES,
    MANIFEST,
    MODEL_FILE,
    SCALES_FILE,
    ImitationSettings,
    Standardisation,
    fit_clone,
    imitation_settings,
    load_imitation,
    train_imitation,
)
from stewart_env.envs import StewartPlatformVectorEnv  # noqa: E402


def _config(tmp_path, name: str, entry: str):
    """A zoo config file of one StewartPlatform-v1 entry (its YAML lines, indented by two)."""
    path = tmp_path / name
    path.write_text("StewartPlatform-v1:\n" + entry)
    return path


def test_bad_imitation_settings_are_named():
    with pytest.raises(TrainingError, match=r"imitate_mpc: seeds must be an integer in \[1, 64\], got 0"):
        imitation_settings({"imitate_mpc": {"seeds": 0}})
    with pytest.raises(TrainingError, match=r"imitate_mpc: rounds must be an integer in \[0, 10\], got 1.5"):
        imitation_settings({"imitate_mpc": {"rounds": 1.5}})
    with pytest.raises(TrainingError, match=r"imitate_mpc: learning_rate must be a number in \(0, 1\], got nan"):
        imitation_settings({"imitate_mpc": {"learning_rate": float("nan")}})
    with pytest.raises(TrainingError, match=r"unknown key\(s\) gain; valid: seeds, max_steps, rounds"):
        imitation_settings({"imitate_mpc": {"gain": 1.0}})
    with pytest.raises(TrainingError, match="needs a mapping imitate_mpc"):
        imitation_settings({"imitate_mpc": [1]})
    settings, rest = imitation_settings({"imitate_mpc": {"seeds": 2}, "n_timesteps": 5})
    assert settings == ImitationSettings(seeds=2) and rest == {"n_timesteps": 5}


def test_bad_residual_settings_are_named():
    with pytest.raises(TrainingError, match=r"residual_mpc: residual_scale must be given, > 0"):
        imitation_settings({"residual_mpc": {"seeds": 1}})
    with pytest.raises(TrainingError, match=r"residual_scale must be a number in \[0, 10\], got nan"):
        imitation_settings({"residual_mpc": {"residual_scale": float("nan")}})
    with pytest.raises(TrainingError, match=r"residual_mpc: a residual on the MPC has no DAgger rounds, got rounds=1"):
        imitation_settings({"residual_mpc": {"residual_scale": 1.0, "rounds": 1}})
    with pytest.raises(TrainingError, match=r"residual_mpc: seeds must be an integer in \[1, 64\], got 0"):
        imitation_settings({"residual_mpc": {"residual_scale": 1.0, "seeds": 0}})
    with pytest.raises(TrainingError, match=r"imitate_mpc: residual_scale is residual_mpc's"):
        imitation_settings({"imitate_mpc": {"residual_scale": 1.0}})
    with pytest.raises(
        TrainingError, match=r"give one of imitate_mpc or residual_mpc, got \['imitate_mpc', 'residual_mpc'\]"
    ):
        imitation_settings({"imitate_mpc": {}, "residual_mpc": {"residual_scale": 1.0}})
    settings, rest = imitation_settings({"residual_mpc": {"residual_scale": 0.5}, "n_timesteps": 5})
    assert settings.residual and settings.key == "residual_mpc" and rest == {"n_timesteps": 5}


def test_the_standardisation_round_trips_and_bounds_the_action():
    rng = np.random.default_rng(0)
    x, u = rng.normal(3.0, 2.0, (500, 4 + FEATURES)), rng.normal([0, 1, 2, 3, 4, 5], [1, 2, 3, 4, 5, 6], (500, 6))
    scales = Standardisation.of(x, u)
    np.testing.assert_allclose(scales.inputs(scales.actions(u)).reshape(-1, 6), u, rtol=0, atol=1e-5)  # float32 actions
    observed = scales.observed(x[:, :4], x[:, 4:])
    np.testing.assert_allclose(observed.mean(axis=0), 0.0, atol=1e-6)  # float32 rounding of 500 values
    np.testing.assert_allclose(observed.std(axis=0), 1.0, atol=1e-6)
    far = scales.inputs(np.full((1, 6), 1e9)).reshape(6)
    np.testing.assert_allclose(far, scales.u_mean + ACTION_BOUND * scales.u_scale)  # clipped at the action's bound
    correction = scales.residual(np.array([[1.0, -2.0, 0.0, 0.5, 1e9, -1e9]]), 0.5).reshape(6)
    np.testing.assert_allclose(
        correction, [0.5, -1.0, 0.0, 0.25, 0.5 * ACTION_BOUND, -0.5 * ACTION_BOUND] * scales.u_scale
    )


def test_the_fit_learns_a_linear_map():
    import torch
    from gymnasium import spaces
    from stable_baselines3.common.policies import ActorCriticPolicy

    rng = np.random.default_rng(1)
    x = rng.normal(size=(4000, 8)).astype(np.float32)
    weights = rng.normal(size=(8, 6)) / 4.0
    y = (x @ weights).astype(np.float32)
    policy = ActorCriticPolicy(
        spaces.Box(-np.inf, np.inf, (8,), np.float32),
        spaces.Box(-ACTION_BOUND, ACTION_BOUND, (6,), np.float32),
        lambda _: 1e-3,
        net_arch=dict(pi=[64, 64], vf=[8]),
        activation_fn=torch.nn.Tanh,
    )
    before = float(np.mean(y**2))
    after = fit_clone(policy, x, y, ImitationSettings(epochs=40, batch_size=128, learning_rate=3e-3), seed=0)
    assert after < 0.01 * before  # a 64-64 tanh network fits a linear map of 8 inputs to 1 % of its variance


@pytest.mark.extra("rl", "mpc")
def test_the_mpcs_own_inputs_give_its_actions_through_the_agents_path():
    from stewart_env.agents.controllers.cueing_mpc import CueingMPCPolicy

    kwargs = dict(task="cueing", action_mode="pose", task_options={"preview": 5, "motions": ("braking",)})
    first, second = (StewartPlatformVectorEnv(num_envs=2, **kwargs) for _ in range(2))
    mpc, split = CueingMPCPolicy(first), CueingMPCPolicy(second)
    a, _ = first.reset(seed=4)
    b, _ = second.reset(seed=4)
    for _ in range(60):
        action, _ = mpc.predict(a)
        split.prepare(b)
        again = split.command(split.mpc.solve())
        assert np.array_equal(action, again)  # predict is prepare, solve, command: the same arithmetic
        a, *_ = first.step(action)
        b, *_ = second.step(again)
    first.close()
    second.close()


@pytest.mark.extra("rl", "mpc")
def test_a_trained_agent_loads_back_and_refuses_a_changed_file(tmp_path):
    config = _config(
        tmp_path,
        "imitation.yml",
        "  n_timesteps: 64\n"
        "  imitate_mpc: {seeds: 1, max_steps: 30, rounds: 1, epochs: 2, batch_size: 64}\n"
        "  env_kwargs: {action_mode: pose, max_episode_steps: 200, task_options: {preview: 3, training_seeds: 1}}\n"
        "  n_envs: 2\n  n_steps: 32\n  batch_size: 32\n  n_epochs: 1\n  normalize: true\n",
    )
    manifest = train_imitation(tmp_path / "agent", config, seed=1)
    assert manifest["num_timesteps"] == 64  # 2 platforms x 32 steps a rollout, one rollout
    assert manifest["samples"][0] == 7 * 30  # seven training motions, 30 steps each, none ended sooner
    assert len(manifest["samples"]) == 2 and len(manifest["clone_mse"]) == 2  # the demonstrations, one DAgger round
    assert set(manifest["cpu_seconds_by_stage"]) == {"demonstrations", "cloning", "dagger", "ppo"}
    env = StewartPlatformVectorEnv(num_envs=1, task="cueing", action_mode="pose", task_options={"preview": 3})
    policy = load_imitation(tmp_path / "agent", env)
    obs, _ = env.reset(seed=0)
    action, _ = policy.predict(obs)
    assert action.shape == (1, 6) and np.all(np.abs(action) <= 1.0)
    env.close()
    scales = tmp_path / "agent" / SCALES_FILE
    scales.write_bytes(scales.read_bytes() + b"\0")
    with pytest.raises(TrainingError, match=f"its sha256 does not match {MANIFEST}: the file was changed"):
        load_imitation(tmp_path / "agent", env)
    (tmp_path / "agent" / MODEL_FILE).unlink()
    with pytest.raises(TrainingError, match=f"{MODEL_FILE}: missing \\({MANIFEST} lists it\\)"):
        load_imitation(tmp_path / "agent", env)
    (tmp_path / "agent" / MANIFEST).write_text("{")
    with pytest.raises(TrainingError, match="no imitation agent"):
        load_imitation(tmp_path / "agent", env)


@pytest.mark.extra("rl", "mpc")
def test_an_environment_without_a_preview_is_refused(tmp_path):
    config = _config(
        tmp_path,
        "imitation.yml",
        "  n_timesteps: 0\n  imitate_mpc: {seeds: 1, max_steps: 10}\n"
        "  env_kwargs: {action_mode: pose}\n  n_envs: 2\n  n_steps: 32\n  batch_size: 32\n",
    )
    with pytest.raises(TrainingError, match="needs the task option preview > 0"):
        train_imitation(tmp_path / "agent", config)


@pytest.mark.extra("rl", "mpc")
def test_an_untrained_residual_on_the_mpc_is_the_mpc(tmp_path):
    from stewart_env.agents.controllers.cueing_mpc import CueingMPCPolicy

    config = _config(
        tmp_path,
        "residual.yml",
        "  n_timesteps: 0\n"
        "  residual_mpc: {seeds: 1, max_steps: 20, residual_scale: 2.0}\n"
        "  env_kwargs: {action_mode: pose, max_episode_steps: 200, task_options: {preview: 5, training_seeds: 1}}\n"
        "  n_envs: 2\n  n_steps: 32\n  batch_size: 32\n  normalize: true\n",
    )
    manifest = train_imitation(tmp_path / "agent", config, seed=0)
    assert manifest["clone_mse"] == [] and manifest["imitation"]["residual_scale"] == 2.0  # no fit
    kwargs = dict(task="cueing", action_mode="pose", task_options={"preview": 5, "motions": ("braking",)})
    first, second = (StewartPlatformVectorEnv(num_envs=2, **kwargs) for _ in range(2))
    mpc, agent = CueingMPCPolicy(first), load_imitation(tmp_path / "agent", second)
    assert agent.residual_scale == 2.0
    a, _ = first.reset(seed=3)
    b, _ = second.reset(seed=3)
    for _ in range(40):
        action, _ = mpc.predict(a)
        again, _ = agent.predict(b)
        assert np.array_equal(action, again)  # a zero mean adds exactly nothing to the MPC's inputs
        a, *_ = first.step(action)
        b, *_ = second.step(again)
    agent.model.policy.action_net.bias.data.fill_(1.0)  # a correction of one unit on every input
    moved, _ = agent.predict(b)
    assert not np.array_equal(moved, mpc.predict(a)[0])
    first.close()
    second.close()
    trained = train_imitation(tmp_path / "trained", config, seed=0, timesteps=64)
    assert trained["num_timesteps"] == 64 and trained["samples"] == manifest["samples"]  # PPO through the MPC
