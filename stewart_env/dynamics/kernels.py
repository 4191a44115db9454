"""Compiled kernels: the one implementation of the Stewart platform's kinematics and dynamics.

Everything physical in the package runs through the functions here; the Python classes around
them only check arguments and pick a kernel.  ``docs/physics.md`` in the repository is the full
account of the physics: frames, parameters, a table of every symbol used below beside the
paper's, the derivations and the tests that decide correctness.  Each function's docstring names
the section of that page and the equations of He et al. (2018) it implements.

Conventions (docs/physics.md section 1)
---------------------------------------
* {B} base frame, fixed.  {P} platform frame: origin P at ``t``, orientation ``R`` (columns =
  {P} axes in {B}).  Velocity ``v`` of P's origin, angular velocity ``w``, linear acceleration
  ``a`` of P's origin and angular acceleration ``alpha``: all in {B}.
* Leg i joins base joint B_i (``b_i`` in {B}) to platform joint P_i (``p_i`` in {P}).
  S_i = t + R p_i - b_i, L_i = |S_i|, e_i = S_i / L_i.
* U joint at B_i: fixed axis k_i, moving axis y_i = unit(k_i x e_i), z_i = e_i x y_i.  The leg
  frame {D_i} = [e_i, y_i, z_i] moves with both leg parts.
* Actuator force F_i > 0 extends the leg; F_s is the force of the platform on the leg at P_i.

Why the leg is worked in its own frame
--------------------------------------
In {D_i} (a prime marks components in that frame) the leg axis is (1, 0, 0), the U joint's
moving axis is (0, 1, 0), the fixed axis is k' = (kx, 0, kz) with kz = |k x e| > 0, and the
normal of the U joint's axis plane is h' = k' x y' = (-kz, 0, kx).  The leg inertias and CoM
offsets are constants in this frame, so the per-leg equations reduce to a few dozen scalar
products and nothing is rotated or allocated.

Map of the kernels
------------------
* Leg kinematics (section 4): ``_leg_frame`` gives a leg's geometry as one value, a
  ``LegFrame``; ``_leg_state`` adds its rates (``_leg_rates``) and the platform's motion seen in
  the leg frame, a ``LegState``; ``_leg_accel``; the Jacobian row ``_jacobian_row``.
* One leg's force on the platform (sections 5.1-5.2): ``_leg_bodies``, ``_leg_inertial_force``,
  ``_leg_rate_force``, ``_leg_split``, ``_leg_force``.  The leg's moment equation about B_i is
  S x F_s + mu h = N; its row along e fixes mu and the rest gives F_s perpendicular to the leg;
  Newton's law for the upper leg along e gives e . F_s.
* The platform (section 5.3): ``_platform_terms``.
* Forward dynamics M [a; alpha] + h = J^T F + W (section 5.4): ``_assemble_one`` builds M and
  h (the columns of each leg's Q_i from ``_unit_inertial_force``), which ``_forward_one``
  solves and ``mass_bias_batch`` returns; inverse dynamics (section 5.5): ``_inverse_one``.
  Both run the same leg loop body, ``_leg_on_platform``.  RK4 (section 5.6):
  :mod:`stewart_env.dynamics.rk4`, built on ``_forward_one``.

The model switches (switch bits, section 6)
-------------------------------------------
* ``C1`` (bit 1), no leg spin: sigma = 0 and alpha_l = (e x a_P - 2 Ldot w_perp) / L.
* ``C2`` (bit 2), U-joint reaction moment along e instead of h: the axial component of the leg
  moment equation is dropped instead of being balanced by mu h.
* ``C3`` (bit 4), legs: shifted inertias I_B used together with r x m a_c, so the parallel-axis
  part is counted twice.
* ``C4`` (bit 8), platform: the same double count, I_P together with rho x m_p a_c.
``CENTROIDAL`` (bit 16) selects the centroidal form (paper eq. 55) instead of the joint form
(eq. 49).  With C3 (C4) both forms use the same double-counted expression for the legs
(platform).

Speed
-----
The per-leg helpers, the platform terms and the 6x6 solve are inlined into their callers
(``inline="always"``: numba compiles them into one function, so LLVM optimises the computation
as a whole; the helpers take no ``*args`` for that reason), and every kernel compiles with
``FASTMATH``.  Together they cut the time of a forward evaluation by about 40 %, and the first
compilation takes no longer than before.  Inlining the assembly ``_assemble_one`` as well gains
a few per cent more but more than doubles the first compilation, so it stays a function.

Each ``*_batch`` function spells out its loop over rows (``prange`` from ``PARALLEL_MIN_ROWS``
rows on, ``range`` below) and hands the row to a ``_*_row`` function.  One generic row runner
taking the row function as an argument would say it once, but numba cannot cache a function
that takes a compiled function as an argument ("uses dynamic globals"), and an uncached kernel
costs every new process its compilation (tens of seconds), so the four lines stay in each.

Packed parameters
-----------------
Kernels take ``prm`` of shape (Np, N_PARAMS), one row per platform (Np == 1 broadcasts over the
batch).  ``PACKED_LAYOUT`` below lists the entries (docs/physics.md section 2); the ``OFF_*``
offsets and :func:`stewart_env.dynamics.model.pack_params` follow from it.
"""

import os
from collections import namedtuple

import numba
import numpy as np
from numba import literal_unroll, njit, prange

# libgomp's idle threads spin: when the cores are shared (a learner training beside the
# simulation, a busy CI runner) a parallel call of these kernels ran 6x slower than one thread.
# numba's own workqueue layer lets idle threads sleep.  A layer the user chose still wins.
if "NUMBA_THREADING_LAYER" not in os.environ:
    numba.config.THREADING_LAYER = "workqueue"

C1 = 1
C2 = 2
C3 = 4
C4 = 8
CENTROIDAL = 16

#: The packed parameter row, in order: (config key, shape).  The one source of the layout: the
#: offsets below, ``model.pack_params`` and ``Randomization.scale_packed`` follow it, and
#: docs/physics.md section 2 lists each key.  Leg entries hold six legs; frames as in section 2.
PACKED_LAYOUT = (
    ("base_joints", (6, 3)),  # b_i, {B}
    ("platform_joints", (6, 3)),  # p_i, {P}
    ("hooke_axes", (6, 3)),  # unit k_i, {B}
    ("platform.mass", ()),  # m_p
    ("platform.com", (3,)),  # R_0, {P}
    ("platform.inertia", (3, 3)),  # about the CoM, {P}
    ("upper_leg.mass", (6,)),  # m_u
    ("upper_leg.com", (6, 3)),  # r_u0 from P_i, {D_i}
    ("upper_leg.inertia", (6, 3, 3)),  # about the CoM, {D_i}
    ("lower_leg.mass", (6,)),  # m_d
    ("lower_leg.com", (6, 3)),  # r_d0 from B_i, {D_i}
    ("lower_leg.inertia", (6, 3, 3)),  # about the CoM, {D_i}
    ("damping", (3,)),  # C_u, C_p, C_s
    ("gravity", (3,)),  # g, {B}
)


