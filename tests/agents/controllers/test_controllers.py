"""The baseline controllers: the PD law (paper eq. 56), computed torque, and their policy faces."""

import gymnasium as gym
import numpy as np
import pytest

import stewart_env as se
from stewart_env.agents import (
    PAPER_KD,
    PAPER_KP,
    PD_LAYOUT,
    ComputedTorque,
    ComputedTorquePolicy,
    PDPolicy,
    TaskSpacePD,
    evaluate,
    pd_control_law,
    pd_control_params,
    preview_acceleration,
    zoh_pd_gains,
    zoh_spectral_radius,
)
from stewart_env.agents.evaluation.evaluation import ENV_ID
from stewart_env.state import PlatformState, Reference


@pytest.fixture
def moving_state(dasgupta, rng):
    """A state near the paper's case pose, moving, and a reference a little away from it."""
    state = PlatformState(
        np.array([0.1, 0.01, 0.39]),
        se.rpy_to_matrix([0.03, -0.02, -0.18]),
        rng.normal(scale=0.05, size=3),
        rng.normal(scale=0.1, size=3),
    )
    reference = Reference(
        np.array([0.1, 0.0, 0.4]),
        se.rpy_to_matrix([0.0, 0.0, -0.2]),
        rng.normal(scale=0.05, size=3),
        rng.normal(scale=0.1, size=3),
        rng.normal(size=3),
        rng.normal(size=3),
    )
    return state, reference


def test_pd_forces_realise_the_pd_wrench(dasgupta, moving_state):
    state, reference = moving_state
    pd = TaskSpacePD(dasgupta)
    forces = pd(state, reference)
    jac = se.jacobian(dasgupta, state.position, state.rotation)
    rpy, rpy_d = se.matrix_to_rpy(state.rotation), se.matrix_to_rpy(reference.rotation)
    from stewart_env.rotations import rpy_rate_matrix

    rate = np.linalg.solve(rpy_rate_matrix(rpy), state.angular_velocity)
    rate_d = np.linalg.solve(rpy_rate_matrix(rpy_d), reference.angular_velocity)
    e = np.concatenate([reference.position - state.position, rpy_d - rpy])
    edot = np.concatenate([reference.velocity - state.velocity, rate_d - rate])
    wrench = PAPER_KP * e + PAPER_KD * edot
    # J^T F must give back the wrench up to the 6x6 solve's rounding (cond(J) ~ 4, |W| ~ 1e5)
    np.testing.assert_allclose(jac.T @ forces, wrench, rtol=1e-10, atol=1e-8 * np.abs(wrench).max())


def test_pd_gravity_compensation_adds_the_holding_forces(dasgupta, moving_state):
    state, reference = moving_state
    plain, compensated = TaskSpacePD(dasgupta), TaskSpacePD(dasgupta, gravity_compensation=True)
    zero = np.zeros(3)
    holding = se.make_dynamics("improved", dasgupta).inverse(state.position, state.rotation, zero, zero, zero, zero)
    # same arithmetic plus one addition: rounding of forces of ~1e4 N
    np.testing.assert_allclose(compensated(state, reference) - plain(state, reference), holding, atol=1e-9)


def test_pd_batched_equals_one_by_one(dasgupta, moving_state):
    state, reference = moving_state
    pd = TaskSpacePD(dasgupta, gravity_compensation=True)
    batch = PlatformState(*(np.stack([x, x]) for x in state))
    out = pd(batch, reference)
    # the same kernels row by row: identical up to the batched solve's rounding
    np.testing.assert_allclose(out, np.stack([pd(state, reference)] * 2), rtol=1e-12, atol=1e-9)


def test_computed_torque_with_the_plant_model_gives_the_commanded_acceleration(dasgupta, moving_state):
    state, reference = moving_state
    for name in ("improved", "classical"):
        ct = ComputedTorque(dasgupta, internal_model=name)
        lin, ang = se.make_dynamics(name, dasgupta).forward(*state, ct(state, reference))
        # forward(inverse(a)) == a to the rounding of the 6x6 solves (accelerations ~ 1e2)
        np.testing.assert_allclose(np.concatenate([lin, ang]), ct.commanded_acceleration(state, reference), atol=1e-8)


def test_computed_torque_solves_the_equations_of_motion_with_the_models_mass_matrix_and_bias(dasgupta, moving_state):
    state, reference = moving_state
    ct = ComputedTorque(dasgupta, internal_model="classical")
    forces = ct(state, reference)
    M, h = ct.model.mass_and_bias(*state)
    jac = se.jacobian(dasgupta, state.position, state.rotation)
    # J^T F = M [a_cmd; alpha_cmd] + h, the compiled assembly's M and h (wrenches ~1e3: rounding)
    np.testing.assert_allclose(jac.T @ forces, M @ ct.commanded_acceleration(state, reference) + h, atol=1e-8)


