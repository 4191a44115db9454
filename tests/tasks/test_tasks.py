"""Tests of the tasks (stewart_env.tasks) and of domain randomisation (stewart_env.randomization)."""

import gymnasium as gym
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import stewart_env.registration  # noqa: F401  (registers StewartPlatform-v1)
from stewart_env.envs import holding_action
from stewart_env.params import load_platform
from stewart_env.randomization import KEYS, Randomization
from stewart_env.rotations import matrix_to_rpy, rotation_error, rpy_to_matrix
from stewart_env.tasks import (
    DisturbanceTask,
    HoldTask,
    PlatformState,
    Reference,
    SetpointTask,
    StepView,
    TrackingTask,
    make_task,
    tracking_errors,
)
from stewart_env.tasks.base import pose_margins, zero_reference
from stewart_env.tasks.setpoint import paper_case

pytestmark = pytest.mark.env

PLATFORMS = ("dasgupta1998", "motion_simulator")


@pytest.fixture(scope="module")
def dasgupta():
    return load_platform("dasgupta1998")


def view(episode, time, state=None):
    """A StepView of the rows of ``episode`` at ``time`` (N,) for the methods that take one (the
    fields they do not read are None)."""
    return StepView(state, None, None, None, None, None, None, None, None, time, None, episode)


def batch(episodes):
    """Per-row episode dicts stacked into the (N, ...) arrays the per-step methods take."""
    return {k: np.stack([e[k] for e in episodes]) for k in episodes[0]}


# -- geometry ----------------------------------------------------------------------------------------------


def test_rotation_error_matches_scipy():
    rng = np.random.default_rng(0)
    R = Rotation.random(50, random_state=1).as_matrix()
    phi = rng.normal(size=(50, 3))
    phi *= (rng.uniform(0, 3.0, 50) / np.linalg.norm(phi, axis=1))[:, None]  # angles up to 3 rad
    R_ref = Rotation.from_rotvec(phi).as_matrix() @ R
    got, angle = rotation_error(R_ref, R)
    np.testing.assert_allclose(got, phi, atol=1e-10)  # rounding of trace and axial vector
    np.testing.assert_allclose(angle, np.linalg.norm(phi, axis=1), atol=1e-10)
    zero, angle0 = rotation_error(R, R)
    assert np.all(zero == 0) and np.all(angle0 == 0)


def test_tracking_errors_are_reference_minus_actual():
    rng = np.random.default_rng(3)
    n = 4
    state = PlatformState(
        rng.normal(size=(n, 3)),
        Rotation.random(n, random_state=2).as_matrix(),
        rng.normal(size=(n, 3)),
        rng.normal(size=(n, 3)),
    )
    ref = Reference(
        rng.normal(size=(n, 3)),
        Rotation.random(n, random_state=3).as_matrix(),
        rng.normal(size=(n, 3)),
        rng.normal(size=(n, 3)),
    )
    e = tracking_errors(state, ref)
    np.testing.assert_array_equal(e.position, ref.position - state.position)
    np.testing.assert_array_equal(e.velocity, ref.velocity - state.velocity)
    np.testing.assert_array_equal(e.angular_velocity, ref.angular_velocity - state.angular_velocity)
    np.testing.assert_allclose(e.position_norm, np.linalg.norm(e.position, axis=1), rtol=1e-15)  # sum order
    np.testing.assert_array_equal(e.orientation, rotation_error(ref.rotation, state.rotation)[0])


def test_pose_margins(dasgupta):
    p = dasgupta
    assert pose_margins(p, p.home_position, p.home_rpy)[0]
    assert not pose_margins(p, [0.0, 0.0, 0.26], [0, 0, 0])[0]  # inside the box but within its margin
    assert not pose_margins(p, p.home_position, [0, 0, 0.48])[0]  # yaw within 10 % of max_angle
    assert pose_margins(p, p.home_position, [0, 0, 0.44])[0]
    # The condition bound: 3.62 at home, 3.81 at the paper's case pose (the config's comments).
    lim = p.limits
    strict = p.replace(
        limits=type(lim)(lim.leg_length, lim.leg_force, lim.position_min, lim.position_max, lim.max_angle, 3.7)
    )
    assert pose_margins(strict, p.home_position, [0, 0, 0], margin=0.0)[0]
    assert not pose_margins(strict, [0.1, 0.0, 0.4], [0, 0, -0.2], margin=0.0)[0]
    assert pose_margins(p, [0.1, 0.0, 0.4], [0, 0, -0.2], margin=0.0)[0]