def _offsets(layout):
    """{key: slice} of each entry of a packed layout, and the row's length (plain Python, run
    once at import).  docs/physics.md section 2 (no paper equation)."""
    slices, start = {}, 0
    for key, shape in layout:
        size = int(np.prod(shape, dtype=np.int64))
        slices[key] = slice(start, start + size)
        start += size
    return slices, start


PACKED_SLICES, N_PARAMS = _offsets(PACKED_LAYOUT)
OFF_B = PACKED_SLICES["base_joints"].start
OFF_P = PACKED_SLICES["platform_joints"].start
OFF_K = PACKED_SLICES["hooke_axes"].start
OFF_MP = PACKED_SLICES["platform.mass"].start
OFF_RHO = PACKED_SLICES["platform.com"].start
OFF_IP = PACKED_SLICES["platform.inertia"].start
OFF_MU = PACKED_SLICES["upper_leg.mass"].start
OFF_RU = PACKED_SLICES["upper_leg.com"].start
OFF_IU = PACKED_SLICES["upper_leg.inertia"].start
OFF_MD = PACKED_SLICES["lower_leg.mass"].start
OFF_RD = PACKED_SLICES["lower_leg.com"].start
OFF_ID = PACKED_SLICES["lower_leg.inertia"].start
OFF_DAMP = PACKED_SLICES["damping"].start
OFF_G = PACKED_SLICES["gravity"].start

# Floating-point licence of every kernel: fused multiply-adds and x / y as x * (1 / y), which
# change results by rounding only (1e-15 relative).  Nothing that assumes finite values (nnan,
# ninf), so a state that stops being finite is still seen as such.
FASTMATH = {"contract", "arcp"}

#: One leg's geometry (docs/physics.md sections 1 and 4.1), the value ``_leg_frame`` returns and
#: the per-leg helpers take: q = R p_i, length L, the unit vectors e, y, z of the leg frame
#: {D_i} (3-tuples in {B}), and the fixed U-joint axis k in {D_i}, (kx, 0, kz) with kz > 0.
LegFrame = namedtuple("LegFrame", ["q", "L", "e", "y", "z", "kx", "kz"])
#: One leg's motion in the platform's state (sections 4.1-4.2), ``_leg_state``'s value: its
#: LegFrame; the rates Ldot, spin sigma and angular velocity (w1, w2) about y and z; and in
#: {D_i} (3-tuples) the platform's angular velocity ``omega``, ``gravity`` and ``a_vel``, the
#: part w x (w x q) of P_i's acceleration that does not depend on the platform's acceleration.
LegState = namedtuple("LegState", ["frame", "Ldot", "sigma", "w1", "w2", "omega", "gravity", "a_vel"])

