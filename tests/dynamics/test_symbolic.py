"""The symbolic model: CasADi functions whose values and Jacobians are the compiled kernels'."""

import sys

import numpy as np
import pytest

import stewart_env as se
from stewart_env.dynamics import symbolic
from stewart_env.extras import MissingExtra
from stewart_env.rotations import rotvec_to_matrix

DT, SUBSTEPS = 0.01, 10
#: A state off home: displaced, turned by 0.12 rad, moving; and leg forces near the holding ones.
X = np.array([0.01, -0.005, 0.38, 0.05, -0.03, 0.1, 0.1, 0.0, 0.2, 0.3, -0.2, 0.1])
F = np.array([200.0, 150.0, 160.0, 170.0, 160.0, 190.0])


@pytest.fixture(scope="module")
def model(dasgupta):
    return se.make_dynamics("improved", dasgupta)


def _central(fun, x, forces, h=1e-6):
    """d fun / d (x, F) (out, 18) by central differences in the function's own coordinates."""
    cols = []
    for k in range(18):
        e = np.zeros(18)
        e[k] = h
        plus = np.array(fun(x + e[:12], forces + e[12:])).ravel()
        minus = np.array(fun(x - e[:12], forces - e[12:])).ravel()
        cols.append((plus - minus) / (2 * h))
    return np.stack(cols, axis=1)


def _jacobian(casadi, fun):
    x, u = casadi.MX.sym("x", 12), casadi.MX.sym("u", 6)
    y = fun(x, u)
    return casadi.Function("jacobians", [x, u], [casadi.jacobian(y, x), casadi.jacobian(y, u)])


@pytest.mark.extra("casadi")
def test_values_are_the_kernels_bit_for_bit(model):
    f = symbolic.forward_dynamics_function(model)
    step = symbolic.control_step_function(model, DT, SUBSTEPS)
    pose = (X[0:3], rotvec_to_matrix(X[3:6]), X[6:9], X[9:12])
    assert np.array_equal(np.array(f(X, F)).ravel(), np.concatenate(model.forward(*pose, F)))
    t, R, v, w = se.rollout(model, *pose, F, dt=DT / SUBSTEPS, steps=SUBSTEPS)
    x_next = np.array(step(X, F)).ravel()
    assert np.array_equal(x_next[[0, 1, 2, 6, 7, 8, 9, 10, 11]], np.concatenate([t, v, w]))
    assert np.abs(rotvec_to_matrix(x_next[3:6]) - R).max() < 1e-15  # exp(log R): a rounding of R


@pytest.mark.extra("casadi")
def test_jacobians_at_zero_rotation_are_the_compiled_ones(model, dasgupta):
    # at theta = 0 the left Jacobian is the identity: CasADi's Jacobian is the kernel's, unchanged
    import casadi

    x = np.concatenate([dasgupta.home_position, np.zeros(3), X[6:]])
    f = symbolic.forward_dynamics_function(model)  # kept: CasADi calls back into it
    d_x, d_f = (np.array(m) for m in _jacobian(casadi, f)(x, F))
    ref = model.acceleration_jacobians(x[0:3], np.eye(3), x[6:9], x[9:12], F)
    assert np.array_equal(d_x, np.hstack([ref.d_pose, ref.d_twist]))
    assert np.array_equal(d_f, ref.d_forces)


@pytest.mark.extra("casadi")
@pytest.mark.parametrize("which", ["forward", "step"])
def test_jacobians_match_central_differences_of_the_function(model, which):
    import casadi

    fun = (
        symbolic.forward_dynamics_function(model)
        if which == "forward"
        else symbolic.control_step_function(model, DT, SUBSTEPS)
    )
    d_x, d_f = (np.array(m) for m in _jacobian(casadi, fun)(X, F))
    num = _central(fun, X, F)
    # central differences of step 1e-6: truncation ~1e-12, rounding ~1e-10 relative to the entries
    scale = np.abs(num).max(axis=1, keepdims=True)
    assert np.abs(d_x - num[:, :12]).max() / scale.min() < 1e-6
    assert (np.abs(d_f - num[:, 12:]) / scale).max() < 1e-6


@pytest.mark.extra("casadi")
def test_ipopt_finds_the_holding_forces_with_the_callback_jacobian(model, dasgupta):
    import casadi

    f = symbolic.forward_dynamics_function(model)
    x = np.concatenate([dasgupta.home_position, np.zeros(9)])
    u = casadi.MX.sym("u", 6)
    acc = f(x, u)
    solver = casadi.nlpsol(
        "hold",
        "ipopt",
        {"x": u, "f": casadi.sumsqr(acc)},
        {
            "ipopt.print_level": 0,
            "ipopt.sb": "yes",
            "print_time": False,
            "ipopt.hessian_approximation": "limited-memory",
        },
    )
    found = np.array(solver(x0=np.full(6, 150.0))["x"]).ravel()
    holding = model.inverse(x[0:3], np.eye(3), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3))
    # IPOPT's default tolerance 1e-8 on the squared acceleration: forces to about a millinewton
    assert np.abs(found - holding).max() < 1e-2


def test_left_jacobian_and_its_inverse():
    for theta in (np.zeros(3), np.array([1e-8, 0.0, -2e-8]), np.array([0.3, -1.2, 0.7])):
        assert np.abs(symbolic.left_jacobian(theta) @ symbolic.left_jacobian_inverse(theta) - np.eye(3)).max() < 1e-14
    # the defining property, to first order: exp(theta + d) = exp(J_l d) exp(theta)
    theta, d = np.array([0.3, -1.2, 0.7]), 1e-7 * np.array([1.0, 2.0, -1.0])
    moved = rotvec_to_matrix(symbolic.left_jacobian(theta) @ d) @ rotvec_to_matrix(theta)
    assert np.abs(rotvec_to_matrix(theta + d) - moved).max() < 1e-13  # second-order remainder ~ |d|^2 = 6e-14


def test_without_casadi_the_error_names_the_extra(model, monkeypatch):
    monkeypatch.setitem(sys.modules, "casadi", None)  # find_spec: not installed
    with pytest.raises(MissingExtra, match=r'symbolic model .* needs casadi.*pip install -e "\.\[casadi\]"'):
        symbolic.forward_dynamics_function(model)


@pytest.mark.extra("casadi")
def test_bad_arguments_are_named(model, dasgupta):
    with pytest.raises(ValueError, match="model: expected a Dynamics"):
        symbolic.forward_dynamics_function(dasgupta)
    with pytest.raises(ValueError, match="model: expected one platform"):
        symbolic.forward_dynamics_function(se.make_dynamics("improved", [dasgupta, dasgupta]))
    with pytest.raises(ValueError, match="dt"):
        symbolic.control_step_function(model, 0.0)
    with pytest.raises(ValueError, match="steps"):
        symbolic.control_step_function(model, DT, 0)
