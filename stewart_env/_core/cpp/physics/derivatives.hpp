// Exact derivatives of the forward dynamics and of one control step, by forward-mode automatic
// differentiation of the kernels themselves (docs/physics.md section 11).
//
// kernels::forward_one and rk4::step_state run on dual numbers (dual.hpp) with 18 directions: the
// state's 12 tangent coordinates x = (dt, dtheta, v, w) and the 6 leg forces.  dt moves P's origin
// in {B}; dtheta rotates the platform on the left in {B}, R' = exp([dtheta]x) R, so
// dR/dtheta_k = [e_k]x R and, for the integrator's unit quaternion q, dq/dtheta_k = (0, e_k)/2 * q;
// v and w are the velocity of P's origin and the angular velocity in {B}.  The next state of a
// step is read back in the same coordinates about the next rotation: dtheta_next = 2 vec(dq q*).
// The values are those of the double kernels bit for bit (dual.hpp), so the acceleration is
// forward_batch's and the next state rollout_batch's.
#pragma once

#include <cstdint>
#include <limits>

#include "physics/dual.hpp"  // first: the kernels' lanes:: calls find its overloads
#include "physics/kernels.hpp"
#include "physics/lanes.hpp"
#include "physics/rk4.hpp"

namespace derivatives {

//: Directions of the derivatives: the 12 tangent coordinates of the state, then the 6 leg forces.
constexpr int DIRECTIONS = 18;
using D = dual::Dual<DIRECTIONS>;

//: Where each group of directions starts: position, rotation, velocity, angular velocity, forces.
constexpr int DIR_T = 0, DIR_THETA = 3, DIR_V = 6, DIR_W = 9, DIR_F = 12;

// The packed parameter row as duals of zero derivative (constants of the differentiation).
inline void constant_params(const double* prm, D* out) {
    for (int k = 0; k < kernels::N_PARAMS; ++k) out[k] = D(prm[k]);
}

// A vector of three seeded along directions first, first + 1, first + 2.
inline void seed3(const double* x, int first, D* out) {
    for (int j = 0; j < 3; ++j) out[j] = D::seed(x[j], first + j);
}

// The six leg forces seeded along the force directions, and the wrench as constants.
inline void seed_forces(const double* F, const double* W, D* Fd, D* Wd) {
    for (int i = 0; i < 6; ++i) {
        Fd[i] = D::seed(F[i], DIR_F + i);
        Wd[i] = D(W[i]);
    }
}

// Whether every value and derivative in x (size duals) is finite.
inline bool all_finite(const D* x, int size) {
    for (int j = 0; j < size; ++j) {
        if (!std::isfinite(x[j].v)) return false;
        if (x[j].active)
            for (int k = 0; k < DIRECTIONS; ++k)
                if (!std::isfinite(x[j].d[k])) return false;
    }
    return true;
}

// The platform's acceleration acc (6,) and its Jacobian jac (6,18) (columns: dt, dtheta, v, w, F)
// for one platform; m_r (6,) the legs' reflected masses or nullptr.  Returns whether all are
// finite (a singular pose gives NaN or inf, which the caller flags).  docs/physics.md section 11.
inline bool acceleration_jacobian_one(const double* prm, int64_t flags, const double* t, const double* R,
                                      const double* v, const double* w, const double* F, const double* W,
                                      const double* m_r, double* acc, double* jac) {
    D P[kernels::N_PARAMS], td[3], Rd[9], vd[3], wd[3], Fd[6], Wd[6], M[36], h[6], out[6], mr[6];
    constant_params(prm, P);
    seed3(t, DIR_T, td);
    seed3(v, DIR_V, vd);
    seed3(w, DIR_W, wd);
    seed_forces(F, W, Fd, Wd);
    // R' = exp([dtheta]x) R: column c of dR/dtheta_k is e_k x (column c of R)
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) {
            D& x = Rd[3 * r + c];
            x = D(R[3 * r + c]);
            x.active = true;
            for (int k = 0; k < DIRECTIONS; ++k) x.d[k] = 0.0;
        }
    for (int c = 0; c < 3; ++c) {
        const double col[3] = {R[c], R[3 + c], R[6 + c]};
        // e_0 x col = (0, -col2, col1), e_1 x col = (col2, 0, -col0), e_2 x col = (-col1, col0, 0)
        Rd[3 * 1 + c].d[DIR_THETA + 0] = -col[2];
        Rd[3 * 2 + c].d[DIR_THETA + 0] = col[1];
        Rd[3 * 0 + c].d[DIR_THETA + 1] = col[2];
        Rd[3 * 2 + c].d[DIR_THETA + 1] = -col[0];
        Rd[3 * 0 + c].d[DIR_THETA + 2] = -col[1];
        Rd[3 * 1 + c].d[DIR_THETA + 2] = col[0];
    }
    if (m_r != nullptr)
        for (int i = 0; i < 6; ++i) mr[i] = D(m_r[i]);
    kernels::forward_one<D>(P, flags, td, Rd, vd, wd, Fd, Wd, M, h, out, m_r == nullptr ? nullptr : mr);
    for (int r = 0; r < 6; ++r) {
        acc[r] = out[r].v;
        for (int k = 0; k < DIRECTIONS; ++k) jac[DIRECTIONS * r + k] = out[r].derivative(k);
    }
    return all_finite(out, 6);
}