# Batches smaller than this run on the calling thread: for a handful of rows, waking numba's
# worker threads costs more than it saves, and far more when other processes hold the cores.
PARALLEL_MIN_ROWS = 16


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _cross(a0, a1, a2, b0, b1, b2):
    """Components of a x b (docs/physics.md section 3.2; no paper equation)."""
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _to_base(fr, u0, u1, u2):
    """{B} components of a vector given in the leg frame fr = [e y z]: u = T_i u'.

    docs/physics.md section 1; paper eq. 15 (T_i).
    """
    e0, e1, e2 = fr.e
    y0, y1, y2 = fr.y
    z0, z1, z2 = fr.z
    return u0 * e0 + u1 * y0 + u2 * z0, u0 * e1 + u1 * y1 + u2 * z1, u0 * e2 + u1 * y2 + u2 * z2


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _to_leg(fr, u0, u1, u2):
    """Leg-frame components (u . e, u . y, u . z) of a vector given in {B}: u' = T_i^T u.

    docs/physics.md section 1; paper eq. 15 (T_i).
    """
    e0, e1, e2 = fr.e
    y0, y1, y2 = fr.y
    z0, z1, z2 = fr.z
    return u0 * e0 + u1 * e1 + u2 * e2, u0 * y0 + u1 * y1 + u2 * y2, u0 * z0 + u1 * z1 + u2 * z2


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _with_platform_acc(acc, fr, A):
    """P_i's acceleration in {D_i}: the velocity part A' plus a + alpha x q for acc = [a; alpha].

    docs/physics.md section 4.1; paper eqs. 10-12 (a_Pi).
    """
    q0, q1, q2 = fr.q
    x0, x1, x2 = _cross(acc[3], acc[4], acc[5], q0, q1, q2)
    x0 += acc[0]
    x1 += acc[1]
    x2 += acc[2]
    d0, d1, d2 = _to_leg(fr, x0, x1, x2)
    return A[0] + d0, A[1] + d1, A[2] + d2


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _inertia(prm, off, s, m, r0, r1, r2):
    """Inertia I = I_c + s m (|r|^2 E - r r^T) as (Ixx, Iyy, Izz, Ixy, Ixz, Iyz).

    ``I_c`` is the 3x3 at ``prm[off:off+9]``; ``s`` counts parallel-axis shifts (the callers pass 0 or 1).
    docs/physics.md sections 5.2 and 6 (C3, C4); the paper's shifted inertias before eq. 32 and
    eq. 44, its CoM inertias eqs. 50 and 52.
    """
    rr = r0 * r0 + r1 * r1 + r2 * r2
    sm = s * m
    return (
        prm[off + 0] + sm * (rr - r0 * r0),
        prm[off + 4] + sm * (rr - r1 * r1),
        prm[off + 8] + sm * (rr - r2 * r2),
        prm[off + 1] - sm * r0 * r1,
        prm[off + 2] - sm * r0 * r2,
        prm[off + 5] - sm * r1 * r2,
    )


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _euler(I, a0, a1, a2, w0, w1, w2):
    """Inertial moment I alpha + w x (I w) of a symmetric inertia I = (xx, yy, zz, xy, xz, yz).

    docs/physics.md sections 5.2-5.3; the Euler terms of paper eqs. 32, 46, 50 and 53.
    """
    i00, i11, i22, i01, i02, i12 = I
    iw0 = i00 * w0 + i01 * w1 + i02 * w2
    iw1 = i01 * w0 + i11 * w1 + i12 * w2
    iw2 = i02 * w0 + i12 * w1 + i22 * w2
    c0, c1, c2 = _cross(w0, w1, w2, iw0, iw1, iw2)
    return (
        i00 * a0 + i01 * a1 + i02 * a2 + c0,
        i01 * a0 + i11 * a1 + i12 * a2 + c1,
        i02 * a0 + i12 * a1 + i22 * a2 + c2,
    )


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _leg_bodies(prm, i, flags, L):
    """Leg i's mass properties at length L, in {D_i}: (m_u, m_d, r_u, r_d, I_u, I_d).

    r_u, r_d are the CoMs from B_i; I_u, I_d the inertias used in the moment equation about
    B_i: about the CoM (centroidal form), shifted to B_i (eq. 49 form), or shifted once more
    than the form needs (C3).  docs/physics.md sections 4.3 (CoMs), 5.2 and 6 (C3); paper
    eqs. 28-29 (r_u, r_d), the inertias about B_i before eq. 32 and about the CoM in eq. 50.
    """
    m_u = prm[OFF_MU + i]
    m_d = prm[OFF_MD + i]
    r_u = (L + prm[OFF_RU + 3 * i], prm[OFF_RU + 3 * i + 1], prm[OFF_RU + 3 * i + 2])
    r_d = (prm[OFF_RD + 3 * i], prm[OFF_RD + 3 * i + 1], prm[OFF_RD + 3 * i + 2])
    if flags & (CENTROIDAL | C3):
        shifts = 1.0 if flags & C3 else 0.0
    else:
        shifts = 1.0
    I_u = _inertia(prm, OFF_IU + 9 * i, shifts, m_u, r_u[0], r_u[1], r_u[2])
    I_d = _inertia(prm, OFF_ID + 9 * i, shifts, m_d, r_d[0], r_d[1], r_d[2])
    return m_u, m_d, r_u, r_d, I_u, I_d


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _leg_frame(prm, i, t, R):
    """Leg i's geometry as one value, a :data:`LegFrame`: q = R p_i, length L, the frame
    [e y z] (vectors in {B}) and k in that frame (kx, kz).
    docs/physics.md sections 1 and 4.1; paper eqs. 6-8 (q_i, S_i, L_i, e_i) and 15 (T_i).
    """
    p0 = prm[OFF_P + 3 * i]
    p1 = prm[OFF_P + 3 * i + 1]
    p2 = prm[OFF_P + 3 * i + 2]
    q0 = R[0, 0] * p0 + R[0, 1] * p1 + R[0, 2] * p2
    q1 = R[1, 0] * p0 + R[1, 1] * p1 + R[1, 2] * p2
    q2 = R[2, 0] * p0 + R[2, 1] * p1 + R[2, 2] * p2
    s0 = t[0] + q0 - prm[OFF_B + 3 * i]
    s1 = t[1] + q1 - prm[OFF_B + 3 * i + 1]
    s2 = t[2] + q2 - prm[OFF_B + 3 * i + 2]
    L = np.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
    e0 = s0 / L
    e1 = s1 / L
    e2 = s2 / L
    k0 = prm[OFF_K + 3 * i]
    k1 = prm[OFF_K + 3 * i + 1]
    k2 = prm[OFF_K + 3 * i + 2]
    c0, c1, c2 = _cross(k0, k1, k2, e0, e1, e2)
    kz = np.sqrt(c0 * c0 + c1 * c1 + c2 * c2)  # = |k x e| = k . z
    y0 = c0 / kz
    y1 = c1 / kz
    y2 = c2 / kz
    z = _cross(e0, e1, e2, y0, y1, y2)
    kx = k0 * e0 + k1 * e1 + k2 * e2
    return LegFrame((q0, q1, q2), L, (e0, e1, e2), (y0, y1, y2), z, kx, kz)


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _leg_rates(flags, fr, u0, u1, u2):
    """Leg rate and angular velocity from v_P' = (u0, u1, u2), P_i's velocity in {D_i}.

    Returns (Ldot, sigma, w1, w2): omega_l' = (sigma, w1, w2) in {D_i}.
    docs/physics.md section 4.2; paper eqs. 13 (Ldot), 20-21 (w_perp) and 22 (the spin sigma);
    C1 sets sigma = 0 (section 6).
    """
    w1 = -u2 / fr.L
    w2 = u1 / fr.L
    sigma = 0.0 if flags & C1 else fr.kx * w2 / fr.kz
    return u0, sigma, w1, w2


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _leg_accel(flags, fr, Ldot, sigma, w1, w2, A0, A1, A2):
    """Leg acceleration from a_P' = (A0, A1, A2), P_i's acceleration in {D_i}, for the leg's
    rates (Ldot, sigma, w1, w2) of ``_leg_rates``.

    Returns (Lddot, al0, al1, al2): alpha_l' in {D_i}.
    docs/physics.md section 4.3; paper eqs. 14 (Lddot), 23-24 (alpha_perp = (al1, al2)), 26
    (alpha_e = al0) and 27; C1 sets al0 = 0 (section 6).
    """
    L, kx, kz = fr.L, fr.kx, fr.kz
    Lddot = A0 + L * (w1 * w1 + w2 * w2)
    al1 = (-A2 - 2.0 * Ldot * w1) / L + sigma * w2
    al2 = (A1 - 2.0 * Ldot * w2) / L - sigma * w1
    if flags & C1:
        al0 = 0.0
    else:
        al0 = (kx * al2 - (sigma * kx + w2 * kz) * w1) / kz
    return Lddot, al0, al1, al2


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _leg_split(flags, fr, N0, N1, N2, axial):
    """Force of the platform on the leg, in {D_i}, from the leg's moment equation about B_i.

    Solves S x F_s + mu h = N for F_s's part perpendicular to the leg: the row along e fixes mu,
    with h' = (-kz, 0, kx).  With C2 the reaction moment lies along e and that row is dropped.
    ``axial`` is e . F_s from the upper leg's Newton equation.  Linear in (N, axial).
    docs/physics.md sections 5.1 and 6 (C2); paper eqs. 35, 37 (mu), 38 and 40.
    """
    n2 = N2 if flags & C2 else N2 + N0 * fr.kx / fr.kz
    return axial, n2 / fr.L, -N1 / fr.L


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _leg_inertial_force(flags, bodies, fr, Lddot, al0, al1, al2):
    """The part of F_s that is linear in the leg's accelerations (Lddot, alpha_l'), {D_i}.

    The accelerations enter the CoMs' accelerations (a_u = Lddot e + alpha_l x r_u + ...,
    a_d = alpha_l x r_d + ..., a_D = Lddot e + ...) and the Euler terms I alpha_l.
    docs/physics.md sections 5.1-5.2 and 6 (C3); paper eqs. 30-31, 33, 36 and 39 (their
    acceleration terms), 41 and, in the centroidal form, 51.
    """
    m_u, m_d, r_u, r_d, I_u, I_d = bodies
    ru0, ru1, ru2 = r_u
    rd0, rd1, rd2 = r_d
    x0, x1, x2 = _cross(al0, al1, al2, ru0, ru1, ru2)
    au0 = Lddot + x0
    if flags & (CENTROIDAL | C3):
        ad0, ad1, ad2 = _cross(al0, al1, al2, rd0, rd1, rd2)
        t0, t1, t2 = _cross(rd0, rd1, rd2, m_d * ad0, m_d * ad1, m_d * ad2)
        u0, u1, u2 = _cross(ru0, ru1, ru2, m_u * au0, m_u * x1, m_u * x2)
    else:
        t0 = t1 = t2 = 0.0
        u0, u1, u2 = _cross(ru0, ru1, ru2, m_u * Lddot, 0.0, 0.0)
    d0, d1, d2 = _euler(I_d, al0, al1, al2, 0.0, 0.0, 0.0)
    e0, e1, e2 = _euler(I_u, al0, al1, al2, 0.0, 0.0, 0.0)
    return _leg_split(flags, fr, t0 + u0 + d0 + e0, t1 + u1 + d1 + e1, t2 + u2 + d2 + e2, m_u * au0)


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _leg_rate_force(prm, flags, bodies, leg):
    """The part of F_s that does not depend on accelerations, {D_i}: velocity products
    (Coriolis 2 Ldot omega_l x e, centripetal omega_l x (omega_l x r), gyroscopic
    omega_l x I omega_l), gravity and joint friction, for the leg's :data:`LegState` ``leg``.
    docs/physics.md sections 5.1-5.2 and 6 (C3); paper eqs. 30-34, 36 and
    39 (their velocity, gravity and friction terms), 41 and, in the centroidal form, 51."""
    Ldot, w0, w1, w2 = leg.Ldot, leg.sigma, leg.w1, leg.w2
    o0, o1, o2 = leg.omega
    g0, g1, g2 = leg.gravity
    m_u, m_d, r_u, r_d, I_u, I_d = bodies
    ru0, ru1, ru2 = r_u
    rd0, rd1, rd2 = r_d
    ww = w0 * w0 + w1 * w1 + w2 * w2
    # a_D: the upper-leg point at B_i; w x (w x r) = w (w.r) - r |w|^2
    aD1 = 2.0 * Ldot * w2
    aD2 = -2.0 * Ldot * w1
    wr = w0 * ru0 + w1 * ru1 + w2 * ru2
    au0 = w0 * wr - ru0 * ww
    au1 = aD1 + w1 * wr - ru1 * ww
    au2 = aD2 + w2 * wr - ru2 * ww
    if flags & (CENTROIDAL | C3):
        wr = w0 * rd0 + w1 * rd1 + w2 * rd2
        t0, t1, t2 = _cross(rd0, rd1, rd2, m_d * (w0 * wr - rd0 * ww), m_d * (w1 * wr - rd1 * ww),
                            m_d * (w2 * wr - rd2 * ww))
        u0, u1, u2 = _cross(ru0, ru1, ru2, m_u * au0, m_u * au1, m_u * au2)
    else:
        t0 = t1 = t2 = 0.0
        u0, u1, u2 = _cross(ru0, ru1, ru2, 0.0, m_u * aD1, m_u * aD2)
    d0, d1, d2 = _euler(I_d, 0.0, 0.0, 0.0, w0, w1, w2)
    e0, e1, e2 = _euler(I_u, 0.0, 0.0, 0.0, w0, w1, w2)
    gd0, gd1, gd2 = _cross(rd0, rd1, rd2, m_d * g0, m_d * g1, m_d * g2)
    gu0, gu1, gu2 = _cross(ru0, ru1, ru2, m_u * g0, m_u * g1, m_u * g2)
    cu = prm[OFF_DAMP]
    cs = prm[OFF_DAMP + 2]
    return _leg_split(
        flags, leg.frame,
        t0 + u0 + d0 + e0 - gd0 - gu0 + cu * w0 + cs * (w0 - o0),
        t1 + u1 + d1 + e1 - gd1 - gu1 + cu * w1 + cs * (w1 - o1),
        t2 + u2 + d2 + e2 - gd2 - gu2 + cu * w2 + cs * (w2 - o2),
        m_u * (au0 - g0) + prm[OFF_DAMP + 1] * Ldot,
    )


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _leg_force(prm, flags, bodies, leg, A0, A1, A2, F_act):
    """Force of the platform on leg i at P_i, in {D_i}, for P_i's acceleration A' in {D_i}.

    ``bodies`` is ``_leg_bodies``' result, ``leg`` the leg's :data:`LegState`; ``F_act`` the
    actuator force (N), which pushes the upper leg along e.
    Returns (F0, F1, F2): the acceleration part plus the rate part.
    docs/physics.md section 5.1; paper eqs. 38-41 (joint form) and 51 (centroidal form).
    """
    Lddot, al0, al1, al2 = _leg_accel(flags, leg.frame, leg.Ldot, leg.sigma, leg.w1, leg.w2, A0, A1, A2)
    a0, a1, a2 = _leg_inertial_force(flags, bodies, leg.frame, Lddot, al0, al1, al2)
    r0, r1, r2 = _leg_rate_force(prm, flags, bodies, leg)
    return a0 + r0 - F_act, a1 + r1, a2 + r2


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _unit_inertial_force(flags, bodies, fr, A0, A1, A2):
    """The acceleration part of F_s, {D_i}, for a P_i acceleration A' with all rates zero: one
    column of Q_i when A' is a {B} unit vector in {D_i}.  docs/physics.md section 5.4; paper
    eqs. 41 and 47-48."""
    Lddot, al0, al1, al2 = _leg_accel(flags, fr, 0.0, 0.0, 0.0, 0.0, A0, A1, A2)
    return _leg_inertial_force(flags, bodies, fr, Lddot, al0, al1, al2)


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _leg_state(prm, i, flags, t, R, v, w):
    """Leg i's :data:`LegState` in the platform state (t, R, v, w): its frame, its rates
    (Ldot, sigma, w1, w2), and in {D_i} the platform's angular velocity, gravity and the
    velocity part w x (w x q) of P_i's acceleration.
    docs/physics.md sections 4.1-4.2; paper eqs. 6-13 and 20-22.
    """
    fr = _leg_frame(prm, i, t, R)
    q0, q1, q2 = fr.q
    c0, c1, c2 = _cross(w[0], w[1], w[2], q0, q1, q2)
    u0, u1, u2 = _to_leg(fr, v[0] + c0, v[1] + c1, v[2] + c2)
    Ldot, sigma, w1, w2 = _leg_rates(flags, fr, u0, u1, u2)
    a0, a1, a2 = _cross(w[0], w[1], w[2], c0, c1, c2)
    return LegState(fr, Ldot, sigma, w1, w2, _to_leg(fr, w[0], w[1], w[2]),
                    _to_leg(fr, prm[OFF_G], prm[OFF_G + 1], prm[OFF_G + 2]), _to_leg(fr, a0, a1, a2))


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _jacobian_row(fr):
    """Row i of the leg Jacobian, [e_i, q_i x e_i] (dL_i/dt = row . [v; omega]), from the leg's
    frame.  docs/physics.md section 4.4; paper eq. 13."""
    q0, q1, q2 = fr.q
    e0, e1, e2 = fr.e
    m0, m1, m2 = _cross(q0, q1, q2, e0, e1, e2)
    return e0, e1, e2, m0, m1, m2


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _jacobian_one(prm, t, R, J):
    """The leg Jacobian J (6,6) of one platform at pose (t, R), rows [e_i, (R p_i) x e_i].
    docs/physics.md section 4.4; paper eq. 13."""
    for i in range(6):
        J[i, 0], J[i, 1], J[i, 2], J[i, 3], J[i, 4], J[i, 5] = _jacobian_row(_leg_frame(prm, i, t, R))


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _leg_on_platform(prm, flags, i, t, R, v, w, acc, h):
    """Add leg i's pull on the platform to h (6,), {B}: the force of the leg on the platform at
    P_i (minus the force of the platform on the leg, F_s, actuator force excluded) as a wrench
    at P, and the spherical joint's friction torque.  The platform's acceleration acc = [a;
    alpha] enters through P_i's acceleration; ``acc`` None means its velocity part alone (the
    bias of forward dynamics; numba compiles that case without the term).  Returns the leg's
    :data:`LegState` and ``_leg_bodies`` for the caller's own use of the leg.
    The one leg loop body of forward dynamics, its M/h assembly and inverse dynamics.
    docs/physics.md sections 5.1 and 5.4-5.5; paper eqs. 38-41 and 47-49 (or 51 and 55).
    """
    leg = _leg_state(prm, i, flags, t, R, v, w)
    fr = leg.frame
    A = leg.a_vel if acc is None else _with_platform_acc(acc, fr, leg.a_vel)
    bodies = _leg_bodies(prm, i, flags, fr.L)
    f0, f1, f2 = _leg_force(prm, flags, bodies, leg, A[0], A[1], A[2], 0.0)
    fs0, fs1, fs2 = _to_base(fr, f0, f1, f2)
    q0, q1, q2 = fr.q
    m0, m1, m2 = _cross(q0, q1, q2, fs0, fs1, fs2)
    # spherical-joint friction acts on the platform: +Cs (omega_l - omega)
    cs = prm[OFF_DAMP + 2]
    wl0, wl1, wl2 = _to_base(fr, leg.sigma, leg.w1, leg.w2)
    h[0] += fs0
    h[1] += fs1
    h[2] += fs2
    h[3] += m0 - cs * (wl0 - w[0])
    h[4] += m1 - cs * (wl1 - w[1])
    h[5] += m2 - cs * (wl2 - w[2])
    return leg, bodies


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _platform_terms(prm, flags, R, w, M, h):
    """Add the platform's own Newton and Euler terms to M (6,6) and h (6,), {B}.

    Newton rows: m_p a_c - m_p g.  Euler rows (about P): the inertial moment in the chosen form
    minus rho x m_p g.  docs/physics.md sections 5.3-5.4 and 6 (C4); paper eqs. 42-46 (joint
    form) and 52-53 (centroidal form).
    """
    m = prm[OFF_MP]
    r0 = R[0, 0] * prm[OFF_RHO] + R[0, 1] * prm[OFF_RHO + 1] + R[0, 2] * prm[OFF_RHO + 2]
    r1 = R[1, 0] * prm[OFF_RHO] + R[1, 1] * prm[OFF_RHO + 1] + R[1, 2] * prm[OFF_RHO + 2]
    r2 = R[2, 0] * prm[OFF_RHO] + R[2, 1] * prm[OFF_RHO + 1] + R[2, 2] * prm[OFF_RHO + 2]
    g0 = prm[OFF_G]
    g1 = prm[OFF_G + 1]
    g2 = prm[OFF_G + 2]
    # centripetal acceleration of the CoM relative to P: w x (w x rho)
    c0, c1, c2 = _cross(w[0], w[1], w[2], r0, r1, r2)
    cc0, cc1, cc2 = _cross(w[0], w[1], w[2], c0, c1, c2)
    # Newton: m (a + alpha x rho + w x (w x rho)) - m g; alpha x rho = -[rho]x alpha
    for j in range(3):
        M[j, j] += m
    M[0, 4] += m * r2
    M[0, 5] -= m * r1
    M[1, 3] -= m * r2
    M[1, 5] += m * r0
    M[2, 3] += m * r1
    M[2, 4] -= m * r0
    h[0] += m * (cc0 - g0)
    h[1] += m * (cc1 - g1)
    h[2] += m * (cc2 - g2)

    # Euler about P.  In {P} the inertia is constant; shifts counts parallel-axis shifts of I_pc.
    use_com_acc = (flags & (CENTROIDAL | C4)) != 0
    shifts = 1.0 if (flags & C4) or not (flags & CENTROIDAL) else 0.0
    # inertia column j in {B}: R I (R^T e_j); bias w x I w via _euler in {P}
    wp0 = R[0, 0] * w[0] + R[1, 0] * w[1] + R[2, 0] * w[2]
    wp1 = R[0, 1] * w[0] + R[1, 1] * w[1] + R[2, 1] * w[2]
    wp2 = R[0, 2] * w[0] + R[1, 2] * w[1] + R[2, 2] * w[2]
    rp0 = prm[OFF_RHO]
    rp1 = prm[OFF_RHO + 1]
    rp2 = prm[OFF_RHO + 2]
    I_p = _inertia(prm, OFF_IP, shifts, m, rp0, rp1, rp2)
    for j in range(3):
        i0, i1, i2 = _euler(I_p, R[j, 0], R[j, 1], R[j, 2], 0.0, 0.0, 0.0)
        for k in range(3):
            M[3 + k, 3 + j] += R[k, 0] * i0 + R[k, 1] * i1 + R[k, 2] * i2
    b0, b1, b2 = _euler(I_p, 0.0, 0.0, 0.0, wp0, wp1, wp2)
    h[3] += R[0, 0] * b0 + R[0, 1] * b1 + R[0, 2] * b2
    h[4] += R[1, 0] * b0 + R[1, 1] * b1 + R[1, 2] * b2
    h[5] += R[2, 0] * b0 + R[2, 1] * b1 + R[2, 2] * b2
    # rho x m a (body-point form) or rho x m a_c: [rho]x m (a + alpha x rho + w x (w x rho))
    M[3, 1] -= m * r2
    M[3, 2] += m * r1
    M[4, 0] += m * r2
    M[4, 2] -= m * r0
    M[5, 0] -= m * r1
    M[5, 1] += m * r0
    if use_com_acc:
        # -m [rho]x [rho]x = m (|rho|^2 E - rho rho^T)
        rr = r0 * r0 + r1 * r1 + r2 * r2
        rv = (r0, r1, r2)
        for a in range(3):
            for b in range(3):
                M[3 + a, 3 + b] += m * ((rr if a == b else 0.0) - rv[a] * rv[b])
        x0, x1, x2 = _cross(r0, r1, r2, cc0, cc1, cc2)
        h[3] += m * x0
        h[4] += m * x1
        h[5] += m * x2
    x0, x1, x2 = _cross(r0, r1, r2, g0, g1, g2)
    h[3] -= m * x0
    h[4] -= m * x1
    h[5] -= m * x2


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _add_column(M, c, q0, q1, q2, f0, f1, f2):
    """Add the wrench at P of a force f at P_i (q = P_i - P) to column c of M: [f; q x f].

    docs/physics.md section 5.4; paper eqs. 47-48.
    """
    n0, n1, n2 = _cross(q0, q1, q2, f0, f1, f2)
    M[0, c] += f0
    M[1, c] += f1
    M[2, c] += f2
    M[3, c] += n0
    M[4, c] += n1
    M[5, c] += n2


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _solve6(M, b, x):
    """Solve M x = b (6x6) by Gaussian elimination with partial pivoting; M and b are overwritten.

    A singular M gives non-finite x, which callers report.  docs/physics.md section 5.4 (no
    paper equation).
    """
    n = 6
    for c in range(n):
        p = c
        big = abs(M[c, c])
        for r in range(c + 1, n):
            if abs(M[r, c]) > big:
                big = abs(M[r, c])
                p = r
        if p != c:
            for k in range(c, n):
                tmp = M[c, k]
                M[c, k] = M[p, k]
                M[p, k] = tmp
            tmp = b[c]
            b[c] = b[p]
            b[p] = tmp
        piv = M[c, c]
        for r in range(c + 1, n):
            f = M[r, c] / piv
            if f != 0.0:
                for k in range(c + 1, n):
                    M[r, k] -= f * M[c, k]
                b[r] -= f * b[c]
    for c in range(n - 1, -1, -1):
        s = b[c]
        for k in range(c + 1, n):
            s -= M[c, k] * x[k]
        x[c] = s / M[c, c]


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def _assemble_one(prm, flags, t, R, v, w, F, M, h):
    """The equations of motion of one platform, {B}: M (6,6) and h (6,) overwritten with the
    mass matrix and h - J^T F, so that M [a; alpha] + h = W.

    With F = 0, ``h`` is the bias: velocity products, gravity and joint friction.  The actuator
    forces are folded in leg by leg, so forward dynamics needs no second pass over the legs.
    docs/physics.md section 5.4; paper eq. 49 (joint form) or 55 (centroidal form).
    """
    for r in range(6):
        h[r] = 0.0
        for c in range(6):
            M[r, c] = 0.0
    for i in range(6):
        # bias: the leg's pull at zero platform acceleration, actuator force excluded
        leg, bodies = _leg_on_platform(prm, flags, i, t, R, v, w, None, h)
        fr = leg.frame
        e0, e1, e2 = fr.e
        y0, y1, y2 = fr.y
        z0, z1, z2 = fr.z
        q0, q1, q2 = fr.q
        # linear part: Q column j = the acceleration part of the leg force for a_P = unit vector j
        # of {B} (row j of T in {D_i}); with zero rates _leg_accel returns only its linear part
        qa0, qa1, qa2 = _unit_inertial_force(flags, bodies, fr, e0, y0, z0)
        qb0, qb1, qb2 = _unit_inertial_force(flags, bodies, fr, e1, y1, z1)
        qc0, qc1, qc2 = _unit_inertial_force(flags, bodies, fr, e2, y2, z2)
        Qx0, Qx1, Qx2 = _to_base(fr, qa0, qa1, qa2)
        Qy0, Qy1, Qy2 = _to_base(fr, qb0, qb1, qb2)
        Qz0, Qz1, Qz2 = _to_base(fr, qc0, qc1, qc2)
        # a_P = a + alpha x q: column k of a moves P_i by e_k, of alpha by e_k x q
        _add_column(M, 0, q0, q1, q2, Qx0, Qx1, Qx2)
        _add_column(M, 1, q0, q1, q2, Qy0, Qy1, Qy2)
        _add_column(M, 2, q0, q1, q2, Qz0, Qz1, Qz2)
        _add_column(M, 3, q0, q1, q2, Qz0 * q1 - Qy0 * q2, Qz1 * q1 - Qy1 * q2, Qz2 * q1 - Qy2 * q2)
        _add_column(M, 4, q0, q1, q2, Qx0 * q2 - Qz0 * q0, Qx1 * q2 - Qz1 * q0, Qx2 * q2 - Qz2 * q0)
        _add_column(M, 5, q0, q1, q2, Qy0 * q0 - Qx0 * q1, Qy1 * q0 - Qx1 * q1, Qy2 * q0 - Qx2 * q1)
        # actuator force along e_i at P_i moves to the right-hand side J^T F
        j0, j1, j2, j3, j4, j5 = _jacobian_row(fr)
        Fi = F[i]
        h[0] -= Fi * j0
        h[1] -= Fi * j1
        h[2] -= Fi * j2
        h[3] -= Fi * j3
        h[4] -= Fi * j4
        h[5] -= Fi * j5
    _platform_terms(prm, flags, R, w, M, h)


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def _forward_one(prm, flags, t, R, v, w, F, W, M, h, out):
    """Forward dynamics of one platform: out[:3] = a, out[3:] = alpha, {B}.

    M (6,6) and h (6,) are scratch.  Assembles M [a; alpha] + h = J^T F + W and solves it.
    docs/physics.md section 5.4; paper eq. 49 (joint form) or 55 (centroidal form).
    """
    _assemble_one(prm, flags, t, R, v, w, F, M, h)
    for r in range(6):
        h[r] = W[r] - h[r]
    _solve6(M, h, out)


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def _inverse_one(prm, flags, t, R, v, w, acc, W, M, h, out):
    """Inverse dynamics of one platform: leg forces ``out`` (6,) for acc = [a; alpha], {B}.

    Each leg's force on the platform follows from its own equations at the given acceleration;
    the platform's six equations then fix the six actuator forces through J^T F = wrench.
    M (6,6) and h (6,) are scratch.  docs/physics.md section 5.5; paper eq. 49 (joint form) or
    55 (centroidal form) solved for the forces.
    """
    for r in range(6):
        h[r] = 0.0
        for c in range(6):
            M[r, c] = 0.0
    for i in range(6):
        leg, _ = _leg_on_platform(prm, flags, i, t, R, v, w, acc, h)
        # column i of J^T
        M[0, i], M[1, i], M[2, i], M[3, i], M[4, i], M[5, i] = _jacobian_row(leg.frame)
    # the platform's own inertial and gravity terms at this acceleration, via its M and h
    Mp = np.zeros((6, 6))
    _platform_terms(prm, flags, R, w, Mp, h)
    for r in range(6):
        total = h[r] - W[r]
        for c in range(6):
            total += Mp[r, c] * acc[c]
        h[r] = total
    _solve6(M, h, out)


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def _leg_kinematics_one(prm, flags, t, R, v, w, acc, frames, lengths, rates, accels,
                        omega_l, alpha_l, jac):
    """Leg kinematics of one platform, {B}: frames (6,3,3) T_i = [e y z] as columns, lengths (6,),
    rates (6,), accels (6,), omega_l (6,3), alpha_l (6,3), jac (6,6) rows [e_i, q_i x e_i].
    docs/physics.md section 4; paper eqs. 6-27."""
    for i in range(6):
        leg = _leg_state(prm, i, flags, t, R, v, w)
        fr = leg.frame
        A0, A1, A2 = _with_platform_acc(acc, fr, leg.a_vel)
        Lddot, al0, al1, al2 = _leg_accel(flags, fr, leg.Ldot, leg.sigma, leg.w1, leg.w2, A0, A1, A2)
        for r in range(3):
            frames[i, r, 0] = fr.e[r]
            frames[i, r, 1] = fr.y[r]
            frames[i, r, 2] = fr.z[r]
        lengths[i] = fr.L
        rates[i] = leg.Ldot
        accels[i] = Lddot
        omega_l[i, 0], omega_l[i, 1], omega_l[i, 2] = _to_base(fr, leg.sigma, leg.w1, leg.w2)
        alpha_l[i, 0], alpha_l[i, 1], alpha_l[i, 2] = _to_base(fr, al0, al1, al2)
        jac[i, 0], jac[i, 1], jac[i, 2], jac[i, 3], jac[i, 4], jac[i, 5] = _jacobian_row(fr)


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _params_row(prm, b):
    """The packed parameters of batch row b: ``prm``'s row b, or its only row, which then serves
    every row of the batch.  docs/physics.md section 2 (no paper equation)."""
    return prm[0] if prm.shape[0] == 1 else prm[b]


