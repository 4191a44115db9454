"""The cueing MPC: its perception model against the vestibular filters, a hand case of its linear
model (the tilt's specific force), the pose it commands, its parameters' checks, the policy inside
the workspace on a held-out manoeuvre, and the error without OSQP."""

import sys

import numpy as np
import pytest

from stewart_env.agents.controllers.cueing_mpc import CueingMPCParams, foh_state_space, pair_model
from stewart_env.agents.controllers.washout import head_pose
from stewart_env.errors import UsageError
from stewart_env.extras import MissingExtra
from stewart_env.tasks.cueing.motion import STANDARD_GRAVITY
from stewart_env.tasks.cueing.vestibular import Otolith, SemicircularCanal

DT = 0.01


@pytest.mark.parametrize("model", [Otolith(), SemicircularCanal()])
def test_the_state_space_form_is_the_vestibular_filter(model):
    # xi_k = x_k - Gamma_2 u_k: the same outputs as the filter the metrics use, from rest
    phi, g, h, j = foh_state_space(*model.transfer_function(), DT)
    sensor = model.discretize(DT)
    sensor.reset(np.zeros(3))
    u = np.cumsum(np.random.default_rng(0).normal(size=500)) * 0.1
    xi = np.zeros(len(g))
    for value in u:
        expected = sensor.step(np.full(3, value))[0]
        # 1e-9: the same matrices summed in another order, over 500 steps of inputs of order 1
        np.testing.assert_allclose(h @ xi + j * value, expected, rtol=0.0, atol=1e-9)
        xi = phi @ xi + g * value


@pytest.mark.parametrize("coupling, sign", [(-STANDARD_GRAVITY, -1.0), (STANDARD_GRAVITY, 1.0)])
def test_a_held_tilt_renders_gravitys_component(coupling, sign):
    # hand case: tilt to 0.1 rad at a constant angular acceleration, then hold it; the model's f is
    # coupling * theta, and a cabin tilted by theta feels g sin(theta) (sign -1 for pitch about y,
    # +1 for roll about x): within the small-angle error theta / sin(theta) - 1 = 0.17 %
    a, b, c, d = pair_model(DT, coupling, 0.0)
    x = np.zeros(9)
    for k in range(200):
        alpha = 0.1 if k < 100 else -0.1  # 0.1 rad/s² for 1 s, then braking the rate: 0.1 rad
        y = c @ x + d @ np.array([0.0, alpha])
        x = a @ x + b @ np.array([0.0, alpha])
    theta = x[3]
    assert theta == pytest.approx(0.1, rel=1e-9)  # 200 exact integrator steps: rounding only
    f = (c @ x)[6]
    # 2e-3: the model's small angle, g theta against g sin theta, differs by 1.7e-3 at 0.1 rad
    assert f == pytest.approx(sign * STANDARD_GRAVITY * np.sin(theta), rel=2e-3)
    assert (c @ x)[7] == pytest.approx(0.0, abs=1e-12)  # no rate once held
    assert y[7] == pytest.approx(0.5 * DT * 0.1 + x[4], abs=1e-3)  # the step's mean rate


def test_the_double_integrator_and_the_platform_origin():
    # a jerk of 1 m/s³ for 1 s from rest: a = 1, v = 1/2, p = 1/6; P' = p' + arm theta'
    a, b, c, d = pair_model(DT, 0.0, -0.8)
    x = np.zeros(9)
    for _ in range(100):
        x = a @ x + b @ np.array([1.0, 0.0])
    np.testing.assert_allclose(x[:3], [1.0 / 6.0, 0.5, 1.0], rtol=1e-9)  # exact integrators: rounding only
    x[3] = 0.05
    y = c @ x + d @ np.zeros(2)
    assert y[5] == pytest.approx(y[2] - 0.8 * 0.05)


