"""Dynamic parameter identification: the regressor against inverse dynamics, the base parameters,
the estimators and the identify experiment (docs/physics.md section 5.6,
docs/guides/identification.md)."""

import itertools

import numpy as np
import pytest

import stewart_env as se
from stewart_env.dynamics import kernels as K
from stewart_env.identification import regressor as reg
from stewart_env.params import Damping, RigidBody
from physics_reference import random_state

# every combination of the four switches over both improved forms (classical = joint form + all four)
SWITCH_SETS = [s for n in range(5) for s in itertools.combinations(("c1", "c2", "c3", "c4"), n)]
ALL_MODELS = [base + "".join("+" + s for s in switches)
              for base in ("improved", "improved_centroidal") for switches in SWITCH_SETS] + ["classical"]


def random_body(rng, mass_scale):
    """A rigid body with a random positive mass, CoM and a physically valid inertia."""
    m = rng.uniform(0.3, 1.5) * mass_scale
    com = rng.normal(scale=0.05, size=3)
    A = rng.normal(size=(3, 3))
    Q, _ = np.linalg.qr(A)
    inertia = Q @ np.diag(rng.uniform(0.2, 1.0, 3) * 0.01 * mass_scale) @ Q.T
    return RigidBody(mass=m, com=com, inertia=inertia)


def random_params(base, rng):
    """``base`` with every inertial and friction parameter drawn at random, each leg its own."""
    return base.replace(
        platform=random_body(rng, base.platform.mass),
        upper_leg=tuple(random_body(rng, 3.0) for _ in range(6)),
        lower_leg=tuple(random_body(rng, 3.0) for _ in range(6)),
        damping=Damping(*rng.uniform(0.5, 5.0, 3)))


@pytest.mark.parametrize("name", ALL_MODELS)
def test_regressor_times_theta_equals_inverse_dynamics(dasgupta, simulator, rng, name):
    for base in (dasgupta, simulator):
        for _ in range(3):
            params = random_params(base, rng)
            model = se.make_dynamics(name, params)
            t, R, v, w = random_state(params, rng, speed=0.5)
            a, alpha = rng.normal(scale=2.0, size=3), rng.normal(scale=4.0, size=3)
            F = model.inverse(t, R, v, w, a, alpha)
            lhs = se.jacobian(params, t, R).T @ F
            Y = reg.regressor_matrix(model, t, R, v, w, a, alpha)
            rhs = Y @ reg.theta_of(params, model.flags)
            # the same products summed in another order, then a 6x6 solve (cond ~ 10): rounding
            assert np.abs(rhs - lhs).max() < 1e-10 * np.abs(lhs).max()


def test_regressor_is_batched_and_checks_its_arguments(dasgupta, rng):
    model = se.make_dynamics("improved", dasgupta)
    states = [random_state(dasgupta, rng) for _ in range(4)]
    t, R, v, w = (np.stack(x) for x in zip(*states))
    acc = rng.normal(size=(4, 6))
    Y = reg.regressor_matrix(model, t, R, v, w, acc[:, :3], acc[:, 3:])
    assert Y.shape == (4, 6, reg.N_THETA)
    for k in range(4):
        one = reg.regressor_matrix(model, t[k], R[k], v[k], w[k], acc[k, :3], acc[k, 3:])
        assert np.array_equal(Y[k], one)  # each row's arithmetic does not depend on the batch
    with pytest.raises(ValueError, match="lin_acc"):
        reg.regressor_matrix(model, t, R, v, w, acc[:3, :3], acc[:, 3:])
    with pytest.raises(ValueError, match="position"):
        reg.regressor_matrix(model, t[0] * np.nan, R[0], v[0], w[0], acc[0, :3], acc[0, 3:])


def test_theta_round_trips_through_the_bodies(dasgupta, rng):
    params = random_params(dasgupta, rng)
    for flags in (0, K.C3 | K.C4):
        theta = reg.theta_of(params, flags)
        shift_leg, shift_plat = reg.shifts_of(flags)
        m, com, inertia = reg.body_from_theta(theta[:10], shift_plat)
        assert m == pytest.approx(params.platform.mass, rel=1e-14)
        # com = (m c) / m and the parallel-axis term taken off again: rounding
        assert np.allclose(com, params.platform.com, rtol=0, atol=1e-14)
        assert np.allclose(inertia, params.platform.inertia, rtol=0, atol=1e-13)


@pytest.mark.parametrize("name", ["improved", "classical", "improved+c1"])
def test_base_parameters_reproduce_the_regressor_and_leave_a_clear_rank_gap(simulator, rng, name):
    from stewart_env.identification import base

    model = se.make_dynamics(name, simulator)
    b = base.base_parameters(model)
    r = b.rank
    assert 40 < r < reg.N_THETA
    # identifiable columns stay far above the tolerance, the dependent ones at rounding
    assert b.diagonal[r - 1] > 1e3 * base.RANK_TOLERANCE and b.diagonal[r] < 1e-3 * base.RANK_TOLERANCE
    # Y theta == Y_base beta on fresh states, for random parameters: the base parameters carry
    # everything the leg forces see (products of a few hundred terms: rounding)
    params = random_params(simulator, rng)
    theta = reg.theta_of(params, model.flags)
    states = base.random_states(simulator, 20, rng)
    Y = reg.regressor_matrix(model, *states)
    full = Y @ theta
    assert np.abs(b.columns(Y) @ b.of_theta(theta) - full).max() < 1e-10 * np.abs(full).max()
    # and the base parameters map back to a theta with the nominal's unidentifiable part
    nominal = reg.theta_of(simulator, model.flags)
    back = b.theta_from(b.of_theta(theta), nominal)
    assert np.allclose(b.of_theta(back), b.of_theta(theta), rtol=1e-12, atol=1e-12)
    assert np.array_equal(back[b.dependent], nominal[b.dependent])
    assert len(b.names) == r and all(n.split(" ")[0] in reg.THETA_NAMES for n in b.names)