@njit(cache=True, parallel=True, error_model="numpy", fastmath=FASTMATH)
def forward_batch(prm, flags, t, R, v, w, F, W, out):
    """Forward dynamics over a batch.  prm (Np, N_PARAMS) with Np in {1, N}; t, v, w (N,3);
    R (N,3,3); F (N,6) N; W (N,6) external wrench [F_ext; M_ext] at P, {B}; out (N,6) [a; alpha].
    docs/physics.md section 5.4; paper eq. 49 or 55."""
    n = t.shape[0]
    if n >= PARALLEL_MIN_ROWS:
        for b in prange(n):
            _forward_row(prm, flags, t, R, v, w, F, W, out, b)
    else:
        for b in range(n):
            _forward_row(prm, flags, t, R, v, w, F, W, out, b)


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def _forward_row(prm, flags, t, R, v, w, F, W, out, b):
    """Row b of ``forward_batch`` (docs/physics.md section 5.4; paper eq. 49 or 55)."""
    M = np.empty((6, 6))
    h = np.empty(6)
    _forward_one(_params_row(prm, b), flags, t[b], R[b], v[b], w[b], F[b], W[b], M, h, out[b])


@njit(cache=True, parallel=True, error_model="numpy", fastmath=FASTMATH)
def mass_bias_batch(prm, flags, t, R, v, w, W, M, h):
    """Mass matrix M (N,6,6) and bias h (N,6) over a batch, so that M [a; alpha] + h = J^T F:
    the assembly of ``forward_batch`` at F = 0, with the external wrench W (N,6) moved into h.
    docs/physics.md section 5.4; paper eq. 49 or 55.
    """
    n = t.shape[0]
    if n >= PARALLEL_MIN_ROWS:
        for b in prange(n):
            _mass_bias_row(prm, flags, t, R, v, w, W, M, h, b)
    else:
        for b in range(n):
            _mass_bias_row(prm, flags, t, R, v, w, W, M, h, b)


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def _mass_bias_row(prm, flags, t, R, v, w, W, M, h, b):
    """Row b of ``mass_bias_batch`` (docs/physics.md section 5.4; paper eq. 49 or 55)."""
    _assemble_one(_params_row(prm, b), flags, t[b], R[b], v[b], w[b], np.zeros(6), M[b], h[b])
    for r in range(6):
        h[b, r] -= W[b, r]


