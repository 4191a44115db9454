"""Tests of the error-integral observation term (``error_integral=True``)."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode
from scipy.spatial.transform import Rotation

import stewart_env.registration  # noqa: F401  (registers StewartPlatform-v1)

pytestmark = pytest.mark.env

ENV_ID = "StewartPlatform-v1"
DT = 0.01
# dasgupta1998: h (half the workspace box, m) and A (max_angle, rad), the observation scales.
H = np.array([0.25, 0.25, 0.15])
A = 0.5


def pose_errors(env) -> np.ndarray:
    """(6,) target minus pose from the state alone: position (m), rotation vector of R_t R^T (rad)."""
    state, target = env.unwrapped.state, env.unwrapped.target
    rotvec = Rotation.from_matrix(target.rotation @ state.rotation.T).as_rotvec()
    return np.concatenate([target.position - state.position, rotvec])


def hold(n_steps, n_envs=None, seed=0):
    """Actions near the holding force (a ~ 0.1), so the platform moves but stays inside."""
    shape = (n_steps, 6) if n_envs is None else (n_steps, n_envs, 6)
    return np.random.default_rng(seed).uniform(-0.1, 0.3, shape).astype(np.float32)


@pytest.mark.parametrize("normalize", [True, False])
@pytest.mark.parametrize("limit", [100.0, 0.02])
def test_integral_is_the_clipped_sum_of_errors_times_dt(normalize, limit):
    env = gym.make(ENV_ID, error_integral=True, error_integral_limit=limit, normalize_observation=normalize)
    sl = env.unwrapped.observation_layout["error_integral"]
    assert sl == slice(21, 27) and env.observation_space.shape == (27,)
    bound = limit * np.concatenate([H, np.full(3, A)])
    obs, _ = env.reset(seed=3)
    assert np.all(obs[sl] == 0.0)
    expected = np.zeros(6)
    for a in hold(8):
        obs, *_ = env.step(a)
        expected = np.clip(expected + pose_errors(env) * DT, -bound, bound)
        observed = obs[sl] * bound if normalize else obs[sl]
        # The observation is float32 (relative rounding ~6e-8); atol covers components near 0.
        np.testing.assert_allclose(observed, expected, rtol=1e-6, atol=1e-9 * bound.max())
        np.testing.assert_allclose(
            env.unwrapped.decode_observation(obs)["error_integral"], expected, rtol=1e-6, atol=1e-9 * bound.max()
        )
    # The start is ~0.1 m from the target: a 0.02 s bound clips within the first steps, 100 s never.
    clipped = np.isclose(np.abs(expected), bound, rtol=1e-12)  # np.clip returns the bound itself
    assert clipped.any() if limit < 1 else not clipped.any()
    if normalize:
        assert np.all(np.abs(obs[sl]) <= 1.0)


def test_a_band_integrates_only_the_error_components_within_it():
    band = 0.02
    env = gym.make(
        ENV_ID, error_integral=True, error_integral_limit=100.0, error_integral_band=band, normalize_observation=False
    )
    sl = env.unwrapped.observation_layout["error_integral"]
    width = band * np.concatenate([H, np.full(3, A)])
    env.reset(seed=3)
    expected, gated = np.zeros(6), 0
    for a in hold(30):
        obs, *_ = env.step(a)
        e = pose_errors(env)
        inside = np.abs(e) <= width
        gated += int((~inside).sum())
        expected += np.where(inside, e, 0.0) * DT
        # The observation is float32 (relative rounding ~6e-8); atol covers components near 0.
        np.testing.assert_allclose(obs[sl], expected, rtol=1e-6, atol=1e-12)
    assert gated > 0 and np.any(expected != 0.0)


def test_decode_observation_round_trips_the_integral():
    env = gym.make(ENV_ID, error_integral=True)
    env.reset(seed=1)
    for a in hold(5):
        obs, *_ = env.step(a)
    core = env.unwrapped._core
    decoded = env.unwrapped.decode_observation(obs.astype(np.float64))["error_integral"]
    np.testing.assert_allclose(decoded, core.error_integral[0], rtol=1e-6)  # decoded from float32
    assert np.any(core.error_integral[0] != 0.0)


def test_reset_zeroes_the_integral():
    env = gym.make(ENV_ID, error_integral=True)
    sl = env.unwrapped.observation_layout["error_integral"]
    env.reset(seed=0)
    for a in hold(5):
        obs, *_ = env.step(a)
    assert np.all(obs[sl] != 0.0)
    obs, _ = env.reset(seed=4)
    assert np.all(obs[sl] == 0.0)


def test_default_observation_is_unchanged_and_the_term_only_appends():
    plain, off, on = (gym.make(ENV_ID, **kw) for kw in ({}, {"error_integral": False}, {"error_integral": True}))
    assert "error_integral" not in plain.unwrapped.observation_layout
    assert plain.observation_space.shape == off.observation_space.shape == (21,)
    streams = []
    for env in (plain, off, on):
        out = [env.reset(seed=7)[0][:21]]
        for a in hold(20):
            obs, rew, term, trunc, _ = env.step(a)
            out += [obs[:21], [rew, term, trunc]]
        streams.append(np.concatenate(out))
    np.testing.assert_array_equal(streams[0], streams[1])
    np.testing.assert_array_equal(streams[0], streams[2])


def test_vector_rows_equal_single_envs_bit_for_bit_across_autoresets():
    n, seed, steps, horizon = 3, 11, 30, 8
    kwargs = {"error_integral": True, "error_integral_limit": 0.05, "observation_noise": 0.01}
    envs = gym.make_vec(
        ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", max_episode_steps=horizon, **kwargs
    )
    singles = [gym.make(ENV_ID, max_episode_steps=horizon, **kwargs) for _ in range(n)]
    actions = hold(steps, n)
    v_obs, _ = envs.reset(seed=seed)
    s_obs = [env.reset(seed=seed + i)[0] for i, env in enumerate(singles)]
    pending = [False] * n
    for k in range(steps):
        np.testing.assert_array_equal(v_obs, np.array(s_obs))
        v_obs, *_ = envs.step(actions[k])
        for i, env in enumerate(singles):
            if pending[i]:
                s_obs[i], _ = env.reset()
                pending[i] = False
            else:
                s_obs[i], _, term, trunc, _ = env.step(actions[k, i])
                pending[i] = term or trunc
    np.testing.assert_array_equal(v_obs, np.array(s_obs))


def test_same_step_autoreset_starts_the_new_episode_at_zero():
    envs = gym.make_vec(
        ENV_ID,
        num_envs=2,
        vectorization_mode="vector_entry_point",
        max_episode_steps=3,
        autoreset_mode=AutoresetMode.SAME_STEP,
        error_integral=True,
    )
    sl = envs.unwrapped.observation_layout["error_integral"]
    envs.reset(seed=0)
    for a in hold(3, 2):
        obs, _, _, trunc, infos = envs.step(a)
    assert trunc.all()
    assert np.all(obs[:, sl] == 0.0)
    assert all(np.all(infos["final_obs"][i][sl] != 0.0) for i in range(2))


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"error_integral": 1}, "error_integral"),
        ({"error_integral": "yes"}, "error_integral"),
        ({"error_integral": True, "error_integral_limit": 0.0}, "error_integral_limit"),
        ({"error_integral": True, "error_integral_limit": float("inf")}, "error_integral_limit"),
        ({"error_integral_limit": -1.0}, "error_integral_limit"),
        ({"error_integral": True, "error_integral_band": 0.0}, "error_integral_band"),
    ],
)
def test_bad_arguments_raise_naming_the_argument(kwargs, name):
    with pytest.raises(ValueError, match=f"^{name}:"):
        gym.make(ENV_ID, **kwargs)