# -- setpoint ---------------------------------------------------------------------------------------------


def test_setpoint_fixed_case_is_the_papers(dasgupta):
    task = SetpointTask(dasgupta, 0.01, randomize=False)
    start, episode = task.initialize_episode(np.random.default_rng(0))
    # Exactly the paper's numbers: home (0, 0, 0.4) plus the offsets, in float64.
    np.testing.assert_allclose(start.position, [0.1, 0.0, 0.395], rtol=0, atol=1e-15)
    np.testing.assert_allclose(matrix_to_rpy(start.rotation), [0.0, 0.0, -0.2], atol=1e-15)
    assert np.all(start.velocity == 0) and np.all(start.angular_velocity == 0)
    np.testing.assert_allclose(episode["target_position"], [0.1, 0.0, 0.4], atol=1e-15)
    np.testing.assert_allclose(matrix_to_rpy(episode["target_rotation"]), [0.0, 0.0, -0.2], atol=1e-15)


@pytest.mark.parametrize("name", PLATFORMS)
def test_setpoint_fixed_case_is_the_reproductions(name):
    """The task's fixed poses and the reproduction's case are one definition, relative to home."""
    p = load_platform(name)
    task = SetpointTask(p, 0.01, randomize=False)
    case = paper_case(p)
    np.testing.assert_array_equal(task.start_position, case.start_position)
    np.testing.assert_array_equal(task.start_rpy, case.start_rpy)
    np.testing.assert_array_equal(task.target_position, case.target_position)
    np.testing.assert_array_equal(task.target_rpy, case.target_rpy)


def test_setpoint_fixed_case_through_the_env():
    env = gym.make("StewartPlatform-v1", task_options={"randomize": False})
    env.reset(seed=0)
    np.testing.assert_allclose(env.unwrapped.state.position, [0.1, 0.0, 0.395], atol=1e-15)  # float64 offsets
    np.testing.assert_allclose(env.unwrapped.target.position, [0.1, 0.0, 0.4], atol=1e-15)


@pytest.mark.parametrize("name", PLATFORMS)
def test_setpoint_random_poses_are_inside_the_limits_and_vary(name):
    p = load_platform(name)
    task = SetpointTask(p, 0.01)
    rng = np.random.default_rng(5)
    starts, targets = [], []
    for _ in range(30):
        start, episode = task.initialize_episode(rng)
        starts.append(start.position)
        targets.append(episode["target_position"])
        for position, R in ((start.position, start.rotation), (episode["target_position"], episode["target_rotation"])):
            assert pose_margins(p, position, matrix_to_rpy(R))[0]
            assert np.all(np.abs(position - p.home_position) <= task.position_range + 1e-15)  # + rounding
    starts, targets = np.array(starts), np.array(targets)
    assert np.all(np.std(starts, axis=0) > 0.1 * task.position_range)  # spread over the range
    assert np.all(np.linalg.norm(starts - targets, axis=1) > 0)


def test_setpoint_rejects_a_fixed_pose_outside_the_limits(dasgupta):
    with pytest.raises(ValueError, match="target_position"):
        SetpointTask(dasgupta, 0.01, randomize=False, target_position=[0.0, 0.0, 0.7])
    with pytest.raises(ValueError, match="randomize"):
        SetpointTask(dasgupta, 0.01, randomize="yes")


# -- tracking ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", PLATFORMS)
def test_tracking_reference_stays_inside_the_limits(name):
    p = load_platform(name)
    task = TrackingTask(p, 0.01)
    rng = np.random.default_rng(7)
    episodes = [task.initialize_episode(rng)[1] for _ in range(20)]
    times = np.linspace(0.0, 20.0, 401)
    ep = batch(episodes)
    for t in times[::20]:
        ref = zero_reference(len(episodes))
        task.reference(ep, np.full(len(episodes), t), ref)
        assert np.all(pose_margins(p, ref.position, matrix_to_rpy(ref.rotation), margin=0.0))
    amplitudes = ep["amplitude"]
    assert np.all(amplitudes[:, :3] <= task.position_amplitude + 1e-15)  # + rounding
    assert np.std(amplitudes[:, 0]) > 0  # random per episode