def test_computed_torque_feeds_the_reference_accelerations_forward(dasgupta, moving_state):
    state, reference = moving_state
    ct = ComputedTorque(dasgupta)
    at_rest = reference._replace(lin_acc=np.zeros(3), ang_acc=np.zeros(3))
    step = ct.commanded_acceleration(state, reference) - ct.commanded_acceleration(state, at_rest)
    # the feedforward adds the reference's accelerations exactly (one addition: rounding)
    np.testing.assert_allclose(step, np.concatenate([reference.lin_acc, reference.ang_acc]), atol=1e-13)
    # a reference built from pose and twist alone has zero accelerations, arrays of its own
    plain = Reference(*reference[:4])
    assert plain.lin_acc.shape == plain.ang_acc.shape == (3,) and plain.lin_acc is not plain.ang_acc
    np.testing.assert_array_equal(ct.commanded_acceleration(state, plain), ct.commanded_acceleration(state, at_rest))


def test_pd_control_params_follow_the_layout(dasgupta, moving_state):
    _, reference = moving_state
    params = pd_control_params(
        dasgupta, reference, kp=2.0, kd=3.0, gravity_compensation=True, gravity_model="classical"
    )
    offsets = np.cumsum([0] + [size for _, size in PD_LAYOUT])
    part = {name: params[offsets[k] : offsets[k + 1]] for k, (name, _) in enumerate(PD_LAYOUT)}
    assert params.shape == (offsets[-1],)
    np.testing.assert_array_equal(part["kp"], np.full(6, 2.0))
    np.testing.assert_array_equal(part["kd"], np.full(6, 3.0))
    np.testing.assert_array_equal(part["rotation"], reference.rotation.ravel())
    np.testing.assert_array_equal(part["angular_velocity"], reference.angular_velocity)
    assert (
        part["gravity_compensation"][0] == 1.0
        and part["gravity_flags"][0] == se.make_dynamics("classical", dasgupta).flags
    )
    np.testing.assert_array_equal(part["platform"], se.make_dynamics("classical", dasgupta).packed[0])
    batched = pd_control_params(dasgupta, Reference(*(np.stack([x, x]) for x in reference[:4])))
    assert batched.shape == (2, offsets[-1])


def test_pd_control_law_in_a_closed_loop_rollout_holds_a_set_point(dasgupta):
    """The example of docs/guides/physics-api.md: the paper's PD law with gravity compensation,
    compiled, in rollout."""
    model = se.make_dynamics("improved", dasgupta)
    target = Reference(
        dasgupta.home_position + [0.0, 0.0, 0.01], se.rpy_to_matrix(dasgupta.home_rpy), np.zeros(3), np.zeros(3)
    )
    params = pd_control_params(dasgupta, target, PAPER_KP, PAPER_KD, gravity_compensation=True)
    zero = np.zeros(3)
    run = se.rollout(
        model,
        dasgupta.home_position,
        se.rpy_to_matrix(dasgupta.home_rpy),
        zero,
        zero,
        dt=2e-4,
        steps=2500,
        control_law=pd_control_law,
        control_params=params,
        record_every=250,
    )
    # gravity compensated exactly, slowest pole near 40 rad/s: after 0.5 s (20 time constants) the
    # error is at the rounding of the 0.41 m height (observed 2e-15)
    np.testing.assert_allclose(run.position[-1], target.position, rtol=0, atol=1e-12)
    np.testing.assert_allclose(run.rotation[-1], target.rotation, rtol=0, atol=1e-12)
    # and it did move: 10 mm up within the first 50 ms
    assert run.position[1, 2] - dasgupta.home_position[2] > 9e-3


def test_tuned_gains_are_stable_under_the_hold_and_the_paper_gains_are_not(dasgupta):
    model = se.make_dynamics("improved", dasgupta)
    kp, kd = zoh_pd_gains(model, 0.01)
    assert zoh_spectral_radius(model, kp, kd, 0.01) < 0.9  # designed at 0.88: the margin of the default
    for scale in (0.5, 2.0):  # still stable with the inertia halved or doubled
        assert zoh_spectral_radius(model, kp, kd, 0.01, inertia_scale=scale) < 1.0
    # the paper's continuous gains put the vertical pole at ~300 rad/s: hopeless at 10 ms
    assert zoh_spectral_radius(model, PAPER_KP, PAPER_KD, 0.01) > 1.0


