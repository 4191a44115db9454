"""The legs' reflected masses in the dynamics (docs/physics.md section 10.2): none changes no
number, inverse and forward dynamics agree with them, a hand case at the home pose, and the
kinetic energy that gains 1/2 m_r l_dot^2."""

import numpy as np
import pytest

import stewart_env as se
from stewart_env import _core
from stewart_env.params import Damping

from physics_reference import kinetic_energy, random_state, rotvec_matrix

pytestmark = pytest.mark.physics

MODELS = ["improved", "improved_centroidal", "classical", "improved+c1+c3"]


def batch_of(params, rng, n, speed=0.5):
    """n random states near home as (t, R, v, w) arrays with a leading n."""
    states = [random_state(params, rng, speed=speed) for _ in range(n)]
    return [np.ascontiguousarray(np.stack(parts)) for parts in zip(*states)]


def forward(model, state, F, W, m_r=None):
    out = np.empty((len(F), 6))
    if m_r is None:
        _core.forward_batch(model.packed, model.flags, *state, F, W, out)
    else:
        _core.forward_reflected_batch(model.packed, model.flags, *state, F, W, m_r, out)
    return out


def inverse(model, state, acc, W, m_r=None):
    out = np.empty((len(acc), 6))
    if m_r is None:
        _core.inverse_batch(model.packed, model.flags, *state, acc, W, out)
    else:
        _core.inverse_reflected_batch(model.packed, model.flags, *state, acc, W, m_r, out)
    return out


@pytest.mark.parametrize("platform_name", ["dasgupta1998", "motion_simulator"])
@pytest.mark.parametrize("name", MODELS)
def test_zero_reflected_mass_changes_no_number(platform_name, name, rng):
    params = se.load_platform(platform_name)
    model = se.make_dynamics(name, params)
    n = 19  # blocks of vector lanes and a remainder
    state = batch_of(params, rng, n)
    F = rng.normal(scale=300.0, size=(n, 6)) + 200.0
    W = rng.normal(scale=20.0, size=(n, 6))
    acc = forward(model, state, F, W)
    zero = np.zeros((1, 6))
    assert np.array_equal(forward(model, state, F, W, zero), acc)
    assert np.array_equal(inverse(model, state, acc, W, zero), inverse(model, state, acc, W))
    # one leg with drive inertia changes that row's numbers, the others' legs add nothing
    assert not np.array_equal(forward(model, state, F, W, np.array([[0, 0, 50.0, 0, 0, 0]])), acc)


@pytest.mark.parametrize("name", MODELS)
def test_inverse_and_forward_dynamics_with_reflected_masses_agree(simulator, name, rng):
    model = se.make_dynamics(name, simulator)
    n = 12
    state = batch_of(simulator, rng, n)
    m_r = rng.uniform(200.0, 1500.0, size=(n, 6))
    acc = rng.normal(scale=2.0, size=(n, 6))
    W = rng.normal(scale=200.0, size=(n, 6))
    F = inverse(model, state, acc, W, m_r)
    # one 6x6 solve of forces of 1e4-1e5 N: rounding, a few 1e-12 relative
    assert np.abs(forward(model, state, F, W, m_r) - acc).max() < 1e-9 * np.abs(acc).max()
    # the reflected masses take force: without them the same forces accelerate differently
    assert np.abs(forward(model, state, F, W) - acc).max() > 1.0


def test_pure_heave_at_home_by_hand(simulator):
    """At rest at the home pose a heave acceleration a_z moves each leg at Lddot_i = e_i,z a_z, so
    each drive pushes m_r e_i,z a_z more than the leg needs; and forward dynamics of those forces
    gives the heave back."""
    model = se.make_dynamics("improved", simulator)
    t = simulator.home_position[None].copy()
    R = np.eye(3)[None].copy()
    zero3 = np.zeros((1, 3))
    state = (t, R, zero3, zero3)
    a_z = 1.5
    acc = np.array([[0.0, 0.0, a_z, 0.0, 0.0, 0.0]])
    W = np.zeros((1, 6))
    m_r = 947.4820225045784  # k^2 J_m of the motion simulator's electric set
    legs = simulator.home_position + simulator.platform_joints - simulator.base_joints
    e_z = legs[:, 2] / np.linalg.norm(legs, axis=1)
    by_hand = m_r * e_z * a_z
    extra = inverse(model, state, acc, W, np.full((1, 6), m_r)) - inverse(model, state, acc, W)
    # differences of forces of ~3e4 N: rounding
    assert extra[0] == pytest.approx(by_hand, rel=1e-10)
    assert forward(model, state, inverse(model, state, acc, W) + by_hand, W, np.full((1, 6), m_r)) == pytest.approx(
        acc, abs=1e-11
    )


