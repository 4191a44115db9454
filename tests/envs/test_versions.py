"""The environment's versions: ``StewartPlatform-v1`` (current) and ``-v0`` (the earlier reward),
each the same through gymnasium.make, the vector entry point and the SB3 VecEnv."""

from __future__ import annotations

import json
import warnings

import gymnasium as gym
import numpy as np
import pytest

import stewart_env  # noqa: F401  (registers the ids)
from stewart_env.envs import StewartPlatformEnv, StewartPlatformVectorEnv, holding_action
from stewart_env.registration import CURRENT_VERSION, ENV_ID, ENV_IDS
from stewart_env.tasks.base import BASE_REWARD_SCALES, PRECISE_REWARD_SCALES

V0, V1 = ENV_IDS[0], ENV_IDS[1]
# the default success band: a 2 mm position error, as a user of the tracking tasks meets it
OFFSET = np.array([0.002, 0.0, 0.0])


def make(env_id: str, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # Gymnasium: "-v0 is out of date"
        return gym.make(env_id, **kwargs)


def make_vec(env_id: str, num_envs: int, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        return gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)


def position_reward_at_2mm(env) -> tuple[float, float]:
    """(reward_position, error after the step) of a step held still 2 mm off the target."""
    env.reset(seed=3)
    u = env.unwrapped
    u.set_state(u.target.position - OFFSET, u.target.rotation)
    _, _, _, _, info = env.step(holding_action(env))
    return info["reward_position"], float(np.linalg.norm(u.target.position - u.state.position))


def test_ids_are_registered_by_version_with_v1_current():
    assert ENV_ID == V1 == "StewartPlatform-v1" and V0 == "StewartPlatform-v0" and CURRENT_VERSION == 1
    for version, env_id in ENV_IDS.items():
        spec = gym.spec(env_id)
        assert spec.kwargs == {"version": version}
        assert spec.max_episode_steps == 500
        assert spec.entry_point == "stewart_env.envs.stewart_platform:StewartPlatformEnv"
        assert spec.vector_entry_point == "stewart_env.envs.vector:StewartPlatformVectorEnv"


def test_making_v0_warns_that_it_is_out_of_date():
    with pytest.warns(DeprecationWarning, match="StewartPlatform-v0 is out of date.*v1"):
        gym.make(V0)


@pytest.mark.parametrize("task", ["tracking", "disturbance"])
def test_v0_and_v1_rewards_at_a_2mm_error(task):
    for env_id, (position_scale, orientation_scale) in ((V0, BASE_REWARD_SCALES), (V1, PRECISE_REWARD_SCALES)):
        env = make(env_id, task=task)
        reward, error = position_reward_at_2mm(env)
        assert error == pytest.approx(0.002, abs=2e-4)  # held by its weight: 2 mm moves little in 10 ms
        # the same formula on the same floats, up to the order of the norm's sum
        assert reward == pytest.approx(0.5 * np.exp(-error / position_scale), rel=1e-12)
        weights = env.unwrapped.task.weights
        assert (weights.position_reward_scale, weights.orientation_reward_scale) == (position_scale, orientation_scale)
    # what the versions mean at 2 mm: about 0.48 (v0) against 0.41 (v1) of the term's 0.5
    assert 0.5 * np.exp(-0.002 / 0.05) == pytest.approx(0.4804, abs=1e-4)
    assert 0.5 * np.exp(-0.002 / 0.01) == pytest.approx(0.4094, abs=1e-4)


@pytest.mark.parametrize("task", ["tracking", "disturbance"])
def test_options_given_win_over_the_versions_defaults(task):
    scales = {"position_reward_scale": 0.2, "orientation_reward_scale": 0.3}
    for env_id in (V0, V1):
        weights = make(env_id, task=task, task_options=scales).unwrapped.task.weights
        assert (weights.position_reward_scale, weights.orientation_reward_scale) == (0.2, 0.3)
    # v1 told v0's scales is v0, step for step
    rewards = []
    for env_id, options in ((V0, {}), (V1, dict(zip(scales, BASE_REWARD_SCALES)))):
        env = make(env_id, task=task, task_options=options)
        env.reset(seed=5)
        rewards.append([env.step(np.full(6, 0.1 * k, np.float32))[1] for k in range(5)])
    assert rewards[0] == rewards[1]


@pytest.mark.parametrize("task", ["setpoint", "hold"])
def test_the_other_tasks_are_the_same_on_both(task):
    runs = []
    for env_id in (V0, V1):
        env = make(env_id, task=task)
        obs, _ = env.reset(seed=11)
        rng = np.random.default_rng(0)
        steps = [env.step(rng.uniform(-0.2, 0.2, 6).astype(np.float32)) for _ in range(20)]
        runs.append((obs, [(o, r, t, info["reward_position"]) for o, r, t, _, info in steps]))
    (obs0, steps0), (obs1, steps1) = runs
    np.testing.assert_array_equal(obs0, obs1)
    for (o0, r0, t0, p0), (o1, r1, t1, p1) in zip(steps0, steps1):
        np.testing.assert_array_equal(o0, o1)
        assert (r0, t0, p0) == (r1, t1, p1)  # bit for bit: the same computation


@pytest.mark.parametrize("task", ["tracking", "disturbance"])
def test_the_vector_entry_point_and_sb3_vecenv_follow_the_version(task):
    for env_id, version, scales in ((V0, 0, BASE_REWARD_SCALES), (V1, 1, PRECISE_REWARD_SCALES)):
        envs = make_vec(env_id, 3, task=task)
        assert isinstance(envs, StewartPlatformVectorEnv)
        weights = envs.task.weights
        assert (weights.position_reward_scale, weights.orientation_reward_scale) == scales
        # row 0 of the batch earns what the single environment earns, step for step
        single = make(env_id, task=task)
        obs, _ = envs.reset(seed=7)
        single_obs, _ = single.reset(seed=7)
        np.testing.assert_array_equal(obs[0], single_obs)
        for k in range(5):
            action = np.full((3, 6), 0.05 * k, np.float32)
            _, reward, *_ = envs.step(action)
            _, single_reward, *_ = single.step(action[0])
            assert reward[0] == single_reward
        envs.close()
        sb3 = pytest.importorskip("stewart_env.envs.sb3")
        venv = sb3.StewartPlatformSB3VecEnv(num_envs=2, task=task, version=version)
        assert venv.get_attr("task")[0].weights.position_reward_scale == scales[0]
    # the classes, not told a version, are the current one
    assert StewartPlatformEnv(task=task).task.weights.position_reward_scale == PRECISE_REWARD_SCALES[0]


@pytest.mark.parametrize("version", [-1, 2, 1.0, True, "1"])
def test_an_unknown_version_is_refused_naming_the_argument(version):
    with pytest.raises(ValueError, match=r"^version: expected an integer in \[0, 1\]"):
        StewartPlatformEnv(version=version)


@pytest.mark.slow
def test_an_agent_trained_under_v0_still_loads(tmp_path):
    # A run folder written before v1 existed records env_id StewartPlatform-v0 in run.json.
    training = pytest.importorskip("stewart_env.agents.training")
    from stewart_env.agents import evaluate

    out = tmp_path / "run"
    training.train("ppo", out, task="tracking", timesteps=100, seed=0, n_envs=1, progress_bar=False)
    manifest = json.loads((out / "run.json").read_text())
    assert manifest["env_id"] == V1
    manifest["env_id"] = V0
    (out / "run.json").write_text(json.dumps(manifest))
    agent = training.load_agent(out)
    assert agent.manifest["env_id"] == V0
    for version in (0, 1):
        result = evaluate(
            agent, {**agent.env_kwargs, "version": version}, episodes=1, seed=0, max_steps=5, progress=False
        )
        assert np.isfinite(result.summary()["rms_position_error"])