def test_tracking_reference_twist_is_its_derivative(dasgupta):
    task = TrackingTask(dasgupta, 0.01)
    _, episode = task.initialize_episode(np.random.default_rng(1))
    ep = batch([episode] * 3)
    h = 1e-6
    t = 0.73
    ref = zero_reference(3)
    task.reference(ep, np.array([t - h, t, t + h]), ref)
    velocity = (ref.position[2] - ref.position[0]) / (2 * h)
    # Central differences: truncation ~h^2 * |x'''| and rounding ~1e-16 / h.
    np.testing.assert_allclose(ref.velocity[1], velocity, atol=1e-8)
    dR = (ref.rotation[2] - ref.rotation[0]) / (2 * h)
    W = dR @ ref.rotation[1].T  # [omega]x
    omega = np.array([W[2, 1], W[0, 2], W[1, 0]])
    np.testing.assert_allclose(ref.angular_velocity[1], omega, atol=1e-8)
    # The accelerations likewise, from the twist: the same truncation and rounding bounds.
    np.testing.assert_allclose(ref.lin_acc[1], (ref.velocity[2] - ref.velocity[0]) / (2 * h), atol=1e-8)
    np.testing.assert_allclose(ref.ang_acc[1], (ref.angular_velocity[2] - ref.angular_velocity[0]) / (2 * h), atol=1e-8)
    assert np.abs(ref.ang_acc[1]).max() > 1e-3  # a moving reference: the check above is not of zeros


def test_fixed_targets_have_zero_accelerations():
    env = gym.make("StewartPlatform-v1", task="hold")
    env.reset(seed=0)
    env.step(np.full(6, 0.1))
    target = env.unwrapped.target
    assert target.lin_acc.shape == target.ang_acc.shape == (3,)
    assert not target.lin_acc.any() and not target.ang_acc.any()


def test_tracking_starts_on_the_reference_and_previews_it():
    env = gym.make(
        "StewartPlatform-v1",
        task="tracking",
        normalize_observation=False,
        task_options={"preview": 2, "preview_interval": 0.05},
    )
    env.reset(seed=9)
    u = env.unwrapped
    s, tg = u.state, u.target
    np.testing.assert_array_equal(s.position, tg.position)
    np.testing.assert_array_equal(s.velocity, tg.velocity)
    np.testing.assert_allclose(s.angular_velocity, tg.angular_velocity, atol=1e-15)  # one rounding apart
    obs, *_ = env.step(np.full(6, 0.1))
    s = u.state
    preview = obs[u.observation_layout["reference_preview"]].reshape(2, 6)
    # The reference does not depend on the actions: step on and read it 5 and 10 steps later.
    later = {}
    for k in range(1, 11):
        env.step(np.full(6, 0.1))
        later[k] = u.target
    for j, ahead in enumerate((5, 10)):
        ref = later[ahead]
        np.testing.assert_allclose(preview[j, :3], ref.position - s.position, atol=1e-6)  # float32
        np.testing.assert_allclose(
            preview[j, 3:], rotation_error(ref.rotation[None], s.rotation[None])[0][0], atol=1e-6
        )


# -- disturbance --------------------------------------------------------------------------------------------


def test_disturbance_wrench_delivers_its_exact_impulse(dasgupta):
    task = DisturbanceTask(dasgupta, 0.01, n_impulses=3, impulse_duration=0.004)
    _, episode = task.initialize_episode(np.random.default_rng(2))
    ep = batch([episode])
    dt, steps = 0.01, 600
    total = np.zeros(6)
    out = np.zeros((1, 6))
    for k in range(steps):
        task.external_wrench(view(ep, np.array([k * dt])), dt, out)
        total += out[0] * dt
    T = steps * dt
    A, w, phi = episode["sine_amplitude"], episode["sine_omega"], episode["sine_phase"]
    sine = A * (np.cos(phi) - np.cos(w * T + phi)) / w
    pulses = (episode["impulse_wrench"] * task.impulse_duration).sum(axis=0)
    # Pulses of 4 ms, shorter than a control step, still deliver all of it; rounding only.
    np.testing.assert_allclose(total, sine + pulses, atol=1e-9)
    assert np.all(np.abs(A[:3]) <= task.sine_force) and np.any(episode["impulse_wrench"] != 0)