@njit(cache=True, parallel=True, error_model="numpy", fastmath=FASTMATH)
def inverse_batch(prm, flags, t, R, v, w, acc, W, out):
    """Inverse dynamics over a batch: acc (N,6) [a; alpha] -> out (N,6) leg forces, N.

    docs/physics.md section 5.5; paper eq. 49 or 55 solved for the forces.
    """
    n = t.shape[0]
    if n >= PARALLEL_MIN_ROWS:
        for b in prange(n):
            _inverse_row(prm, flags, t, R, v, w, acc, W, out, b)
    else:
        for b in range(n):
            _inverse_row(prm, flags, t, R, v, w, acc, W, out, b)


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def _inverse_row(prm, flags, t, R, v, w, acc, W, out, b):
    """Row b of ``inverse_batch`` (docs/physics.md section 5.5; paper eq. 49 or 55)."""
    M = np.empty((6, 6))
    h = np.empty(6)
    _inverse_one(_params_row(prm, b), flags, t[b], R[b], v[b], w[b], acc[b], W[b], M, h, out[b])


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def leg_kinematics_batch(prm, flags, t, R, v, w, acc, frames, lengths, rates, accels,
                         omega_l, alpha_l, jac):
    """Leg kinematics over a batch (shapes of ``_leg_kinematics_one`` with a leading N).

    Serial: it serves analysis and tests, not the per-step path.  docs/physics.md section 4;
    paper eqs. 6-27."""
    n = t.shape[0]
    for b in range(n):
        _leg_kinematics_one(_params_row(prm, b), flags, t[b], R[b], v[b], w[b], acc[b],
                            frames[b], lengths[b], rates[b], accels[b], omega_l[b], alpha_l[b], jac[b])


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def jacobian_batch(prm, t, R, J):
    """The leg Jacobian J (N,6,6) of each pose (t (N,3), R (N,3,3)): ``_jacobian_one`` over a
    batch, serial.  docs/physics.md section 4.4; paper eq. 13."""
    for b in range(t.shape[0]):
        _jacobian_one(_params_row(prm, b), t[b], R[b], J[b])


