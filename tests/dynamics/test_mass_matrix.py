"""Mass matrix and bias: the assembly forward dynamics solves, checked against forward and inverse
dynamics, the kinetic energy of all 13 bodies, and itself over a batch."""

import numpy as np
import pytest

import stewart_env as se
from stewart_env.params import RigidBody

from physics_reference import kinetic_energy, random_state

pytestmark = pytest.mark.physics

ALL_MODELS = [
    "improved",
    "improved_centroidal",
    "classical",
    "improved+c1",
    "improved+c2",
    "improved+c3",
    "improved+c4",
    "improved+c1+c2",
    "improved+c3+c4",
    "improved_centroidal+c1+c3",
    "improved_centroidal+c2+c4",
]


@pytest.fixture(params=["dasgupta", "simulator"])
def platform(request):
    return request.getfixturevalue(request.param)


def random_case(params, rng):
    state = random_state(params, rng, speed=0.5)
    F = rng.normal(size=6) * 300 + 180
    W = np.concatenate([rng.normal(scale=50.0, size=3), rng.normal(scale=5.0, size=3)])
    return state, F, W


@pytest.mark.parametrize("name", ALL_MODELS)
def test_mass_matrix_and_bias_reproduce_forward_dynamics(platform, rng, name):
    model = se.make_dynamics(name, platform)
    for _ in range(5):
        (t, R, v, w), F, W = random_case(platform, rng)
        M, h = model.mass_and_bias(t, R, v, w)
        acc = np.concatenate(model.forward(t, R, v, w, F, W))
        rhs = se.jacobian(platform, t, R).T @ F + W
        # a well-conditioned 6x6 solve (cond(M) ~ 10) of sums of a few hundred products: rounding
        assert np.abs(M @ acc + h - rhs).max() < 1e-12 * np.abs(rhs).max()
        # the external wrench enters the bias as -W
        assert np.allclose(model.bias(t, R, v, w, W), h - W, rtol=0, atol=1e-12 * np.abs(h).max())


@pytest.mark.parametrize("name", ALL_MODELS)
def test_mass_matrix_and_bias_equal_unit_acceleration_probes_of_inverse_dynamics(platform, rng, name):
    model = se.make_dynamics(name, platform)
    (t, R, v, w), _, W = random_case(platform, rng)
    probes = np.vstack([np.eye(6), np.zeros(6)])
    forces = model.inverse(
        np.broadcast_to(t, (7, 3)),
        np.broadcast_to(R, (7, 3, 3)),
        np.broadcast_to(v, (7, 3)),
        np.broadcast_to(w, (7, 3)),
        probes[:, :3],
        probes[:, 3:],
        np.broadcast_to(W, (7, 6)),
    )
    J = se.jacobian(platform, t, R)
    M, h = model.mass_and_bias(t, R, v, w, W)
    # inverse dynamics is affine in the acceleration, so the probes are exact up to the
    # cancellation of forces of ~1e3 N against differences of ~10 N
    assert np.abs(M - J.T @ (forces[:6] - forces[6]).T).max() < 1e-11 * np.abs(M).max()
    assert np.abs(h - J.T @ forces[6]).max() < 1e-11 * np.abs(h).max()


@pytest.mark.parametrize("name", ["improved", "improved_centroidal"])
def test_exact_mass_matrix_is_symmetric_positive_definite_and_gives_the_kinetic_energy(platform, rng, name):
    model = se.make_dynamics(name, platform)
    for _ in range(5):
        t, R, v, w = random_state(platform, rng, speed=0.5)
        M = model.mass_matrix(t, R)
        # sums of the same products in different orders: rounding
        assert np.abs(M - M.T).max() < 1e-13 * np.abs(M).max()
        assert np.linalg.eigvalsh(M).min() > 0.1
        twist = np.concatenate([v, w])
        # T = 1/2 [v; w]^T M [v; w] for the exact model; the reference sums all 13 bodies independently
        assert 0.5 * twist @ M @ twist == pytest.approx(kinetic_energy(platform, t, R, v, w), rel=1e-12)


def test_c1_or_c2_alone_makes_the_mass_matrix_unsymmetric_and_both_together_do_not(dasgupta, rng):
    t, R, _, _ = random_state(dasgupta, rng)
    for name in ("improved+c1", "improved+c2"):
        M = se.make_dynamics(name, dasgupta).mass_matrix(t, R)
        # 0.2-0.3 % on this platform (docs/physics.md section 5.4): far beyond rounding
        assert np.abs(M - M.T).max() > 1e-3 * np.abs(M).max()
    for name in ("classical", "improved+c1+c2", "improved+c3", "improved+c4"):
        M = se.make_dynamics(name, dasgupta).mass_matrix(t, R)
        # sums of the same products in different orders: rounding
        assert np.abs(M - M.T).max() < 1e-13 * np.abs(M).max()


def test_mass_matrix_does_not_depend_on_the_rates(dasgupta, rng):
    model = se.make_dynamics("improved", dasgupta)
    t, R, v, w = random_state(dasgupta, rng, speed=0.5)
    assert np.array_equal(model.mass_matrix(t, R, v, w), model.mass_matrix(t, R))


def test_batched_mass_matrix_and_bias_equal_single_calls(dasgupta, rng):
    n = 20  # a batch of many rows: each row as the single call
    params = [
        dasgupta.replace(
            platform=RigidBody(
                dasgupta.platform.mass * (1 + 0.05 * i), dasgupta.platform.com, dasgupta.platform.inertia
            )
        )
        for i in range(n)
    ]
    for model in (se.make_dynamics("improved", dasgupta), se.make_dynamics("classical", params)):
        cases = [random_case(dasgupta, rng) for _ in range(n)]
        t, R, v, w = (np.array(x) for x in zip(*(c[0] for c in cases)))
        W = np.array([c[2] for c in cases])
        M, h = model.mass_and_bias(t, R, v, w, W)
        assert M.shape == (n, 6, 6) and h.shape == (n, 6)
        for b in range(n):
            single = model if len(model.params) == 1 else se.make_dynamics(model.name, model.params[b])
            M1, h1 = single.mass_and_bias(t[b], R[b], v[b], w[b], W[b])
            assert np.array_equal(M1, M[b]) and np.array_equal(h1, h[b])  # same code path: bit-identical