def test_disturbance_holds_home_under_a_wrench_it_does_not_observe():
    env = gym.make("StewartPlatform-v1", task="disturbance")
    obs, _ = env.reset(seed=4)
    u = env.unwrapped
    p = u.platform
    np.testing.assert_array_equal(u.state.position, p.home_position)
    np.testing.assert_array_equal(u.target.position, p.home_position)
    env.step(np.full(6, 0.1))
    assert np.any(u.external_wrench != 0)
    assert set(u.observation_layout) == {
        "position",
        "orientation",
        "velocity",
        "angular_velocity",
        "position_error",
        "orientation_error",
    }


def test_disturbance_wrench_moves_the_platform():
    calm = gym.make(
        "StewartPlatform-v1", task="disturbance", task_options={"sine_force": 0.0, "sine_moment": 0.0, "n_impulses": 0}
    )
    pushed = gym.make("StewartPlatform-v1", task="disturbance")
    for env in (calm, pushed):
        env.reset(seed=1)
    a = np.full(6, 0.08)
    for _ in range(5):
        calm.step(a)
        pushed.step(a)
    assert np.all(calm.unwrapped.external_wrench == 0)
    assert not np.array_equal(calm.unwrapped.state.position, pushed.unwrapped.state.position)


# -- options ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "task, options, message",
    [
        ("setpoint", {"position_rang": 0.1}, "position_rang"),
        ("setpoint", {"angle_range": -0.1}, "angle_range"),
        ("tracking", {"frequency_range": (1.0, 0.5)}, "frequency_range"),
        ("tracking", {"preview": -1}, "preview"),
        ("tracking", {"preview_interval": 0.0}, "preview_interval"),
        ("disturbance", {"n_impulses": 1.5}, "n_impulses"),
        ("disturbance", {"impulse_duration": 0.0}, "impulse_duration"),
        ("disturbance", {"horizon": 0.01, "impulse_duration": 0.05}, "horizon"),
        ("disturbance", {"sine_force": [1.0, 2.0]}, "sine_force"),
    ],
)
def test_bad_task_options_name_the_option(dasgupta, task, options, message):
    with pytest.raises(ValueError, match=message):
        make_task(task, dasgupta, 0.01, options)


def test_make_task_accepts_a_task_class(dasgupta):
    assert isinstance(make_task(TrackingTask, dasgupta, 0.01, {"preview": 1}), TrackingTask)
    with pytest.raises(ValueError, match="task"):
        make_task(3, dasgupta, 0.01)


# -- domain randomisation --------------------------------------------------------------------------------


def test_randomization_validates_its_spec():
    with pytest.raises(ValueError, match="unknown key.*'weight'"):
        Randomization({"weight": (0.9, 1.1)})
    with pytest.raises(ValueError, match="platform.mass.*> 0"):
        Randomization({"platform.mass": (0.0, 1.1)})
    with pytest.raises(ValueError, match="damping.*>= 0"):
        Randomization({"damping": (-0.1, 1.1)})
    with pytest.raises(ValueError, match="com.*low <= high"):
        Randomization({"com": (1.1, 0.9)})
    with pytest.raises(ValueError, match="inertia.*low, high"):
        Randomization({"inertia": 1.1})
    Randomization({"com": (-1.0, 1.0), "damping": (0.0, 0.0)})


