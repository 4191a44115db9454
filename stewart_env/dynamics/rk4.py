"""Classical RK4 over a batch of platforms, with a compiled control law evaluated at every stage.

The one time integrator of the package (docs/physics.md section 5.6).  The state of a row is
x = [t (3), quaternion (4), v (3), w (3)]: position of P's origin, orientation as a unit
quaternion (w, x, y, z), velocity of P's origin and angular velocity, all in {B}.  At each of the
four stages of a step the control law gives the leg forces for the stage's time and state, and
the forward dynamics (:func:`stewart_env.dynamics.kernels._forward_one`) the accelerations.

Control laws
------------
A control law is a numba ``@njit`` function that returns nothing and writes six leg forces:

    law(time, position, rotation, velocity, angular_velocity, params, forces)

time (float64, s); position (3,), rotation (3,3), velocity (3,), angular_velocity (3,): the
stage's state in {B}, to be read only; params (P,): the law's own parameter row (gains, targets,
... in a layout the law defines); forces (6,): the leg forces, N, positive extending the leg.
All arrays are C-contiguous float64 (:data:`LAW_SIGNATURE`).  The law reaches the integrator as
a first-class function (a pointer of type :data:`LAW_TYPE`), so :func:`rollout_law_batch` is
compiled once for every law and cached like the package's other kernels; the law itself is
compiled (and, with ``cache=True``, cached) on its own.  ``stewart_env.agents.pd.pd_control_law``
is a worked example of a user's law.

Without a law the forces are held constant over the call (the zero-order hold of the
environment's step): :func:`rollout_batch`, the same RK4 row with the law ``None``.

Inside a law, :func:`jacobian` and :func:`inverse_dynamics` give the platform's Jacobian and
inverse dynamics from a packed parameter row (:func:`stewart_env.dynamics.model.pack_params`,
e.g. the controller's belief of the platform, carried in its ``params``): the kernels' own code.
"""

import numpy as np
from numba import njit, prange, types

from stewart_env.dynamics.kernels import FASTMATH, PARALLEL_MIN_ROWS, _forward_one, _inverse_one, _jacobian_one

