"""The environment on MuJoCo's simulation of the same mechanism: plant="mujoco" (or model="mujoco")."""

import copy
import pickle

import gymnasium as gym
import numpy as np
import pytest

import stewart_env.mujoco as twin
import stewart_env.registration  # noqa: F401  (registers StewartPlatform-v1)
from stewart_env.envs import StewartPlatformEnv, holding_action

pytestmark = pytest.mark.env

ENV_ID = "StewartPlatform-v1"
FIXED = {"task": "setpoint", "task_options": {"randomize": False}}


@pytest.fixture
def mujoco():
    return pytest.importorskip("mujoco")


def test_the_same_task_runs_on_mujoco_and_agrees_with_the_exact_model(mujoco):
    plant, exact = gym.make(ENV_ID, model="mujoco", **FIXED), gym.make(ENV_ID, **FIXED)
    obs_m, _ = plant.reset(seed=0)
    obs_c, _ = exact.reset(seed=0)
    np.testing.assert_array_equal(obs_m, obs_c)  # the same start: the plant starts from the task's state
    assert plant.unwrapped.observation_layout == exact.unwrapped.observation_layout
    target = exact.unwrapped.target
    a = holding_action(exact, target.position, target.rotation)
    for _ in range(30):
        obs_m, reward_m, terminated, _, info_m = plant.step(a)
        obs_c, reward_c, _, _, info_c = exact.step(a)
    assert not terminated
    assert set(info_m) == set(info_c) | {"closure_error"}
    assert type(info_m["closure_error"]) is np.float64
    # MuJoCo closes the six loops with soft constraints: gaps of tens of nanometres at its defaults
    # (stewart_env.mujoco.DEFAULT_SOLREF); 1 um would be a loop coming apart.
    assert 0.0 < info_m["closure_error"] < 1e-6
    # 0.3 s from the same state under the same forces: the two engines agree to ~1e-8 m (measured
    # 1.4e-8 m over 0.5 s); 1e-6 m is far below any motion the forces cause (the start is 5 mm off).
    np.testing.assert_allclose(plant.unwrapped.state.position, exact.unwrapped.state.position, rtol=0, atol=1e-6)
    assert reward_m == pytest.approx(reward_c, abs=1e-5)  # the same reward terms of nearly the same state


def test_a_vector_row_on_mujoco_is_the_single_env_bit_for_bit(mujoco):
    envs = gym.make_vec(ENV_ID, num_envs=3, vectorization_mode="vector_entry_point", model="mujoco", task="hold")
    single = gym.make(ENV_ID, model="mujoco", task="hold")
    obs_v, _ = envs.reset(seed=0)
    obs_s, _ = single.reset(seed=1)
    np.testing.assert_array_equal(obs_v[1], obs_s)
    a = holding_action(single)
    for _ in range(10):
        obs_v, reward_v, _, _, infos = envs.step(np.tile(a, (3, 1)))
        obs_s, reward_s, _, _, info = single.step(a)
        np.testing.assert_array_equal(obs_v[1], obs_s)
        assert reward_v[1] == reward_s and infos["closure_error"][1] == info["closure_error"]
    assert infos["_closure_error"].all()


def test_the_sb3_adapter_steps_a_mujoco_batch(mujoco):
    pytest.importorskip("stable_baselines3")
    from stewart_env.envs import StewartPlatformSB3VecEnv

    venv = StewartPlatformSB3VecEnv(num_envs=2, model="mujoco", task="hold")
    obs = venv.reset()
    a = np.tile(holding_action(venv.venv._row(0)), (2, 1))
    for _ in range(3):
        obs, reward, done, infos = venv.step(a)
    assert obs.shape == (2, venv.observation_space.shape[0]) and np.all(np.isfinite(reward)) and not done.any()


def test_randomised_rows_give_the_plant_their_parameters(mujoco):
    env = StewartPlatformEnv(model="mujoco", task="hold", randomization={"platform.mass": (1.5, 2.0)})
    env.reset(seed=0)
    assert env.plant.params[0] is env.episode_params
    assert 1.5 * env.platform.platform.mass <= env.episode_params.platform.mass <= 2.0 * env.platform.platform.mass
    env.step(holding_action(env))


@pytest.mark.parametrize("how", [copy.deepcopy, lambda env: pickle.loads(pickle.dumps(env))])
def test_a_copy_on_mujoco_continues_bit_for_bit(mujoco, how):
    env = StewartPlatformEnv(model="mujoco", task="hold", randomization={"platform.mass": (0.8, 1.2)})
    env.reset(seed=0)
    a = holding_action(env)
    for _ in range(3):
        env.step(a)
    twin_env = how(env)
    assert twin_env.plant is not env.plant
    for _ in range(5):
        obs, reward, _, _, info = env.step(a)
        obs_twin, reward_twin, _, _, info_twin = twin_env.step(a)
        np.testing.assert_array_equal(obs_twin, obs)
        assert reward_twin == reward and info_twin["closure_error"] == info["closure_error"]


def test_without_mujoco_the_error_names_the_model_and_the_extra(monkeypatch):
    monkeypatch.setattr(twin.library, "_mj", None)
    with pytest.raises(
        ImportError, match=r"plant='mujoco' \(or model='mujoco'\): .*mujoco.* is not installed.*pip install"
    ):
        gym.make(ENV_ID, model="mujoco")


def test_plant_mujoco_is_model_mujoco_on_the_improved_model(mujoco):
    """The two spellings make the same environment: the MuJoCo plant, the improved model, the same steps."""
    new, old = StewartPlatformEnv(plant="mujoco", **FIXED), StewartPlatformEnv(model="mujoco", **FIXED)
    for env in (new, old):
        assert env.plant.name == "mujoco" and isinstance(env.plant, twin.MujocoPlant)
        assert env.model.name == "improved"
        env.reset(seed=0)
    a = holding_action(new)
    for _ in range(3):
        obs_new, reward_new, _, _, info_new = new.step(a)
        obs_old, reward_old, _, _, info_old = old.step(a)
    np.testing.assert_array_equal(obs_new, obs_old)
    assert reward_new == reward_old and info_new == info_old


def test_the_mujoco_plant_answers_the_plant_interface(mujoco):
    from stewart_env.envs.plant import Plant

    env = StewartPlatformEnv(plant="mujoco", model="classical")
    assert isinstance(env.plant, Plant)
    assert env.model.name == "classical"  # the closed-form model of the sensors and the holding forces
