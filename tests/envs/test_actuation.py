"""The action modes (force, leg_length, pose with its three laws) and the actuators (ideal, lag,
electric, hydraulic) of the environments: every combination under both env checkers, seeded,
copied and pickled, fused step == step of parts, a row of a batch == a batch of one; the inner
loops reach their set points; the electric drive's energy balance; the errors of bad input."""

from __future__ import annotations

import copy
import pickle
import sys
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env

import stewart_env.registration  # noqa: F401  (registers StewartPlatform-v1)
from stewart_env.envs import StewartPlatformEnv
from stewart_env.rotations import rotation_error, rpy_to_matrix

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from physics_reference import dissipated_power, kinetic_energy, potential_energy  # noqa: E402

pytestmark = pytest.mark.env

ENV_ID = "StewartPlatform-v1"
MODES = (
    {"action_mode": "force"},
    {"action_mode": "leg_length"},
    {"action_mode": "pose", "pose_law": "ik"},
    {"action_mode": "pose", "pose_law": "pd_gravity"},
    {"action_mode": "pose", "pose_law": "computed_torque"},
)
ACTUATORS = (
    {"actuator": "ideal"},
    {"actuator": "lag", "actuator_tau": 0.02},
    {"actuator": "electric", "platform": "motion_simulator", "observe_actuators": True},
    {"actuator": "hydraulic", "platform": "motion_simulator", "observe_actuators": True},
)
COMBOS = [{**mode, **actuator} for mode in MODES for actuator in ACTUATORS]
IDS = ["-".join(str(v) for k, v in c.items() if k in ("action_mode", "pose_law", "actuator")) for c in COMBOS]
# a pose inside every platform's workspace box and angle range, normalised
POSE = np.array([0.3, -0.2, 0.4, 0.3, -0.2, 0.2])


def _no_warnings():
    context = warnings.catch_warnings()
    context.__enter__()
    warnings.simplefilter("error")
    # unbounded observation boxes are intended (as in Gymnasium's MuJoCo environments)
    warnings.filterwarnings("ignore", message=".*Box observation space (minimum|maximum) value is")
    return context


def _settle(env, action, seconds=3.0):
    """Step ``env`` with ``action`` held for ``seconds``; fails on a termination."""
    u = env.unwrapped
    for _ in range(round(seconds / u._core.control_dt)):
        _, _, terminated, _, info = env.step(np.asarray(action, dtype=np.float32))
        assert not terminated, info
    return u._core


# -- conformance ------------------------------------------------------------------------------------


@pytest.mark.parametrize("kwargs", COMBOS, ids=IDS)
def test_every_mode_and_actuator_passes_gymnasium_check_env(kwargs):
    env = StewartPlatformEnv(**kwargs)
    context = _no_warnings()
    try:
        gym_check_env(env, skip_render_check=True)
    finally:
        context.__exit__(None, None, None)


@pytest.mark.extra("rl")
@pytest.mark.parametrize("kwargs", COMBOS, ids=IDS)
def test_every_mode_and_actuator_passes_sb3_check_env(kwargs):
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = StewartPlatformEnv(**kwargs)
    context = _no_warnings()
    try:
        sb3_check_env(env, warn=True)
    finally:
        context.__exit__(None, None, None)


def _vector_run(kwargs, mode, num_envs=3, steps=40, seed=3):
    envs = gym.make_vec(
        ENV_ID, num_envs=num_envs, vectorization_mode="vector_entry_point", max_episode_steps=15, **kwargs
    )
    core = envs.unwrapped._core
    core.set_step_mode(mode)
    rng = np.random.default_rng(1)
    out = [envs.reset(seed=seed)[0]]
    for _ in range(steps):
        # large actions too, so that some rows leave the limits and terminate
        obs, reward, terminated, truncated, _ = envs.step(rng.uniform(-1.5, 1.5, (num_envs, 6)))
        out += [obs, reward, terminated, truncated]
    envs.close()
    return out, core