_VEC = types.float64[::1]
_MAT = types.float64[:, ::1]
#: numba signature of a control law (see the module docstring).
LAW_SIGNATURE = types.void(types.float64, _VEC, _MAT, _VEC, _VEC, _VEC, _VEC)
#: numba type of a control law passed to :func:`rollout_law_batch`.
LAW_TYPE = types.FunctionType(LAW_SIGNATURE)
_REC = types.float64[:, :, ::1]
#: The one signature :func:`law_kernel` compiles :func:`rollout_law_batch` for: prm (read-only),
#: flags, t, R, v, w, law, ctrl, W (read-only), time, dt, steps, every, rec_t, rec_R, rec_v, rec_w,
#: rec_F.
LAW_KERNEL_SIGNATURE = (
    types.Array(types.float64, 2, "C", readonly=True), types.int64, _MAT, _REC, _MAT, _MAT, LAW_TYPE, _MAT,
    types.Array(types.float64, 2, "C", readonly=True), types.float64, types.float64, types.int64, types.int64,
    _REC, types.float64[:, :, :, ::1], _REC, _REC, _REC,
)


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def jacobian(prm, t, R, J):
    """The leg Jacobian J (6,6) of one platform, dL/dt = J [v; omega]: row i = [e_i, q_i x e_i]
    with q_i = R p_i ({B}); prm a packed parameter row (N_PARAMS,).  For control laws.
    docs/physics.md section 4.4; paper eq. 13."""
    _jacobian_one(prm, t, R, J)


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def inverse_dynamics(prm, flags, t, R, v, w, acc, W, out):
    """Leg forces ``out`` (6,), N, that give one platform the accelerations acc = [a; alpha]
    (6,) under the external wrench W (6,), {B}; prm a packed parameter row, flags the model's
    switch bits.  For control laws (e.g. gravity compensation: v = w = acc = W = 0).
    docs/physics.md section 5.5; paper eq. 49 or 55."""
    _inverse_one(prm, flags, t, R, v, w, acc, W, np.empty((6, 6)), np.empty(6), out)


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def constant_forces(time, position, rotation, velocity, angular_velocity, params, forces):
    """The simplest control law: forces = params[:6], N, whatever the time and state (the hold of
    :func:`rollout_batch`, for a rollout that records its trajectory)."""
    for i in range(6):
        forces[i] = params[i]


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def _leg_forces(law, ctrl, time, x, R, F):
    """The leg forces (6,), N, at a stage: the law's at (time, x), R the stage's rotation, written
    into F (a force it leaves unwritten is NaN); or, when ``law`` is None (the zero-order hold),
    ctrl itself.  numba drops the branch not taken when it compiles, so the hold costs nothing."""
    if law is None:
        return ctrl
    # a force the law leaves unwritten is NaN, so the rollout stops as non-finite instead of
    # integrating whatever the buffer held
    for i in range(6):
        F[i] = np.nan
    law(time, x[0:3], R, x[7:10], x[10:13], ctrl, F)
    return F


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def _quat_to_matrix(q, R):
    """Unit quaternion q = (w, x, y, z) to rotation matrix R (3,3), normalising q first.

    docs/physics.md section 5.6 (no paper equation).
    """
    n = np.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    a = q[0] / n
    b = q[1] / n
    c = q[2] / n
    d = q[3] / n
    R[0, 0] = a * a + b * b - c * c - d * d
    R[0, 1] = 2.0 * (b * c - a * d)
    R[0, 2] = 2.0 * (b * d + a * c)
    R[1, 0] = 2.0 * (b * c + a * d)
    R[1, 1] = a * a - b * b + c * c - d * d
    R[1, 2] = 2.0 * (c * d - a * b)
    R[2, 0] = 2.0 * (b * d - a * c)
    R[2, 1] = 2.0 * (c * d + a * b)
    R[2, 2] = a * a - b * b - c * c + d * d


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def _matrix_to_quat(R, q):
    """Rotation matrix to unit quaternion (w, x, y, z), w >= 0 (Shepperd's method: the division
    is by the largest of the four candidates, so a half turn is as exact as any other rotation).

    docs/physics.md section 5.6 (no paper equation).
    """
    tr = R[0, 0] + R[1, 1] + R[2, 2]
    if tr > 0.0:
        s = 2.0 * np.sqrt(1.0 + tr)
        q[0] = 0.25 * s
        q[1] = (R[2, 1] - R[1, 2]) / s
        q[2] = (R[0, 2] - R[2, 0]) / s
        q[3] = (R[1, 0] - R[0, 1]) / s
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = 2.0 * np.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2])
        q[0] = (R[2, 1] - R[1, 2]) / s
        q[1] = 0.25 * s
        q[2] = (R[0, 1] + R[1, 0]) / s
        q[3] = (R[0, 2] + R[2, 0]) / s
    elif R[1, 1] > R[2, 2]:
        s = 2.0 * np.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2])
        q[0] = (R[0, 2] - R[2, 0]) / s
        q[1] = (R[0, 1] + R[1, 0]) / s
        q[2] = 0.25 * s
        q[3] = (R[1, 2] + R[2, 1]) / s
    else:
        s = 2.0 * np.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1])
        q[0] = (R[1, 0] - R[0, 1]) / s
        q[1] = (R[0, 2] + R[2, 0]) / s
        q[2] = (R[1, 2] + R[2, 1]) / s
        q[3] = 0.25 * s
    if q[0] < 0.0:
        for j in range(4):
            q[j] = -q[j]


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def _state_derivative(prm, flags, law, ctrl, time, x, F, W, R, M, h, acc, dx):
    """dx/dt for x = [t (3), quaternion (4), v (3), w (3)] under the leg forces of
    :func:`_leg_forces` at (time, x); quaternion rate 0.5 (0, w) * q.  F, R, M, h, acc are scratch.

    docs/physics.md section 5.6; the accelerations from paper eq. 49 or 55.
    """
    _quat_to_matrix(x[3:7], R)
    forces = _leg_forces(law, ctrl, time, x, R, F)
    _forward_one(prm, flags, x[0:3], R, x[7:10], x[10:13], forces, W, M, h, acc)
    dx[0] = x[7]
    dx[1] = x[8]
    dx[2] = x[9]
    w0 = x[10]
    w1 = x[11]
    w2 = x[12]
    qa = x[3]
    qb = x[4]
    qc = x[5]
    qd = x[6]
    dx[3] = 0.5 * (-w0 * qb - w1 * qc - w2 * qd)
    dx[4] = 0.5 * (w0 * qa + w1 * qd - w2 * qc)
    dx[5] = 0.5 * (-w0 * qd + w1 * qa + w2 * qb)
    dx[6] = 0.5 * (w0 * qc - w1 * qb + w2 * qa)
    for j in range(6):
        dx[7 + j] = acc[j]