def test_randomization_scales_the_declared_parameters(dasgupta):
    spec = {
        "platform.mass": (0.5, 0.5),
        "legs.mass": (2.0, 2.0),
        "inertia": (3.0, 3.0),
        "upper_leg.com": (-1.0, -1.0),
        "damping.prismatic": (4.0, 4.0),
        "mass": (1.5, 1.5),
    }
    r = Randomization(spec)
    factors = r.sample(np.random.default_rng(0))
    assert list(factors) == [k for k in KEYS if k in spec]  # drawn in the order of KEYS
    q = r.apply(dasgupta, factors)
    p = dasgupta
    # One or two multiplications each: equal to rounding.
    assert q.platform.mass == pytest.approx(p.platform.mass * 0.5 * 1.5, rel=1e-15)
    assert q.upper_leg[3].mass == pytest.approx(p.upper_leg[3].mass * 2.0 * 1.5, rel=1e-15)
    np.testing.assert_allclose(q.lower_leg[0].inertia, 3.0 * p.lower_leg[0].inertia, rtol=1e-15)
    np.testing.assert_allclose(q.upper_leg[0].com, -p.upper_leg[0].com, rtol=1e-15)
    np.testing.assert_array_equal(q.lower_leg[0].com, p.lower_leg[0].com)
    assert q.damping.prismatic == pytest.approx(4.0 * p.damping.prismatic, rel=1e-15)
    assert q.damping.universal == p.damping.universal
    assert q.upper_leg[0] is q.upper_leg[5]  # shared legs stay shared
    np.testing.assert_array_equal(q.base_joints, p.base_joints)


def test_randomization_order_does_not_depend_on_the_dict_order():
    a = Randomization({"mass": (0.5, 2.0), "damping": (0.5, 2.0)}).sample(np.random.default_rng(3))
    b = Randomization({"damping": (0.5, 2.0), "mass": (0.5, 2.0)}).sample(np.random.default_rng(3))
    assert a == b


def test_randomized_env_draws_new_params_each_episode_and_reports_them():
    spec = {
        "platform.mass": (0.8, 1.2),
        "legs.mass": (0.9, 1.1),
        "inertia": (0.8, 1.2),
        "com": (0.9, 1.1),
        "damping": (0.5, 2.0),
    }
    env = gym.make("StewartPlatform-v1", randomization=spec)
    _, info1 = env.reset(seed=0)
    params1 = env.unwrapped.model.params[0]
    assert env.unwrapped.episode_params == params1
    _, info2 = env.reset()
    params2 = env.unwrapped.model.params[0]
    assert env.unwrapped.episode_params == params2
    assert set(info1["randomization"]) == set(spec)
    for key, (lo, hi) in spec.items():
        assert lo <= info1["randomization"][key] <= hi
        assert type(info1["randomization"][key]) is np.float64
    assert info1["randomization"] != info2["randomization"]
    assert params1 != params2
    nominal = env.unwrapped.platform
    # One multiplication: equal to rounding.
    assert params1.platform.mass == pytest.approx(
        nominal.platform.mass * info1["randomization"]["platform.mass"], rel=1e-15
    )
    _, again = env.reset(seed=0)
    assert again["randomization"] == info1["randomization"]


def test_randomized_dynamics_differ_from_nominal():
    nominal = gym.make("StewartPlatform-v1", task="disturbance")
    heavy = gym.make("StewartPlatform-v1", task="disturbance", randomization={"platform.mass": (1.5, 1.5)})
    for env in (nominal, heavy):
        env.reset(seed=0)
        for _ in range(3):
            env.step(np.full(6, 0.1))
    # Same forces and wrench on a 50 % heavier platform: a different motion, by far more than
    # the 1e-9 m rounding could explain.
    assert not np.allclose(nominal.unwrapped.state.position, heavy.unwrapped.state.position, rtol=0, atol=1e-9)


class _NearTarget(SetpointTask):
    """A task with a termination of its own: the episode ends, a success, once within 2 cm of the target."""

    name = "near_target"
    termination_reasons = (*SetpointTask.termination_reasons, "reached")
    success_reasons = ("reached",)

    def termination(self, view):
        code = super().termination(view)
        self.end(code, view.errors.position_norm < 0.02, "reached")
        return code


