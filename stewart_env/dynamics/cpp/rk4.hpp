// Classical RK4 over a batch of platforms, with a compiled control law evaluated at every stage.
//
// The one time integrator of the package (docs/physics.md section 5.6).  The state of a row is
// x = [t (3), quaternion (4), v (3), w (3)]: position of P's origin, orientation as a unit
// quaternion (w, x, y, z), velocity of P's origin and angular velocity, all in {B}.  At each of
// the four stages of a step the control law gives the leg forces for the stage's time and state,
// and the forward dynamics (kernels::forward_one) the accelerations.
//
// A control law is a C function (ControlLaw) that returns nothing and writes six leg forces:
//
//     law(time, position, rotation, velocity, angular_velocity, params, n_params, forces)
//
// time (s); position (3,), rotation (3,3) row-major, velocity (3,), angular_velocity (3,): the
// stage's state in {B}, to be read only; params (n_params,): the law's own parameter row (gains,
// targets, ... in a layout the law defines); forces (6,): the leg forces, N, positive extending
// the leg.  Without a law (nullptr) the forces are held constant over the call (the zero-order
// hold of the environment's step).
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>

#include "kernels.hpp"

namespace rk4 {

//: A control law (see the file comment).
typedef void (*ControlLaw)(double time, const double* position, const double* rotation, const double* velocity,
                           const double* angular_velocity, const double* params, int64_t n_params, double* forces);

//: Where a recorded rollout writes its samples (record's target): rec_t (n,T,3), rec_R (n,T,3,3),
//: rec_v (n,T,3), rec_w (n,T,3), rec_F (n,T,6) with T samples per row.
struct Record {
    double* t;
    double* R;
    double* v;
    double* w;
    double* F;
    int64_t samples;
};

// The simplest control law: forces = params[:6], N, whatever the time and state (the hold of
// rollout_batch, for a rollout that records its trajectory); a row shorter than six leaves the
// rest NaN.  docs/physics.md section 5.6 (no paper equation).
extern "C" inline void constant_forces(double, const double*, const double*, const double*, const double*,
                                       const double* params, int64_t n_params, double* forces) {
    for (int i = 0; i < 6 && i < n_params; ++i) forces[i] = params[i];
}

// The leg Jacobian J (6,6), row-major, of one platform, dL/dt = J [v; omega]: row i =
// [e_i, q_i x e_i] with q_i = R p_i ({B}); prm a packed parameter row (N_PARAMS,).  For control
// laws.  docs/physics.md section 4.4; paper eq. 13.
extern "C" inline void law_jacobian(const double* prm, const double* t, const double* R, double* J) {
    kernels::jacobian_one(prm, t, R, J);
}

// Leg forces out (6,), N, that give one platform the accelerations acc = [a; alpha] (6,) under the
// external wrench W (6,), {B}; prm a packed parameter row, flags the model's switch bits.  For
// control laws (e.g. gravity compensation: v = w = acc = W = 0).  docs/physics.md section 5.5;
// paper eq. 49 or 55.
extern "C" inline void law_inverse_dynamics(const double* prm, int64_t flags, const double* t, const double* R,
                                            const double* v, const double* w, const double* acc, const double* W,
                                            double* out) {
    double M[36];
    double h[6];
    kernels::inverse_one(prm, flags, t, R, v, w, acc, W, M, h, out);
}

// The leg forces (6,), N, at a stage: the law's at (time, x), R the stage's rotation, written
// into F (a force it leaves unwritten is NaN); or, when law is nullptr (the zero-order hold),
// ctrl itself.  docs/physics.md section 5.6 (no paper equation).
inline const double* leg_forces(ControlLaw law, const double* ctrl, int64_t n_ctrl, double time, const double* x,
                                const double* R, double* F) {
    if (law == nullptr) return ctrl;
    // a force the law leaves unwritten is NaN, so the rollout stops as non-finite instead of
    // integrating whatever the buffer held
    for (int i = 0; i < 6; ++i) F[i] = std::numeric_limits<double>::quiet_NaN();
    law(time, x, R, x + 7, x + 10, ctrl, n_ctrl, F);
    return F;
}

// Unit quaternion q = (w, x, y, z) to rotation matrix R (3,3), normalising q first.
// docs/physics.md section 5.6 (no paper equation).
inline void quat_to_matrix(const double* q, double* R) {
    const double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    const double a = q[0] / n;
    const double b = q[1] / n;
    const double c = q[2] / n;
    const double d = q[3] / n;
    R[0] = a * a + b * b - c * c - d * d;
    R[1] = 2.0 * (b * c - a * d);
    R[2] = 2.0 * (b * d + a * c);
    R[3] = 2.0 * (b * c + a * d);
    R[4] = a * a - b * b + c * c - d * d;
    R[5] = 2.0 * (c * d - a * b);
    R[6] = 2.0 * (b * d - a * c);
    R[7] = 2.0 * (c * d + a * b);
    R[8] = a * a - b * b - c * c + d * d;
}

// Rotation matrix to unit quaternion (w, x, y, z), w >= 0 (Shepperd's method: the division is by
// the largest of the four candidates, so a half turn is as exact as any other rotation).
// docs/physics.md section 5.6 (no paper equation).
inline void matrix_to_quat(const double* R, double* q) {
    const double tr = R[0] + R[4] + R[8];
    if (tr > 0.0) {
        const double s = 2.0 * std::sqrt(1.0 + tr);
        q[0] = 0.25 * s;
        q[1] = (R[7] - R[5]) / s;
        q[2] = (R[2] - R[6]) / s;
        q[3] = (R[3] - R[1]) / s;
    } else if (R[0] > R[4] && R[0] > R[8]) {
        const double s = 2.0 * std::sqrt(1.0 + R[0] - R[4] - R[8]);
        q[0] = (R[7] - R[5]) / s;
        q[1] = 0.25 * s;
        q[2] = (R[1] + R[3]) / s;
        q[3] = (R[2] + R[6]) / s;
    } else if (R[4] > R[8]) {
        const double s = 2.0 * std::sqrt(1.0 + R[4] - R[0] - R[8]);
        q[0] = (R[2] - R[6]) / s;
        q[1] = (R[1] + R[3]) / s;
        q[2] = 0.25 * s;
        q[3] = (R[5] + R[7]) / s;
    } else {
        const double s = 2.0 * std::sqrt(1.0 + R[8] - R[0] - R[4]);
        q[0] = (R[3] - R[1]) / s;
        q[1] = (R[2] + R[6]) / s;
        q[2] = (R[5] + R[7]) / s;
        q[3] = 0.25 * s;
    }
    if (q[0] < 0.0)
        for (int j = 0; j < 4; ++j) q[j] = -q[j];
}

// dx/dt for x = [t (3), quaternion (4), v (3), w (3)] under the leg forces of leg_forces at
// (time, x); quaternion rate 0.5 (0, w) * q.  F, R, M, h, acc are scratch.
// docs/physics.md section 5.6; the accelerations from paper eq. 49 or 55.
inline void state_derivative(const double* prm, int64_t flags, ControlLaw law, const double* ctrl, int64_t n_ctrl,
                             double time, const double* x, double* F, const double* W, double* R, double* M,
                             double* h, double* acc, double* dx) {
    quat_to_matrix(x + 3, R);
    const double* forces = leg_forces(law, ctrl, n_ctrl, time, x, R, F);
    kernels::forward_one(prm, flags, x, R, x + 7, x + 10, forces, W, M, h, acc);
    dx[0] = x[7];
    dx[1] = x[8];
    dx[2] = x[9];
    const double w0 = x[10];
    const double w1 = x[11];
    const double w2 = x[12];
    const double qa = x[3];
    const double qb = x[4];
    const double qc = x[5];
    const double qd = x[6];
    dx[3] = 0.5 * (-w0 * qb - w1 * qc - w2 * qd);
    dx[4] = 0.5 * (w0 * qa + w1 * qd - w2 * qc);
    dx[5] = 0.5 * (-w0 * qd + w1 * qa + w2 * qb);
    dx[6] = 0.5 * (w0 * qc - w1 * qb + w2 * qa);
    for (int j = 0; j < 6; ++j) dx[7 + j] = acc[j];
}

// Sample s of row b into rec: the state x and the law's forces there.  docs/physics.md section
// 5.6 (no paper equation).
inline void record(ControlLaw law, const double* c, int64_t n_ctrl, double time, const double* x, double* Rs,
                   double* F, const Record& rec, int64_t b, int64_t s) {
    quat_to_matrix(x + 3, Rs);
    const double* forces = leg_forces(law, c, n_ctrl, time, x, Rs, F);
    const int64_t k = b * rec.samples + s;
    for (int j = 0; j < 3; ++j) {
        rec.t[3 * k + j] = x[j];
        rec.v[3 * k + j] = x[7 + j];
        rec.w[3 * k + j] = x[10 + j];
    }
    for (int j = 0; j < 9; ++j) rec.R[9 * k + j] = Rs[j];
    for (int j = 0; j < 6; ++j) rec.F[6 * k + j] = forces[j];
}

// Row b of rollout_batch and rollout_law_batch (docs/physics.md section 5.6; no paper equation);
// rec the record arrays, or nullptr (nothing recorded).  ctrl (n_ctrl_rows, n_ctrl): the law's
// parameter rows, or the held forces (n_ctrl = 6).
inline void rollout_row(const double* prm, int64_t n_prm, int64_t flags, double* t, double* R, double* v, double* w,
                        ControlLaw law, const double* ctrl, int64_t n_ctrl_rows, int64_t n_ctrl, const double* W,
                        double time, double dt, int64_t steps, int64_t every, const Record* rec, int64_t b) {
    const double* p = kernels::params_row(prm, n_prm, b);
    const double* c = n_ctrl_rows == 1 ? ctrl : ctrl + n_ctrl * b;
    const double* Wb = W + 6 * b;
    double x[13];
    double xs[13];
    double k[4][13];
    double F[6];
    double Rs[9];
    double M[36];
    double h[6];
    double acc[6];
    for (int j = 0; j < 3; ++j) {
        x[j] = t[3 * b + j];
        x[7 + j] = v[3 * b + j];
        x[10 + j] = w[3 * b + j];
    }
    matrix_to_quat(R + 9 * b, x + 3);
    int64_t recorded = 0;
    if (rec != nullptr && every > 0) {
        record(law, c, n_ctrl, time, x, Rs, F, *rec, b, 0);
        recorded = 1;
    }
    for (int64_t step = 0; step < steps; ++step) {
        const double t0 = time + static_cast<double>(step) * dt;
        state_derivative(p, flags, law, c, n_ctrl, t0, x, F, Wb, Rs, M, h, acc, k[0]);
        for (int j = 0; j < 13; ++j) xs[j] = x[j] + 0.5 * dt * k[0][j];
        state_derivative(p, flags, law, c, n_ctrl, t0 + 0.5 * dt, xs, F, Wb, Rs, M, h, acc, k[1]);
        for (int j = 0; j < 13; ++j) xs[j] = x[j] + 0.5 * dt * k[1][j];
        state_derivative(p, flags, law, c, n_ctrl, t0 + 0.5 * dt, xs, F, Wb, Rs, M, h, acc, k[2]);
        for (int j = 0; j < 13; ++j) xs[j] = x[j] + dt * k[2][j];
        state_derivative(p, flags, law, c, n_ctrl, t0 + dt, xs, F, Wb, Rs, M, h, acc, k[3]);
        bool finite = true;
        for (int j = 0; j < 13; ++j) {
            x[j] += dt / 6.0 * (k[0][j] + 2.0 * k[1][j] + 2.0 * k[2][j] + k[3][j]);
            finite = finite && std::isfinite(x[j]);
        }
        const double nq = std::sqrt(x[3] * x[3] + x[4] * x[4] + x[5] * x[5] + x[6] * x[6]);
        for (int j = 3; j < 7; ++j) x[j] /= nq;
        if (rec != nullptr && every > 0 && (step + 1) % every == 0) {
            record(law, c, n_ctrl, time + static_cast<double>(step + 1) * dt, x, Rs, F, *rec, b, recorded);
            recorded += 1;
        }
        if (!finite) break;
    }
    if (rec != nullptr) {
        // after a break: the non-finite state to the end
        for (int64_t s = recorded; s < rec->samples; ++s)
            record(law, c, n_ctrl, time + static_cast<double>(steps) * dt, x, Rs, F, *rec, b, s);
    }
    for (int j = 0; j < 3; ++j) {
        t[3 * b + j] = x[j];
        v[3 * b + j] = x[7 + j];
        w[3 * b + j] = x[10 + j];
    }
    quat_to_matrix(x + 3, R + 9 * b);
}

// Integrate steps classical RK4 steps of dt seconds with F (n,6) and W (n,6) held constant:
// rollout_law_batch without a law (the zero-order hold), nothing recorded.  t (n,3), R (n,3,3),
// v (n,3), w (n,3) are overwritten with the final state.  The env's step.
// docs/physics.md section 5.6 (no paper equation).
inline void rollout_batch(const double* prm, int64_t n_prm, int64_t flags, double* t, double* R, double* v,
                          double* w, const double* F, const double* W, double dt, int64_t steps, int64_t n) {
    for (int64_t b = 0; b < n; ++b)
        rollout_row(prm, n_prm, flags, t, R, v, w, nullptr, F, n, 6, W, 0.0, dt, steps, 0, nullptr, b);
}

// Integrate steps classical RK4 steps of dt seconds from time s, the leg forces given by law (see
// the file comment) with the parameter row ctrl[b] (ctrl of shape (n, n_ctrl), or (1, n_ctrl) for
// one row shared by the batch) at every stage; W (n,6) held constant.
// t (n,3), R (n,3,3), v (n,3), w (n,3) are overwritten with the final state.  The orientation is
// carried as a unit quaternion (renormalised after each step) so R stays a rotation.  With every
// > 0 the state after every every steps, the start included, is written into rec (T = steps /
// every + 1 samples per row), and the law's forces at that state into rec.F; with every == 0
// nothing is recorded.  A row whose state stops being finite is left at its first non-finite
// value (its later samples too).  docs/physics.md section 5.6 (no paper equation).
inline void rollout_law_batch(const double* prm, int64_t n_prm, int64_t flags, double* t, double* R, double* v,
                              double* w, ControlLaw law, const double* ctrl, int64_t n_ctrl_rows, int64_t n_ctrl,
                              const double* W, double time, double dt, int64_t steps, int64_t every,
                              const Record* rec, int64_t n) {
    for (int64_t b = 0; b < n; ++b)
        rollout_row(prm, n_prm, flags, t, R, v, w, law, ctrl, n_ctrl_rows, n_ctrl, W, time, dt, steps, every,
                    every > 0 ? rec : nullptr, b);
}

}  // namespace rk4
