// The inverse dynamics linear in the inertial parameters: J^T F + W = Y(x, v, a) theta.
//
// docs/physics.md section 5.7 is the account of this file.  theta (N_THETA numbers) holds, in
// order:
// * the platform (10): m_p, the first moment m_p R_0 in {P} (3), and the inertia about P in {P}
//   axes (6, order xx, yy, zz, xy, xz, yz as tensor entries);
// * for each leg i = 0..5 (20 each): the upper leg's m_u, first moment m_u r_u0 about P_i in
//   {D_i} (3), inertia about P_i in {D_i} (6); then the lower leg's m_d, first moment m_d r_d0
//   about B_i in {D_i} (3), inertia about B_i in {D_i} (6);
// * the joints' viscous coefficients C_u, C_p, C_s (3);
// * the legs' drives (2, shared by the six legs): the Coulomb friction f_c, whose force on leg i
//   is f_c tanh(Ldot_i / v_s) (the drive model's smooth sign, v_s the friction_speed argument), and
//   the reflected mass m_r, whose force is m_r Lddot_i.  Both act along the leg, as C_p's viscous
//   force C_p Ldot_i does (which so also holds a drive's viscous friction b: C_p + b is one
//   parameter).
//
// How Y is built: each column is the wrench the kernels' own leg and platform functions give for
// a unit value of that parameter, evaluated in the joint form (eq. 49, flags without CENTROIDAL,
// C3, C4).  In that form every CoM offset r enters the kernels only multiplied by its mass m (r x
// m a_D, m (w x (w x r)), r x m g) and the inertia only linearly, so with m = 1 a kernel's output
// is exactly affine in (r, I): a first-moment column is the difference of two evaluations that
// differ by a unit r, and the mass and inertia columns are single evaluations.  The other forms
// need no other columns: the centroidal form equals the joint form identically (section 5.2);
// C3 (C4) replaces each leg part's (the platform's) inertia about its reference point by that
// inertia plus once more m (|r|^2 E - r r^T) (section 6), which regressor_theta puts into
// theta's inertia, and which for the upper leg, whose reference point P_i moves along the leg,
// also doubles the L-dependent parallel-axis columns below.  C1 and C2 change only the leg
// kinematics and the leg split, which the joint-form evaluation runs with the model's own bits.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "physics/kernels.hpp"