def test_bad_gains_and_platform_are_named():
    with pytest.raises(ValueError, match="kp"):
        TaskSpacePD(se.load_platform("dasgupta1998"), kp=[1.0, 2.0])
    with pytest.raises(ValueError, match="kd"):
        ComputedTorque(se.load_platform("dasgupta1998"), kd=-1.0)
    with pytest.raises(ValueError, match="platform"):
        TaskSpacePD("dasgupta1998")
    with pytest.raises(ValueError, match="model"):
        ComputedTorque(se.load_platform("dasgupta1998"), internal_model="newtonian")


def test_policy_decodes_the_true_state_and_target():
    env = gym.make(ENV_ID, task="tracking")
    obs, _ = env.reset(seed=4)
    env.step(env.action_space.sample())
    obs, *_ = env.step(np.zeros(6, dtype=np.float32))
    state, reference = PDPolicy(env).decode(obs)
    true, target = env.unwrapped.state, env.unwrapped.target
    # observations are float32, scaled by ~0.25 m and 0.5 rad: ~1e-7 relative
    np.testing.assert_allclose(state.position[0], true.position, atol=1e-6)
    np.testing.assert_allclose(state.rotation[0], true.rotation, atol=1e-6)
    np.testing.assert_allclose(state.velocity[0], true.velocity, atol=1e-6)
    np.testing.assert_allclose(reference.position[0], target.position, atol=1e-6)
    np.testing.assert_allclose(reference.rotation[0], target.rotation, atol=1e-6)
    np.testing.assert_allclose(reference.velocity[0], target.velocity, atol=1e-6)
    np.testing.assert_allclose(reference.angular_velocity[0], target.angular_velocity, atol=1e-5)


def test_policy_actions_apply_the_controller_forces_single_and_batched():
    env = gym.make(ENV_ID, task="setpoint", task_options={"randomize": False})
    policy = PDPolicy(env)
    obs, _ = env.reset(seed=0)
    action, state = policy.predict(obs)
    batch_action, _ = policy.predict(np.stack([obs, obs]))
    assert action.shape == (6,) and state is None and batch_action.shape == (2, 6)
    np.testing.assert_array_equal(batch_action, np.stack([action, action]))
    s, ref = policy.decode(obs)
    forces = policy.controller(s, ref)[0]
    assert np.all(np.abs(action) < 1)  # the paper's start is 5 mm from its target: no saturation
    env.step(action)
    # the env maps the float32 action back to forces: float32 rounding of +-2000 N
    np.testing.assert_allclose(env.unwrapped.leg_forces, forces, atol=1e-3)


def test_policy_needs_the_pose_observation():
    env = gym.make(ENV_ID, observation_mode="sensors")
    with pytest.raises(ValueError, match="observation"):
        PDPolicy(env)


def test_preview_acceleration_of_a_sinusoid():
    amplitude, omega, phase = 0.1, 2 * np.pi * 0.5, 0.3  # the tracking task's fastest axis
    h = 0.1 * np.arange(1, 4)
    for t in np.linspace(0.0, 2.0, 7):
        x = lambda s: amplitude * np.sin(omega * s + phase)  # noqa: E731
        step = np.broadcast_to((x(t + h) - x(t))[None, :, None], (1, 3, 3))
        rate = np.full((1, 3), amplitude * omega * np.cos(omega * t + phase))
        acc = preview_acceleration(step, step, rate, rate, h)
        exact = -amplitude * omega**2 * np.sin(omega * t + phase)
        # exact cubic interpolation of 3 samples over 0.3 s: the quartic remainder, 0.31 % of the amplitude
        np.testing.assert_allclose(acc[0], exact, atol=4e-3 * amplitude * omega**2)


def test_pd_with_gravity_compensation_settles_the_setpoint_task_on_both_models():
    for model in ("classical", "improved"):
        result = evaluate(
            lambda env: PDPolicy(env, gravity_compensation=True),
            {"model": model, "task": "setpoint"},
            episodes=2,
            seed=0,
            max_steps=150,
            progress=False,
        )
        for ep in result.episodes:
            m = ep.metrics
            assert ep.termination is None
            assert m["success"] == 1.0
            # poles at 20 rad/s, critically damped: 2 mm reached in ~0.3 s from ~10 cm
            assert m["settling_time"] < 0.6
            # the compensation uses the improved statics; on the classical plant they miss by ~1e-3 of
            # the weight (simplification C2), leaving ~0.02 mm and ~0.9 mrad; exact on improved
            bound_p, bound_o = (1e-4, 2e-3) if model == "classical" else (1e-6, 1e-5)
            assert m["steady_state_position_error"] < bound_p
            assert m["steady_state_orientation_error"] < bound_o


