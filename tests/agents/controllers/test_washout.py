"""Classical washout: its filters against their transfer functions, the tilt's rate limit, a hand
case, the parameters' checks and the policy on the cueing task."""

import math

import gymnasium as gym
import numpy as np
import pytest

from stewart_env.agents.controllers.washout import (
    Washout,
    WashoutParams,
    WashoutPolicy,
    bilinear,
    discretize,
    head_pose,
    load_washout_params,
    washout_transfer_functions,
)
from stewart_env.errors import UsageError
from stewart_env.tasks.cueing.motion import STANDARD_GRAVITY
from stewart_env.tasks.cueing.task import DEFAULT_HEAD

DT = 0.01
#: Frequencies of the response checks, rad/s: from below the slowest break to 10 rad/s (1.6 Hz).
FREQUENCIES = np.array([0.2, 0.7, 2.0, 5.0, 10.0])


def measured_response(bank, channels: int, frequencies: np.ndarray) -> np.ndarray:
    """The filter bank's complex gain at each frequency (F, channels), fitted by least squares to
    the last two periods of the slowest sine, after the transients (all sines in one batch)."""
    period = 2.0 * np.pi / frequencies.min()
    n = int(np.ceil(8.0 * period / DT))
    t = np.arange(n) * DT
    u = np.sin(np.outer(t, frequencies))  # (n, F)
    y = np.stack([bank.step(np.repeat(u[k][:, None], channels, axis=1)) for k in range(n)])
    tail = slice(n - int(2.0 * period / DT), n)
    gains = np.empty((len(frequencies), channels), dtype=complex)
    for j, w in enumerate(frequencies):
        basis = np.stack([np.sin(w * t[tail]), np.cos(w * t[tail])], axis=1)
        coef = np.linalg.lstsq(basis, y[tail, j, :], rcond=None)[0]  # y = Re(H) sin + Im(H) cos
        gains[j] = coef[0] + 1j * coef[1]
    return gains


@pytest.mark.parametrize(
    "channel",
    ["translational_highpass", "translational_position", "tilt_lowpass", "rotational_highpass", "rotational_angle"],
)
def test_each_filter_matches_its_transfer_function(channel):
    params = WashoutParams(translational_frequency=(2.5, 1.5, 4.0), translational_break=(0.5, 0.3, 1.0))
    tfs = washout_transfer_functions(params)[channel]
    measured = measured_response(discretize(tfs, DT), len(tfs), FREQUENCIES)
    for c, (num, den) in enumerate(tfs):
        expected = np.polyval(num, 1j * FREQUENCIES) / np.polyval(den, 1j * FREQUENCIES)
        # 1 %: the brief's bound; Tustin's frequency warping is below 0.3 % up to 10 rad/s at 10 ms
        np.testing.assert_array_less(np.abs(measured[:, c] - expected) / np.abs(expected), 0.01)


def test_bilinear_is_scipys_tustin():
    import scipy.signal

    for tfs in washout_transfer_functions(WashoutParams(translational_break=(0.5, 0.0, 1.0))).values():
        for num, den in tfs:
            b, a = bilinear(num, den, DT)
            b_ref, a_ref, _ = scipy.signal.cont2discrete((num, den), DT, method="bilinear")
            np.testing.assert_allclose(b, np.ravel(b_ref)[-len(b) :], rtol=0, atol=1e-12)  # rounding of two routes
            np.testing.assert_allclose(a, a_ref, rtol=0, atol=1e-12)


def test_third_order_position_returns_to_zero_and_second_order_keeps_an_offset():
    # a unit step in acceleration: the 3rd-order channel's displacement is s / (den s) -> 0,
    # the 2nd-order one's settles at 1 / w² (the break w_b = 0)
    for wb, final in ((0.5, 0.0), (0.0, 1.0 / 2.5**2)):
        params = WashoutParams(translational_break=(wb, wb, wb))
        bank = discretize(washout_transfer_functions(params)["translational_position"], DT)
        y = [bank.step(np.array([1.0, 0.0, 0.0]))[0] for _ in range(8000)]
        assert y[-1] == pytest.approx(final, abs=1e-6)  # 80 s: the slowest pole's e^-40