namespace regressor {

using kernels::Inertia;
using kernels::LegBodies;
using kernels::LegState;
using kernels::V3;

constexpr int N_BODY = 10;                      // m, m r (3), I (6)
constexpr int N_LEG = 2 * N_BODY;               // upper leg, lower leg
constexpr int OFF_LEGS = N_BODY;                // after the platform
constexpr int OFF_FRICTION = N_BODY + 6 * N_LEG;
constexpr int OFF_DRIVE = OFF_FRICTION + 3;     // Coulomb friction, reflected mass
constexpr int N_THETA = OFF_DRIVE + 2;          // 135
// Default speed scale v_s (m/s) of the Coulomb friction's tanh, for a platform without a drive's.
constexpr double FRICTION_SPEED = 1e-3;

// Leg i's wrench on the platform at P, {B}, for the leg's LegState<> leg and the acceleration A' of
// P_i in {D_i} and the platform's angular velocity w ({B}): [-F_s; -q x F_s + C_s (omega_l - omega)] sign-flipped to the inverse-dynamics
// side, exactly as kernels::leg_on_platform adds it to h, for given bodies and damping (C_u, C_p,
// C_s).  docs/physics.md sections 5.1, 5.5 and 5.7; paper eqs. 38-41.
inline void leg_wrench(int64_t flags, const LegBodies<>& bodies, const LegState<>& leg, const V3<>& A, const double* w,
                       const double* damping, double* out) {
    double prm[kernels::N_PARAMS] = {0.0};
    prm[kernels::OFF_DAMP] = damping[0];
    prm[kernels::OFF_DAMP + 1] = damping[1];
    prm[kernels::OFF_DAMP + 2] = damping[2];
    const auto& fr = leg.frame;
    const auto [f0, f1, f2] = kernels::leg_force(prm, flags, bodies, leg, A[0], A[1], A[2], 0.0);
    const auto [fs0, fs1, fs2] = kernels::to_base(fr, f0, f1, f2);
    const auto& [q0, q1, q2] = fr.q;
    const auto [m0, m1, m2] = kernels::cross<double>(q0, q1, q2, fs0, fs1, fs2);
    const auto [wl0, wl1, wl2] = kernels::to_base(fr, leg.sigma, leg.w1, leg.w2);
    const double cs = damping[2];
    out[0] = fs0;
    out[1] = fs1;
    out[2] = fs2;
    out[3] = m0 - cs * (wl0 - w[0]);
    out[4] = m1 - cs * (wl1 - w[1]);
    out[5] = m2 - cs * (wl2 - w[2]);
}

// Write column c of the row-major (6, N_THETA) block Y: value (6,), minus base (6,) if given.
// docs/physics.md section 5.7 (no paper equation).
inline void put_column(double* Y, int c, const double* value, const double* base = nullptr) {
    for (int r = 0; r < 6; ++r) Y[N_THETA * r + c] = base ? value[r] - base[r] : value[r];
}

// One leg part's LegBodies<> with only the upper (upper = true) or lower part present: mass m,
// CoM r from B_i and inertia I about B_i, all in {D_i}.  docs/physics.md section 5.7 (no paper
// equation).
inline LegBodies<> part(bool upper, double m, const V3<>& r, const Inertia<>& I) {
    const V3<> zero = {0.0, 0.0, 0.0};
    const Inertia<> none = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    if (upper) return {m, 0.0, r, zero, I, none};
    return {0.0, m, zero, r, none, I};
}

// The platform's own terms M_p acc + h_p, {B}, for a packed row whose platform entries hold
// (m, R_0, I_c), evaluated in the joint form.  docs/physics.md section 5.3; paper eqs. 42-46.
inline void platform_wrench(const double* prm, int64_t flags, const double* R, const double* w, const double* acc,
                            double* out) {
    double Mp[36] = {0.0};
    double h[6] = {0.0};
    kernels::platform_terms(prm, flags, R, w, Mp, h);
    for (int r = 0; r < 6; ++r) {
        double total = h[r];
        for (int c = 0; c < 6; ++c) total += Mp[6 * r + c] * acc[c];
        out[r] = total;
    }
}

// The regressor Y (6, N_THETA), row-major, of one platform state: J^T F + W = Y theta for the
// model flags, with the geometry (joints, Hooke axes) and gravity of the packed row prm (its
// inertial and friction entries are not read).  t, R, v, w the state, acc = [a; alpha], {B}.
// docs/physics.md section 5.7; paper eq. 49 (55) with each body's terms written linear in its
// inertial parameters; the drives' columns as at the top of this file (section 10.2's forces).
inline void regressor_one(const double* prm, int64_t flags, const double* t, const double* R, const double* v,
                          const double* w, const double* acc, double* Y, double friction_speed = FRICTION_SPEED) {
    std::fill(Y, Y + 6 * N_THETA, 0.0);
    const int64_t joint = flags & (kernels::C1 | kernels::C2);  // joint form, the model's kinematics bits
    const double k_leg = (flags & kernels::C3) ? 2.0 : 1.0;     // parallel-axis shifts of the legs
    double col[6], base[6];

    // platform: a packed row with only (m, R_0, I_c) of the column changed
    double p[kernels::N_PARAMS];
    std::copy(prm, prm + kernels::N_PARAMS, p);
    auto set_platform = [&p](double m, int j, const Inertia<>& Ic) {
        p[kernels::OFF_MP] = m;
        for (int k = 0; k < 3; ++k) p[kernels::OFF_RHO + k] = (k == j) ? 1.0 : 0.0;
        const double full[9] = {Ic[0], Ic[3], Ic[4], Ic[3], Ic[1], Ic[5], Ic[4], Ic[5], Ic[2]};
        for (int k = 0; k < 9; ++k) p[kernels::OFF_IP + k] = full[k];
    };
    const Inertia<> none = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    set_platform(1.0, -1, none);
    platform_wrench(p, joint, R, w, acc, base);
    put_column(Y, 0, base);
    for (int j = 0; j < 3; ++j) {
        // m = 1 at R_0 = e_j; I_c = -(E - e_j e_j^T) cancels the shift, so I about P is zero
        Inertia<> Ic = {-1.0, -1.0, -1.0, 0.0, 0.0, 0.0};
        Ic[j] = 0.0;
        set_platform(1.0, j, Ic);
        platform_wrench(p, joint, R, w, acc, col);
        put_column(Y, 1 + j, col, base);
    }
    for (int j = 0; j < 6; ++j) {
        Inertia<> Ic = none;
        Ic[j] = 1.0;
        set_platform(0.0, -1, Ic);
        platform_wrench(p, joint, R, w, acc, col);
        put_column(Y, 4 + j, col);
    }

    const double no_damping[3] = {0.0, 0.0, 0.0};
    for (int i = 0; i < 6; ++i) {
        const LegState<> leg = kernels::leg_state(prm, i, flags, t, R, v, w);
        const V3<> A = kernels::with_platform_acc(acc, leg.frame, leg.a_vel);
        const double L = leg.frame.L;
        const int off_u = OFF_LEGS + N_LEG * i;
        const int off_d = off_u + N_BODY;
        // upper leg about P_i = B_i + L e: its inertia about B_i is the one about P_i plus
        // k_leg (L^2 m S(e) + L (2 (e . m r0) E - e (m r0)^T - (m r0) e^T)), S(r) = |r|^2 E - r r^T
        const V3<> rP = {L, 0.0, 0.0};
        leg_wrench(joint, part(true, 1.0, rP, {0.0, 0.0, 0.0, 0.0, 0.0, 0.0}), leg, A, w, no_damping, base);
        leg_wrench(joint, part(true, 1.0, rP, {0.0, k_leg * L * L, k_leg * L * L, 0.0, 0.0, 0.0}), leg, A, w,
                   no_damping, col);
        put_column(Y, off_u, col);
        const Inertia<> shift_u[3] = {
            {0.0, 2.0 * k_leg * L, 2.0 * k_leg * L, 0.0, 0.0, 0.0},
            {0.0, 0.0, 0.0, -k_leg * L, 0.0, 0.0},
            {0.0, 0.0, 0.0, 0.0, -k_leg * L, 0.0},
        };
        for (int j = 0; j < 3; ++j) {
            V3<> r = rP;
            r[j] += 1.0;
            leg_wrench(joint, part(true, 1.0, r, shift_u[j]), leg, A, w, no_damping, col);
            put_column(Y, off_u + 1 + j, col, base);
        }
        // lower leg about B_i, the point the kernels take moments about
        const V3<> r0 = {0.0, 0.0, 0.0};
        leg_wrench(joint, part(false, 1.0, r0, none), leg, A, w, no_damping, base);
        put_column(Y, off_d, base);
        for (int j = 0; j < 3; ++j) {
            V3<> r = r0;
            r[j] = 1.0;
            leg_wrench(joint, part(false, 1.0, r, none), leg, A, w, no_damping, col);
            put_column(Y, off_d + 1 + j, col, base);
        }
        for (int j = 0; j < 6; ++j) {
            Inertia<> I = none;
            I[j] = 1.0;
            leg_wrench(joint, part(true, 0.0, r0, I), leg, A, w, no_damping, col);
            put_column(Y, off_u + 4 + j, col);
            leg_wrench(joint, part(false, 0.0, r0, I), leg, A, w, no_damping, col);
            put_column(Y, off_d + 4 + j, col);
        }
        // friction: C_u, C_p, C_s shared by the six legs
        for (int j = 0; j < 3; ++j) {
            double d[3] = {0.0, 0.0, 0.0};
            d[j] = 1.0;
            leg_wrench(joint, part(false, 0.0, r0, none), leg, A, w, d, col);
            for (int r = 0; r < 6; ++r) Y[N_THETA * r + OFF_FRICTION + j] += col[r];
        }
        // the drive's forces along the leg: a unit leg force's wrench [e; q x e] times tanh(Ldot / v_s)
        // (Coulomb) and times Lddot (reflected mass), with leg_accel's Lddot of the model's kinematics
        const auto [e0, e1, e2] = kernels::to_base(leg.frame, 1.0, 0.0, 0.0);
        const auto& [q0, q1, q2] = leg.frame.q;
        const auto [n0, n1, n2] = kernels::cross<double>(q0, q1, q2, e0, e1, e2);
        const double unit[6] = {e0, e1, e2, n0, n1, n2};
        const double coulomb = std::tanh(leg.Ldot / friction_speed);
        const double Lddot =
            kernels::leg_accel(joint, leg.frame, leg.Ldot, leg.sigma, leg.w1, leg.w2, A[0], A[1], A[2]).Lddot;
        for (int r = 0; r < 6; ++r) {
            Y[N_THETA * r + OFF_DRIVE] += coulomb * unit[r];
            Y[N_THETA * r + OFF_DRIVE + 1] += Lddot * unit[r];
        }
    }
}

// Y (n, 6, N_THETA) over a batch: prm (Np, N_PARAMS) with Np in {1, n}; t, v, w (n,3); R (n,3,3);
// acc (n,6).  docs/physics.md section 5.7 (no paper equation).
inline void regressor_batch(const double* prm, int64_t n_prm, int64_t flags, const double* t, const double* R,
                            const double* v, const double* w, const double* acc, double* Y, int64_t n,
                            double friction_speed = FRICTION_SPEED) {
    for (int64_t b = 0; b < n; ++b)
        regressor_one(kernels::params_row(prm, n_prm, b), flags, t + 3 * b, R + 9 * b, v + 3 * b, w + 3 * b,
                      acc + 6 * b, Y + 6 * N_THETA * b, friction_speed);
}

}  // namespace regressor