def test_pd_without_compensation_sags_until_its_wrench_holds_the_weight():
    env = gym.make(ENV_ID, task="setpoint", max_episode_steps=300)
    policy = PDPolicy(env)
    obs, _ = env.reset(seed=3)
    for _ in range(300):
        obs, *_ = env.step(policy.predict(obs)[0])
    base = env.unwrapped
    state, target = base.state, base.target
    # poles at 20 rad/s, critically damped: after 3 s the transient is e^-60 of the step, gone; what
    # moves is the jitter of float32 actions (steps of 1e-4 N on 45 kg): nm/s
    assert np.linalg.norm(state.velocity) < 1e-7 and np.linalg.norm(state.angular_velocity) < 1e-7
    zero = np.zeros(3)
    holding = base.model.inverse(state.position, state.rotation, zero, zero, zero, zero)
    # at rest the legs carry exactly the statics: float32 rounding of the action, 2000 N * 2^-24
    np.testing.assert_allclose(base.leg_forces, holding, atol=1e-3)
    # and the law makes that wrench from the error alone: J^T F_hold = Kp e, so the sag is Kp^-1 J^T F_hold
    # (up to the same float32 action rounding, mapped through J^T: below 1e-3 N, N m)
    jac = se.jacobian(base.model, state.position, state.rotation)
    error = np.concatenate(
        [target.position - state.position, se.matrix_to_rpy(target.rotation) - se.matrix_to_rpy(state.rotation)]
    )
    np.testing.assert_allclose(policy.controller.kp * error, jac.T @ holding, rtol=1e-6, atol=1e-3)
    assert 0.02 < target.position[2] - state.position[2] < 0.035  # 480 N of weight / Kp_z: 27 mm


def test_computed_torque_with_the_plant_model_beats_pd_on_tracking():
    for model in ("improved", "classical"):
        env_kwargs = {"model": model, "task": "tracking"}
        runs = {
            label: evaluate(policy, env_kwargs, episodes=2, seed=0, max_steps=150, progress=False)
            for label, policy in (
                ("pd", lambda env: PDPolicy(env, gravity_compensation=True)),
                ("matched", lambda env, m=model: ComputedTorquePolicy(env, m)),
                (
                    "mismatched",
                    lambda env, m=model: ComputedTorquePolicy(env, "classical" if m == "improved" else "improved"),
                ),
            )
        }
        rms = {k: np.mean([ep.metrics["rms_position_error"] for ep in r.episodes]) for k, r in runs.items()}
        # feedforward + the right model: ~15x below PD's lag on 0.1-0.5 Hz sinusoids; 5x is the bound
        assert rms["matched"] < rms["pd"] / 5
        # the wrong model leaves a model-error disturbance: about twice the matched error
        assert rms["matched"] < 0.8 * rms["mismatched"]


def test_the_compiled_laws_angles_and_rates_are_the_packages(dasgupta, rng):
    """pd_control_law computes roll-pitch-yaw and their rates in compiled code: the same convention
    as stewart_env.matrix_to_rpy and rotations.rpy_rate_matrix.  With gains on the angles alone and
    the reference at zero angles and rates, the law's wrench is -Kp rpy - Kd E^-1 w, realised by J^-T."""
    from stewart_env.agents.controllers.pd import pd_control_law, pd_control_params
    from stewart_env.dynamics.rk4 import law_forces
    from stewart_env.rotations import rpy_rate_matrix

    kp, kd = np.array([0, 0, 0, 300.0, 200.0, 100.0]), np.array([0, 0, 0, 30.0, 20.0, 10.0])
    z = np.zeros(3)
    row = pd_control_params(dasgupta, se.Reference(dasgupta.home_position, np.eye(3), z, z), kp, kd)
    for _ in range(20):
        rpy = rng.uniform(-0.3, 0.3, size=3)
        R, w = se.rpy_to_matrix(rpy), rng.normal(size=3)
        got = law_forces(pd_control_law, row[None], dasgupta.home_position[None], R[None], z[None], w[None])[0]
        wrench = np.concatenate([z, -kp[3:] * se.matrix_to_rpy(R) - kd[3:] * np.linalg.solve(rpy_rate_matrix(rpy), w)])
        want = np.linalg.solve(se.jacobian(dasgupta, dasgupta.home_position, R).T, wrench)
        # closed-form inverse of E and the law's own 6x6 solve against LU solves: rounding, scaled by cond(J) ~ 10
        np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-10 * np.abs(want).max())
