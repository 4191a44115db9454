// The one implementation of the Stewart platform's kinematics and dynamics.
//
// Everything physical in the package runs through the functions here; the Python classes around
// them only check arguments and pick a kernel.  docs/physics.md in the repository is the full
// account of the physics: frames, parameters, a table of every symbol used below beside the
// paper's, the derivations and the tests that decide correctness.  Each function's comment names
// the section of that page and the equations of He et al. (2018) it implements.
//
// Conventions (docs/physics.md section 1)
// * {B} base frame, fixed.  {P} platform frame: origin P at t, orientation R (columns = {P} axes
//   in {B}).  Velocity v of P's origin, angular velocity w, linear acceleration a of P's origin
//   and angular acceleration alpha: all in {B}.
// * Leg i joins base joint B_i (b_i in {B}) to platform joint P_i (p_i in {P}).
//   S_i = t + R p_i - b_i, L_i = |S_i|, e_i = S_i / L_i.
// * U joint at B_i: fixed axis k_i, moving axis y_i = unit(k_i x e_i), z_i = e_i x y_i.  The leg
//   frame {D_i} = [e_i, y_i, z_i] moves with both leg parts.
// * Actuator force F_i > 0 extends the leg; F_s is the force of the platform on the leg at P_i.
//
// Why the leg is worked in its own frame: in {D_i} (a prime marks components in that frame) the
// leg axis is (1, 0, 0), the U joint's moving axis is (0, 1, 0), the fixed axis is
// k' = (kx, 0, kz) with kz = |k x e| > 0, and the normal of the U joint's axis plane is
// h' = k' x y' = (-kz, 0, kx).  The leg inertias and CoM offsets are constants in this frame, so
// the per-leg equations reduce to a few dozen scalar products and nothing is rotated or allocated.
//
// Map of the kernels
// * Leg kinematics (section 4): leg_frame gives a leg's geometry as one value, a LegFrame;
//   leg_state adds its rates (leg_rates) and the platform's motion seen in the leg frame, a
//   LegState; leg_accel; the Jacobian row jacobian_row.
// * One leg's force on the platform (sections 5.1-5.2): leg_bodies, leg_inertial_force,
//   leg_rate_force, leg_split, leg_force.  The leg's moment equation about B_i is
//   S x F_s + mu h = N; its row along e fixes mu and the rest gives F_s perpendicular to the leg;
//   Newton's law for the upper leg along e gives e . F_s.
// * The platform (section 5.3): platform_terms.
// * Forward dynamics M [a; alpha] + h = J^T F + W (section 5.4): assemble_one builds M and h (the
//   columns of each leg's Q_i from unit_inertial_force), which forward_one solves and
//   mass_bias_batch returns; inverse dynamics (section 5.5): inverse_one.  Both run the same leg
//   loop body, leg_on_platform.  RK4 (section 5.6): rk4.hpp, built on forward_one.
//
// The model switches (switch bits, section 6)
// * C1 (bit 1), no leg spin: sigma = 0 and alpha_l = (e x a_P - 2 Ldot w_perp) / L.
// * C2 (bit 2), U-joint reaction moment along e instead of h: the axial component of the leg
//   moment equation is dropped instead of being balanced by mu h.
// * C3 (bit 4), legs: shifted inertias I_B used together with r x m a_c, so the parallel-axis
//   part is counted twice.
// * C4 (bit 8), platform: the same double count, I_P together with rho x m_p a_c.
// CENTROIDAL (bit 16) selects the centroidal form (paper eq. 55) instead of the joint form
// (eq. 49).  With C3 (C4) both forms use the same double-counted expression for the legs
// (platform).
//
// Arrays are C-contiguous float64: a vector of three is a pointer to three doubles, a 3x3 or 6x6
// matrix is row-major.  Each *_batch function loops over the rows of a batch and hands them to a
// *_row function, eight at a time in the lanes of a vector where it can (lanes.hpp: the kernels are
// templates over their number type); a row's arithmetic does not depend on the batch size.
//
// Packed parameters: kernels take prm of shape (Np, N_PARAMS), one row per platform (Np == 1
// broadcasts over the batch).  PACKED_LAYOUT below lists the entries (docs/physics.md section 2);
// the OFF_* offsets and stewart_env.dynamics.model.pack_params follow from it.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

#include "physics/lanes.hpp"