RANDOMIZED = {"randomization": {"mass": (0.8, 1.2)}, "observation_noise": {"actuator_states": 0.01}}


@pytest.mark.parametrize(
    "kwargs",
    [*COMBOS, {**COMBOS[10], **RANDOMIZED}, {**COMBOS[19], **RANDOMIZED}],
    ids=[*IDS, "randomized-electric", "randomized-hydraulic"],
)
def test_the_fused_step_is_the_step_of_parts_bit_for_bit(kwargs):
    fused, core = _vector_run(kwargs, "fused")
    assert core.fused
    parts, core = _vector_run(kwargs, "parts")
    assert not core.fused
    for a, b in zip(fused, parts):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("kwargs", COMBOS, ids=IDS)
def test_a_row_of_a_batch_of_16_is_a_batch_of_1(kwargs):
    n, seed, steps = 16, 5, 25
    envs = gym.make_vec(ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    actions = np.random.default_rng(2).uniform(-0.5, 0.5, (steps, n, 6)).astype(np.float32)
    rows = (0, 5, 13, 15)  # in a block of vector lanes, and after the blocks
    singles = {i: StewartPlatformEnv(**kwargs) for i in rows}
    v_obs, _ = envs.reset(seed=seed)
    s_obs = {i: env.reset(seed=seed + i)[0] for i, env in singles.items()}
    for k in range(steps):
        for i in rows:
            np.testing.assert_array_equal(v_obs[i], s_obs[i])
        v_obs, v_rew, v_term, _, _ = envs.step(actions[k])
        if v_term.any():
            break
        for i, env in singles.items():
            s_obs[i], reward, *_ = env.step(actions[k, i])
            assert v_rew[i] == reward, (k, i)
    envs.close()


@pytest.mark.parametrize("kwargs", [COMBOS[i] for i in (5, 10, 15, 19)], ids=[IDS[i] for i in (5, 10, 15, 19)])
def test_seeded_runs_repeat_and_copies_step_as_the_original(kwargs):
    runs = []
    for _ in range(2):
        env = StewartPlatformEnv(**kwargs)
        obs = [env.reset(seed=11)[0]]
        obs += [env.step(np.full(6, 0.1 * k % 0.5, dtype=np.float32))[0] for k in range(10)]
        runs.append(np.array(obs))
    np.testing.assert_array_equal(runs[0], runs[1])
    copies = [copy.deepcopy(env), pickle.loads(pickle.dumps(env))]
    a = np.full(6, 0.2, dtype=np.float32)
    steps = [e.step(a) for e in (env, *copies)]
    for obs, reward, *_ in steps[1:]:
        np.testing.assert_array_equal(obs, steps[0][0])
        assert reward == steps[0][1]
    # the copies' drives are their own: stepping one leaves the original's state alone
    if env.unwrapped._core.actuation is not None:
        before = env.unwrapped._core.actuation.state.copy()
        copies[0].step(-a)
        np.testing.assert_array_equal(env.unwrapped._core.actuation.state, before)


# -- the inner loops reach their set points ------------------------------------------------------------


@pytest.mark.parametrize(
    "kwargs, bound",
    [
        # the holding forces of the current pose are fed forward on the exact model: what is left
        # after 3 s (15 closed-loop time constants) is the decayed transient
        ({}, 1e-5),
        ({"actuator": "lag", "actuator_tau": 0.02}, 2e-3),
        # the screw's Coulomb friction (300 N) over the servo's stiffness (~1.5e7 N/m)
        ({"actuator": "electric", "platform": "motion_simulator"}, 1e-4),
        ({"actuator": "hydraulic", "platform": "motion_simulator"}, 1e-4),
    ],
    ids=["ideal", "lag", "electric", "hydraulic"],
)
def test_leg_length_mode_holds_its_set_point(kwargs, bound):
    env = StewartPlatformEnv(action_mode="leg_length", **kwargs)
    env.reset(seed=0)
    u = env.unwrapped
    lim = u.platform.limits
    # the leg lengths of a reachable pose, as leg-length commands
    t = 0.5 * (lim.position_min + lim.position_max) + POSE[:3] * 0.5 * (lim.position_max - lim.position_min)
    R = rpy_to_matrix(u.platform.home_rpy + POSE[3:] * lim.max_angle)
    lengths = np.linalg.norm(t + (R @ u.platform.platform_joints.T).T - u.platform.base_joints, axis=1)
    lo, hi = lim.leg_length
    core = _settle(env, (lengths - 0.5 * (lo + hi)) / (0.5 * (hi - lo)))
    assert np.abs(core.leg_lengths[0] - lengths).max() < bound


@pytest.mark.parametrize("law", ["ik", "pd_gravity", "computed_torque"])
@pytest.mark.parametrize(
    "kwargs",
    [{}, {"actuator": "electric", "platform": "motion_simulator"}],
    ids=["ideal", "electric"],
)
def test_pose_mode_reaches_its_set_point(law, kwargs):
    env = StewartPlatformEnv(action_mode="pose", pose_law=law, **kwargs)
    env.reset(seed=0)
    u = env.unwrapped
    lim = u.platform.limits
    core = _settle(env, POSE)
    t = 0.5 * (lim.position_min + lim.position_max) + POSE[:3] * 0.5 * (lim.position_max - lim.position_min)
    R = rpy_to_matrix(u.platform.home_rpy + POSE[3:] * lim.max_angle)
    # 3 s is 15 time constants of the 5 Hz loops; the electric ik servo is left the screw's
    # Coulomb friction over its stiffness (~2e-5 m per leg)
    assert np.linalg.norm(core.position[0] - t) < 1e-4
    assert np.linalg.norm(rotation_error(R[None], core.rotation)[0]) < 1e-4


# -- the electric drive's energy ----------------------------------------------------------------------


def test_electric_energy_balance_with_the_reflected_masses():
    # one RK4 step per control step: the leg forces are held over it, so their work is F . dL
    env = StewartPlatformEnv(
        platform="motion_simulator",
        actuator="electric",
        action_mode="pose",
        pose_law="computed_torque",
        control_dt=0.001,
        physics_dt=0.001,
    )
    env.reset(seed=0)
    core = env.unwrapped._core
    params, m_r = core.platform, core.actuation.reflected_mass
    assert m_r[0] > 100.0  # kg: the rotor seen through a 25 mm lead is heavy

    def energy(with_rotor=True):
        s = [x[0].copy() for x in (core.position, core.rotation, core.velocity, core.angular_velocity)]
        rotor = 0.5 * m_r @ core.leg_rates[0] ** 2 if with_rotor else 0.0
        return kinetic_energy(params, *s) + potential_energy(params, s[0], s[1]) + rotor, dissipated_power(params, *s)

    E0, P0 = energy()
    T0 = energy(False)[0]
    L0 = core.leg_lengths[0].copy()
    residual, work, residual_without_rotor = [], [], []
    for _ in range(300):
        env.step(POSE.astype(np.float32))
        E1, P1 = energy()
        T1 = energy(False)[0]
        L1 = core.leg_lengths[0].copy()
        # the legs' forces are the motor's eta k K_t i less the screw's friction
        w = core.leg_forces[0] @ (L1 - L0)
        lost = 0.5 * (P0 + P1) * 0.001  # the joints' damping, trapezoid rule over the step
        residual.append(E1 - E0 - (w - lost))
        residual_without_rotor.append(T1 - T0 - (w - lost))
        work.append(abs(w))
        E0, P0, T0, L0 = E1, P1, T1, L1
    scale = max(work)
    assert scale > 50.0  # J per step: the platform really moves
    # RK4 at 1 ms and the trapezoid rule on the damping: ~1e-5 J measured against ~200 J of work
    assert np.abs(residual).max() < 1e-6 * scale
    # without the rotors' kinetic energy the balance fails: the reflected masses are in the dynamics
    assert np.abs(residual_without_rotor).max() > 1e-2 * scale


# -- reset at equilibrium, observed drive states ---------------------------------------------------------


@pytest.mark.parametrize("actuator", ["electric", "hydraulic"])
def test_drives_start_at_equilibrium_and_are_observed(actuator):
    env = StewartPlatformEnv(platform="motion_simulator", actuator=actuator, observe_actuators=True)
    obs, _ = env.reset(seed=4)
    core = env.unwrapped._core
    z = np.zeros((1, 3))
    holding = core.model.inverse(core.position, core.rotation, z, z, z, z)[0]
    state = core.actuation.state[0]
    if actuator == "electric":
        pushed = state[:, 0] * core.actuation.force_per_amp
        assert env.observation_space.shape == (27,)
    else:
        p = core.platform.actuators.hydraulic
        pushed = state[:, 1] * p.area_a - state[:, 2] * p.area_b
        assert env.observation_space.shape == (33,)
    # the forces that hold the start state, to rounding of the division and back
    np.testing.assert_allclose(pushed, holding, rtol=1e-12)
    decoded = env.unwrapped.decode_observation(obs)["actuator_states"]
    np.testing.assert_allclose(decoded, core.actuation.reported(slice(0, 1))[0], rtol=1e-6)  # float32
    # held at rest by the drives the platform barely moves in its first step
    before = core.position.copy()
    forces = holding
    action = (forces - np.mean(core.platform.limits.leg_force)) / (0.5 * np.ptp(core.platform.limits.leg_force))
    env.step(action.astype(np.float32))
    assert np.abs(core.position - before).max() < 1e-4  # m: float32 action rounding, 10 ms


# -- bad input -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"action_mode": "torque"}, r"^action_mode: expected one of 'force', 'leg_length', 'pose', got 'torque'"),
        ({"pose_law": "lqr"}, r"^pose_law: expected one of 'ik', 'pd_gravity', 'computed_torque', got 'lqr'"),
        ({"actuator": "pneumatic"}, r"^actuator: expected one of 'ideal', 'lag', 'electric', 'hydraulic'"),
        ({"actuator": "lag"}, r'^actuator_tau: must be > 0 for actuator="lag"'),
        ({"observe_actuators": True}, r"^observe_actuators: the 'ideal' actuator reports no state"),
        ({"actuator": "ideal", "actuator_tau": 0.1, "observation_noise": {"leg_forces": 0.1}}, r"leg_forces"),
        ({"actuator": "electric"}, r"^actuator: the platform 'dasgupta1998' has no 'electric' set"),
        ({"action_mode": "pose", "plant": "mujoco"}, r"^action_mode: the 'mujoco' plant takes leg forces only"),
    ],
)
def test_bad_arguments_name_themselves_and_list_the_choices(kwargs, message):
    with pytest.raises(ValueError, match=message):
        StewartPlatformEnv(**kwargs)


@pytest.mark.parametrize("kwargs", [COMBOS[5], COMBOS[10], COMBOS[19]], ids=[IDS[5], IDS[10], IDS[19]])
def test_commands_are_checked_and_clipped_as_forces_are(kwargs):
    env = StewartPlatformEnv(**kwargs)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"^action"):
        env.step(np.array([0.0, np.nan, 0.0, 0.0, 0.0, 0.0]))
    with pytest.raises(ValueError, match=r"^action"):
        env.step(np.zeros(5))
    # outside [-1, 1] a command is clipped: the same step as at the bound
    twin = copy.deepcopy(env)
    a = np.array([1.7, -3.0, 0.2, 0.0, 1.0, -1.0])
    obs, reward, *_ = env.step(a)
    obs_bound, reward_bound, *_ = twin.step(np.clip(a, -1.0, 1.0))
    np.testing.assert_array_equal(obs, obs_bound)
    assert reward == reward_bound
