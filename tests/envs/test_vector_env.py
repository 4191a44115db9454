"""Tests of the vector environment and the stable-baselines3 adapter (stewart_env.envs.vector, .sb3)."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import stewart_env.registration  # noqa: F401  (registers StewartPlatform-v1)
from stewart_env.envs import StewartPlatformVectorEnv
from stewart_env.envs import core as core_module
from stewart_env.envs import plant as plant_module
from stewart_env.envs.config import EnvConfig

pytestmark = pytest.mark.env

ENV_ID = "StewartPlatform-v1"
CONFIGS = [
    {},
    {
        "task": "tracking",
        "observation_noise": 0.02,
        "observation_delay": 1,
        "randomization": {"mass": (0.8, 1.2), "inertia": (0.9, 1.1), "damping": (0.5, 2.0)},
    },
    {"task": "disturbance", "actuator_tau": 0.02, "model": "classical"},
    {"task": "hold", "error_integral": True, "randomization": {"platform.mass": (0.8, 1.2)}},
]


def make_vec(num_envs, **kwargs):
    return gym.make_vec(ENV_ID, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)


def actions_for(n_steps, n_envs, seed=0):
    """Actions around the holding force (a ~ 0.1): episodes last tens of steps, so the runs below
    cross several autoresets."""
    return np.random.default_rng(seed).uniform(-0.3, 0.5, (n_steps, n_envs, 6))


def test_make_vec_uses_the_native_vector_env():
    envs = make_vec(3)
    assert isinstance(envs.unwrapped, StewartPlatformVectorEnv)
    assert envs.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert envs.observation_space.shape == (3, 21) and envs.action_space.shape == (3, 6)
    assert envs.single_observation_space.dtype == np.float32
    obs, _ = envs.reset(seed=0)
    assert obs.shape == (3, 21) and obs.dtype == np.float32
    assert envs.unwrapped.max_episode_steps == 500


@pytest.mark.parametrize("kwargs", CONFIGS)
def test_row_i_equals_a_single_env_seeded_seed_plus_i(kwargs):
    # 13 rows: a block of vector lanes and five rows alone, shared with the helper threads
    n, seed, steps = 13, 21, 120
    envs = make_vec(n, max_episode_steps=40, **kwargs)
    singles = [gym.make(ENV_ID, max_episode_steps=40, **kwargs) for _ in range(n)]
    actions = actions_for(steps, n)
    v_obs, _ = envs.reset(seed=seed)
    s_obs = [env.reset(seed=seed + i)[0] for i, env in enumerate(singles)]
    pending = [False] * n
    resets = 0
    for k in range(steps):
        np.testing.assert_array_equal(v_obs, np.array(s_obs))
        v_obs, v_rew, v_term, v_trunc, v_info = envs.step(actions[k].astype(np.float32))
        for i, env in enumerate(singles):
            if pending[i]:
                # Next-step autoreset: this step resets the row and ignores its action.
                s_obs[i], _ = env.reset()
                rew, term, trunc = 0.0, False, False
                resets += 1
            else:
                s_obs[i], rew, term, trunc, info = env.step(actions[k, i].astype(np.float32))
                assert {key: v_info[key][i] for key in info} == info, (k, i)
            assert v_rew[i] == rew and v_term[i] == term and v_trunc[i] == trunc, (k, i)
            pending[i] = term or trunc
    assert resets >= n, "the run should cross autoresets"


def test_same_seed_gives_bit_identical_vector_trajectories():
    actions = actions_for(60, 4, seed=1)
    runs = []
    for _ in range(2):
        envs = make_vec(4, **CONFIGS[1])
        out = [envs.reset(seed=5)[0]]
        for a in actions:
            obs, rew, *_ = envs.step(a)
            out += [obs, rew[:, None]]
        runs.append(np.concatenate([x.reshape(4, -1) for x in out], axis=1))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_one_compiled_control_step_per_step(monkeypatch):
    """The whole batch's control step (actuators, RK4 substeps, sensors, errors, termination,
    reward, observation) in one compiled call."""
    calls = []
    original = core_module._core.BatchStep.step

    def counting(self, action, *args):
        calls.append(action.shape[0])
        return original(self, action, *args)

    monkeypatch.setattr(core_module._core.BatchStep, "step", counting)
    monkeypatch.setattr(plant_module, "rollout_inplace", None)  # the plant's own path is not taken
    envs = make_vec(16)
    envs.reset(seed=0)
    for a in actions_for(30, 16):
        envs.step(a)
    assert calls == [16] * 30


def test_domain_randomisation_per_row():
    spec = {"platform.mass": (0.5, 1.5), "damping": (0.5, 2.0)}
    envs = make_vec(4, randomization=spec)
    _, infos = envs.reset(seed=0)
    model = envs.unwrapped.model
    assert model.packed.shape[0] == 4
    masses = [p.platform.mass for p in model.params]
    assert len(set(masses)) == 4
    assert infos["_randomization"].all()
    np.testing.assert_allclose(
        infos["randomization"]["platform.mass"] * envs.unwrapped.platform.platform.mass, masses, rtol=1e-15
    )  # the factor times the nominal mass
    assert envs.unwrapped.episode_params == tuple(model.params)
    assert envs.unwrapped.get_attr("episode_params") == tuple(model.params)


def test_next_step_autoreset_infos_follow_gymnasium():
    envs = make_vec(2, max_episode_steps=3, randomization={"mass": (0.9, 1.1)})
    envs.reset(seed=0)
    a = np.full((2, 6), 0.09)
    for _ in range(3):
        _, _, _, truncated, infos = envs.step(a)
    assert truncated.all()
    assert infos["_reward_position"].all() and infos["termination"].tolist() == [0, 0]
    obs, reward, terminated, truncated, infos = envs.step(a)
    assert np.all(reward == 0) and not terminated.any() and not truncated.any()
    assert not infos["_reward_position"].any()  # the rows were reset, not stepped
    assert infos["_randomization"].all()
    np.testing.assert_array_equal(infos["time"], 0.0)


def test_same_step_autoreset_gives_final_observation():
    kwargs = {"max_episode_steps": 4}
    same = make_vec(2, autoreset_mode=AutoresetMode.SAME_STEP, **kwargs)
    nxt = make_vec(2, **kwargs)
    assert same.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    same.reset(seed=3)
    nxt.reset(seed=3)
    a = np.full((2, 6), 0.09)
    for _ in range(4):
        s_obs, _, _, s_trunc, s_info = same.step(a)
        n_obs, _, _, n_trunc, _ = nxt.step(a)
    assert s_trunc.all() and n_trunc.all()
    final = np.stack(s_info["final_obs"])
    np.testing.assert_array_equal(final, n_obs)
    assert s_info["_final_info"].all() and "reward_position" in s_info["final_info"]
    n_obs, *_ = nxt.step(a)  # next-step: the reset observation comes one step later
    np.testing.assert_array_equal(s_obs, n_obs)


def test_disabled_autoreset_needs_a_reset_mask():
    envs = make_vec(2, max_episode_steps=2, autoreset_mode="Disabled")
    envs.reset(seed=0)
    a = np.full((2, 6), 0.09)
    envs.step(a)
    envs.step(a)
    with pytest.raises(ValueError, match="reset_mask"):
        envs.step(a)
    obs, _ = envs.reset(options={"reset_mask": np.array([True, False])})
    envs.reset(options={"reset_mask": np.array([False, True])})
    envs.step(a)
    with pytest.raises(ValueError, match="reset_mask"):
        envs.reset(options={"reset_mask": [True, False]})


def test_vector_truncation_counts_each_row():
    envs = make_vec(2, max_episode_steps=3)
    envs.reset(seed=0)
    a = np.full((2, 6), 0.09)
    flags = [envs.step(a)[3].tolist() for _ in range(3)]
    assert flags == [[False, False], [False, False], [True, True]]


@pytest.mark.parametrize(
    "actions, message",
    [
        (np.full((3, 6), np.nan), "NaN"),
        (np.full((3, 6), np.inf), "inf"),
        (np.zeros((3, 5)), "shape"),
        (np.zeros(6), "shape"),
    ],
)
def test_vector_bad_actions_raise(actions, message):
    envs = make_vec(3)
    envs.reset(seed=0)
    with pytest.raises(ValueError, match=message):
        envs.step(actions)


def test_vector_seeding_list_and_none():
    envs = make_vec(2)
    by_list, _ = envs.reset(seed=[7, 8])
    by_int, _ = envs.reset(seed=7)
    np.testing.assert_array_equal(by_list, by_int)
    envs.reset()  # continues each row's generator
    with pytest.raises(ValueError, match="seeds"):
        envs.reset(seed=[1, 2, 3])
    with pytest.raises(ValueError, match=r"^seed: "):
        envs.reset(seed=True)
    with pytest.raises(ValueError, match=r"^seed\[1\]: "):
        envs.reset(seed=[1, -2])


def test_vector_render_gives_one_frame_per_row():
    envs = StewartPlatformVectorEnv(num_envs=2, render_mode="rgb_array", width=64, height=48)
    envs.reset(seed=0)
    frames = envs.render()
    envs.step(np.full((2, 6), 0.5))  # a frame shows the rows as they were at render()
    assert len(frames) == 2 and frames[0].shape == frames[1].shape == (48, 64, 3)
    assert not np.array_equal(frames[0], frames[1])  # two rows, two start poses
    np.testing.assert_array_equal(frames[-1], frames[1])
    assert [f.shape for f in frames[:]] == [(48, 64, 3)] * 2
    envs.close()


def test_vector_exposes_state_target_model_and_forces():
    envs = make_vec(3).unwrapped
    envs.reset(seed=0)
    envs.step(np.full((3, 6), 0.25))
    assert envs.state.position.shape == (3, 3) and envs.target.rotation.shape == (3, 3, 3)
    assert envs.leg_forces.shape == (3, 6) and np.all(envs.leg_forces == 500.0)  # 0.25 x 2000 N
    assert envs.model.name == "improved"
    assert set(envs.observation_layout) >= {
        "position",
        "orientation",
        "velocity",
        "angular_velocity",
        "position_error",
        "orientation_error",
    }


# -- stable-baselines3 -------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def sb3():
    return pytest.importorskip("stable_baselines3", reason="needs the rl extra")


def test_sb3_adapter_rows_equal_single_envs(sb3):
    from stewart_env.envs import StewartPlatformSB3VecEnv

    n = 2
    venv = StewartPlatformSB3VecEnv(num_envs=n, max_episode_steps=25)
    singles = [gym.make(ENV_ID, max_episode_steps=25) for _ in range(n)]
    venv.seed(4)
    obs = venv.reset()
    s_obs = [env.reset(seed=4 + i)[0] for i, env in enumerate(singles)]
    np.testing.assert_array_equal(obs, np.array(s_obs))
    actions = actions_for(60, n, seed=2).astype(np.float32)
    ended = 0
    for a in actions:
        obs, rewards, dones, infos = venv.step(a)
        for i, env in enumerate(singles):
            o, r, term, trunc, info = env.step(a[i])
            assert rewards[i] == np.float32(r) and dones[i] == (term or trunc)
            assert infos[i]["TimeLimit.truncated"] == (trunc and not term)
            if term or trunc:
                ended += 1
                np.testing.assert_array_equal(infos[i]["terminal_observation"], o)
                assert infos[i]["termination"] == info["termination"]
                o, _ = env.reset()
            np.testing.assert_array_equal(obs[i], o)
    assert ended >= n
    assert venv.get_attr("render_mode") == [None, None]
    assert venv.env_method("decode_observation", obs)[0]["position"].shape == (n, 3)
    assert venv.env_is_wrapped(gym.Wrapper) == [False, False]


def test_sb3_ppo_trains_a_few_steps(sb3):
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecMonitor

    from stewart_env.envs import StewartPlatformSB3VecEnv

    venv = VecMonitor(StewartPlatformSB3VecEnv(num_envs=4, randomization={"mass": (0.9, 1.1)}))
    model = PPO("MlpPolicy", venv, n_steps=8, batch_size=16, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=64)
    assert model.num_timesteps >= 64
    action, _ = model.predict(venv.reset(), deterministic=True)
    assert action.shape == (4, 6)


def test_sb3_render_and_reset_infos(sb3):
    from stewart_env.envs import StewartPlatformSB3VecEnv

    venv = StewartPlatformSB3VecEnv(
        num_envs=2, render_mode="rgb_array", width=32, height=32, randomization={"platform.mass": (0.9, 1.1)}
    )
    venv.seed(0)
    venv.reset()
    assert venv.render().shape == (32, 32, 3)
    assert 0.9 <= venv.reset_infos[1]["randomization"]["platform.mass"] <= 1.1
    venv.close()


def test_a_row_that_goes_non_finite_is_marked_alone():
    """A zero-length leg makes its row's physics NaN inside the compiled rollout; only that row
    is terminated, and the others step exactly as in a batch without it."""
    rows = np.arange(3)
    batches = []
    for _ in range(2):
        batch = core_module.PlatformBatch(3, EnvConfig.of(task="disturbance"))
        batch.reset_rows(rows, [np.random.default_rng(i) for i in rows])
        batches.append(batch)
    p = batches[1].platform
    degenerate = p.base_joints[0] - p.platform_joints[0]  # P_0 on B_0 with R = I: leg 0 has length 0
    batches[1].position[1], batches[1].rotation[1] = degenerate, np.eye(3)
    a = np.full((3, 6), 0.09)
    _, code_ok, *_ = batches[0].step(a, [None] * 3)
    _, code, *_ = batches[1].step(a, [None] * 3)
    assert batches[1].reasons(code).tolist() == ["", "non_finite", ""]
    assert code_ok.tolist() == [0, 0, 0]
    for i in (0, 2):
        np.testing.assert_array_equal(batches[1].position[i], batches[0].position[i])
    np.testing.assert_array_equal(batches[1].position[1], degenerate)  # the last finite state


@pytest.mark.parametrize(
    "kwargs",
    [
        {"max_episode_steps": 15, "randomization": {"platform.mass": (0.8, 1.2)}},
        # every row ends at once, so that every row is reset at the same step, with noise and delay
        {"max_episode_steps": 6, "observation_noise": 0.01, "observation_delay": 2},
    ],
    ids=["rows_apart", "rows_together"],
)
@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_native_vector_env_matches_gymnasiums_sync_vector_env(mode, kwargs):
    """Gymnasium's own SyncVectorEnv over the single env is the reference for the autoreset
    semantics and the info layout."""
    n, steps = 3, 60
    native = make_vec(n, autoreset_mode=mode, **kwargs)
    sync = gym.make_vec(ENV_ID, num_envs=n, vectorization_mode="sync", vector_kwargs={"autoreset_mode": mode}, **kwargs)
    a_obs, a_info = native.reset(seed=8)
    b_obs, b_info = sync.reset(seed=8)
    np.testing.assert_array_equal(a_obs, b_obs)
    assert set(a_info) == set(b_info)
    for a in actions_for(steps, n, seed=4).astype(np.float32):
        a_out = native.step(a)
        b_out = sync.step(a)
        for x, y in zip(a_out[:4], b_out[:4]):
            np.testing.assert_array_equal(x, y)
        a_info, b_info = a_out[4], b_out[4]
        # at a step that resets every row Gymnasium's infos hold no step key; the native env's hold
        # them, masked out everywhere
        extra = set(a_info) - set(b_info)
        assert set(b_info) <= set(a_info) and not any(a_info[k].any() for k in extra if k.startswith("_"))
        assert not extra or not any(b_info.get("_" + k, np.zeros(1)).any() for k in ("termination", "time"))
        for key in ("reward_position", "_reward_position", "reward_termination", "termination", "_termination", "time"):
            if key in b_info:
                assert list(a_info[key]) == list(b_info[key]), key
        if "final_obs" in b_info:
            assert a_info["_final_obs"].tolist() == b_info["_final_obs"].tolist()
            for i in np.flatnonzero(b_info["_final_obs"]):
                np.testing.assert_array_equal(a_info["final_obs"][i], b_info["final_obs"][i])


# -- a batch too large for memory --------------------------------------------------------------


def test_a_vector_env_too_large_for_memory_names_num_envs():
    from stewart_env.envs import StewartPlatformVectorEnv

    with pytest.raises(ValueError, match="^num_envs: 2147483647 platforms do not fit"):
        StewartPlatformVectorEnv(2**31 - 1)