namespace kernels {

template <typename T = double>
using V3 = std::array<T, 3>;
//: A symmetric inertia (xx, yy, zz, xy, xz, yz).
template <typename T = double>
using Inertia = std::array<T, 6>;
template <typename T = double>
using Row6 = std::array<T, 6>;

//: How the small kernels below take a number: by value where it fits a vector register (double,
//: Lanes), by reference where it does not (a dual number, in lanes most of a kilobyte, whose copy
//: would cost more than its use).
template <typename T>
using Arg = std::conditional_t<(sizeof(T) <= 64), T, const T&>;

constexpr int64_t C1 = 1;
constexpr int64_t C2 = 2;
constexpr int64_t C3 = 4;
constexpr int64_t C4 = 8;
constexpr int64_t CENTROIDAL = 16;

//: One entry of the packed parameter row: its config key and shape (ndim 0-3).
struct LayoutEntry {
    const char* key;
    int ndim;
    int shape[3];
};

//: The packed parameter row, in order: (config key, shape).  The one source of the layout: the
//: offsets below, model.pack_params and Randomization.scale_packed follow it, and
//: docs/physics.md section 2 lists each key.  Leg entries hold six legs; frames as in section 2.
constexpr LayoutEntry PACKED_LAYOUT[] = {
    {"base_joints", 2, {6, 3, 0}},           // b_i, {B}
    {"platform_joints", 2, {6, 3, 0}},       // p_i, {P}
    {"hooke_axes", 2, {6, 3, 0}},            // unit k_i, {B}
    {"platform.mass", 0, {0, 0, 0}},         // m_p
    {"platform.com", 1, {3, 0, 0}},          // R_0, {P}
    {"platform.inertia", 2, {3, 3, 0}},      // about the CoM, {P}
    {"upper_leg.mass", 1, {6, 0, 0}},        // m_u
    {"upper_leg.com", 2, {6, 3, 0}},         // r_u0 from P_i, {D_i}
    {"upper_leg.inertia", 3, {6, 3, 3}},     // about the CoM, {D_i}
    {"lower_leg.mass", 1, {6, 0, 0}},        // m_d
    {"lower_leg.com", 2, {6, 3, 0}},         // r_d0 from B_i, {D_i}
    {"lower_leg.inertia", 3, {6, 3, 3}},     // about the CoM, {D_i}
    {"damping", 1, {3, 0, 0}},               // C_u, C_p, C_s
    {"gravity", 1, {3, 0, 0}},               // g, {B}
};
constexpr int N_LAYOUT = sizeof(PACKED_LAYOUT) / sizeof(PACKED_LAYOUT[0]);

// Number of floats of one layout entry.  docs/physics.md section 2 (no paper equation).
constexpr int entry_size(const LayoutEntry& entry) {
    int size = 1;
    for (int d = 0; d < entry.ndim; ++d) size *= entry.shape[d];
    return size;
}

// Where entry k of PACKED_LAYOUT starts in the packed row (k == N_LAYOUT: the row's length).
// docs/physics.md section 2 (no paper equation).
constexpr int offset_of(int k) {
    int start = 0;
    for (int j = 0; j < k; ++j) start += entry_size(PACKED_LAYOUT[j]);
    return start;
}

constexpr int N_PARAMS = offset_of(N_LAYOUT);
constexpr int OFF_B = offset_of(0);
constexpr int OFF_P = offset_of(1);
constexpr int OFF_K = offset_of(2);
constexpr int OFF_MP = offset_of(3);
constexpr int OFF_RHO = offset_of(4);
constexpr int OFF_IP = offset_of(5);
constexpr int OFF_MU = offset_of(6);
constexpr int OFF_RU = offset_of(7);
constexpr int OFF_IU = offset_of(8);
constexpr int OFF_MD = offset_of(9);
constexpr int OFF_RD = offset_of(10);
constexpr int OFF_ID = offset_of(11);
constexpr int OFF_DAMP = offset_of(12);
constexpr int OFF_G = offset_of(13);

//: One leg's geometry (docs/physics.md sections 1 and 4.1), the value leg_frame returns and the
//: per-leg helpers take: q = R p_i, length L, the unit vectors e, y, z of the leg frame {D_i}
//: (in {B}), and the fixed U-joint axis k in {D_i}, (kx, 0, kz) with kz > 0.
template <typename T = double>
struct LegFrame {
    V3<T> q;
    T L;
    V3<T> e, y, z;
    T kx, kz;
};

//: One leg's motion in the platform's state (sections 4.1-4.2), leg_state's value: its LegFrame<T>;
//: the rates Ldot, spin sigma and angular velocity (w1, w2) about y and z; and in {D_i} the
//: platform's angular velocity omega, gravity and a_vel, the part w x (w x q) of P_i's
//: acceleration that does not depend on the platform's acceleration.
template <typename T = double>
struct LegState {
    LegFrame<T> frame;
    T Ldot, sigma, w1, w2;
    V3<T> omega, gravity, a_vel;
};

//: One leg's mass properties (leg_bodies' value): m_u, m_d, the CoMs r_u, r_d from B_i and the
//: inertias I_u, I_d, all in {D_i}.
template <typename T = double>
struct LegBodies {
    T m_u, m_d;
    V3<T> r_u, r_d;
    Inertia<T> I_u, I_d;
};

//: The leg's rates (leg_rates' value): Ldot, sigma, w1, w2.
template <typename T = double>
struct LegRates {
    T Ldot, sigma, w1, w2;
};

//: The leg's accelerations (leg_accel's value): Lddot and alpha_l' = (al0, al1, al2) in {D_i}.
template <typename T = double>
struct LegAccel {
    T Lddot, al0, al1, al2;
};

// Components of a x b (docs/physics.md section 3.2; no paper equation).
template <typename T>
inline V3<T> cross(Arg<T> a0, Arg<T> a1, Arg<T> a2, Arg<T> b0, Arg<T> b1, Arg<T> b2) {
    return {a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0};
}

// {B} components of a vector given in the leg frame fr = [e y z]: u = T_i u'.
// docs/physics.md section 1; paper eq. 15 (T_i).
template <typename T>
inline V3<T> to_base(const LegFrame<T>& fr, Arg<T> u0, Arg<T> u1, Arg<T> u2) {
    const auto& [e0, e1, e2] = fr.e;
    const auto& [y0, y1, y2] = fr.y;
    const auto& [z0, z1, z2] = fr.z;
    return {u0 * e0 + u1 * y0 + u2 * z0, u0 * e1 + u1 * y1 + u2 * z1, u0 * e2 + u1 * y2 + u2 * z2};
}

// Leg-frame components (u . e, u . y, u . z) of a vector given in {B}: u' = T_i^T u.
// docs/physics.md section 1; paper eq. 15 (T_i).
template <typename T>
inline V3<T> to_leg(const LegFrame<T>& fr, Arg<T> u0, Arg<T> u1, Arg<T> u2) {
    const auto& [e0, e1, e2] = fr.e;
    const auto& [y0, y1, y2] = fr.y;
    const auto& [z0, z1, z2] = fr.z;
    return {u0 * e0 + u1 * e1 + u2 * e2, u0 * y0 + u1 * y1 + u2 * y2, u0 * z0 + u1 * z1 + u2 * z2};
}

// P_i's acceleration in {D_i}: the velocity part A' plus a + alpha x q for acc = [a; alpha].
// docs/physics.md section 4.1; paper eqs. 10-12 (a_Pi).
template <typename T>
inline V3<T> with_platform_acc(const T* acc, const LegFrame<T>& fr, const V3<T>& A) {
    const auto& [q0, q1, q2] = fr.q;
    auto [x0, x1, x2] = cross<T>(acc[3], acc[4], acc[5], q0, q1, q2);
    x0 += acc[0];
    x1 += acc[1];
    x2 += acc[2];
    const auto [d0, d1, d2] = to_leg<T>(fr, x0, x1, x2);
    return {A[0] + d0, A[1] + d1, A[2] + d2};
}

// Inertia<T> I = I_c + s m (|r|^2 E - r r^T) as (Ixx, Iyy, Izz, Ixy, Ixz, Iyz).
// I_c is the 3x3 at prm[off:off+9]; s counts parallel-axis shifts (the callers pass 0 or 1).
// docs/physics.md sections 5.2 and 6 (C3, C4); the paper's shifted inertias before eq. 32 and
// eq. 44, its CoM inertias eqs. 50 and 52.
template <typename T>
inline Inertia<T> inertia(const T* prm, int off, Arg<T> s, Arg<T> m, Arg<T> r0, Arg<T> r1, Arg<T> r2) {
    const T rr = r0 * r0 + r1 * r1 + r2 * r2;
    const T sm = s * m;
    return {
        prm[off + 0] + sm * (rr - r0 * r0),
        prm[off + 4] + sm * (rr - r1 * r1),
        prm[off + 8] + sm * (rr - r2 * r2),
        prm[off + 1] - sm * r0 * r1,
        prm[off + 2] - sm * r0 * r2,
        prm[off + 5] - sm * r1 * r2,
    };
}

// Inertial moment I alpha + w x (I w) of a symmetric inertia I = (xx, yy, zz, xy, xz, yz).
// docs/physics.md sections 5.2-5.3; the Euler terms of paper eqs. 32, 46, 50 and 53.
template <typename T>
inline V3<T> euler(const Inertia<T>& I, Arg<T> a0, Arg<T> a1, Arg<T> a2, Arg<T> w0, Arg<T> w1, Arg<T> w2) {
    const auto& [i00, i11, i22, i01, i02, i12] = I;
    const T iw0 = i00 * w0 + i01 * w1 + i02 * w2;
    const T iw1 = i01 * w0 + i11 * w1 + i12 * w2;
    const T iw2 = i02 * w0 + i12 * w1 + i22 * w2;
    const auto [c0, c1, c2] = cross<T>(w0, w1, w2, iw0, iw1, iw2);
    return {
        i00 * a0 + i01 * a1 + i02 * a2 + c0,
        i01 * a0 + i11 * a1 + i12 * a2 + c1,
        i02 * a0 + i12 * a1 + i22 * a2 + c2,
    };
}

// Leg i's mass properties at length L, in {D_i}: (m_u, m_d, r_u, r_d, I_u, I_d).
// r_u, r_d are the CoMs from B_i; I_u, I_d the inertias used in the moment equation about B_i:
// about the CoM (centroidal form), shifted to B_i (eq. 49 form), or shifted once more than the
// form needs (C3).  docs/physics.md sections 4.3 (CoMs), 5.2 and 6 (C3); paper eqs. 28-29
// (r_u, r_d), the inertias about B_i before eq. 32 and about the CoM in eq. 50.
template <typename T>
inline LegBodies<T> leg_bodies(const T* prm, int i, int64_t flags, Arg<T> L) {
    const T m_u = prm[OFF_MU + i];
    const T m_d = prm[OFF_MD + i];
    const V3<T> r_u = {L + prm[OFF_RU + 3 * i], prm[OFF_RU + 3 * i + 1], prm[OFF_RU + 3 * i + 2]};
    const V3<T> r_d = {prm[OFF_RD + 3 * i], prm[OFF_RD + 3 * i + 1], prm[OFF_RD + 3 * i + 2]};
    T shifts;
    if (flags & (CENTROIDAL | C3)) {
        shifts = (flags & C3) ? 1.0 : 0.0;
    } else {
        shifts = 1.0;
    }
    const Inertia<T> I_u = inertia<T>(prm, OFF_IU + 9 * i, shifts, m_u, r_u[0], r_u[1], r_u[2]);
    const Inertia<T> I_d = inertia<T>(prm, OFF_ID + 9 * i, shifts, m_d, r_d[0], r_d[1], r_d[2]);
    return {m_u, m_d, r_u, r_d, I_u, I_d};
}

// Leg i's geometry as one value, a LegFrame<T>: q = R p_i, length L, the frame [e y z] (vectors in
// {B}) and k in that frame (kx, kz).
// docs/physics.md sections 1 and 4.1; paper eqs. 6-8 (q_i, S_i, L_i, e_i) and 15 (T_i).
template <typename T>
inline LegFrame<T> leg_frame(const T* prm, int i, const T* t, const T* R) {
    const T p0 = prm[OFF_P + 3 * i];
    const T p1 = prm[OFF_P + 3 * i + 1];
    const T p2 = prm[OFF_P + 3 * i + 2];
    const T q0 = R[0] * p0 + R[1] * p1 + R[2] * p2;
    const T q1 = R[3] * p0 + R[4] * p1 + R[5] * p2;
    const T q2 = R[6] * p0 + R[7] * p1 + R[8] * p2;
    const T s0 = t[0] + q0 - prm[OFF_B + 3 * i];
    const T s1 = t[1] + q1 - prm[OFF_B + 3 * i + 1];
    const T s2 = t[2] + q2 - prm[OFF_B + 3 * i + 2];
    const T L = lanes::sqrt_of(s0 * s0 + s1 * s1 + s2 * s2);
    const T e0 = s0 / L;
    const T e1 = s1 / L;
    const T e2 = s2 / L;
    const T k0 = prm[OFF_K + 3 * i];
    const T k1 = prm[OFF_K + 3 * i + 1];
    const T k2 = prm[OFF_K + 3 * i + 2];
    const auto [c0, c1, c2] = cross<T>(k0, k1, k2, e0, e1, e2);
    const T kz = lanes::sqrt_of(c0 * c0 + c1 * c1 + c2 * c2);  // = |k x e| = k . z
    const T y0 = c0 / kz;
    const T y1 = c1 / kz;
    const T y2 = c2 / kz;
    const V3<T> z = cross<T>(e0, e1, e2, y0, y1, y2);
    const T kx = k0 * e0 + k1 * e1 + k2 * e2;
    return {{q0, q1, q2}, L, {e0, e1, e2}, {y0, y1, y2}, z, kx, kz};
}

// Leg rate and angular velocity from v_P' = (u0, u1, u2), P_i's velocity in {D_i}.
// Returns (Ldot, sigma, w1, w2): omega_l' = (sigma, w1, w2) in {D_i}.
// docs/physics.md section 4.2; paper eqs. 13 (Ldot), 20-21 (w_perp) and 22 (the spin sigma);
// C1 sets sigma = 0 (section 6).
template <typename T>
inline LegRates<T> leg_rates(int64_t flags, const LegFrame<T>& fr, Arg<T> u0, Arg<T> u1, Arg<T> u2) {
    const T w1 = -u2 / fr.L;
    const T w2 = u1 / fr.L;
    const T sigma = (flags & C1) ? 0.0 : fr.kx * w2 / fr.kz;
    return {u0, sigma, w1, w2};
}

// Leg acceleration from a_P' = (A0, A1, A2), P_i's acceleration in {D_i}, for the leg's rates
// (Ldot, sigma, w1, w2) of leg_rates.
// Returns (Lddot, al0, al1, al2): alpha_l' in {D_i}.
// docs/physics.md section 4.3; paper eqs. 14 (Lddot), 23-24 (alpha_perp = (al1, al2)), 26
// (alpha_e = al0) and 27; C1 sets al0 = 0 (section 6).
template <typename T>
inline LegAccel<T> leg_accel(int64_t flags, const LegFrame<T>& fr, Arg<T> Ldot, Arg<T> sigma, Arg<T> w1, Arg<T> w2,
                          Arg<T> A0, Arg<T> A1, Arg<T> A2) {
    const Arg<T> L = fr.L, kx = fr.kx, kz = fr.kz;
    const T Lddot = A0 + L * (w1 * w1 + w2 * w2);
    const T al1 = (-A2 - 2.0 * Ldot * w1) / L + sigma * w2;
    const T al2 = (A1 - 2.0 * Ldot * w2) / L - sigma * w1;
    T al0;
    if (flags & C1) {
        al0 = 0.0;
    } else {
        al0 = (kx * al2 - (sigma * kx + w2 * kz) * w1) / kz;
    }
    return {Lddot, al0, al1, al2};
}

// Force of the platform on the leg, in {D_i}, from the leg's moment equation about B_i.
// Solves S x F_s + mu h = N for F_s's part perpendicular to the leg: the row along e fixes mu,
// with h' = (-kz, 0, kx).  With C2 the reaction moment lies along e and that row is dropped.
// axial is e . F_s from the upper leg's Newton equation.  Linear in (N, axial).
// docs/physics.md sections 5.1 and 6 (C2); paper eqs. 35, 37 (mu), 38 and 40.
template <typename T>
inline V3<T> leg_split(int64_t flags, const LegFrame<T>& fr, Arg<T> N0, Arg<T> N1, Arg<T> N2, Arg<T> axial) {
    const T n2 = (flags & C2) ? N2 : N2 + N0 * fr.kx / fr.kz;
    return {axial, n2 / fr.L, -N1 / fr.L};
}

// The part of F_s that is linear in the leg's accelerations (Lddot, alpha_l'), {D_i}.
// The accelerations enter the CoMs' accelerations (a_u = Lddot e + alpha_l x r_u + ...,
// a_d = alpha_l x r_d + ..., a_D = Lddot e + ...) and the Euler terms I alpha_l.
// docs/physics.md sections 5.1-5.2 and 6 (C3); paper eqs. 30-31, 33, 36 and 39 (their
// acceleration terms), 41 and, in the centroidal form, 51.
template <typename T>
inline V3<T> leg_inertial_force(int64_t flags, const LegBodies<T>& bodies, const LegFrame<T>& fr, Arg<T> Lddot,
                             Arg<T> al0, Arg<T> al1, Arg<T> al2) {
    const Arg<T> m_u = bodies.m_u, m_d = bodies.m_d;
    const auto& [ru0, ru1, ru2] = bodies.r_u;
    const auto& [rd0, rd1, rd2] = bodies.r_d;
    const auto [x0, x1, x2] = cross<T>(al0, al1, al2, ru0, ru1, ru2);
    const T au0 = Lddot + x0;
    V3<T> t, u;
    if (flags & (CENTROIDAL | C3)) {
        const auto [ad0, ad1, ad2] = cross<T>(al0, al1, al2, rd0, rd1, rd2);
        t = cross<T>(rd0, rd1, rd2, m_d * ad0, m_d * ad1, m_d * ad2);
        u = cross<T>(ru0, ru1, ru2, m_u * au0, m_u * x1, m_u * x2);
    } else {
        t = {0.0, 0.0, 0.0};
        u = cross<T>(ru0, ru1, ru2, m_u * Lddot, 0.0, 0.0);
    }
    const auto [d0, d1, d2] = euler<T>(bodies.I_d, al0, al1, al2, 0.0, 0.0, 0.0);
    const auto [e0, e1, e2] = euler<T>(bodies.I_u, al0, al1, al2, 0.0, 0.0, 0.0);
    return leg_split<T>(flags, fr, t[0] + u[0] + d0 + e0, t[1] + u[1] + d1 + e1, t[2] + u[2] + d2 + e2, m_u * au0);
}

// The part of F_s that does not depend on accelerations, {D_i}: velocity products (Coriolis
// 2 Ldot omega_l x e, centripetal omega_l x (omega_l x r), gyroscopic omega_l x I omega_l),
// gravity and joint friction, for the leg's LegState<T> leg.
// docs/physics.md sections 5.1-5.2 and 6 (C3); paper eqs. 30-34, 36 and 39 (their velocity,
// gravity and friction terms), 41 and, in the centroidal form, 51.
template <typename T>
inline V3<T> leg_rate_force(const T* prm, int64_t flags, const LegBodies<T>& bodies, const LegState<T>& leg) {
    const Arg<T> Ldot = leg.Ldot, w0 = leg.sigma, w1 = leg.w1, w2 = leg.w2;
    const auto& [o0, o1, o2] = leg.omega;
    const auto& [g0, g1, g2] = leg.gravity;
    const Arg<T> m_u = bodies.m_u, m_d = bodies.m_d;
    const auto& [ru0, ru1, ru2] = bodies.r_u;
    const auto& [rd0, rd1, rd2] = bodies.r_d;
    const T ww = w0 * w0 + w1 * w1 + w2 * w2;
    // a_D: the upper-leg point at B_i; w x (w x r) = w (w.r) - r |w|^2
    const T aD1 = 2.0 * Ldot * w2;
    const T aD2 = -2.0 * Ldot * w1;
    T wr = w0 * ru0 + w1 * ru1 + w2 * ru2;
    const T au0 = w0 * wr - ru0 * ww;
    const T au1 = aD1 + w1 * wr - ru1 * ww;
    const T au2 = aD2 + w2 * wr - ru2 * ww;
    V3<T> t, u;
    if (flags & (CENTROIDAL | C3)) {
        wr = w0 * rd0 + w1 * rd1 + w2 * rd2;
        t = cross<T>(rd0, rd1, rd2, m_d * (w0 * wr - rd0 * ww), m_d * (w1 * wr - rd1 * ww), m_d * (w2 * wr - rd2 * ww));
        u = cross<T>(ru0, ru1, ru2, m_u * au0, m_u * au1, m_u * au2);
    } else {
        t = {0.0, 0.0, 0.0};
        u = cross<T>(ru0, ru1, ru2, 0.0, m_u * aD1, m_u * aD2);
    }
    const auto [d0, d1, d2] = euler<T>(bodies.I_d, 0.0, 0.0, 0.0, w0, w1, w2);
    const auto [e0, e1, e2] = euler<T>(bodies.I_u, 0.0, 0.0, 0.0, w0, w1, w2);
    const auto [gd0, gd1, gd2] = cross<T>(rd0, rd1, rd2, m_d * g0, m_d * g1, m_d * g2);
    const auto [gu0, gu1, gu2] = cross<T>(ru0, ru1, ru2, m_u * g0, m_u * g1, m_u * g2);
    const T cu = prm[OFF_DAMP];
    const T cs = prm[OFF_DAMP + 2];
    return leg_split<T>(
        flags, leg.frame,
        t[0] + u[0] + d0 + e0 - gd0 - gu0 + cu * w0 + cs * (w0 - o0),
        t[1] + u[1] + d1 + e1 - gd1 - gu1 + cu * w1 + cs * (w1 - o1),
        t[2] + u[2] + d2 + e2 - gd2 - gu2 + cu * w2 + cs * (w2 - o2),
        m_u * (au0 - g0) + prm[OFF_DAMP + 1] * Ldot);
}

// Force of the platform on leg i at P_i, in {D_i}, for P_i's acceleration A' in {D_i}.
// bodies is leg_bodies' result, leg the leg's LegState<T>; F_act the actuator force (N), which
// pushes the upper leg along e.  Returns (F0, F1, F2): the acceleration part plus the rate part.
// docs/physics.md section 5.1; paper eqs. 38-41 (joint form) and 51 (centroidal form).
template <typename T>
inline V3<T> leg_force(const T* prm, int64_t flags, const LegBodies<T>& bodies, const LegState<T>& leg, Arg<T> A0,
                    Arg<T> A1, Arg<T> A2, Arg<T> F_act) {
    const LegAccel<T> acc = leg_accel<T>(flags, leg.frame, leg.Ldot, leg.sigma, leg.w1, leg.w2, A0, A1, A2);
    const auto [a0, a1, a2] = leg_inertial_force<T>(flags, bodies, leg.frame, acc.Lddot, acc.al0, acc.al1, acc.al2);
    const auto [r0, r1, r2] = leg_rate_force<T>(prm, flags, bodies, leg);
    return {a0 + r0 - F_act, a1 + r1, a2 + r2};
}

// The acceleration part of F_s, {D_i}, for a P_i acceleration A' with all rates zero: one column
// of Q_i when A' is a {B} unit vector in {D_i}.  docs/physics.md section 5.4; paper eqs. 41 and
// 47-48.
template <typename T>
inline V3<T> unit_inertial_force(int64_t flags, const LegBodies<T>& bodies, const LegFrame<T>& fr, Arg<T> A0, Arg<T> A1,
                              Arg<T> A2) {
    const LegAccel<T> acc = leg_accel<T>(flags, fr, 0.0, 0.0, 0.0, 0.0, A0, A1, A2);
    return leg_inertial_force<T>(flags, bodies, fr, acc.Lddot, acc.al0, acc.al1, acc.al2);
}

// Leg i's LegState<T> in the platform state (t, R, v, w): its frame, its rates (Ldot, sigma, w1,
// w2), and in {D_i} the platform's angular velocity, gravity and the velocity part w x (w x q) of
// P_i's acceleration.
// docs/physics.md sections 4.1-4.2; paper eqs. 6-13 and 20-22.
template <typename T>
inline LegState<T> leg_state(const T* prm, int i, int64_t flags, const T* t, const T* R,
                          const T* v, const T* w) {
    // the frame made in place, neither copied in nor the rest zeroed first (in vector lanes each
    // is a kilobyte): every member is set below
    LegState<T> leg;
    new (&leg.frame) LegFrame<T>(leg_frame<T>(prm, i, t, R));
    const LegFrame<T>& fr = leg.frame;
    const auto& [q0, q1, q2] = fr.q;
    const auto [c0, c1, c2] = cross<T>(w[0], w[1], w[2], q0, q1, q2);
    const auto [u0, u1, u2] = to_leg<T>(fr, v[0] + c0, v[1] + c1, v[2] + c2);
    const LegRates<T> rates = leg_rates<T>(flags, fr, u0, u1, u2);
    const auto [a0, a1, a2] = cross<T>(w[0], w[1], w[2], c0, c1, c2);
    leg.Ldot = rates.Ldot;
    leg.sigma = rates.sigma;
    leg.w1 = rates.w1;
    leg.w2 = rates.w2;
    leg.omega = to_leg<T>(fr, w[0], w[1], w[2]);
    leg.gravity = to_leg<T>(fr, prm[OFF_G], prm[OFF_G + 1], prm[OFF_G + 2]);
    leg.a_vel = to_leg<T>(fr, a0, a1, a2);
    return leg;
}

// Row i of the leg Jacobian, [e_i, q_i x e_i] (dL_i/dt = row . [v; omega]), from the leg's frame.
// docs/physics.md section 4.4; paper eq. 13.
template <typename T>
inline Row6<T> jacobian_row(const LegFrame<T>& fr) {
    const auto& [q0, q1, q2] = fr.q;
    const auto& [e0, e1, e2] = fr.e;
    const auto [m0, m1, m2] = cross<T>(q0, q1, q2, e0, e1, e2);
    return {e0, e1, e2, m0, m1, m2};
}

// The leg Jacobian J (6,6) of one platform at pose (t, R), rows [e_i, (R p_i) x e_i].
// docs/physics.md section 4.4; paper eq. 13.
template <typename T>
inline void jacobian_one(const T* prm, const T* t, const T* R, T* J) {
    for (int i = 0; i < 6; ++i) {
        const Row6<T> row = jacobian_row<T>(leg_frame<T>(prm, i, t, R));
        for (int c = 0; c < 6; ++c) J[6 * i + c] = row[c];
    }
}

// Add leg i's pull on the platform to h (6,), {B}: the force of the leg on the platform at P_i
// (minus the force of the platform on the leg, F_s, actuator force excluded) as a wrench at P,
// and the spherical joint's friction torque.  The platform's acceleration acc = [a; alpha] enters
// through P_i's acceleration; acc nullptr means its velocity part alone (the bias of forward
// dynamics).  leg and bodies: the leg's LegState<T> (leg_state) and leg_bodies, which the caller
// makes (in its own variables, not copied in: in vector lanes they are kilobytes) and uses again.
// The one leg loop body of forward dynamics, its M/h assembly and inverse dynamics.
// docs/physics.md sections 5.1 and 5.4-5.5; paper eqs. 38-41 and 47-49 (or 51 and 55).
template <typename T>
inline void leg_on_platform(const T* prm, int64_t flags, const T* w, const T* acc, T* h, const LegState<T>& leg,
                            const LegBodies<T>& bodies) {
    const LegFrame<T>& fr = leg.frame;
    const V3<T> A = acc == nullptr ? leg.a_vel : with_platform_acc<T>(acc, fr, leg.a_vel);
    const auto [f0, f1, f2] = leg_force<T>(prm, flags, bodies, leg, A[0], A[1], A[2], 0.0);
    const auto [fs0, fs1, fs2] = to_base<T>(fr, f0, f1, f2);
    const auto& [q0, q1, q2] = fr.q;
    const auto [m0, m1, m2] = cross<T>(q0, q1, q2, fs0, fs1, fs2);
    // spherical-joint friction acts on the platform: +Cs (omega_l - omega)
    const T cs = prm[OFF_DAMP + 2];
    const auto [wl0, wl1, wl2] = to_base<T>(fr, leg.sigma, leg.w1, leg.w2);
    h[0] += fs0;
    h[1] += fs1;
    h[2] += fs2;
    h[3] += m0 - cs * (wl0 - w[0]);
    h[4] += m1 - cs * (wl1 - w[1]);
    h[5] += m2 - cs * (wl2 - w[2]);
}

// Add the platform's own Newton and Euler terms to M (6,6) and h (6,), {B}.
// Newton rows: m_p a_c - m_p g.  Euler rows (about P): the inertial moment in the chosen form
// minus rho x m_p g.  docs/physics.md sections 5.3-5.4 and 6 (C4); paper eqs. 42-46 (joint form)
// and 52-53 (centroidal form).
template <typename T>
inline void platform_terms(const T* prm, int64_t flags, const T* R, const T* w, T* M,
                           T* h) {
    const T m = prm[OFF_MP];
    const T r0 = R[0] * prm[OFF_RHO] + R[1] * prm[OFF_RHO + 1] + R[2] * prm[OFF_RHO + 2];
    const T r1 = R[3] * prm[OFF_RHO] + R[4] * prm[OFF_RHO + 1] + R[5] * prm[OFF_RHO + 2];
    const T r2 = R[6] * prm[OFF_RHO] + R[7] * prm[OFF_RHO + 1] + R[8] * prm[OFF_RHO + 2];
    const T g0 = prm[OFF_G];
    const T g1 = prm[OFF_G + 1];
    const T g2 = prm[OFF_G + 2];
    // centripetal acceleration of the CoM relative to P: w x (w x rho)
    const auto [c0, c1, c2] = cross<T>(w[0], w[1], w[2], r0, r1, r2);
    const auto [cc0, cc1, cc2] = cross<T>(w[0], w[1], w[2], c0, c1, c2);
    // Newton: m (a + alpha x rho + w x (w x rho)) - m g; alpha x rho = -[rho]x alpha
    for (int j = 0; j < 3; ++j) M[6 * j + j] += m;
    M[6 * 0 + 4] += m * r2;
    M[6 * 0 + 5] -= m * r1;
    M[6 * 1 + 3] -= m * r2;
    M[6 * 1 + 5] += m * r0;
    M[6 * 2 + 3] += m * r1;
    M[6 * 2 + 4] -= m * r0;
    h[0] += m * (cc0 - g0);
    h[1] += m * (cc1 - g1);
    h[2] += m * (cc2 - g2);

    // Euler about P.  In {P} the inertia is constant; shifts counts parallel-axis shifts of I_pc.
    const bool use_com_acc = (flags & (CENTROIDAL | C4)) != 0;
    const T shifts = ((flags & C4) || !(flags & CENTROIDAL)) ? 1.0 : 0.0;
    // inertia column j in {B}: R I (R^T e_j); bias w x I w via euler in {P}
    const T wp0 = R[0] * w[0] + R[3] * w[1] + R[6] * w[2];
    const T wp1 = R[1] * w[0] + R[4] * w[1] + R[7] * w[2];
    const T wp2 = R[2] * w[0] + R[5] * w[1] + R[8] * w[2];
    const T rp0 = prm[OFF_RHO];
    const T rp1 = prm[OFF_RHO + 1];
    const T rp2 = prm[OFF_RHO + 2];
    const Inertia<T> I_p = inertia<T>(prm, OFF_IP, shifts, m, rp0, rp1, rp2);
    for (int j = 0; j < 3; ++j) {
        const auto [i0, i1, i2] = euler<T>(I_p, R[3 * j + 0], R[3 * j + 1], R[3 * j + 2], 0.0, 0.0, 0.0);
        for (int k = 0; k < 3; ++k) M[6 * (3 + k) + 3 + j] += R[3 * k + 0] * i0 + R[3 * k + 1] * i1 + R[3 * k + 2] * i2;
    }
    const auto [b0, b1, b2] = euler<T>(I_p, 0.0, 0.0, 0.0, wp0, wp1, wp2);
    h[3] += R[0] * b0 + R[1] * b1 + R[2] * b2;
    h[4] += R[3] * b0 + R[4] * b1 + R[5] * b2;
    h[5] += R[6] * b0 + R[7] * b1 + R[8] * b2;
    // rho x m a (body-point form) or rho x m a_c: [rho]x m (a + alpha x rho + w x (w x rho))
    M[6 * 3 + 1] -= m * r2;
    M[6 * 3 + 2] += m * r1;
    M[6 * 4 + 0] += m * r2;
    M[6 * 4 + 2] -= m * r0;
    M[6 * 5 + 0] -= m * r1;
    M[6 * 5 + 1] += m * r0;
    if (use_com_acc) {
        // -m [rho]x [rho]x = m (|rho|^2 E - rho rho^T)
        const T rr = r0 * r0 + r1 * r1 + r2 * r2;
        const T rv[3] = {r0, r1, r2};
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) M[6 * (3 + a) + 3 + b] += m * ((a == b ? rr : 0.0) - rv[a] * rv[b]);
        const auto [x0, x1, x2] = cross<T>(r0, r1, r2, cc0, cc1, cc2);
        h[3] += m * x0;
        h[4] += m * x1;
        h[5] += m * x2;
    }
    const auto [x0, x1, x2] = cross<T>(r0, r1, r2, g0, g1, g2);
    h[3] -= m * x0;
    h[4] -= m * x1;
    h[5] -= m * x2;
}

