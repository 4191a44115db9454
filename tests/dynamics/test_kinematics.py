"""Kinematics against finite differences along a smooth platform path, and forward kinematics."""

import numpy as np
import pytest

import stewart_env as se

from physics_reference import left_jacobian, leg_frames, random_state, rotvec_matrix

pytestmark = pytest.mark.physics

H = 1e-5  # finite-difference step, s


def path(state, acc, s):
    """Platform state at time s on t = t0 + v s + a s^2 / 2, R = exp([w s + alpha s^2 / 2]x) R0.

    Its velocity and angular velocity at s = 0 are v and w; its accelerations a and alpha.
    """
    t, R, v, w = state
    a, alpha = acc
    phi = w * s + 0.5 * alpha * s * s
    return (t + v * s + 0.5 * a * s * s, rotvec_matrix(phi) @ R, v + a * s, left_jacobian(phi) @ (w + alpha * s))


@pytest.fixture(params=["dasgupta", "simulator"])
def platform(request):
    return request.getfixturevalue(request.param)


def test_leg_rates_and_jacobian_match_finite_differences(platform, rng):
    for _ in range(5):
        state = random_state(platform, rng)
        acc = (rng.normal(size=3), rng.normal(size=3))
        k = se.leg_kinematics(platform, *state, *acc)
        Lp, Lm = (leg_frames(platform, *path(state, acc, s)[:2])[0] for s in (H, -H))
        L0 = leg_frames(platform, *state[:2])[0]
        # central differences: truncation O(H^2) ~ 1e-10, rounding 1e-16 / H^2 ~ 1e-6 for the second
        np.testing.assert_allclose(k.lengths, L0, rtol=1e-14)  # one norm, two orders of summation
        np.testing.assert_allclose(k.rates, (Lp - Lm) / (2 * H), atol=1e-9)
        np.testing.assert_allclose(k.accelerations, (Lp - 2 * L0 + Lm) / H**2, atol=2e-5)
        np.testing.assert_allclose(k.jacobian @ np.concatenate(state[2:]), k.rates, atol=1e-13)  # rounding of m/s terms


def test_leg_angular_velocity_includes_the_spin_the_u_joint_imposes(platform, rng):
    for _ in range(5):
        state = random_state(platform, rng)
        acc = (rng.normal(size=3), rng.normal(size=3))
        k = se.leg_kinematics(platform, *state, *acc)
        Tp, Tm = (leg_frames(platform, *path(state, acc, s)[:2])[1] for s in (H, -H))
        T0 = leg_frames(platform, *state[:2])[1]
        np.testing.assert_allclose(k.frames, T0, atol=1e-15)  # unit vectors: a few ulps
        for i in range(6):
            # the whole leg frame turns with omega_l: dT/dt = [omega_l]x T (spin about e included)
            Wx = (Tp[i] - Tm[i]) / (2 * H) @ T0[i].T
            np.testing.assert_allclose(Wx + Wx.T, 0, atol=1e-9)  # a rotation rate is skew, to O(H^2)
            omega_fd = np.array([Wx[2, 1], Wx[0, 2], Wx[1, 0]])
            np.testing.assert_allclose(k.omega[i], omega_fd, atol=1e-8)  # O(H^2) truncation
            h = np.cross(platform.hooke_axes[i], T0[i][:, 1])
            assert abs(k.omega[i] @ h) < 1e-13  # the joint cannot turn about h
        # spin is present: the leg's angular velocity has a component along its own axis
        assert np.abs(np.einsum("ij,ij->i", k.omega, k.units)).max() > 1e-3  # rad/s, far above rounding


def test_leg_angular_acceleration_matches_finite_differences(platform, rng):
    for _ in range(5):
        state = random_state(platform, rng)
        acc = (rng.normal(size=3), rng.normal(size=3))
        k = se.leg_kinematics(platform, *state, *acc)
        wp, wm = (se.leg_kinematics(platform, *path(state, acc, s)).omega for s in (H, -H))
        np.testing.assert_allclose(k.alpha, (wp - wm) / (2 * H), atol=1e-8)  # O(H^2) truncation


def test_classical_leg_kinematics_has_no_spin(dasgupta, rng):
    state = random_state(dasgupta, rng)
    k = se.leg_kinematics(dasgupta, *state, model="classical")
    np.testing.assert_allclose(np.einsum("ij,ij->i", k.omega, k.units), 0, atol=1e-15)  # rounding of a zero
    # C1: omega_l = e x v_P / L, perpendicular to the leg (rounding of rad/s terms)
    np.testing.assert_allclose(k.omega, np.cross(k.units, _vp(dasgupta, state)) / k.lengths[:, None], atol=1e-14)


