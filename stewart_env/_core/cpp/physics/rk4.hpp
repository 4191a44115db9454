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

#include "physics/kernels.hpp"
#include "physics/lanes.hpp"

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

//: Where the leg forces of rows b, b + 1, ... come from (leg_forces' source): the control law and
//: its parameter rows ctrl (row r at ctrl + stride * r, stride 0 when one row serves the batch,
//: n_ctrl numbers each), or, when law is nullptr, the held forces (6,) of the rows.
template <typename T>
struct LawRows {
    ControlLaw law;
    const double* ctrl;
    int64_t stride;
    int64_t n_ctrl;
    int64_t b;
    const T* held;
};

// The leg forces (6,), N, at a stage of the rows of src (one per lane of T): the law's at (time,
// x), R the stage's rotation, written into F (a force it leaves unwritten is NaN; a lane in skip
// is not evaluated and gets NaN); or, when there is no law (the zero-order hold), the held forces.
// docs/physics.md section 5.6 (no paper equation).
template <typename T, typename Mask>
inline const T* leg_forces(const LawRows<T>& src, double time, const T* x, const T* R, Mask skip, T* F) {
    if (src.law == nullptr) return src.held;
    for (int k = 0; k < lanes::width<T>; ++k) {
        // a force the law leaves unwritten is NaN, so the rollout stops as non-finite instead of
        // integrating whatever the buffer held
        double xs[13], Rs[9], Fs[6];
        for (int i = 0; i < 6; ++i) Fs[i] = std::numeric_limits<double>::quiet_NaN();
        if (!lanes::lane(skip, k)) {
            for (int j = 0; j < 13; ++j) xs[j] = lanes::get(x[j], k);
            for (int j = 0; j < 9; ++j) Rs[j] = lanes::get(R[j], k);
            src.law(time, xs, Rs, xs + 7, xs + 10, src.ctrl + src.stride * (src.b + k), src.n_ctrl, Fs);
        }
        for (int i = 0; i < 6; ++i) lanes::put(F[i], k, Fs[i]);
    }
    return F;
}