// Add the wrench at P of a force f at P_i (q = P_i - P) to column c of M: [f; q x f].
// docs/physics.md section 5.4; paper eqs. 47-48.
template <typename T>
inline void add_column(T* M, int c, Arg<T> q0, Arg<T> q1, Arg<T> q2, Arg<T> f0, Arg<T> f1, Arg<T> f2) {
    const auto [n0, n1, n2] = cross<T>(q0, q1, q2, f0, f1, f2);
    M[6 * 0 + c] += f0;
    M[6 * 1 + c] += f1;
    M[6 * 2 + c] += f2;
    M[6 * 3 + c] += n0;
    M[6 * 4 + c] += n1;
    M[6 * 5 + c] += n2;
}

// The pivot row of column c of a 6x6 matrix M in elimination: the first of rows c.. with the
// largest |M[r][c]| (in each lane its own), as a row index of type T.  docs/physics.md section
// 5.4 (no paper equation).
template <typename T>
inline T pivot_row(const T* M, int c) {
    constexpr int n = 6;
    T big = lanes::abs_of(M[n * c + c]);
    T p = T(c);
    for (int r = c + 1; r < n; ++r) {
        const T a = lanes::abs_of(M[n * r + c]);
        const auto larger = a > big;
        big = lanes::select(larger, a, big);
        p = lanes::select(larger, T(r), p);
    }
    return p;
}

