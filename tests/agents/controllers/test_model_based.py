"""The model-based controllers: the LQR around home and the linearised MPC, and their compute time."""

import sys

import numpy as np
import pytest

import stewart_env as se
from stewart_env.agents import evaluate
from stewart_env.agents.controllers.lqr import (
    LinearQuadraticRegulator,
    LQRPolicy,
    home_linearisation,
    tangent_error,
)
from stewart_env.agents.controllers.timing import ComputeTime, control_step_times
from stewart_env.extras import MissingExtra
from stewart_env.rotations import rotvec_to_matrix
from stewart_env.state import PlatformState, Reference

from conftest import exit_code

DT, SUBSTEPS = 0.01, 10


@pytest.fixture(scope="module")
def lqr(dasgupta):
    return LinearQuadraticRegulator(dasgupta, "improved", DT, SUBSTEPS)


def _home(params, offset=(0.0, 0.0, 0.0)):
    return PlatformState(params.home_position + np.asarray(offset), np.eye(3), np.zeros(3), np.zeros(3))


def test_lqr_gain_solves_the_riccati_equation_and_stabilises_the_step(lqr):
    A, B, Q, P, K = lqr.A, lqr.B, lqr.Q, lqr.P, lqr.K
    residual = A.T @ P @ A - P - A.T @ P @ B @ K + Q
    assert np.abs(residual).max() / np.abs(P).max() < 1e-9  # the DARE's solver to rounding of P's scale
    assert lqr.spectral_radius() == pytest.approx(0.845, abs=0.005)  # the module docstring's figure
    # the open loop at home drifts (a double integrator per axis): its spectral radius is 1 or above
    assert np.abs(np.linalg.eigvals(A)).max() >= 1 - 1e-9


def test_lqr_linearisation_is_the_steps_jacobians_under_the_holding_forces(dasgupta):
    model = se.make_dynamics("improved", dasgupta)
    A, B, holding = home_linearisation(model, DT, SUBSTEPS)
    state = _home(dasgupta)
    assert np.allclose(model.forward(*state, holding)[0], 0, atol=1e-9)  # at rest under them
    step = model.step_jacobians(*state, holding, DT, SUBSTEPS)
    assert np.array_equal(A, step.A) and np.array_equal(B, step.B)


def test_lqr_at_the_reference_gives_the_feedforward_and_acts_against_an_error(lqr, dasgupta):
    at_home = _home(dasgupta)
    reference = Reference(*at_home)
    assert np.array_equal(lqr(at_home, reference), lqr.holding_forces)
    low = _home(dasgupta, (0, 0, -0.005))  # 5 mm below the target: every leg pushes harder
    assert np.all(lqr(low, reference) > lqr.holding_forces)
    assert np.allclose(lqr(low, reference) - lqr.holding_forces, lqr.K[:, 2] * 0.005, rtol=1e-12)


def test_tangent_error_is_the_left_rotation_vector_about_the_reference(dasgupta):
    reference = Reference(dasgupta.home_position, rotvec_to_matrix([0.0, 0.1, 0.0]), np.zeros(3), np.zeros(3))
    turned = rotvec_to_matrix([0.02, 0.0, 0.0]) @ reference.rotation
    state = PlatformState(dasgupta.home_position + [0.001, 0, 0], turned, np.ones(3), np.zeros(3))
    e = tangent_error(state, reference)
    assert np.allclose(e, [0.001, 0, 0, 0.02, 0, 0, 1, 1, 1, 0, 0, 0], atol=1e-15)


def test_lqr_batched_equals_one_by_one(lqr, dasgupta):
    rng = np.random.default_rng(3)
    offsets = rng.uniform(-0.01, 0.01, (4, 3))
    states = PlatformState(
        dasgupta.home_position + offsets, np.repeat(np.eye(3)[None], 4, 0), rng.normal(size=(4, 3)), np.zeros((4, 3))
    )
    reference = Reference(*_home(dasgupta))
    batched = lqr(states, reference)
    single = [lqr(PlatformState(*(f[i] for f in states)), reference) for i in range(4)]
    assert np.allclose(batched, single, rtol=0, atol=1e-10)  # the same numbers, summed in another order


def test_lqr_bad_arguments_are_named(dasgupta):
    with pytest.raises(ValueError, match="platform: expected PlatformParams"):
        LinearQuadraticRegulator("dasgupta1998")
    with pytest.raises(ValueError, match="state_scales: expected 12"):
        LinearQuadraticRegulator(dasgupta, state_scales=[1.0] * 6)
    with pytest.raises(ValueError, match="force_scale"):
        LinearQuadraticRegulator(dasgupta, force_scale=-1)
    with pytest.raises(ValueError, match="internal_model"):
        LinearQuadraticRegulator(dasgupta, internal_model="newtonian")