@njit(cache=True, parallel=True, error_model="numpy", fastmath=FASTMATH)
def rollout_batch(prm, flags, t, R, v, w, F, W, dt, steps):
    """Integrate ``steps`` classical RK4 steps of ``dt`` seconds with F (N,6) and W (N,6) held
    constant: :func:`rollout_law_batch` without a law (the zero-order hold), nothing recorded.

    t (N,3), R (N,3,3), v (N,3), w (N,3) are overwritten with the final state.  The env's step.
    docs/physics.md section 5.6 (no paper equation).
    """
    n = t.shape[0]
    if n >= PARALLEL_MIN_ROWS:
        for b in prange(n):
            _rollout_row(prm, flags, t, R, v, w, None, F, W, 0.0, dt, steps, 0, None, b)
    else:
        for b in range(n):
            _rollout_row(prm, flags, t, R, v, w, None, F, W, 0.0, dt, steps, 0, None, b)


@njit(cache=True, parallel=True, error_model="numpy", fastmath=FASTMATH)
def rollout_law_batch(prm, flags, t, R, v, w, law, ctrl, W, time, dt, steps, every,
                      rec_t, rec_R, rec_v, rec_w, rec_F):
    """Integrate ``steps`` classical RK4 steps of ``dt`` seconds from ``time`` s, the leg forces
    given by ``law`` (see the module docstring; a first-class function of :data:`LAW_TYPE`) with
    the parameter row ``ctrl[b]`` (``ctrl`` of shape (N, P), or (1, P) for one row shared by the
    batch) at every stage; W (N,6) held constant.

    t (N,3), R (N,3,3), v (N,3), w (N,3) are overwritten with the final state.  The orientation is
    carried as a unit quaternion (renormalised after each step) so R stays a rotation.  With
    ``every`` > 0 the state after every ``every`` steps, the start included, is written into
    rec_t (N,T,3), rec_R (N,T,3,3), rec_v (N,T,3), rec_w (N,T,3), T = steps // every + 1, and the
    law's forces at that state into rec_F (N,T,6); with ``every`` == 0 they are not touched.  A row
    whose state stops being finite is left at its first non-finite value (its later samples too).
    docs/physics.md section 5.6 (no paper equation).
    """
    n = t.shape[0]
    rec = (rec_t, rec_R, rec_v, rec_w, rec_F)
    if n >= PARALLEL_MIN_ROWS:
        for b in prange(n):
            _rollout_row(prm, flags, t, R, v, w, law, ctrl, W, time, dt, steps, every, rec, b)
    else:
        for b in range(n):
            _rollout_row(prm, flags, t, R, v, w, law, ctrl, W, time, dt, steps, every, rec, b)


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def _record(law, c, time, x, Rs, F, rec, b, s):
    """Sample s of row b into rec = (rec_t, rec_R, rec_v, rec_w, rec_F): the state x and the
    law's forces there."""
    rec_t, rec_R, rec_v, rec_w, rec_F = rec
    _quat_to_matrix(x[3:7], Rs)
    forces = _leg_forces(law, c, time, x, Rs, F)
    for j in range(3):
        rec_t[b, s, j] = x[j]
        rec_v[b, s, j] = x[7 + j]
        rec_w[b, s, j] = x[10 + j]
    rec_R[b, s] = Rs
    rec_F[b, s] = forces


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def _rollout_row(prm, flags, t, R, v, w, law, ctrl, W, time, dt, steps, every, rec, b):
    """Row b of :func:`rollout_batch` and :func:`rollout_law_batch` (docs/physics.md section 5.6);
    rec the tuple of record arrays, or None (numba then compiles no recording at all)."""
    p = prm[0] if prm.shape[0] == 1 else prm[b]
    c = ctrl[0] if ctrl.shape[0] == 1 else ctrl[b]
    x = np.empty(13)
    xs = np.empty(13)
    k = np.empty((4, 13))
    F = np.empty(6)
    Rs = np.empty((3, 3))
    M = np.empty((6, 6))
    h = np.empty(6)
    acc = np.empty(6)
    for j in range(3):
        x[j] = t[b, j]
        x[7 + j] = v[b, j]
        x[10 + j] = w[b, j]
    _matrix_to_quat(R[b], x[3:7])
    recorded = 0
    if rec is not None:
        if every > 0:
            _record(law, c, time, x, Rs, F, rec, b, 0)
            recorded = 1
    for step in range(steps):
        t0 = time + step * dt
        _state_derivative(p, flags, law, c, t0, x, F, W[b], Rs, M, h, acc, k[0])
        for j in range(13):
            xs[j] = x[j] + 0.5 * dt * k[0, j]
        _state_derivative(p, flags, law, c, t0 + 0.5 * dt, xs, F, W[b], Rs, M, h, acc, k[1])
        for j in range(13):
            xs[j] = x[j] + 0.5 * dt * k[1, j]
        _state_derivative(p, flags, law, c, t0 + 0.5 * dt, xs, F, W[b], Rs, M, h, acc, k[2])
        for j in range(13):
            xs[j] = x[j] + dt * k[2, j]
        _state_derivative(p, flags, law, c, t0 + dt, xs, F, W[b], Rs, M, h, acc, k[3])
        finite = True
        for j in range(13):
            x[j] += dt / 6.0 * (k[0, j] + 2.0 * k[1, j] + 2.0 * k[2, j] + k[3, j])
            finite = finite and np.isfinite(x[j])
        nq = np.sqrt(x[3] * x[3] + x[4] * x[4] + x[5] * x[5] + x[6] * x[6])
        for j in range(3, 7):
            x[j] /= nq
        if rec is not None:
            if every > 0 and (step + 1) % every == 0:
                _record(law, c, time + (step + 1) * dt, x, Rs, F, rec, b, recorded)
                recorded += 1
        if not finite:
            break
    if rec is not None:
        for s in range(recorded, rec[0].shape[1]):  # after a break: the non-finite state to the end
            _record(law, c, time + steps * dt, x, Rs, F, rec, b, s)
    for j in range(3):
        t[b, j] = x[j]
        v[b, j] = x[7 + j]
        w[b, j] = x[10 + j]
    _quat_to_matrix(x[3:7], R[b])


def law_kernel():
    """:func:`rollout_law_batch` compiled for :data:`LAW_KERNEL_SIGNATURE` (loaded from numba's
    cache when it is warm), and only for it: a law passed as a numba dispatcher is then converted
    to a :data:`LAW_TYPE` pointer instead of compiling the integrator again for each law."""
    if not rollout_law_batch.overloads:
        rollout_law_batch.compile(LAW_KERNEL_SIGNATURE)
        rollout_law_batch.disable_compile()
    return rollout_law_batch