def test_a_task_of_ones_own_ends_an_episode_with_a_success_and_no_termination_cost():
    env = gym.make("StewartPlatform-v1", task=_NearTarget, task_options={"randomize": False})
    env.reset(seed=0)
    u = env.unwrapped
    assert u.task.name == "near_target"
    # The fixed case starts 5 mm below the target: the first step already ends the episode.
    _, reward, terminated, _, info = env.step(np.full(6, 0.09))
    assert terminated and env.unwrapped.termination_reasons[info["termination"]] == "reached"
    # The task's reasons follow the platform's limits.
    assert u.termination_reasons == ("", "non_finite", "singularity", "leg_stroke", "workspace", "reached")
    assert info["termination"] == 5
    assert info["reward_termination"] == 0.0  # a success: the task pays no termination cost
    assert reward == sum(v for k, v in info.items() if k.startswith("reward_"))
    # The limits rank first: on the target position but pitched 0.52 rad (past max_angle 0.5;
    # legs 1.17-1.46 m, in stroke) both apply, and "workspace" wins, a failure.
    u.set_state([0.1, 0.0, 0.4], rpy_to_matrix([0.0, 0.52, 0.0]))
    _, _, terminated, _, info = env.step(np.full(6, 0.09))
    assert terminated and env.unwrapped.termination_reasons[info["termination"]] == "workspace"
    assert info["reward_termination"] == -10.0  # the default termination_cost of a failure
    cheap = gym.make("StewartPlatform-v1", task=_NearTarget, task_options={"randomize": False, "termination_cost": 3.0})
    cheap.reset(seed=0)
    cheap.unwrapped.set_state([0.1, 0.0, 0.4], rpy_to_matrix([0.0, 0.52, 0.0]))
    assert cheap.step(np.full(6, 0.09))[4]["reward_termination"] == -3.0


def test_a_task_sees_the_batch_read_only():
    seen = []

    class Peek(SetpointTask):
        def reward_terms(self, view):
            seen.append(view)
            return super().reward_terms(view)

    env = gym.make("StewartPlatform-v1", task=Peek)
    env.reset(seed=0)
    env.step(np.full(6, 0.1))
    v = seen[-1]
    u = env.unwrapped
    np.testing.assert_array_equal(v.leg_lengths[0], u.leg_lengths)
    np.testing.assert_array_equal(v.leg_forces[0], u.leg_forces)
    np.testing.assert_array_equal(v.state.position[0], u.state.position)
    assert v.time[0] == 0.01 and v.episode["target_position"].shape == (1, 3)
    for array in (
        v.state.position,
        v.errors.position,
        v.errors.position_norm,
        v.leg_rates,
        v.condition,
        v.action,
        v.episode["target_rotation"],
    ):
        with pytest.raises(ValueError, match="read-only"):
            array[...] = 0.0


@pytest.mark.parametrize(
    "bad, message",
    [
        ({"termination_reasons": ("reached",)}, "must begin with"),
        ({"success_reasons": ("landed",)}, "success reason"),
        ({"episode_fields": lambda self: {"goal": (3,)}}, "fixed target"),
    ],
)
def test_a_task_that_breaks_the_interface_is_refused_at_construction(dasgupta, bad, message):
    broken = type("Broken", (SetpointTask,), bad)
    with pytest.raises(TypeError, match=message):
        broken(dasgupta, 0.01)


def test_a_tasks_flags_follow_from_what_it_overrides(dasgupta):
    assert not SetpointTask(dasgupta, 0.01).moving_reference
    assert TrackingTask(dasgupta, 0.01).moving_reference
    assert not SetpointTask(dasgupta, 0.01).has_external_wrench
    assert DisturbanceTask(dasgupta, 0.01).has_external_wrench
    assert HoldTask(dasgupta, 0.01).has_external_wrench and not HoldTask(dasgupta, 0.01).moving_reference


# -- hold -----------------------------------------------------------------------------------------------------


def test_hold_payload_is_a_dead_weight_at_its_point(dasgupta):
    task = HoldTask(dasgupta, 0.01, max_payload=10.0)
    _, episode = task.initialize_episode(np.random.default_rng(3))
    m, c = episode["payload_mass"], episode["payload_offset"]
    assert 0.0 <= m <= 10.0 and np.hypot(*c[:2]) <= task.payload_radius and c[2] == 0.0
    R = rpy_to_matrix(np.array([0.1, -0.2, 0.3]))
    state = PlatformState(dasgupta.home_position[None], R[None], np.zeros((1, 3)), np.zeros((1, 3)))
    out = np.zeros((1, 6))
    task.external_wrench(view(batch([episode]), np.zeros(1), state), 0.01, out)
    force = m * dasgupta.gravity
    np.testing.assert_array_equal(out[0, :3], force)
    # The moment of the weight about P: (R c) x m g, checked against the triple product written out
    # (the two differ by rounding only: ~1e-15 relative, and atol for components that cancel to ~0).
    arm = R @ c
    np.testing.assert_allclose(
        out[0, 3:],
        [
            arm[1] * force[2] - arm[2] * force[1],
            arm[2] * force[0] - arm[0] * force[2],
            arm[0] * force[1] - arm[1] * force[0],
        ],
        rtol=1e-15,
        atol=1e-12,
    )