// a and b trade values where swap holds (lane by lane): a row swap of the elimination.
// docs/physics.md section 5.4 (no paper equation).
template <typename T, typename Mask>
inline void trade(const Mask& swap, T& a, T& b) {
    const T mine = a;
    const T theirs = b;
    a = lanes::select(swap, theirs, mine);
    b = lanes::select(swap, mine, theirs);
}

// Solve M x = b (6x6) by Gaussian elimination with partial pivoting; M and b are overwritten.
// A singular M gives non-finite x, which callers report.  docs/physics.md section 5.4 (no paper
// equation).
template <typename T>
inline void solve6(T* M, T* b, T* x) {
    constexpr int n = 6;
    for (int c = 0; c < n; ++c) {
        const T p = pivot_row(M, c);
        // rows c and p trade places
        for (int r = c + 1; r < n; ++r) {
            const auto swap = p == T(r);
            if (!lanes::any(swap)) continue;
            for (int k = c; k < n; ++k) trade(swap, M[n * c + k], M[n * r + k]);
            trade(swap, b[c], b[r]);
        }
        const T piv = M[n * c + c];
        for (int r = c + 1; r < n; ++r) {
            const T f = M[n * r + c] / piv;
            // a zero factor leaves the row as it is (not even 0 * inf = NaN)
            const auto nonzero = f != T(0.0);
            if (!lanes::any(nonzero)) continue;
            for (int k = c + 1; k < n; ++k) M[n * r + k] = lanes::select(nonzero, M[n * r + k] - f * M[n * c + k], M[n * r + k]);
            b[r] = lanes::select(nonzero, b[r] - f * b[c], b[r]);
        }
    }
    for (int c = n - 1; c >= 0; --c) {
        T s = b[c];
        for (int k = c + 1; k < n; ++k) s -= M[n * c + k] * x[k];
        x[c] = s / M[n * c + c];
    }
}