def test_step_in_forward_specific_force_washes_out_and_tilts_to_asin():
    # the hand case: f_x steps by 1 m/s² at 1 s, unit scale; the high-passed translation comes
    # back to 0 and the pitch settles at -asin(f_x / g) (nose up renders forward acceleration)
    params = WashoutParams(force_scale=(1.0, 1.0, 1.0), force_limit=(20.0, 20.0, 20.0))
    n = 6000
    f = np.zeros((n, 3))
    f[:, 2] = STANDARD_GRAVITY
    f[100:, 0] = 1.0
    displacement, rpy = Washout(params, DT).run(f, np.zeros((n, 3)))
    assert np.all(displacement[:100] == 0.0)
    assert displacement[200, 0] > 0.05  # the onset is cued by moving forward
    assert abs(displacement[-1, 0]) < 1e-9
    assert rpy[-1, 1] == pytest.approx(-math.asin(1.0 / STANDARD_GRAVITY), rel=1e-9)
    assert np.abs(rpy[-1, [0, 2]]).max() < 1e-12
    # and the tilt renders the force: a cabin pitched so feels R^T (0, 0, g) with f_x = -g sin(pitch)
    assert -STANDARD_GRAVITY * math.sin(rpy[-1, 1]) == pytest.approx(1.0, rel=1e-9)


def test_tilt_rate_limit_is_honoured():
    rate = math.radians(3.0)
    params = WashoutParams(force_scale=(1.0, 1.0, 1.0), force_limit=(20.0, 20.0, 20.0), tilt_rate_limit=rate)
    n = 3000
    f = np.zeros((n, 3))
    f[:, 2] = STANDARD_GRAVITY
    f[10:, 0] = 3.0
    f[10:, 1] = -2.0
    _, rpy = Washout(params, DT).run(f, np.zeros((n, 3)))
    rates = np.abs(np.diff(rpy[:, :2], axis=0)) / DT
    assert rates.max() <= rate * (1 + 1e-12)  # rounding of the sum of clipped increments
    assert rates.max() == pytest.approx(rate, rel=1e-9)  # the limit binds in this step
    roll = math.asin(-2.0 / (STANDARD_GRAVITY * math.cos(math.asin(3.0 / STANDARD_GRAVITY))))
    assert rpy[-1, 0] == pytest.approx(roll, rel=1e-9)


def test_batch_rows_are_the_single_runs():
    rng = np.random.default_rng(0)
    f = rng.normal(size=(300, 2, 3)) + np.array([0.0, 0.0, STANDARD_GRAVITY])
    w = rng.normal(size=(300, 2, 3)) * 0.3
    params = WashoutParams()
    d_batch, a_batch = Washout(params, DT).run(f, w)
    for row in range(2):
        d_one, a_one = Washout(params, DT).run(f[:, row], w[:, row])
        np.testing.assert_allclose(d_batch[:, row], d_one, rtol=0, atol=1e-15)  # the same arithmetic
        np.testing.assert_allclose(a_batch[:, row], a_one, rtol=0, atol=1e-15)


def test_reset_of_rows_restarts_only_them():
    washout = Washout(WashoutParams(), DT)
    f = np.array([[1.0, 0.0, STANDARD_GRAVITY], [1.0, 0.0, STANDARD_GRAVITY]])
    for _ in range(50):
        washout.step(f, np.zeros((2, 3)))
    washout.reset(np.array([True, False]))
    first, _ = washout.step(np.array([[0.0, 0.0, STANDARD_GRAVITY]] * 2), np.zeros((2, 3)))
    assert first[0, 0] == 0.0
    assert first[1, 0] != 0.0


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"force_scale": (1.0, 1.0)}, "force_scale: must be 3 numbers"),
        ({"translational_frequency": (0.0, 1.0, 1.0)}, "translational_frequency: must be finite and > 0"),
        ({"tilt_rate_limit": -1.0}, "tilt_rate_limit: must be finite and > 0"),
        ({"tilt_limit": 2.0}, "tilt_limit: must be below pi/2"),
        ({"angular_limit": (1.0, float("nan"), 1.0)}, "angular_limit: must be finite"),
        ({"tilt_frequency": "fast"}, "tilt_frequency: must be 2 numbers"),
    ],
)
def test_bad_params_name_the_field(kwargs, message):
    with pytest.raises(UsageError, match=message):
        WashoutParams(**kwargs)