// One control step of `steps` RK4 substeps of dt seconds (forces F and wrench W held) from
// (t, R, v, w) of one platform: the next state into (t_next, R_next, v_next, w_next) and its
// Jacobian jac (12,18) (rows: the next state's dt, dtheta, v, w; columns: the state's, then F).
// The integrator's own steps (rk4::step_state), started as rk4::rollout_row starts them.  Returns
// whether all are finite.  docs/physics.md sections 5.6 and 11.
inline bool step_jacobian_one(const double* prm, int64_t flags, const double* t, const double* R,
                              const double* v, const double* w, const double* F, const double* W,
                              const double* m_r, double dt, int64_t steps, double* t_next, double* R_next,
                              double* v_next, double* w_next, double* jac) {
    D P[kernels::N_PARAMS], x[13], xn[13], Fd[6], Wd[6], mr[6];
    constant_params(prm, P);
    seed3(t, DIR_T, x);
    seed3(v, DIR_V, x + 7);
    seed3(w, DIR_W, x + 10);
    seed_forces(F, W, Fd, Wd);
    double q[4];
    rk4::matrix_to_quat(R, q);
    // dq/dtheta_k = (0, e_k)/2 * q = (-q_k, q0 e_k + e_k x q_vec) / 2 for q = (q0, q_vec)
    for (int j = 0; j < 4; ++j) {
        x[3 + j] = D(q[j]);
        x[3 + j].active = true;
        for (int k = 0; k < DIRECTIONS; ++k) x[3 + j].d[k] = 0.0;
    }
    for (int k = 0; k < 3; ++k) {
        double e[3] = {0.0, 0.0, 0.0};
        e[k] = 1.0;
        const double c[3] = {e[1] * q[3] - e[2] * q[2], e[2] * q[1] - e[0] * q[3], e[0] * q[2] - e[1] * q[1]};
        x[3].d[DIR_THETA + k] = -0.5 * q[1 + k];
        for (int j = 0; j < 3; ++j) x[4 + j].d[DIR_THETA + k] = 0.5 * (q[0] * e[j] + c[j]);
    }
    if (m_r != nullptr)
        for (int i = 0; i < 6; ++i) mr[i] = D(m_r[i]);
    const rk4::LawRows<D> src{nullptr, nullptr, 0, 6, 0, Fd};
    bool finite = true;
    for (int64_t step = 0; step < steps && finite; ++step) {
        finite = rk4::step_state<D>(P, flags, src, static_cast<double>(step) * dt, dt, x, Wd, false, xn,
                                    m_r == nullptr ? nullptr : mr);
        for (int j = 0; j < 13; ++j) x[j] = xn[j];
    }
    double qn[4];
    for (int j = 0; j < 4; ++j) qn[j] = x[3 + j].v;
    rk4::quat_to_matrix<double>(qn, R_next);
    for (int j = 0; j < 3; ++j) {
        t_next[j] = x[j].v;
        v_next[j] = x[7 + j].v;
        w_next[j] = x[10 + j].v;
    }
    for (int k = 0; k < DIRECTIONS; ++k) {
        // dtheta_next = 2 vec(dq q*), q* = (q0, -q_vec): the left rotation that moves q by dq
        const double d0 = x[3].derivative(k), d1 = x[4].derivative(k), d2 = x[5].derivative(k);
        const double d3 = x[6].derivative(k);
        const double a = qn[0], b = -qn[1], c = -qn[2], e = -qn[3];
        const double theta[3] = {
            2.0 * (d0 * b + d1 * a + d2 * e - d3 * c),
            2.0 * (d0 * c - d1 * e + d2 * a + d3 * b),
            2.0 * (d0 * e + d1 * c - d2 * b + d3 * a),
        };
        for (int j = 0; j < 3; ++j) {
            jac[DIRECTIONS * j + k] = x[j].derivative(k);
            jac[DIRECTIONS * (3 + j) + k] = theta[j];
            jac[DIRECTIONS * (6 + j) + k] = x[7 + j].derivative(k);
            jac[DIRECTIONS * (9 + j) + k] = x[10 + j].derivative(k);
        }
    }
    return finite && all_finite(x, 13);
}