// Leg i's share of the equations of motion, {B}: into h_leg (6,) its pull on the platform
// (leg_on_platform: the velocity part, or with acc the whole), into M_leg (36,) (when not nullptr)
// the columns it adds to the mass matrix, and its Jacobian row into jac.  Each entry is the number
// leg_on_platform and add_column would add (the buffers start at -0.0, which adding leaves every
// number as it is, signed zeros included).  docs/physics.md sections 5.1 and 5.4-5.5; paper eqs.
// 38-41 and 47-49 (or 51 and 55).
template <typename T>
inline void leg_share(const T* prm, int64_t flags, int i, const T* t, const T* R, const T* v, const T* w,
                      const T* acc, T* h_leg, T* M_leg, Row6<T>& jac, T* Lddot_vel = nullptr) {
    std::fill(h_leg, h_leg + 6, -0.0);
    const LegState<T> leg = leg_state<T>(prm, i, flags, t, R, v, w);
    const LegFrame<T>& fr = leg.frame;
    const LegBodies<T> bodies = leg_bodies<T>(prm, i, flags, fr.L);
    leg_on_platform<T>(prm, flags, w, acc, h_leg, leg, bodies);
    jac = jacobian_row<T>(fr);
    // the velocity part of Lddot (P_i's acceleration a_vel alone) from this frame, for the
    // reflected masses (add_reflected_mass), so they need no second pass over the legs
    if (Lddot_vel != nullptr)
        *Lddot_vel = leg_accel<T>(flags, fr, leg.Ldot, leg.sigma, leg.w1, leg.w2, leg.a_vel[0], leg.a_vel[1],
                                  leg.a_vel[2]).Lddot;
    if (M_leg == nullptr) return;
    std::fill(M_leg, M_leg + 36, -0.0);
    const auto& [e0, e1, e2] = fr.e;
    const auto& [y0, y1, y2] = fr.y;
    const auto& [z0, z1, z2] = fr.z;
    const auto& [q0, q1, q2] = fr.q;
    // linear part: Q column j = the acceleration part of the leg force for a_P = unit vector j
    // of {B} (row j of T in {D_i}); with zero rates leg_accel returns only its linear part
    const auto [qa0, qa1, qa2] = unit_inertial_force<T>(flags, bodies, fr, e0, y0, z0);
    const auto [qb0, qb1, qb2] = unit_inertial_force<T>(flags, bodies, fr, e1, y1, z1);
    const auto [qc0, qc1, qc2] = unit_inertial_force<T>(flags, bodies, fr, e2, y2, z2);
    const auto [Qx0, Qx1, Qx2] = to_base<T>(fr, qa0, qa1, qa2);
    const auto [Qy0, Qy1, Qy2] = to_base<T>(fr, qb0, qb1, qb2);
    const auto [Qz0, Qz1, Qz2] = to_base<T>(fr, qc0, qc1, qc2);
    // a_P = a + alpha x q: column k of a moves P_i by e_k, of alpha by e_k x q
    add_column<T>(M_leg, 0, q0, q1, q2, Qx0, Qx1, Qx2);
    add_column<T>(M_leg, 1, q0, q1, q2, Qy0, Qy1, Qy2);
    add_column<T>(M_leg, 2, q0, q1, q2, Qz0, Qz1, Qz2);
    add_column<T>(M_leg, 3, q0, q1, q2, Qz0 * q1 - Qy0 * q2, Qz1 * q1 - Qy1 * q2, Qz2 * q1 - Qy2 * q2);
    add_column<T>(M_leg, 4, q0, q1, q2, Qx0 * q2 - Qz0 * q0, Qx1 * q2 - Qz1 * q0, Qx2 * q2 - Qz2 * q0);
    add_column<T>(M_leg, 5, q0, q1, q2, Qy0 * q0 - Qx0 * q1, Qy1 * q0 - Qx1 * q1, Qy2 * q0 - Qx2 * q1);
}

#ifdef STEWART_ENV_VECTOR_EXTENSIONS
// Entry k of the packed row prm spread into lanes P for leg_shares: lane l holds leg l's numbers
// where the kernels read leg 0's (lanes 6 and 7 repeat leg 5), the platform's numbers the legs
// read (damping, gravity) are in every lane.  Offsets and sizes are compile-time constants, so the
// spread is plain loads and stores (it runs at every evaluation outside a SpreadOnce).
// docs/physics.md section 2 (the packed layout); no paper equation.
template <int k>
inline void spread_entry(const double* prm, lanes::Lanes* P) {
    constexpr LayoutEntry entry = PACKED_LAYOUT[k];
    constexpr int off = offset_of(k);
    constexpr int size = entry_size(entry);
    if constexpr (entry.ndim >= 1 && entry.shape[0] == 6) {
        constexpr int per_leg = size / 6;
        for (int j = 0; j < per_leg; ++j)
            for (int l = 0; l < lanes::LANES; ++l) P[off + j].v[l] = prm[off + per_leg * (l < 5 ? l : 5) + j];
    } else {
        for (int j = 0; j < size; ++j) P[off + j] = prm[off + j];
    }
}
// Every entry k... of the packed layout spread (spread_entry).  docs/physics.md section 2; no paper equation.
template <std::size_t... k>
inline void spread_entries(const double* prm, lanes::Lanes* P, std::index_sequence<k...>) {
    (spread_entry<static_cast<int>(k)>(prm, P), ...);
}
// The packed row prm (N_PARAMS,) spread into lanes P (N_PARAMS,), one leg per lane (spread_entry).
// docs/physics.md section 2; no paper equation.
inline void spread_legs(const double* prm, lanes::Lanes* P) {
    spread_entries(prm, P, std::make_index_sequence<N_LAYOUT>{});
}

//: A packed row and its lanes (spread_legs).
struct SpreadRow {
    const double* prm;
    lanes::Lanes lanes[N_PARAMS];
};
//: The row spread by this thread's innermost live SpreadOnce (nullptr: none).
inline thread_local const SpreadRow* spread_row = nullptr;

//: While it lives, leg_shares on this thread reads the packed row prm from lanes spread once here
//: rather than spreading it at each evaluation: for a rollout, whose row does not change.  The
//: numbers are the same bit for bit.  prm must outlive it unchanged.  Inside one of the same row
//: (a control step's rollouts of one physics step each) it spreads nothing and reads the outer's.
class SpreadOnce {
   public:
    explicit SpreadOnce(const double* prm) : outer_(spread_row) {
        if (outer_ != nullptr && outer_->prm == prm) return;
        row_.prm = prm;
        spread_legs(prm, row_.lanes);
        spread_row = &row_;
    }
    ~SpreadOnce() { spread_row = outer_; }
    SpreadOnce(const SpreadOnce&) = delete;
    SpreadOnce& operator=(const SpreadOnce&) = delete;

   private:
    SpreadRow row_;
    const SpreadRow* outer_;
};
#endif

//: SpreadOnce where leg_shares spreads rows into lanes (one platform, T = double), else nothing.
template <typename T>
struct SpreadFor {
    explicit SpreadFor(const T*) {}
};
#ifdef STEWART_ENV_VECTOR_EXTENSIONS
template <>
struct SpreadFor<double> : SpreadOnce {
    using SpreadOnce::SpreadOnce;
};
#endif