@njit(cache=True, error_model="numpy", fastmath=FASTMATH, inline="always")
def _rotation_error(A):
    """How far one 3x3 matrix A is from a rotation: (largest entry of |A^T A - I|, det A).

    docs/physics.md section 1 (no paper equation)."""
    worst = 0.0
    for i in range(3):
        for j in range(3):
            g = A[0, i] * A[0, j] + A[1, i] * A[1, j] + A[2, i] * A[2, j] - (1.0 if i == j else 0.0)
            worst = max(worst, abs(g))
    det = (A[0, 0] * (A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1])
           - A[0, 1] * (A[1, 0] * A[2, 2] - A[1, 2] * A[2, 0])
           + A[0, 2] * (A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]))
    return worst, det


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def rotation_errors_batch(R, orth, det):
    """How far each matrix of R (N,3,3) is from a rotation: orth (N,) the largest entry of
    |R^T R - I| and det (N,) its determinant.  Returns the largest of all orth and |det - 1|.
    docs/physics.md section 1 (no paper equation)."""
    largest = 0.0
    for b in range(R.shape[0]):
        orth[b], det[b] = _rotation_error(R[b])
        largest = max(largest, orth[b], abs(det[b] - 1.0))
    return largest


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def largest_rotation_error(R):
    """The largest |R^T R - I| entry or |det R - 1| over R (N,3,3), without output arrays: the
    argument check of a single-platform call costs a fraction of a microsecond this way.
    docs/physics.md section 1 (no paper equation)."""
    largest = 0.0
    for b in range(R.shape[0]):
        orth, det = _rotation_error(R[b])
        largest = max(largest, orth, abs(det - 1.0))
    return largest


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def first_nonfinite(arrays):
    """Position in the tuple ``arrays`` of the first array holding a NaN or inf, or -1: the
    finiteness check of every argument in one compiled call (numpy's isfinite(x).all() costs
    2 us on a 3-vector, and this checks all six arguments of a call in 0.6 us).
    docs/physics.md section 1 (no paper equation)."""
    k = 0
    for a in literal_unroll(arrays):
        for x in a.flat:
            if not np.isfinite(x):
                return k
        k += 1
    return -1