def test_hold_the_holding_forces_of_the_bare_platform_let_the_payload_pull_it_down():
    env = gym.make("StewartPlatform-v1", task="hold", task_options={"max_payload": 20.0, "payload_radius": 0.0})
    env.reset(seed=1)
    u = env.unwrapped
    p = u.platform
    np.testing.assert_array_equal(u.state.position, p.home_position)
    np.testing.assert_array_equal(u.target.position, p.home_position)
    assert u.termination_reasons == ("", "non_finite", "singularity", "leg_stroke", "workspace")
    a = holding_action(env)
    for _ in range(20):
        _, _, terminated, _, info = env.step(a)
    assert not terminated
    mass = u.task.max_payload  # the episode's payload, at most this
    # A downward weight, no moment at P's origin; 1e-9 N covers rounding of m g.
    assert 0.0 < -u.external_wrench[2] <= mass * np.linalg.norm(p.gravity) + 1e-9
    np.testing.assert_array_equal(u.external_wrench[3:], 0.0)
    # 0.2 s under a weight the forces do not carry: the platform has sunk, by more than rounding.
    assert u.state.position[2] < p.home_position[2] - 1e-4
    assert set(u.observation_layout) == {
        "position",
        "orientation",
        "velocity",
        "angular_velocity",
        "position_error",
        "orientation_error",
    }


def test_hold_options_are_checked(dasgupta):
    with pytest.raises(ValueError, match=r"task_options\['max_payload'\]"):
        HoldTask(dasgupta, 0.01, max_payload=-1.0)
    with pytest.raises(ValueError, match=r"task_options\['payload_radius'\]"):
        HoldTask(dasgupta, 0.01, payload_radius=5.0)


# -- the environment's keywords for the tasks --------------------------------------------------


@pytest.mark.parametrize("name", ["termination_cost", "ctrl_cost_weight", "position_reward_scale"])
def test_old_reward_keywords_say_they_moved_to_task_options(make, name):
    with pytest.raises(TypeError, match=rf"the reward weights are options of the task: pass task_options=\{{'{name}'"):
        make(**{name: 1.0})


@pytest.mark.parametrize(
    "name, value",
    [
        ("termination_cost", np.nan),
        ("termination_cost", np.inf),
        ("ctrl_cost_weight", -1.0),
        ("ctrl_cost_weight", 1e300),
        ("position_reward_scale", 0.0),
        ("velocity_cost_weight", "1"),
    ],
)
def test_hostile_reward_weights_are_refused_naming_the_option(make, name, value):
    with pytest.raises((ValueError, TypeError), match=rf"task_options\['{name}'\]"):
        make(task_options={name: value})


@pytest.mark.parametrize(
    "options",
    [
        {"max_payload": -1.0},
        {"max_payload": np.nan},
        {"max_payload": 401.0},
        {"max_payload": True},
        {"payload_radius": np.inf},
    ],
)
def test_hold_task_refuses_hostile_payload_options(make, options):
    name = next(iter(options))
    with pytest.raises((ValueError, TypeError), match=rf"task_options\['{name}'\]"):
        make(task="hold", task_options=options)


def test_an_option_of_another_task_is_refused_listing_the_valid_ones(make):
    with pytest.raises(ValueError, match=r"unknown option\(s\) 'max_payload' for task 'setpoint'; valid options: "):
        make(task="setpoint", task_options={"max_payload": 3.0})


def test_hold_task_rewards_holding_the_platform_above_letting_it_fall(make):
    held, dropped = make(task="hold"), make(task="hold")
    hold = holding_action(held).astype(np.float32)
    for _ in range(5):
        held_reward = held.step(hold)[1]
        dropped_reward = dropped.step(np.zeros(6, np.float32))[1]
    assert held_reward > dropped_reward  # sinking away from the target pose costs reward