// The six legs' shares (leg_share) of one platform, or of one platform per lane: h_leg (6,6),
// M_leg (6,36) (nullptr: no columns), jac (6,) rows, Lddot_vel (6,) (nullptr: not wanted) the
// velocity parts of the legs' accelerations, M_sum (36,) (nullptr: not wanted) the six M_leg
// summed (leg 0 first, onto zero).  One platform (T = double) on a processor
// with vector lanes runs its six legs side by side, one per lane, with the same numbers as one by
// one.  docs/physics.md sections 5.1 and 5.4-5.5; paper eqs. 38-41 and 47-49 (or 51 and 55).
template <typename T>
inline void leg_shares(const T* prm, int64_t flags, const T* t, const T* R, const T* v, const T* w, const T* acc,
                       T (*h_leg)[6], T (*M_leg)[36], Row6<T>* jac, T* Lddot_vel = nullptr, T* M_sum = nullptr) {
    const bool columns = M_leg != nullptr || M_sum != nullptr;
#ifdef STEWART_ENV_VECTOR_EXTENSIONS
    if constexpr (std::is_same_v<T, double>) {
        using lanes::Lanes;
        // the row the innermost SpreadOnce of this thread spread already, else spread here
        Lanes own[N_PARAMS];
        const Lanes* P = spread_row != nullptr && spread_row->prm == prm ? spread_row->lanes : own;
        if (P == own) spread_legs(prm, own);
        Lanes tl[3], Rl[9], vl[3], wl[3], al[6], hl[6], Ml[36];
        for (int j = 0; j < 3; ++j) tl[j] = t[j], vl[j] = v[j], wl[j] = w[j];
        for (int j = 0; j < 9; ++j) Rl[j] = R[j];
        if (acc != nullptr)
            for (int j = 0; j < 6; ++j) al[j] = acc[j];
        Row6<Lanes> jl;
        Lanes cl;
        leg_share<Lanes>(P, flags, 0, tl, Rl, vl, wl, acc == nullptr ? nullptr : al, hl, columns ? Ml : nullptr, jl,
                         Lddot_vel == nullptr ? nullptr : &cl);
        for (int i = 0; i < 6; ++i) {
            for (int r = 0; r < 6; ++r) h_leg[i][r] = hl[r][i], jac[i][r] = jl[r][i];
            if (Lddot_vel != nullptr) Lddot_vel[i] = cl[i];
            if (M_leg != nullptr)
                for (int k = 0; k < 36; ++k) M_leg[i][k] = Ml[k][i];
        }
        // summed where the lanes hold them, leg after leg onto zero as the caller would sum them
        if (M_sum != nullptr)
            for (int k = 0; k < 36; ++k) {
                double sum = 0.0;
                for (int i = 0; i < 6; ++i) sum += Ml[k][i];
                M_sum[k] = sum;
            }
        return;
    }
#endif
    if (M_sum != nullptr) std::fill(M_sum, M_sum + 36, 0.0);
    for (int i = 0; i < 6; ++i) {
        T columns_i[36];
        T* Mi = M_leg != nullptr ? M_leg[i] : columns ? columns_i : nullptr;
        leg_share<T>(prm, flags, i, t, R, v, w, acc, h_leg[i], Mi, jac[i], Lddot_vel == nullptr ? nullptr : Lddot_vel + i);
        if (M_sum != nullptr)
            for (int k = 0; k < 36; ++k) M_sum[k] += Mi[k];
    }
}

// The reflected masses m_r (6,) of the legs' drives entered into M (6,6) and h (6,), {B}: a rotor
// behind a screw adds m_r along its leg's prismatic axis only, so the actuator force reaching the
// leg is F_i - m_r,i Lddot_i with Lddot_i = j_i [a; alpha] + c_i (j_i the Jacobian row, c_i the
// velocity part of leg_accel's Lddot): M gains m_r,i j_i^T j_i and h gains m_r,i c_i j_i^T.
// docs/physics.md section 10.2 (reflected mass; no paper equation).
// jac (6,) the legs' Jacobian rows and Lddot_vel (6,) their c_i, as leg_shares gives them.
template <typename T>
inline void add_reflected_mass(const Row6<T>* jac_rows, const T* Lddot_vel, const T* m_r, T* M, T* h) {
    for (int i = 0; i < 6; ++i) {
        const Row6<T>& jac = jac_rows[i];
        const T mr = m_r[i];
        // a leg without drive inertia adds nothing, not even a signed zero (lane by lane)
        const auto inert = mr != T(0.0);
        if (!lanes::any(inert)) continue;
        for (int r = 0; r < 6; ++r) {
            h[r] = lanes::select(inert, h[r] + mr * Lddot_vel[i] * jac[r], h[r]);
            for (int c = 0; c < 6; ++c)
                M[6 * r + c] = lanes::select(inert, M[6 * r + c] + mr * jac[r] * jac[c], M[6 * r + c]);
        }
    }
}

// Leg i's drive force F_i = f_i + m_r,i Lddot_i (out (6,) holds the forces f_i reaching the legs,
// as inverse_one gives them): what the motors push with to make acc = [a; alpha].
// docs/physics.md section 10.2 (reflected mass; no paper equation).
template <typename T>
inline void add_reflected_force(const T* prm, int64_t flags, const T* t, const T* R, const T* v, const T* w,
                                const T* acc, const T* m_r, T* out) {
    for (int i = 0; i < 6; ++i) {
        const LegState<T> leg = leg_state<T>(prm, i, flags, t, R, v, w);
        const auto A = with_platform_acc<T>(acc, leg.frame, leg.a_vel);
        const LegAccel<T> la = leg_accel<T>(flags, leg.frame, leg.Ldot, leg.sigma, leg.w1, leg.w2, A[0], A[1], A[2]);
        out[i] = lanes::select(m_r[i] != T(0.0), out[i] + m_r[i] * la.Lddot, out[i]);
    }
}

// The equations of motion of one platform, {B}: M (6,6) and h (6,) overwritten with the mass
// matrix and h - J^T F, so that M [a; alpha] + h = W.
// With F = 0, h is the bias: velocity products, gravity and joint friction.  The actuator forces
// are folded in leg by leg, so forward dynamics needs no second pass over the legs.
// docs/physics.md section 5.4; paper eq. 49 (joint form) or 55 (centroidal form).
// With the legs' reflected masses m_r (6,) (nullptr: none) M and h also carry their terms
// (add_reflected_mass), from the same pass over the legs.
template <typename T>
inline void assemble_one(const T* prm, int64_t flags, const T* t, const T* R, const T* v,
                         const T* w, const T* F, T* M, T* h, const T* m_r = nullptr) {
    T h_leg[6][6], Lddot_vel[6];
    Row6<T> jac[6];
    // bias: each leg's pull at zero platform acceleration, actuator force excluded; M the legs'
    // columns summed (leg_shares' M_sum)
    leg_shares<T>(prm, flags, t, R, v, w, nullptr, h_leg, nullptr, jac, m_r == nullptr ? nullptr : Lddot_vel, M);
    std::fill(h, h + 6, 0.0);
    for (int i = 0; i < 6; ++i) {
        for (int r = 0; r < 6; ++r) h[r] += h_leg[i][r];
        // actuator force along e_i at P_i moves to the right-hand side J^T F
        const T Fi = F[i];
        for (int r = 0; r < 6; ++r) h[r] -= Fi * jac[i][r];
    }
    platform_terms<T>(prm, flags, R, w, M, h);
    // nullptr: no drive inertia, and not one operation more (the results bit for bit as without)
    if (m_r != nullptr) add_reflected_mass<T>(jac, Lddot_vel, m_r, M, h);
}

// Forward dynamics of one platform: out[:3] = a, out[3:] = alpha, {B}.
// M (6,6) and h (6,) are scratch.  Assembles M [a; alpha] + h = J^T F + W and solves it; with the
// legs' reflected masses m_r (6,) (nullptr: none), (M + J^T diag(m_r) J) [a; alpha] + h +
// J^T diag(m_r) c = J^T F + W (add_reflected_mass).  docs/physics.md sections 5.4 and 10.2; paper
// eq. 49 (joint form) or 55 (centroidal form).  M_kept (36,), when not nullptr, receives the mass
// matrix before the solve overwrites M (the derivatives solve with it again).
template <typename T>
inline void forward_one(const T* prm, int64_t flags, const T* t, const T* R, const T* v,
                        const T* w, const T* F, const T* W, T* M, T* h, T* out, const T* m_r = nullptr,
                        T* M_kept = nullptr) {
    assemble_one<T>(prm, flags, t, R, v, w, F, M, h, m_r);
    if (M_kept != nullptr) std::copy(M, M + 36, M_kept);
    for (int r = 0; r < 6; ++r) h[r] = W[r] - h[r];
    solve6<T>(M, h, out);
}

// Inverse dynamics of one platform: leg forces out (6,) for acc = [a; alpha], {B}.
// Each leg's force on the platform follows from its own equations at the given acceleration; the
// platform's six equations then fix the six actuator forces through J^T F = wrench.  M (6,6) and
// h (6,) are scratch.  With the legs' reflected masses m_r (6,) (nullptr: none) out holds the drive
// forces F_i = f_i + m_r,i Lddot_i (add_reflected_force).  docs/physics.md sections 5.5 and 10.2;
// paper eq. 49 (joint form) or 55 (centroidal form) solved for the forces.
template <typename T>
inline void inverse_one(const T* prm, int64_t flags, const T* t, const T* R, const T* v,
                        const T* w, const T* acc, const T* W, T* M, T* h, T* out, const T* m_r = nullptr) {
    T h_leg[6][6];
    Row6<T> jac[6];
    leg_shares<T>(prm, flags, t, R, v, w, acc, h_leg, nullptr, jac);
    std::fill(M, M + 36, 0.0);
    std::fill(h, h + 6, 0.0);
    for (int i = 0; i < 6; ++i) {
        for (int r = 0; r < 6; ++r) h[r] += h_leg[i][r];
        // column i of J^T
        for (int r = 0; r < 6; ++r) M[6 * r + i] = jac[i][r];
    }
    // the platform's own inertial and gravity terms at this acceleration, via its M and h
    T Mp[36] = {0.0};
    platform_terms<T>(prm, flags, R, w, Mp, h);
    for (int r = 0; r < 6; ++r) {
        T total = h[r] - W[r];
        for (int c = 0; c < 6; ++c) total += Mp[6 * r + c] * acc[c];
        h[r] = total;
    }
    solve6<T>(M, h, out);
    if (m_r != nullptr) add_reflected_force<T>(prm, flags, t, R, v, w, acc, m_r, out);
}

// Leg kinematics of one platform, {B}: frames (6,3,3) T_i = [e y z] as columns, lengths (6,),
// rates (6,), accels (6,), omega_l (6,3), alpha_l (6,3), jac (6,6) rows [e_i, q_i x e_i].
// docs/physics.md section 4; paper eqs. 6-27.
inline void leg_kinematics_one(const double* prm, int64_t flags, const double* t, const double* R, const double* v,
                               const double* w, const double* acc, double* frames, double* lengths, double* rates,
                               double* accels, double* omega_l, double* alpha_l, double* jac) {
    for (int i = 0; i < 6; ++i) {
        const auto leg = leg_state(prm, i, flags, t, R, v, w);
        const auto& fr = leg.frame;
        const auto [A0, A1, A2] = with_platform_acc(acc, fr, leg.a_vel);
        const auto la = leg_accel<double>(flags, fr, leg.Ldot, leg.sigma, leg.w1, leg.w2, A0, A1, A2);
        for (int r = 0; r < 3; ++r) {
            frames[9 * i + 3 * r + 0] = fr.e[r];
            frames[9 * i + 3 * r + 1] = fr.y[r];
            frames[9 * i + 3 * r + 2] = fr.z[r];
        }
        lengths[i] = fr.L;
        rates[i] = leg.Ldot;
        accels[i] = la.Lddot;
        const auto om = to_base(fr, leg.sigma, leg.w1, leg.w2);
        const auto al = to_base(fr, la.al0, la.al1, la.al2);
        const auto row = jacobian_row(fr);
        for (int r = 0; r < 3; ++r) {
            omega_l[3 * i + r] = om[r];
            alpha_l[3 * i + r] = al[r];
        }
        for (int c = 0; c < 6; ++c) jac[6 * i + c] = row[c];
    }
}