// The NaN a row that is not finite gets throughout (a partly finite Jacobian is no Jacobian).
inline void fill_nan(double* x, int size) {
    for (int j = 0; j < size; ++j) x[j] = std::numeric_limits<double>::quiet_NaN();
}

// acceleration_jacobian_one over a batch of n rows: prm (n_prm, N_PARAMS) with n_prm 1 or n; t, v,
// w (n,3); R (n,3,3); F, W (n,6); m_r (n_mr, 6) with n_mr 1 or n, or nullptr; acc (n,6), jac
// (n,6,18), a row NaN throughout where not finite; finite (n,) whether it is.  Rows run on every
// core (lanes::for_each_row), each row's numbers those it has alone.
inline void acceleration_jacobian_batch(const double* prm, int64_t n_prm, int64_t flags, const double* t,
                                        const double* R, const double* v, const double* w, const double* F,
                                        const double* W, const double* m_r, int64_t n_mr, double* acc, double* jac,
                                        bool* finite, int64_t n) {
    // a row costs about 30 forward evaluations
    lanes::for_each_row(n, 30, [&](int64_t b) {
        const double* mr = m_r == nullptr ? nullptr : m_r + 6 * (n_mr == 1 ? 0 : b);
        finite[b] = acceleration_jacobian_one(kernels::params_row(prm, n_prm, b), flags, t + 3 * b, R + 9 * b,
                                              v + 3 * b, w + 3 * b, F + 6 * b, W + 6 * b, mr, acc + 6 * b,
                                              jac + 6 * DIRECTIONS * b);
        if (!finite[b]) {
            fill_nan(acc + 6 * b, 6);
            fill_nan(jac + 6 * DIRECTIONS * b, 6 * DIRECTIONS);
        }
    });
}

// step_jacobian_one over a batch (shapes as acceleration_jacobian_batch; t_next, v_next, w_next
// (n,3), R_next (n,3,3), jac (n,12,18)).
inline void step_jacobian_batch(const double* prm, int64_t n_prm, int64_t flags, const double* t, const double* R,
                                const double* v, const double* w, const double* F, const double* W,
                                const double* m_r, int64_t n_mr, double dt, int64_t steps, double* t_next,
                                double* R_next, double* v_next, double* w_next, double* jac, bool* finite,
                                int64_t n) {
    lanes::for_each_row(n, 120 * steps, [&](int64_t b) {
        const double* mr = m_r == nullptr ? nullptr : m_r + 6 * (n_mr == 1 ? 0 : b);
        finite[b] = step_jacobian_one(kernels::params_row(prm, n_prm, b), flags, t + 3 * b, R + 9 * b, v + 3 * b,
                                      w + 3 * b, F + 6 * b, W + 6 * b, mr, dt, steps, t_next + 3 * b,
                                      R_next + 9 * b, v_next + 3 * b, w_next + 3 * b, jac + 12 * DIRECTIONS * b);
        if (!finite[b]) {
            fill_nan(t_next + 3 * b, 3);
            fill_nan(R_next + 9 * b, 9);
            fill_nan(v_next + 3 * b, 3);
            fill_nan(w_next + 3 * b, 3);
            fill_nan(jac + 12 * DIRECTIONS * b, 12 * DIRECTIONS);
        }
    });
}

}  // namespace derivatives