@njit(cache=True, parallel=True, error_model="numpy", fastmath=FASTMATH)
def leg_sensors_batch(prm, t, R, v, w, max_condition, lengths, rates, condition):
    """What the environment checks after each control step, over a batch: leg lengths (N,6) m,
    leg rates (N,6) m/s and the Jacobian's condition number (N,) against ``max_condition``.

    ``condition`` is the 2-norm condition number wherever it exceeds ``max_condition`` (inf when
    singular or non-finite); below it, the cheaper bound ||J||_F ||J^-1||_F >= cond_2, itself
    at most ``max_condition``.  So ``condition > max_condition`` holds exactly when cond_2 does.
    docs/physics.md section 4.4; paper eqs. 7 and 13.
    """
    n = t.shape[0]
    if n >= PARALLEL_MIN_ROWS:
        for b in prange(n):
            _leg_sensors_row(prm, t, R, v, w, max_condition, lengths, rates, condition, b)
    else:
        for b in range(n):
            _leg_sensors_row(prm, t, R, v, w, max_condition, lengths, rates, condition, b)


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def _leg_sensors_row(prm, t, R, v, w, max_condition, lengths, rates, condition, b):
    """Row b of ``leg_sensors_batch`` (docs/physics.md section 4.4; paper eqs. 7 and 13)."""
    p = _params_row(prm, b)
    jac = np.empty((6, 6))
    for i in range(6):
        leg = _leg_state(p, i, 0, t[b], R[b], v[b], w[b])
        lengths[b, i] = leg.frame.L
        rates[b, i] = leg.Ldot
        jac[i, 0], jac[i, 1], jac[i, 2], jac[i, 3], jac[i, 4], jac[i, 5] = _jacobian_row(leg.frame)
    bound = _frobenius_condition(jac)
    if bound <= max_condition:
        condition[b] = bound
    elif np.isfinite(bound):
        sv = np.linalg.svd(jac)[1]
        condition[b] = sv[0] / sv[5] if sv[5] > 0.0 else np.inf
    else:
        condition[b] = np.inf


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def _frobenius_condition(J):
    """||J||_F ||J^-1||_F of a 6x6 matrix, an upper bound of its 2-norm condition number (inf
    or NaN when J is singular or not finite).  docs/physics.md section 4.4 (no paper equation)."""
    M = np.empty((6, 6))
    e = np.empty(6)
    x = np.empty(6)
    norm = 0.0
    for i in range(6):
        for j in range(6):
            norm += J[i, j] * J[i, j]
    inv_norm = 0.0
    for k in range(6):
        M[:, :] = J
        e[:] = 0.0
        e[k] = 1.0
        _solve6(M, e, x)
        for j in range(6):
            inv_norm += x[j] * x[j]
    return np.sqrt(norm * inv_norm)