// The packed parameters of batch row b: prm's row b, or its only row, which then serves every row
// of the batch.  docs/physics.md section 2 (no paper equation).
inline const double* params_row(const double* prm, int64_t n_prm, int64_t b) {
    return n_prm == 1 ? prm : prm + N_PARAMS * b;
}

//: The packed parameter rows of a batch, prm (n_prm, N_PARAMS) with n_prm 1 or the batch size, as
//: the kernels of each number type read them: a row of doubles for one platform, N_PARAMS Lanes
//: for a block of rows (the one parameter row broadcast to every lane once for the whole batch, or
//: the block's own rows gathered into the caller's scratch).
struct ParamRows {
    const double* prm;
    int64_t n_prm;
#ifdef STEWART_ENV_VECTOR_EXTENSIONS
    std::vector<lanes::Lanes> shared;
#endif
    // n: the batch size (a batch smaller than a block needs no broadcast row)
    ParamRows(const double* prm, int64_t n_prm, int64_t n) : prm(prm), n_prm(n_prm) {
#ifdef STEWART_ENV_VECTOR_EXTENSIONS
        if (n_prm == 1 && n >= lanes::LANES) shared.assign(prm, prm + N_PARAMS);
#else
        (void)n;
#endif
    }
    const double* rows(int64_t b, double*) const { return params_row(prm, n_prm, b); }
#ifdef STEWART_ENV_VECTOR_EXTENSIONS
    const lanes::Lanes* rows(int64_t b, lanes::Lanes* scratch) const {
        if (n_prm == 1) return shared.data();
        lanes::load(prm, N_PARAMS, b, N_PARAMS, scratch);
        return scratch;
    }
#endif
};

//: Scratch for the parameters of a block of rows of number type T (none for one platform).
template <typename T>
struct ParamScratch {
    T rows[(lanes::width<T> > 1) ? N_PARAMS : 1];
};

// Rows b, b + 1, ... of forward_batch (forward true) or inverse_batch, as many as T carries:
// forward_one or inverse_one on the rows' numbers loaded into T, out written back.  x (n,6) are
// the leg forces or the accelerations.  docs/physics.md sections 5.4-5.5; paper eq. 49 or 55.
template <typename T, bool forward>
inline void solve_row(const ParamRows& prm, int64_t flags, const double* t, const double* R, const double* v,
                      const double* w, const double* x, const double* W, double* out, int64_t b,
                      const double* m_r = nullptr, int64_t n_mr = 0) {
    ParamScratch<T> scratch;
    T tl[3], Rl[9], vl[3], wl[3], xl[6], Wl[6], M[36], h[6], o[6], mr[6];
    // the reflected masses (n_mr, 6): the row's own, or the only row (stride 0) for every row
    if (m_r != nullptr) lanes::load(m_r, n_mr == 1 ? 0 : 6, n_mr == 1 ? 0 : b, 6, mr);
    const T* mrl = m_r == nullptr ? nullptr : mr;
    lanes::load(t, 3, b, 3, tl);
    lanes::load(R, 9, b, 9, Rl);
    lanes::load(v, 3, b, 3, vl);
    lanes::load(w, 3, b, 3, wl);
    lanes::load(x, 6, b, 6, xl);
    lanes::load(W, 6, b, 6, Wl);
    const T* p = prm.rows(b, scratch.rows);
    if constexpr (forward) {
        forward_one<T>(p, flags, tl, Rl, vl, wl, xl, Wl, M, h, o, mrl);
    } else {
        inverse_one<T>(p, flags, tl, Rl, vl, wl, xl, Wl, M, h, o, mrl);
    }
    lanes::store(o, 6, out, 6, b);
}

// Forward dynamics over a batch of n rows.  prm (Np, N_PARAMS) with Np in {1, n}; t, v, w (n,3);
// R (n,3,3); F (n,6) N; W (n,6) external wrench [F_ext; M_ext] at P, {B}; out (n,6) [a; alpha].
// Blocks of rows run in the lanes of a vector and on every core (lanes.hpp): each row's numbers
// are those of forward_one alone.  docs/physics.md section 5.4; paper eq. 49 or 55.
inline void forward_batch(const double* prm, int64_t n_prm, int64_t flags, const double* t, const double* R,
                          const double* v, const double* w, const double* F, const double* W, double* out,
                          int64_t n) {
    const ParamRows rows(prm, n_prm, n);
    lanes::for_rows(n, 1, [&](int64_t b, auto tag) {
        solve_row<decltype(tag), true>(rows, flags, t, R, v, w, F, W, out, b);
    });
}

// Rows b, b + 1, ... of mass_bias_batch, as many as T carries (docs/physics.md section 5.4;
// paper eq. 49 or 55).
template <typename T>
inline void mass_bias_row(const ParamRows& prm, int64_t flags, const double* t, const double* R, const double* v,
                          const double* w, const double* W, double* M, double* h, int64_t b) {
    ParamScratch<T> scratch;
    T tl[3], Rl[9], vl[3], wl[3], Wl[6], Ml[36], hl[6];
    const T zero[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    lanes::load(t, 3, b, 3, tl);
    lanes::load(R, 9, b, 9, Rl);
    lanes::load(v, 3, b, 3, vl);
    lanes::load(w, 3, b, 3, wl);
    lanes::load(W, 6, b, 6, Wl);
    assemble_one<T>(prm.rows(b, scratch.rows), flags, tl, Rl, vl, wl, zero, Ml, hl);
    for (int r = 0; r < 6; ++r) hl[r] -= Wl[r];
    lanes::store(Ml, 36, M, 36, b);
    lanes::store(hl, 6, h, 6, b);
}

// Mass matrix M (n,6,6) and bias h (n,6) over a batch, so that M [a; alpha] + h = J^T F: the
// assembly of forward_batch at F = 0, with the external wrench W (n,6) moved into h.
// docs/physics.md section 5.4; paper eq. 49 or 55.
inline void mass_bias_batch(const double* prm, int64_t n_prm, int64_t flags, const double* t, const double* R,
                            const double* v, const double* w, const double* W, double* M, double* h, int64_t n) {
    const ParamRows rows(prm, n_prm, n);
    lanes::for_rows(n, 1, [&](int64_t b, auto tag) {
        mass_bias_row<decltype(tag)>(rows, flags, t, R, v, w, W, M, h, b);
    });
}

// Inverse dynamics over a batch: acc (n,6) [a; alpha] -> out (n,6) leg forces, N; blocks of rows
// in vector lanes and on every core, as forward_batch.  docs/physics.md section 5.5; paper eq. 49
// or 55 solved for the forces.
inline void inverse_batch(const double* prm, int64_t n_prm, int64_t flags, const double* t, const double* R,
                          const double* v, const double* w, const double* acc, const double* W, double* out,
                          int64_t n) {
    const ParamRows rows(prm, n_prm, n);
    lanes::for_rows(n, 1, [&](int64_t b, auto tag) {
        solve_row<decltype(tag), false>(rows, flags, t, R, v, w, acc, W, out, b);
    });
}

// forward_batch (forward true) or inverse_batch with the legs' reflected masses m_r (n_mr, 6), kg,
// n_mr 1 (one row for the batch) or n: forward dynamics of the drive forces F, or the drive forces
// of acc (forward_one and inverse_one with m_r).  docs/physics.md sections 5.4-5.5 and 10.2; paper eq. 49 or 55.
template <bool forward>
inline void reflected_batch(const double* prm, int64_t n_prm, int64_t flags, const double* t, const double* R,
                            const double* v, const double* w, const double* x, const double* W, const double* m_r,
                            int64_t n_mr, double* out, int64_t n) {
    const ParamRows rows(prm, n_prm, n);
    lanes::for_rows(n, 1, [&](int64_t b, auto tag) {
        solve_row<decltype(tag), forward>(rows, flags, t, R, v, w, x, W, out, b, m_r, n_mr);
    });
}

// Leg kinematics over a batch (shapes of leg_kinematics_one with a leading n).  Serial: it serves
// analysis and tests, not the per-step path.  docs/physics.md section 4; paper eqs. 6-27.
inline void leg_kinematics_batch(const double* prm, int64_t n_prm, int64_t flags, const double* t, const double* R,
                                 const double* v, const double* w, const double* acc, double* frames,
                                 double* lengths, double* rates, double* accels, double* omega_l, double* alpha_l,
                                 double* jac, int64_t n) {
    for (int64_t b = 0; b < n; ++b)
        leg_kinematics_one(params_row(prm, n_prm, b), flags, t + 3 * b, R + 9 * b, v + 3 * b, w + 3 * b, acc + 6 * b,
                           frames + 54 * b, lengths + 6 * b, rates + 6 * b, accels + 6 * b, omega_l + 18 * b,
                           alpha_l + 18 * b, jac + 36 * b);
}

// The leg Jacobian J (n,6,6) of each pose (t (n,3), R (n,3,3)): jacobian_one over a batch,
// serial.  docs/physics.md section 4.4; paper eq. 13.
inline void jacobian_batch(const double* prm, int64_t n_prm, const double* t, const double* R, double* J, int64_t n) {
    for (int64_t b = 0; b < n; ++b) jacobian_one(params_row(prm, n_prm, b), t + 3 * b, R + 9 * b, J + 36 * b);
}

//: How far one 3x3 matrix is from a rotation (rotation_error's value).
struct RotationError {
    double orth, det;
};

// How far one 3x3 matrix A is from a rotation: (largest entry of |A^T A - I|, det A).
// docs/physics.md section 1 (no paper equation).
inline RotationError rotation_error(const double* A) {
    double worst = 0.0;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            const double g = A[i] * A[j] + A[3 + i] * A[3 + j] + A[6 + i] * A[6 + j] - (i == j ? 1.0 : 0.0);
            // a NaN entry makes the matrix no rotation (numpy's max propagates NaN the same way)
            worst = std::isnan(g) || std::isnan(worst) ? std::numeric_limits<double>::quiet_NaN()
                                                       : std::max(worst, std::abs(g));
        }
    }
    const double det = (A[0] * (A[4] * A[8] - A[5] * A[7]) - A[1] * (A[3] * A[8] - A[5] * A[6]) +
                        A[2] * (A[3] * A[7] - A[4] * A[6]));
    return {worst, det};
}