def test_params_round_trip_and_unknown_keys(tmp_path):
    params = WashoutParams(force_scale=(0.3, 0.4, 0.2))
    assert WashoutParams.from_mapping(params.as_dict()) == params
    with pytest.raises(UsageError, match=r"params: unknown washout parameters \['gain'\]"):
        WashoutParams.from_mapping({"gain": 1.0})
    bad = tmp_path / "w.yaml"
    bad.write_text("params:\n  tilt_limit: 3.0\n")
    with pytest.raises(UsageError, match=r"w.yaml: params: tilt_limit: must be below pi/2"):
        load_washout_params(bad)
    bad.write_text("washout: {}\n")
    with pytest.raises(UsageError, match=r"w.yaml has no 'params' mapping"):
        load_washout_params(bad)


@pytest.fixture(scope="module")
def cueing_env():
    env = gym.make("StewartPlatform-v1", task="cueing", action_mode="pose", task_options={"motions": ("braking",)})
    yield env
    env.close()


def test_policy_commands_the_washouts_pose_through_the_envs_normalisation(cueing_env):
    policy = WashoutPolicy(cueing_env)
    assert np.array_equal(policy.head, DEFAULT_HEAD)  # the task's head point
    obs, _ = cueing_env.reset(seed=3)
    twin = Washout(WashoutParams(), cueing_env.unwrapped.dt)
    base = cueing_env.unwrapped
    moved = 0.0
    for _ in range(400):
        action, state = policy.predict(obs)
        assert state is None and action.dtype == np.float32 and action.shape == (6,)
        part = base.decode_observation(obs[None].astype(float))
        displacement, rpy = twin.step(part["vehicle_specific_force"], part["vehicle_angular_velocity"])
        position, rotation = head_pose(base.platform, DEFAULT_HEAD, displacement, rpy)
        expected = base._core.actuation.pose_command(position[0], rotation[0])
        np.testing.assert_allclose(action, np.clip(expected, -1, 1), rtol=0, atol=1e-6)  # float32 actions
        moved = max(moved, float(np.abs(displacement).max()))
        obs, _, terminated, truncated, _ = cueing_env.step(action)
        if terminated or truncated:
            break
    assert moved > 1e-2  # the braking began: the check saw the washout move


def test_policy_restarts_at_episode_start(cueing_env):
    policy = WashoutPolicy(cueing_env)
    obs, _ = cueing_env.reset(seed=3)
    first, _ = policy.predict(obs)
    for _ in range(150):
        obs, *_ = cueing_env.step(policy.predict(obs)[0])
    obs, _ = cueing_env.reset(seed=3)
    again, _ = policy.predict(obs[None], episode_start=np.array([True]))
    assert np.array_equal(again[0], first)


def test_policy_refuses_other_envs():
    with pytest.raises(UsageError, match="env: its observations lack .*task='cueing'"):
        WashoutPolicy(gym.make("StewartPlatform-v1"))
    with pytest.raises(UsageError, match="env: washout commands poses: make the environment with action_mode='pose'"):
        WashoutPolicy(gym.make("StewartPlatform-v1", task="cueing"))
    env = gym.make("StewartPlatform-v1", task="cueing", action_mode="pose")
    with pytest.raises(UsageError, match=r"head: must be three finite numbers"):
        WashoutPolicy(env, head=(0.0, 1.0))


def test_policy_drives_an_sb3_vec_env_and_refuses_a_stranger():
    from stewart_env.envs import StewartPlatformSB3VecEnv

    vec = StewartPlatformSB3VecEnv(num_envs=2, task="cueing", action_mode="pose")
    try:
        vec.seed(0)
        obs = vec.reset()
        action, _ = WashoutPolicy(vec).predict(obs)  # the VecEnv's own environment is found under it
        assert action.shape == (2, 6) and np.all(np.isfinite(action))
    finally:
        vec.close()
    with pytest.raises(UsageError, match=r"env: expected a stewart-env environment"):
        WashoutPolicy(object())