@pytest.mark.extra("mpc")
def test_the_head_offset_is_head_pose():
    import stewart_env as se
    from stewart_env.agents.controllers.cueing_mpc import CueingMPC

    mpc = CueingMPC(CueingMPCParams(horizon=20, block=10), DT, 0.8)
    params = se.load_platform("dasgupta1998")
    displacement, rpy = np.array([[0.02, -0.01, 0.03]]), np.array([[0.1, -0.05, 0.2]])
    position, _ = head_pose(params, (0.0, 0.0, 0.8), displacement, rpy)
    np.testing.assert_allclose(mpc.head_offset(displacement[0], rpy[0]), position[0] - params.home_position, atol=1e-12)


@pytest.mark.parametrize(
    "field, value",
    [
        ("horizon", 0),
        ("block", 7),
        ("stride", 2.5),
        ("force_weight", -1.0),
        ("angle_bound", (0.1, 0.1)),
        ("loop_delay", (0, 0, 0, 0, 0, 10)),
        ("loop_frequency", (14.0, 14.0, 0.0, 30.0, 30.0, 30.0)),
        ("reference_decay", 0.0),
    ],
)
def test_bad_parameters_are_refused(field, value):
    with pytest.raises(UsageError, match=field):
        CueingMPCParams(**{field: value})


@pytest.mark.extra("mpc")
def test_the_policy_stays_inside_the_workspace_on_a_held_out_lane_change():
    from stewart_env.agents.controllers.cueing_mpc import CueingMPCPolicy
    from stewart_env.agents.evaluation.cueing import ScheduledEpisodes
    from stewart_env.tasks.cueing.motions import EVALUATION_SEEDS

    runner = ScheduledEpisodes(
        [("double_lane_change", EVALUATION_SEEDS[0])], {"action_mode": "pose", "task_options": {"preview": 10}}
    )
    try:
        (row,) = runner.run(lambda env: CueingMPCPolicy(env))
    finally:
        runner.close()
    assert row["failed"] == 0.0 and row["played"] == 1.0
    assert row["limit_hits"] == 0.0
    assert row["stroke_use"] < 0.8 and row["workspace_use"] < 0.8
    assert row["rms_specific_force_error"] < 1.8  # washout's on the same episodes: 1.63 on average


def test_the_cueing_mpc_without_osqp_names_the_extra(monkeypatch):
    from stewart_env.agents.controllers.cueing_mpc import CueingMPC

    monkeypatch.setitem(sys.modules, "osqp", None)  # find_spec: not installed
    with pytest.raises(MissingExtra, match=r'needs osqp.*pip install -e "\.\[mpc\]"'):
        CueingMPC()


def test_policy_drives_an_sb3_vec_env():
    pytest.importorskip("osqp")
    from stewart_env.agents.controllers.cueing_mpc import CueingMPCPolicy
    from stewart_env.envs import StewartPlatformSB3VecEnv

    vec = StewartPlatformSB3VecEnv(num_envs=2, task="cueing", action_mode="pose")
    try:
        vec.seed(0)
        obs = vec.reset()
        action, _ = CueingMPCPolicy(vec).predict(obs)
        assert action.shape == (2, 6) and np.all(np.abs(action) <= 1.0)
    finally:
        vec.close()


def test_an_infeasible_programme_gives_no_input():
    pytest.importorskip("osqp")
    from stewart_env.agents.controllers.cueing_mpc import SOLVED, CueingMPC

    mpc = CueingMPC(CueingMPCParams(), 0.01, 0.8)
    heave = mpc.pairs[2]
    state = np.zeros(9)
    state[0], state[1] = 0.5, 2.0  # 0.5 m above home and rising at 2 m/s: past the 0.06 m bound at every point
    reference = np.zeros(mpc.params.horizon)
    inputs, status = heave.solve(0, state, reference, reference)
    assert status not in SOLVED  # OSQP's certificate of infeasibility, not a solution
    assert np.array_equal(inputs, np.zeros(2))
    inputs, status = heave.solve(1, np.zeros(9), reference, reference)
    assert status in SOLVED and np.all(
        np.abs(inputs) < 1e-6
    )  # at rest with nothing to cue: no input (OSQP's 1e-4 tolerance on a tiny input)