// The larger of a and b, NaN if either is NaN (numpy's maximum).  docs/physics.md section 1 (no
// paper equation).
inline double nan_max(double a, double b) {
    return (std::isnan(a) || std::isnan(b)) ? std::numeric_limits<double>::quiet_NaN() : std::max(a, b);
}

// How far each matrix of R (n,3,3) is from a rotation: orth (n,) the largest entry of
// |R^T R - I| and det (n,) its determinant.  Returns the largest of all orth and |det - 1|.
// docs/physics.md section 1 (no paper equation).
inline double rotation_errors_batch(const double* R, double* orth, double* det, int64_t n) {
    double largest = 0.0;
    for (int64_t b = 0; b < n; ++b) {
        const RotationError err = rotation_error(R + 9 * b);
        orth[b] = err.orth;
        det[b] = err.det;
        largest = nan_max(largest, nan_max(orth[b], std::abs(det[b] - 1.0)));
    }
    return largest;
}

// The largest |R^T R - I| entry or |det R - 1| over R (n,3,3), without output arrays: the
// argument check of a single-platform call.  docs/physics.md section 1 (no paper equation).
inline double largest_rotation_error(const double* R, int64_t n) {
    double largest = 0.0;
    for (int64_t b = 0; b < n; ++b) {
        const RotationError err = rotation_error(R + 9 * b);
        largest = nan_max(largest, nan_max(err.orth, std::abs(err.det - 1.0)));
    }
    return largest;
}

// Whether all size numbers at x are finite: one argument of the finiteness check of every entry
// point (the caller reports the first array that is not).  docs/physics.md section 1 (no paper
// equation).
inline bool all_finite(const double* x, int64_t size) {
    for (int64_t k = 0; k < size; ++k)
        if (!std::isfinite(x[k])) return false;
    return true;
}

// ||J||_F ||J^-1||_F of a 6x6 matrix, an upper bound of its 2-norm condition number (inf or NaN
// when J is singular or not finite); T = double, or Lanes of one J each.  J^-1 column by column,
// as solve6 would solve J x = e_k for each unit vector e_k: one elimination with the six
// right-hand sides carried along (the pivots and factors depend on J alone), every column's
// numbers those solve6 gives it.  docs/physics.md section 4.4 (no paper equation).
template <typename T>
inline T frobenius_condition(const T* J) {
    constexpr int n = 6;
    T M[36];
    T E[36];  // row r, column k: entry r of the right-hand side e_k, then of the solution
    T norm = 0.0;
    for (int k = 0; k < 36; ++k) {
        norm += J[k] * J[k];
        M[k] = J[k];
        E[k] = 0.0;
    }
    for (int k = 0; k < n; ++k) E[n * k + k] = 1.0;
    for (int c = 0; c < n; ++c) {
        const T p = pivot_row(M, c);
        // rows c and p trade places
        for (int r = c + 1; r < n; ++r) {
            const auto swap = p == T(r);
            if (!lanes::any(swap)) continue;
            for (int k = 0; k < n; ++k) {
                if (k >= c) trade(swap, M[n * c + k], M[n * r + k]);
                trade(swap, E[n * c + k], E[n * r + k]);
            }
        }
        const T piv = M[n * c + c];
        for (int r = c + 1; r < n; ++r) {
            const T f = M[n * r + c] / piv;
            // a zero factor leaves the row as it is (not even 0 * inf = NaN)
            const auto nonzero = f != T(0.0);
            if (!lanes::any(nonzero)) continue;
            for (int k = c + 1; k < n; ++k)
                M[n * r + k] = lanes::select(nonzero, M[n * r + k] - f * M[n * c + k], M[n * r + k]);
            for (int k = 0; k < n; ++k)
                E[n * r + k] = lanes::select(nonzero, E[n * r + k] - f * E[n * c + k], E[n * r + k]);
        }
    }
    for (int c = n - 1; c >= 0; --c)
        for (int k = 0; k < n; ++k) {
            T s = E[n * c + k];
            for (int j = c + 1; j < n; ++j) s -= M[n * c + j] * E[n * j + k];
            E[n * c + k] = s / M[n * c + c];
        }
    T inv_norm = 0.0;
    for (int k = 0; k < n; ++k)
        for (int j = 0; j < n; ++j) inv_norm += E[n * j + k] * E[n * j + k];
    return lanes::sqrt_of(norm * inv_norm);
}

// The 2-norm condition number sigma_max / sigma_min of a finite 6x6 matrix J, by one-sided Jacobi
// rotations of its columns (Hestenes): the columns converge to orthogonal ones whose norms are the
// singular values.  inf when J is singular.  docs/physics.md section 4.4 (no paper equation).
inline double jacobi_condition(const double* J) {
    double A[36];
    for (int k = 0; k < 36; ++k) A[k] = J[k];
    for (int sweep = 0; sweep < 60; ++sweep) {
        bool rotated = false;
        for (int p = 0; p < 5; ++p) {
            for (int q = p + 1; q < 6; ++q) {
                double alpha = 0.0, beta = 0.0, gamma = 0.0;
                for (int r = 0; r < 6; ++r) {
                    alpha += A[6 * r + p] * A[6 * r + p];
                    beta += A[6 * r + q] * A[6 * r + q];
                    gamma += A[6 * r + p] * A[6 * r + q];
                }
                if (gamma == 0.0 || std::abs(gamma) <= 1e-17 * std::sqrt(alpha * beta)) continue;
                rotated = true;
                const double zeta = (beta - alpha) / (2.0 * gamma);
                const double tan = std::copysign(1.0, zeta) / (std::abs(zeta) + std::sqrt(1.0 + zeta * zeta));
                const double cos = 1.0 / std::sqrt(1.0 + tan * tan);
                const double sin = cos * tan;
                for (int r = 0; r < 6; ++r) {
                    const double ap = A[6 * r + p];
                    const double aq = A[6 * r + q];
                    A[6 * r + p] = cos * ap - sin * aq;
                    A[6 * r + q] = sin * ap + cos * aq;
                }
            }
        }
        if (!rotated) break;
    }
    double largest = 0.0;
    double smallest = std::numeric_limits<double>::infinity();
    for (int c = 0; c < 6; ++c) {
        double s = 0.0;
        for (int r = 0; r < 6; ++r) s += A[6 * r + c] * A[6 * r + c];
        s = std::sqrt(s);
        largest = std::max(largest, s);
        smallest = std::min(smallest, s);
    }
    return smallest > 0.0 ? largest / smallest : std::numeric_limits<double>::infinity();
}

// Rows b, b + 1, ... of leg_sensors_batch, as many as T carries (docs/physics.md section 4.4;
// paper eqs. 7 and 13): prm the nominal parameter rows.
template <typename T>
inline void leg_sensors_row(const ParamRows& prm, const double* t, const double* R, const double* v,
                            const double* w, double max_condition, double* lengths, double* rates,
                            double* condition, int64_t b) {
    ParamScratch<T> scratch;
    const T* p = prm.rows(b, scratch.rows);
    T tl[3], Rl[9], vl[3], wl[3], L[6], Ldot[6], jac[36];
    lanes::load(t, 3, b, 3, tl);
    lanes::load(R, 9, b, 9, Rl);
    lanes::load(v, 3, b, 3, vl);
    lanes::load(w, 3, b, 3, wl);
    for (int i = 0; i < 6; ++i) {
        const auto leg = leg_state<T>(p, i, 0, tl, Rl, vl, wl);
        L[i] = leg.frame.L;
        Ldot[i] = leg.Ldot;
        const auto row = jacobian_row<T>(leg.frame);
        for (int c = 0; c < 6; ++c) jac[6 * i + c] = row[c];
    }
    lanes::store(L, 6, lengths, 6, b);
    lanes::store(Ldot, 6, rates, 6, b);
    const T bound = frobenius_condition<T>(jac);
    for (int lane = 0; lane < lanes::width<T>; ++lane) {
        const double x = lanes::get(bound, lane);
        double& out = condition[b + lane];
        if (x <= max_condition) {
            out = x;
        } else if (std::isfinite(x)) {
            double J[36];
            for (int k = 0; k < 36; ++k) J[k] = lanes::get(jac[k], lane);
            out = jacobi_condition(J);
        } else {
            out = std::numeric_limits<double>::infinity();
        }
    }
}

// What the environment checks after each control step, over a batch: leg lengths (n,6) m, leg
// rates (n,6) m/s and the Jacobian's condition number (n,) against max_condition.
// condition is the 2-norm condition number wherever it exceeds max_condition (inf when singular or
// non-finite); below it, the cheaper bound ||J||_F ||J^-1||_F >= cond_2, itself at most
// max_condition.  So condition > max_condition holds exactly when cond_2 does.
// Blocks of rows run in vector lanes and on every core (lanes::for_rows).  docs/physics.md
// section 4.4; paper eqs. 7 and 13.
inline void leg_sensors_batch(const double* prm, int64_t n_prm, const double* t, const double* R, const double* v,
                              const double* w, double max_condition, double* lengths, double* rates,
                              double* condition, int64_t n) {
    const ParamRows rows(prm, n_prm, n);
    // a row costs about as much as one forward evaluation: blocks shared with the helpers
    lanes::for_rows(n, 1, [&](int64_t b, auto tag) {
        leg_sensors_row<decltype(tag)>(rows, t, R, v, w, max_condition, lengths, rates, condition, b);
    });
}

}  // namespace kernels