// Unit quaternion q = (w, x, y, z) to rotation matrix R (3,3), normalising q first.
// docs/physics.md section 5.6 (no paper equation).
template <typename T>
inline void quat_to_matrix(const T* q, T* R) {
    const T n = lanes::sqrt_of(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    const T a = q[0] / n;
    const T b = q[1] / n;
    const T c = q[2] / n;
    const T d = q[3] / n;
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
// (time, x) (lanes in skip not evaluated); quaternion rate 0.5 (0, w) * q.  F, R, M, h, acc are
// scratch; M_kept (36,), when not nullptr, receives the mass matrix (kernels::forward_one).
// docs/physics.md section 5.6; the accelerations from paper eq. 49 or 55.
template <typename T, typename Mask>
inline void state_derivative(const T* prm, int64_t flags, const LawRows<T>& src, double time, const T* x, T* F,
                             const T* W, T* R, T* M, T* h, T* acc, Mask skip, T* dx, const T* m_r = nullptr,
                             T* M_kept = nullptr) {
    quat_to_matrix<T>(x + 3, R);
    const T* forces = leg_forces<T>(src, time, x, R, skip, F);
    kernels::forward_one<T>(prm, flags, x, R, x + 7, x + 10, forces, W, M, h, acc, m_r, M_kept);
    dx[0] = x[7];
    dx[1] = x[8];
    dx[2] = x[9];
    const T w0 = x[10];
    const T w1 = x[11];
    const T w2 = x[12];
    const T qa = x[3];
    const T qb = x[4];
    const T qc = x[5];
    const T qd = x[6];
    dx[3] = 0.5 * (-w0 * qb - w1 * qc - w2 * qd);
    dx[4] = 0.5 * (w0 * qa + w1 * qd - w2 * qc);
    dx[5] = 0.5 * (-w0 * qd + w1 * qa + w2 * qb);
    dx[6] = 0.5 * (w0 * qc - w1 * qb + w2 * qa);
    for (int j = 0; j < 6; ++j) dx[7 + j] = acc[j];
}

// One classical RK4 step of dt seconds from the state x (13,) at time t0 to xn (13,), the leg
// forces of src at every stage (lanes in skip not evaluated), the quaternion renormalised.
// Returns, lane by lane, whether xn was finite before the renormalisation.  The step of every
// rollout (rollout_row) and of its derivatives (derivatives.hpp, T a dual number).
// docs/physics.md section 5.6 (no paper equation).
template <typename T, typename Mask>
inline Mask step_state(const T* prm, int64_t flags, const LawRows<T>& src, double t0, double dt, const T* x,
                       const T* W, Mask skip, T* xn, const T* m_r = nullptr) {
    T xs[13], k[4][13], F[6], Rs[9], M[36], h[6], acc[6];
    state_derivative<T>(prm, flags, src, t0, x, F, W, Rs, M, h, acc, skip, k[0], m_r);
    for (int j = 0; j < 13; ++j) xs[j] = x[j] + 0.5 * dt * k[0][j];
    state_derivative<T>(prm, flags, src, t0 + 0.5 * dt, xs, F, W, Rs, M, h, acc, skip, k[1], m_r);
    for (int j = 0; j < 13; ++j) xs[j] = x[j] + 0.5 * dt * k[1][j];
    state_derivative<T>(prm, flags, src, t0 + 0.5 * dt, xs, F, W, Rs, M, h, acc, skip, k[2], m_r);
    for (int j = 0; j < 13; ++j) xs[j] = x[j] + dt * k[2][j];
    state_derivative<T>(prm, flags, src, t0 + dt, xs, F, W, Rs, M, h, acc, skip, k[3], m_r);
    Mask finite = !(T(0.0) != T(0.0));
    for (int j = 0; j < 13; ++j) {
        xn[j] = x[j] + dt / 6.0 * (k[0][j] + 2.0 * k[1][j] + 2.0 * k[2][j] + k[3][j]);
        finite = finite && lanes::finite(xn[j]);
    }
    const T nq = lanes::sqrt_of(xn[3] * xn[3] + xn[4] * xn[4] + xn[5] * xn[5] + xn[6] * xn[6]);
    for (int j = 3; j < 7; ++j) xn[j] /= nq;
    return finite;
}

// Sample s of lane k of the rows of src (batch row src.b + k) into rec: the lane's state x and
// the forces there.  docs/physics.md section 5.6 (no paper equation).
template <typename T>
inline void record(const LawRows<T>& src, double time, const T* x, int k, const Record& rec, int64_t s) {
    double xs[13], Rs[9], Fs[6];
    for (int j = 0; j < 13; ++j) xs[j] = lanes::get(x[j], k);
    quat_to_matrix<double>(xs + 3, Rs);
    double held[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    if (src.held != nullptr)
        for (int i = 0; i < 6; ++i) held[i] = lanes::get(src.held[i], k);
    const LawRows<double> one{src.law, src.ctrl, src.stride, src.n_ctrl, src.b + k, held};
    const double* forces = leg_forces<double>(one, time, xs, Rs, false, Fs);
    const int64_t row = (src.b + k) * rec.samples + s;
    for (int j = 0; j < 3; ++j) {
        rec.t[3 * row + j] = xs[j];
        rec.v[3 * row + j] = xs[7 + j];
        rec.w[3 * row + j] = xs[10 + j];
    }
    for (int j = 0; j < 9; ++j) rec.R[9 * row + j] = Rs[j];
    for (int j = 0; j < 6; ++j) rec.F[6 * row + j] = forces[j];
}

// Rows b, b + 1, ... of rollout_batch and rollout_law_batch, as many as T carries
// (docs/physics.md section 5.6; no paper equation); rec the record arrays, or nullptr (nothing
// recorded).  ctrl (n_ctrl_rows, n_ctrl): the law's parameter rows, or the held forces
// (n_ctrl = 6).  A lane whose state stops being finite keeps that state while the others go on.
// m_r (6,): the legs' reflected masses in the dynamics (kernels::forward_one), nullptr: none.
template <typename T>
inline void rollout_row(const kernels::ParamRows& prm, int64_t flags, double* t, double* R, double* v, double* w,
                        ControlLaw law, const double* ctrl, int64_t n_ctrl_rows, int64_t n_ctrl, const double* W,
                        double time, double dt, int64_t steps, int64_t every, const Record* rec, int64_t b,
                        const double* m_r = nullptr) {
    constexpr int width = lanes::width<T>;
    using Mask = decltype(lanes::finite(T{}));
    kernels::ParamScratch<T> scratch;
    const T* p = prm.rows(b, scratch.rows);
    // the row does not change over the rollout: one platform's spread into leg lanes once
    const kernels::SpreadFor<T> spread(p);
    T held[6];
    const int64_t stride = n_ctrl_rows == 1 ? 0 : n_ctrl;
    if (law == nullptr) lanes::load(ctrl, stride, b, 6, held);
    const LawRows<T> src{law, ctrl, stride, n_ctrl, b, law == nullptr ? held : nullptr};
    T Wb[6];
    lanes::load(W, 6, b, 6, Wb);
    T x[13], xn[13], Rs[9], mr[6];
    if (m_r != nullptr)
        for (int i = 0; i < 6; ++i) mr[i] = T(m_r[i]);
    const T* reflected = m_r != nullptr ? mr : nullptr;
    lanes::load(t, 3, b, 3, x);
    lanes::load(v, 3, b, 3, x + 7);
    lanes::load(w, 3, b, 3, x + 10);
    for (int lane = 0; lane < width; ++lane) {
        double q[4];
        matrix_to_quat(R + 9 * (b + lane), q);
        for (int j = 0; j < 4; ++j) lanes::put(x[3 + j], lane, q[j]);
    }
    const bool recording = rec != nullptr && every > 0;
    int64_t recorded[width];
    for (int lane = 0; lane < width; ++lane) {
        recorded[lane] = 0;
        if (recording) record<T>(src, time, x, lane, *rec, recorded[lane]++);
    }
    const Mask none = T(0.0) != T(0.0);
    Mask stopped = none;
    for (int64_t step = 0; step < steps; ++step) {
        const double t0 = time + static_cast<double>(step) * dt;
        const Mask finite = step_state<T>(p, flags, src, t0, dt, x, Wb, stopped, xn, reflected);
        // a lane stopped at an earlier step keeps its first non-finite state
        for (int j = 0; j < 13; ++j) x[j] = lanes::select(stopped, x[j], xn[j]);
        if (recording && (step + 1) % every == 0) {
            for (int lane = 0; lane < width; ++lane)
                if (!lanes::lane(stopped, lane))
                    record<T>(src, time + static_cast<double>(step + 1) * dt, x, lane, *rec, recorded[lane]++);
        }
        stopped = stopped || !finite;
        if (lanes::all(stopped)) break;
    }
    if (rec != nullptr) {
        // after a stop: the non-finite state to the end
        for (int lane = 0; lane < width; ++lane)
            for (int64_t s = recorded[lane]; s < rec->samples; ++s)
                record<T>(src, time + static_cast<double>(steps) * dt, x, lane, *rec, s);
    }
    lanes::store(x, 3, t, 3, b);
    lanes::store(x + 7, 3, v, 3, b);
    lanes::store(x + 10, 3, w, 3, b);
    quat_to_matrix<T>(x + 3, Rs);
    lanes::store(Rs, 9, R, 9, b);
}

// Integrate steps classical RK4 steps of dt seconds from time s, the leg forces given by law (see
// the file comment) with the parameter row ctrl[b] (ctrl of shape (n, n_ctrl), or (1, n_ctrl) for
// one row shared by the batch) at every stage; W (n,6) held constant.
// t (n,3), R (n,3,3), v (n,3), w (n,3) are overwritten with the final state.  The orientation is
// carried as a unit quaternion (renormalised after each step) so R stays a rotation.  With every
// > 0 the state after every every steps, the start included, is written into rec (T = steps /
// every + 1 samples per row), and the law's forces at that state into rec.F; with every == 0
// nothing is recorded.  A row whose state stops being finite is left at its first non-finite
// value (its later samples too).  Blocks of rows run in vector lanes and on every core
// (lanes.hpp), each row's numbers those it has alone; the law may be called from several threads
// at once.  docs/physics.md section 5.6 (no paper equation).
inline void rollout_law_batch(const double* prm, int64_t n_prm, int64_t flags, double* t, double* R, double* v,
                              double* w, ControlLaw law, const double* ctrl, int64_t n_ctrl_rows, int64_t n_ctrl,
                              const double* W, double time, double dt, int64_t steps, int64_t every,
                              const Record* rec, int64_t n) {
    const kernels::ParamRows rows(prm, n_prm, n);
    lanes::for_rows(n, 4 * steps, [&](int64_t b, auto tag) {
        rollout_row<decltype(tag)>(rows, flags, t, R, v, w, law, ctrl, n_ctrl_rows, n_ctrl, W, time, dt, steps,
                                   every, every > 0 ? rec : nullptr, b);
    });
}

// Integrate steps classical RK4 steps of dt seconds with F (n,6) and W (n,6) held constant:
// rollout_law_batch without a law (the zero-order hold), nothing recorded.  t (n,3), R (n,3,3),
// v (n,3), w (n,3) are overwritten with the final state.  The env's step.
// docs/physics.md section 5.6 (no paper equation).
inline void rollout_batch(const double* prm, int64_t n_prm, int64_t flags, double* t, double* R, double* v,
                          double* w, const double* F, const double* W, double dt, int64_t steps, int64_t n) {
    rollout_law_batch(prm, n_prm, flags, t, R, v, w, nullptr, F, n, 6, W, 0.0, dt, steps, 0, nullptr, n);
}

}  // namespace rk4