def test_leg_kinematics_follows_the_switches_of_a_dynamics_model(dasgupta, rng):
    state = random_state(dasgupta, rng)
    classical = se.leg_kinematics(se.make_dynamics("classical", dasgupta), *state)
    np.testing.assert_allclose(
        np.einsum("ij,ij->i", classical.omega, classical.units), 0, atol=1e-15
    )  # rounding of a zero
    expected = se.leg_kinematics(dasgupta, *state, model="classical")
    assert np.array_equal(classical.omega, expected.omega) and np.array_equal(classical.alpha, expected.alpha)
    improved = se.leg_kinematics(se.make_dynamics("improved", dasgupta), *state, model="improved")
    assert np.abs(np.einsum("ij,ij->i", improved.omega, improved.units)).max() > 1e-3  # rad/s: the spin is there
    with pytest.raises(ValueError, match="model: 'improved' disagrees"):
        se.leg_kinematics(se.make_dynamics("classical", dasgupta), *state, model="improved")


def _vp(params, state):
    """Velocities of the platform joints P_i, (6,3) in {B}."""
    t, R, v, w = state
    return v + np.cross(w, (R @ params.platform_joints.T).T)


def test_forward_kinematics_inverts_inverse_kinematics(platform, rng):
    for _ in range(5):
        t, R, _, _ = random_state(platform, rng)
        lengths, _ = se.inverse_kinematics(platform, t, R)
        t_fk, R_fk = se.forward_kinematics(
            platform, lengths, platform.home_position, se.rpy_to_matrix(platform.home_rpy)
        )
        np.testing.assert_allclose(t_fk, t, atol=1e-10)  # 1e-12 m leg residual, J cond < 10
        np.testing.assert_allclose(R_fk, R, atol=1e-10)


def test_forward_kinematics_reports_failure(dasgupta):
    with pytest.raises(se.ConvergenceError, match="did not converge"):
        se.forward_kinematics(dasgupta, np.full(6, 1.3), dasgupta.home_position, np.eye(3), max_iter=1)
    with pytest.raises(ValueError, match="leg_lengths"):
        se.forward_kinematics(dasgupta, np.full(5, 1.3), dasgupta.home_position, np.eye(3))


def test_rpy_round_trip(rng):
    rpy = rng.uniform(-1.2, 1.2, size=(50, 3))
    np.testing.assert_allclose(se.matrix_to_rpy(se.rpy_to_matrix(rpy)), rpy, atol=1e-13)  # arcsin near 1.2 rad
    Rz = se.rpy_to_matrix([0, 0, np.pi / 2])
    np.testing.assert_allclose(Rz @ [1, 0, 0], [0, 1, 0], atol=1e-16)  # cos(pi/2) = 6e-17


def test_leg_sensors_decide_the_condition_threshold_exactly(dasgupta, rng):
    from stewart_env.kinematics import leg_sensors_inplace

    states = [random_state(dasgupta, rng) for _ in range(20)]
    t, R, v, w = (np.ascontiguousarray(x) for x in map(np.array, zip(*states)))
    k = se.leg_kinematics(dasgupta, t, R, v, w)
    exact = np.linalg.cond(k.jacobian)
    threshold = np.median(exact)  # half the rows above it, half below
    lengths, rates, condition = np.empty((20, 6)), np.empty((20, 6)), np.empty(20)
    leg_sensors_inplace(dasgupta, t, R, v, w, threshold, lengths, rates, condition)
    np.testing.assert_array_equal(lengths, k.lengths)  # the same kernel code
    np.testing.assert_allclose(rates, k.rates, rtol=0, atol=1e-15)  # same formula, other call path
    above = exact > threshold
    np.testing.assert_allclose(condition[above], exact[above], rtol=1e-12)  # SVD both ways
    # below the threshold the bound ||J||_F ||J^-1||_F: above cond_2, at most the threshold
    assert np.all(condition[~above] >= exact[~above] * (1 - 1e-12))
    assert np.all(condition[~above] <= threshold)
    assert np.array_equal(condition > threshold, above)


def test_rotation_vectors_round_trip(rng):
    from stewart_env.rotations import rotation_error, rotvec_to_matrix

    phi = rng.normal(size=(50, 3)) * np.concatenate([np.full(25, 1e-10), np.full(25, 0.8)])[:, None]
    R = rotvec_to_matrix(phi)
    np.testing.assert_allclose(R, [rotvec_matrix(p) for p in phi], atol=1e-15)  # Rodrigues, written out
    back, angle = rotation_error(R, np.eye(3))
    np.testing.assert_allclose(back, phi, rtol=1e-12, atol=1e-16)  # the small-angle series keeps digits
    np.testing.assert_allclose(angle, np.linalg.norm(phi, axis=1), rtol=1e-12)


def test_jacobian_is_the_leg_kinematics_jacobian_bit_for_bit(dasgupta, rng):
    t = dasgupta.home_position + rng.uniform(-0.05, 0.05, (4, 3))
    R = np.stack([se.rpy_to_matrix(rng.uniform(-0.15, 0.15, 3)) for _ in range(4)])
    J = se.jacobian(dasgupta, t, R)
    assert J.shape == (4, 6, 6)
    assert np.array_equal(J, se.leg_kinematics(dasgupta, t, R).jacobian)
    assert np.array_equal(se.jacobian(dasgupta, t[1], R[1]), J[1])