def effective_mass(model, state, m_r):
    """M + J^T diag(m_r) J, column by column from forward dynamics: M^-1 e_k is the change of the
    acceleration that a unit wrench W = e_k makes."""
    base = forward(model, state, np.zeros((1, 6)), np.zeros((1, 6)), m_r)
    inv = np.column_stack(
        [forward(model, state, np.zeros((1, 6)), np.eye(6)[k][None], m_r)[0] - base[0] for k in range(6)]
    )
    return np.linalg.inv(inv)


def test_the_kinetic_energy_gains_half_m_r_l_dot_squared(simulator, rng):
    model = se.make_dynamics("improved", simulator)
    m_r = rng.uniform(300.0, 1200.0, size=(1, 6))
    for _ in range(3):
        t, R, v, w = random_state(simulator, rng, speed=0.5)
        state = tuple(np.ascontiguousarray(x[None]) for x in (t, R, v, w))
        twist = np.concatenate([v, w])
        J = se.kinematics.jacobian(simulator, t, R)
        l_dot = J @ twist
        M = effective_mass(model, state, m_r)
        expected = kinetic_energy(simulator, t, R, v, w) + 0.5 * np.sum(m_r[0] * l_dot**2)
        # the inverse of a difference of solves of a 6x6 system: rounding, ~1e-10 relative
        assert 0.5 * twist @ M @ twist == pytest.approx(expected, rel=1e-8)


def test_no_power_goes_missing_with_reflected_masses(simulator, rng):
    """With no gravity, friction, leg force or wrench the energy 1/2 x_dot^T (M + J^T m_r J) x_dot
    is conserved: its rate x_dot^T M_eff x_ddot + 1/2 x_dot^T M_eff_dot x_dot is zero, which checks
    the velocity term J^T m_r Jdot x_dot (M_eff_dot by central differences along the motion)."""
    free = simulator.replace(gravity=np.zeros(3), damping=Damping(universal=0.0, prismatic=0.0, spherical=0.0))
    model = se.make_dynamics("improved", free)
    m_r = np.full((1, 6), 950.0)
    t, R, v, w = random_state(free, rng, speed=0.5)
    state = tuple(np.ascontiguousarray(x[None]) for x in (t, R, v, w))
    twist = np.concatenate([v, w])
    acc = forward(model, state, np.zeros((1, 6)), np.zeros((1, 6)), m_r)[0]

    def mass_at(h):
        pose = (t + h * v, rotvec_matrix(h * w) @ R)
        J = se.kinematics.jacobian(free, *pose)
        return model.mass_matrix(*pose) + J.T @ np.diag(m_r[0]) @ J

    h = 1e-5
    M_dot = (mass_at(h) - mass_at(-h)) / (2 * h)
    work = twist @ mass_at(0.0) @ acc
    rate = work + 0.5 * twist @ M_dot @ twist
    # the central difference's truncation (h^2) and its rounding (eps / h): ~1e-8 of the terms
    assert abs(rate) < 1e-6 * abs(work)
    # the velocity term matters: dropping it (forward dynamics without it) leaves power unaccounted
    without = np.linalg.solve(mass_at(0.0), -model.bias(t, R, v, w))
    assert abs(twist @ mass_at(0.0) @ without + 0.5 * twist @ M_dot @ twist) > 1e-3 * abs(work)


def test_a_row_s_numbers_with_reflected_masses_do_not_depend_on_its_batch(simulator, rng):
    """Rows in blocks of vector lanes and a row alone run the same arithmetic: bit for bit."""
    model = se.make_dynamics("improved", simulator)
    n = 19
    state = batch_of(simulator, rng, n)
    m_r = rng.uniform(200.0, 1500.0, size=(n, 6))
    F = rng.normal(scale=3e4, size=(n, 6))
    W = rng.normal(scale=200.0, size=(n, 6))
    acc = forward(model, state, F, W, m_r)
    forces = inverse(model, state, acc, W, m_r)
    for row in (0, 8, 17, 18):
        alone = tuple(np.ascontiguousarray(x[row : row + 1]) for x in state)
        assert np.array_equal(
            forward(model, alone, F[row : row + 1], W[row : row + 1], m_r[row : row + 1]), acc[row : row + 1]
        )
        assert np.array_equal(
            inverse(model, alone, acc[row : row + 1], W[row : row + 1], m_r[row : row + 1]), forces[row : row + 1]
        )