@pytest.mark.extra("mpc")
def test_mpc_without_active_limits_is_the_lqr(dasgupta, lqr):
    from stewart_env.agents.controllers.mpc import LinearisedMPC

    mpc = LinearisedMPC(dasgupta, "improved", DT, SUBSTEPS)
    state, reference = _home(dasgupta, (0, 0, -0.001)), Reference(*_home(dasgupta))
    forces = mpc(state, reference)
    assert mpc.solve_status == ["solved"]
    # at home (the linearisation point) with the LQR's terminal cost P and no active constraint the
    # MPC's first move is the LQR's; OSQP's tolerances 1e-6 leave differences far below a newton
    assert np.abs(forces - lqr(state, reference)).max() < 0.05


@pytest.mark.extra("mpc")
def test_mpc_keeps_the_forces_within_the_limits_where_the_lqr_does_not(dasgupta, lqr):
    from stewart_env.agents.controllers.mpc import LinearisedMPC

    mpc = LinearisedMPC(dasgupta, "improved", DT, SUBSTEPS)
    state = _home(dasgupta)
    reference = Reference(*_home(dasgupta, (0, 0, 0.15)))  # 15 cm up at once
    low, high = dasgupta.limits.leg_force
    assert lqr(state, reference).max() > high  # the unconstrained gain asks for more than a leg gives
    forces = mpc(state, reference)
    assert mpc.solve_status == ["solved"]
    assert forces.max() <= high + 1e-2 and forces.min() >= low - 1e-2  # OSQP's tolerance, in newtons
    assert forces.max() > high - 1.0  # and it uses what the legs give


@pytest.mark.extra("mpc")
def test_mpc_prediction_is_the_recursion(dasgupta):
    from stewart_env.agents.controllers.mpc import LinearisedMPC

    mpc = LinearisedMPC(dasgupta, "improved", DT, SUBSTEPS, horizon=4)
    rng = np.random.default_rng(0)
    A, B = rng.normal(size=(12, 12)) / 4, rng.normal(size=(12, 6))
    e0, d, u = rng.normal(size=12), rng.normal(size=12), rng.normal(size=(4, 6))
    s_x, s_u, s_1 = mpc.prediction(A, B)
    e, stacked = e0, []
    for k in range(4):
        e = A @ e + B @ u[k] + d
        stacked.append(e)
    assert np.allclose(s_x @ e0 + s_u @ u.ravel() + s_1 @ d, np.concatenate(stacked), rtol=1e-12, atol=1e-12)


@pytest.mark.extra("mpc")
def test_mpc_bad_horizon_is_named(dasgupta):
    from stewart_env.agents.controllers.mpc import LinearisedMPC

    for bad in (0, 2.5, True):
        with pytest.raises(ValueError, match="horizon"):
            LinearisedMPC(dasgupta, horizon=bad)


def test_mpc_without_osqp_names_the_extra(dasgupta, monkeypatch):
    from stewart_env.agents.controllers.mpc import LinearisedMPC

    monkeypatch.setitem(sys.modules, "osqp", None)  # find_spec: not installed
    with pytest.raises(MissingExtra, match=r'needs osqp.*pip install -e "\.\[mpc\]"'):
        LinearisedMPC(dasgupta)
    assert exit_code(["evaluate", "--policy", "mpc"]) == 2


@pytest.mark.extra("mpc")
@pytest.mark.parametrize("task", ["setpoint", "tracking"])
def test_lqr_and_mpc_policies_succeed_on_the_tasks_with_ct(task):
    from stewart_env.agents.controllers.computed_torque import ComputedTorquePolicy
    from stewart_env.agents.controllers.mpc import MPCPolicy

    results = {
        name: evaluate(policy, {"task": task}, episodes=2, seed=0, max_steps=150).summary()
        for name, policy in (("ct", ComputedTorquePolicy), ("lqr", LQRPolicy), ("mpc", MPCPolicy))
    }
    for name, summary in results.items():
        assert summary["success"] == 1.0, name
    # both model-based controllers are at least as precise as computed torque at the same model
    # (10 % margin: two episodes)
    for name in ("lqr", "mpc"):
        assert results[name]["rms_position_error"] <= 1.1 * results["ct"]["rms_position_error"], name


def test_compute_time_per_control_step():
    timed = control_step_times(LQRPolicy, {"task": "setpoint"}, steps=5)
    assert isinstance(timed, ComputeTime) and timed.steps == 5 and timed.period == 0.01
    assert 0 < timed.mean <= timed.max and timed.real_time_factor == timed.mean / 0.01
    assert "ms mean" in str(timed)
    with pytest.raises(ValueError, match="steps: expected a positive integer"):
        control_step_times(LQRPolicy, steps=0)
