"""The exact step Jacobians (Dynamics.step_jacobians) against MuJoCo's finite-difference derivatives
of its own step (``mujoco.mjd_transitionFD``) on the twin of the same mechanism, mapped into the
closed form's tangent coordinates (dt, left dtheta, v, w)."""

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

import stewart_env as se  # noqa: E402
from stewart_env.mujoco.mjcf import DEFAULT_SOLIMP, DEFAULT_SOLREF  # noqa: E402
from stewart_env.mujoco.twin import Twin  # noqa: E402
from stewart_env.params import Damping  # noqa: E402

from physics_reference import random_state  # noqa: E402

pytestmark = pytest.mark.extra("mujoco")

CONTROL_DT = 0.01  # one 10 ms control step, ten RK4 substeps of 1 ms in the closed form
TWIN_STEPS = 50  # the twin's steps of 0.2 ms: mjd_transitionFD takes no RK4, so Euler, finer


def skew(x):
    return np.array([[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]])


def twin_state_map(tw, t, R, v, w, h=1e-6):
    """G (2 nv, 12): how MuJoCo's state (its tangent dqpos, then qvel) moves along each of the
    closed form's tangent coordinates, the legs following by inverse kinematics (central
    differences of Twin.set_state, which is smooth: h = 1e-6 leaves an error near 1e-10)."""
    m = tw.model
    d = mujoco.MjData(m)
    G = np.empty((2 * m.nv, 12))
    for k in range(12):
        moved = []
        for sign in (1.0, -1.0):
            x = [t.copy(), R.copy(), v.copy(), w.copy()]
            step = sign * h
            if k < 3:
                x[0][k] += step
            elif k < 6:
                phi = np.zeros(3)
                phi[k - 3] = step
                x[1] = se.rotations.rotvec_to_matrix(phi) @ R
            elif k < 9:
                x[2][k - 6] += step
            else:
                x[3][k - 9] += step
            tw.set_state(d, *x)
            moved.append((d.qpos.copy(), d.qvel.copy()))
        (qp, vp), (qm, vm) = moved
        dq = np.empty(m.nv)
        mujoco.mj_differentiatePos(m, dq, 2 * h, qm, qp)
        G[: m.nv, k] = dq
        G[m.nv :, k] = (vp - vm) / (2 * h)
    return G


def platform_map(tw, d):
    """P (12, 2 nv): the closed form's tangent coordinates of a change of MuJoCo's state.  The free
    joint turns and spins in its body frame: dtheta = R dtheta_body, and w = R w_body moves by
    R dw_body + dtheta x w."""
    m = tw.model
    R = d.xmat[tw.body].reshape(3, 3)
    w = R @ d.qvel[tw.v_free + 3 : tw.v_free + 6]
    P = np.zeros((12, 2 * m.nv))
    f = tw.v_free
    P[0:3, f : f + 3] = np.eye(3)
    P[3:6, f + 3 : f + 6] = R
    P[6:9, m.nv + f : m.nv + f + 3] = np.eye(3)
    P[9:12, m.nv + f + 3 : m.nv + f + 6] = R
    P[9:12, f + 3 : f + 6] = -skew(w) @ R
    return P


def twin_step_jacobians(params, t, R, v, w, F, integrator="mjINT_EULER"):
    """The twin's A (12,12) and B (12,6) of a control step, TWIN_STEPS steps chained from
    mjd_transitionFD at each step (centred differences, eps 1e-6), mapped into the closed form's
    coordinates."""
    tw = Twin(params, CONTROL_DT / TWIN_STEPS, DEFAULT_SOLREF, DEFAULT_SOLIMP)
    m = tw.model
    m.opt.integrator = getattr(mujoco.mjtIntegrator, integrator)
    G = twin_state_map(tw, t, R, v, w)
    d = mujoco.MjData(m)
    tw.set_state(d, t, R, v, w)  # resets the data, the controls too: the forces after it
    tw.set_wrench(d, t, R, F, np.zeros(6))
    nx = 2 * m.nv + m.na
    A_total, B_total = np.eye(nx), np.zeros((nx, m.nu))
    A, B = np.empty((nx, nx)), np.empty((nx, m.nu))
    for _ in range(TWIN_STEPS):
        mujoco.mjd_transitionFD(m, d, 1e-6, 1, A, B, None, None)
        A_total, B_total = A @ A_total, A @ B_total + B
        mujoco.mj_step(m, d)
    P = platform_map(tw, d)
    return P @ A_total @ G, P @ B_total


def test_step_jacobians_match_mujocos_finite_differences_on_the_twin(dasgupta):
    d = dasgupta.damping
    params = dasgupta.replace(damping=Damping(d.universal, d.prismatic, 0.0))  # the twin has no C_s
    rng = np.random.default_rng(0)
    t, R, v, w = random_state(params, rng, speed=0.2)
    z = np.zeros(3)
    model = se.make_dynamics("improved", params)
    F = 1.1 * model.inverse(t, R, z, z, z, z)
    exact = model.step_jacobians(t, R, v, w, F, CONTROL_DT, 10)
    A, B = twin_step_jacobians(params, t, R, v, w, F)
    # relative to each block's largest entry: measured 0.9e-4 to 2.1e-4 (the twin's Euler steps
    # of 0.2 ms against RK4 at 1 ms, O(dt): 4x finer steps measured 4x less; its loops' softness)
    for rows in (slice(0, 6), slice(6, 12)):
        for cols in (slice(0, 6), slice(6, 12)):
            block, twin_block = exact.A[rows, cols], A[rows, cols]
            err = np.abs(block - twin_block).max()
            assert err <= TOLERANCE * np.abs(block).max(), (rows, cols, err, np.abs(block).max())
    err = np.abs(exact.B - B).max()
    assert err <= TOLERANCE * np.abs(exact.B).max(), err


TOLERANCE = 1e-3  # 5x the largest measured
