// Exact derivatives of the forward dynamics and of one control step, by forward-mode automatic
// differentiation of the kernels themselves (docs/physics.md section 11).
//
// The Jacobians' 18 columns are the state's 12 tangent coordinates x = (dt, dtheta, v, w) and the 6
// leg forces.  dt moves P's origin in {B}; dtheta rotates the platform on the left in {B},
// R' = exp([dtheta]x) R, so dR/dtheta_k = [e_k]x R and, for the integrator's quaternion q,
// dq/dtheta_k = (0, e_k)/2 * q; v and w are the velocity of P's origin and the angular velocity in
// {B}.  The next state of a step is read back in the same coordinates about the next rotation:
// dtheta_next = 2 vec(dq q*).
//
// The values are the value kernels' own (kernels::forward_one, rk4::state_derivative on double),
// so the acceleration is forward_batch's and the next state rollout_batch's bit for bit.  The
// acceleration's Jacobian comes from the equations of motion M(x) acc + h(x) - J(x)^T F - W = 0
// differentiated at the fixed acceleration: M dacc = -dr for their left side r at that
// acceleration, the inverse dynamics' pulls of the legs and the platform (kernels::leg_shares and
// kernels::platform_terms given acc), which run on dual numbers (dual.hpp) of the 12 state
// directions with no column of the mass matrix among them; the forces' columns are M^-1 J^T (the
// acceleration is affine in them), and one elimination with the values' M gives all 18 columns
// (acceleration_tangent).  A control step chains its RK4 stages by hand: each stage's acceleration
// Jacobian is taken at the stage's state, and the tangents of the state (13 x 18, the
// quaternion's four rows among them) are carried through the integrator's sums as plain numbers,
// as rk4::step_state carries the values.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>

#include "physics/dual.hpp"  // first: the kernels' lanes:: calls find its overloads
#include "physics/kernels.hpp"
#include "physics/lanes.hpp"
#include "physics/rk4.hpp"

namespace derivatives {

//: Columns of the Jacobians: the 12 tangent coordinates of the state, then the 6 leg forces.
constexpr int DIRECTIONS = 18;
//: Directions the dual numbers carry: the state's, in a block for the pose and one for the twist.
constexpr int STATE_DIRECTIONS = 12;
//: The duals of the state directions over the number type V: double (one platform) or
//: lanes::Lanes (one platform per lane, the same numbers in each as alone).
template <typename V>
using DualOf = dual::Dual<STATE_DIRECTIONS, V>;
using D = DualOf<double>;

//: Where each group of columns starts: position, rotation, velocity, angular velocity, forces.
//: The pose's six directions fill the duals' first block, the twist's six the second
//: (dual::BLOCKS), so that what depends on the pose alone carries six derivatives, not twelve.
constexpr int DIR_T = 0, DIR_THETA = 3, DIR_V = 6, DIR_W = 9, DIR_F = 12;

// The packed parameter row as duals of zero derivative (constants of the differentiation).
template <typename V>
inline void constant_params(const V* prm, DualOf<V>* out) {
    for (int k = 0; k < kernels::N_PARAMS; ++k) out[k] = DualOf<V>(prm[k]);
}

// Whether every one of the size numbers at x is finite (lane by lane).
template <typename V>
inline auto all_finite(const V* x, int size) {
    auto finite = lanes::finite(x[0]);
    for (int j = 1; j < size; ++j) finite = finite && lanes::finite(x[j]);
    return finite;
}

// x + 0 for the size numbers at x: a zero's sign made +, every other number as it is.  The
// derivatives' zeros are signed as their operations sign them, and one platform alone and one in
// lanes sign some differently (dual.hpp: an inactive block's zeros against computed ones); a zero
// never becomes another number by multiplication and addition, so after this the two are the
// same bits.
template <typename V>
inline void unsigned_zeros(V* x, int size) {
    for (int j = 0; j < size; ++j) x[j] = x[j] + V(0.0);
}

// Solve M X = B for the 6x6 M (row-major) and the cols columns of B (6, cols), row-major, X into
// B: Gaussian elimination with partial pivoting (kernels::pivot_row, the first of the largest),
// every column at once (M and B are overwritten), for one platform (V = double) or one per lane
// (each lane pivots on its own numbers).  A singular M gives non-finite X, which the callers flag.
// docs/physics.md section 11 (no paper equation).
template <typename V>
inline void solve_columns(V* M, V* B, int cols) {
    constexpr int n = 6;
    for (int c = 0; c < n; ++c) {
        const V p = kernels::pivot_row<V>(M, c);
        for (int r = c + 1; r < n; ++r) {
            const auto swap = p == V(r);
            if (!lanes::any(swap)) continue;
            for (int k = c; k < n; ++k) kernels::trade(swap, M[n * c + k], M[n * r + k]);
            for (int k = 0; k < cols; ++k) kernels::trade(swap, B[cols * c + k], B[cols * r + k]);
        }
        for (int r = c + 1; r < n; ++r) {
            const V f = M[n * r + c] / M[n * c + c];
            for (int k = c + 1; k < n; ++k) M[n * r + k] -= f * M[n * c + k];
            for (int k = 0; k < cols; ++k) B[cols * r + k] -= f * B[cols * c + k];
        }
    }
    for (int c = n - 1; c >= 0; --c) {
        for (int k = c + 1; k < n; ++k)
            for (int j = 0; j < cols; ++j) B[cols * c + j] -= M[n * c + k] * B[cols * k + j];
        for (int j = 0; j < cols; ++j) B[cols * c + j] /= M[n * c + c];
    }
}

// The Jacobian jac (6,18) (columns: dt, dtheta, v, w, F) of the acceleration acc (6,) at one
// state (t, R, v, w) under the forces F, acc given (the value kernels'); P the packed row as
// constant duals, m_r (6,) the legs' reflected masses or nullptr (mr the same as duals), M (6,6)
// the state's mass matrix (forward_one's, kept before its solve; overwritten here).  The equations
// of motion M(x) acc + h(x) - J(x)^T F - W = 0 (their reflected masses' terms included)
// differentiated at the fixed acc give M dacc = -dr, with r(x) their left side at that acc: the
// inverse dynamics' sum of the legs' and the platform's pulls (leg_shares and platform_terms with
// acc), which run on duals of the 12 state directions, with no mass-matrix column among them; M
// solves for every column at once, the forces' M^-1 J^T beside the state's (J's rows the legs'
// rows' values).  docs/physics.md sections 5.4, 5.5, 10.2 and 11.
template <typename V>
inline void acceleration_tangent(const DualOf<V>* P, int64_t flags, const V* t, const V* R, const V* v, const V* w,
                                 const V* F, const V* m_r, const DualOf<V>* mr, const V* acc, V* M, V* jac) {
    using D = DualOf<V>;
    D td[3], Rd[9], vd[3], wd[3], ad[6];
    for (int j = 0; j < 3; ++j) {
        td[j] = D::seed(t[j], DIR_T + j);
        vd[j] = D::seed(v[j], DIR_V + j);
        wd[j] = D::seed(w[j], DIR_W + j);
    }
    for (int j = 0; j < 6; ++j) ad[j] = D(acc[j]);
    // R' = exp([dtheta]x) R: column c of dR/dtheta_k is e_k x (column c of R)
    for (int j = 0; j < 9; ++j) {
        Rd[j] = D(R[j]);
        Rd[j].activate(0);  // the pose's block: dR depends on dtheta alone
    }
    for (int c = 0; c < 3; ++c) {
        const V col[3] = {R[c], R[3 + c], R[6 + c]};
        // e_0 x col = (0, -col2, col1), e_1 x col = (col2, 0, -col0), e_2 x col = (-col1, col0, 0)
        Rd[3 * 1 + c].at(DIR_THETA + 0) = -col[2];
        Rd[3 * 2 + c].at(DIR_THETA + 0) = col[1];
        Rd[3 * 0 + c].at(DIR_THETA + 1) = col[2];
        Rd[3 * 2 + c].at(DIR_THETA + 1) = -col[0];
        Rd[3 * 0 + c].at(DIR_THETA + 2) = -col[1];
        Rd[3 * 1 + c].at(DIR_THETA + 2) = col[0];
    }
    // r: the legs' pulls at acc (as inverse_one sums them), the actuators' J^T F moved to the left
    D h_leg[6][6], Lddot_vel[6], r[6];
    kernels::Row6<D> rows[6];
    kernels::leg_shares<D>(P, flags, td, Rd, vd, wd, ad, h_leg, nullptr, rows, m_r == nullptr ? nullptr : Lddot_vel);
    for (int k = 0; k < 6; ++k) r[k] = D(0.0);
    for (int i = 0; i < 6; ++i)
        for (int k = 0; k < 6; ++k) r[k] += h_leg[i][k] - D(F[i]) * rows[i][k];
    // the platform's own terms at acc
    D Mp[36];
    for (int k = 0; k < 36; ++k) Mp[k] = D(0.0);
    kernels::platform_terms<D>(P, flags, Rd, wd, Mp, r);
    for (int k = 0; k < 6; ++k)
        for (int c = 0; c < 6; ++c) r[k] += Mp[6 * k + c] * D(acc[c]);
    // a drive's reflected mass pulls m_r,i Lddot_i along its row, Lddot_i = j_i acc + c_i
    if (m_r != nullptr)
        for (int i = 0; i < 6; ++i) {
            // a leg without drive inertia adds nothing (lane by lane)
            const auto inert = m_r[i] != V(0.0);
            if (!lanes::any(inert)) continue;
            D Lddot = Lddot_vel[i];
            for (int c = 0; c < 6; ++c) Lddot += rows[i][c] * D(acc[c]);
            for (int k = 0; k < 6; ++k) r[k] = lanes::select(inert, r[k] + mr[i] * Lddot * rows[i][k], r[k]);
        }
    // M [dacc/dx, dacc/dF] = [-dr/dx, J^T]; J's rows are the legs' rows' values (jacobian_row's)
    for (int k = 0; k < 6; ++k) {
        for (int m = 0; m < STATE_DIRECTIONS; ++m) jac[DIRECTIONS * k + m] = -r[k].derivative(m);
        for (int i = 0; i < 6; ++i) jac[DIRECTIONS * k + DIR_F + i] = rows[i][k].v;
    }
    solve_columns<V>(M, jac, DIRECTIONS);
}

// The platform's acceleration acc (6,) and its Jacobian jac (6,18) (columns: dt, dtheta, v, w, F)
// for one platform (V = double) or one per lane (V = lanes::Lanes, prm the lanes' rows); m_r (6,)
// the legs' reflected masses or nullptr.  The acceleration is forward_one's (the value kernel's
// own), its Jacobian acceleration_tangent's.  Returns, lane by lane, whether all are finite (a
// singular pose gives NaN or inf, which the caller flags).  docs/physics.md section 11.
template <typename V>
inline auto acceleration_jacobian(const V* prm, int64_t flags, const V* t, const V* R, const V* v, const V* w,
                                  const V* F, const V* W, const V* m_r, V* acc, V* jac) {
    const kernels::SpreadFor<V> spread(prm);  // for forward_one's legs and assemble_one's
    DualOf<V> P[kernels::N_PARAMS], mr[6];
    constant_params<V>(prm, P);
    if (m_r != nullptr)
        for (int i = 0; i < 6; ++i) mr[i] = DualOf<V>(m_r[i]);
    V M[36], h[6], M_kept[36];
    kernels::forward_one<V>(prm, flags, t, R, v, w, F, W, M, h, acc, m_r, M_kept);
    acceleration_tangent<V>(P, flags, t, R, v, w, F, m_r, mr, acc, M_kept, jac);
    unsigned_zeros<V>(jac, 6 * DIRECTIONS);
    return all_finite<V>(acc, 6) && all_finite<V>(jac, 6 * DIRECTIONS);
}

//: The numbers of a control step that stay the same over its stages: the parameters and reflected
//: masses as duals of zero derivative, and the parameters, held forces, wrench and reflected masses
//: as numbers of type V.
template <typename V>
struct StepInputs {
    DualOf<V> P[kernels::N_PARAMS], mr[6];
    const V* prm;
    int64_t flags;
    const V* forces;
    const V* wrench;
    const V* m_r;
};

// One RK4 stage's derivative k (13,) = dx/dt of rk4::state_derivative at the stage's state xs
// (13,) (the value kernel's own numbers), and its tangent K (13,18) = dk along the columns whose
// tangent of xs is Xs (13,18) (row-major).  The acceleration's rows chain acceleration_tangent's
// Jacobian with Xs in the stage's coordinates (the quaternion's as dtheta = 2 vec(dq q*) / |q|^2:
// the rotation is that of q / |q|); the position's rows are the velocity's tangent, and the
// quaternion's rate (0, w) q / 2, bilinear, has the tangent ((0, dw) q + (0, w) dq) / 2.
// docs/physics.md sections 5.6 and 11.
template <typename V>
inline void stage_tangent(const StepInputs<V>& in, const V* xs, const V* Xs, V* k, V* K) {
    constexpr int S = DIRECTIONS;
    V F[6], R[9], M[36], h[6], acc[6], ja[6 * S], M_kept[36];
    const rk4::LawRows<V> src{nullptr, nullptr, 0, 6, 0, in.forces};
    const auto evaluate_all = V(0.0) != V(0.0);  // no lane skipped
    rk4::state_derivative<V>(in.prm, in.flags, src, 0.0, xs, F, in.wrench, R, M, h, acc, evaluate_all, k, in.m_r,
                             M_kept);
    acceleration_tangent<V>(in.P, in.flags, xs, R, xs + 7, xs + 10, in.forces, in.m_r, in.mr, acc, M_kept, ja);
    const V* q = xs + 3;
    const V n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    // Xs in the stage's 12 coordinates, Z (12,18)
    V Z[STATE_DIRECTIONS][S];
    for (int c = 0; c < S; ++c) {
        const V d0 = Xs[S * 3 + c], d1 = Xs[S * 4 + c];
        const V d2 = Xs[S * 5 + c], d3 = Xs[S * 6 + c];
        // 2 vec(dq q*) with q* = (q0, -q_vec)
        Z[3][c] = 2.0 * (-d0 * q[1] + d1 * q[0] - d2 * q[3] + d3 * q[2]) / n2;
        Z[4][c] = 2.0 * (-d0 * q[2] + d1 * q[3] + d2 * q[0] - d3 * q[1]) / n2;
        Z[5][c] = 2.0 * (-d0 * q[3] - d1 * q[2] + d2 * q[1] + d3 * q[0]) / n2;
        for (int j = 0; j < 3; ++j) {
            Z[j][c] = Xs[S * j + c];
            Z[6 + j][c] = Xs[S * (7 + j) + c];
            Z[9 + j][c] = Xs[S * (10 + j) + c];
        }
    }
    const V* w = xs + 10;
    for (int c = 0; c < S; ++c) {
        for (int j = 0; j < 3; ++j) K[S * j + c] = Xs[S * (7 + j) + c];
        // dq/dt = (0, w) q / 2 as rk4::state_derivative writes it, in w and in q
        const V dw0 = Xs[S * 10 + c], dw1 = Xs[S * 11 + c], dw2 = Xs[S * 12 + c];
        const V d0 = Xs[S * 3 + c], d1 = Xs[S * 4 + c], d2 = Xs[S * 5 + c], d3 = Xs[S * 6 + c];
        K[S * 3 + c] = 0.5 * ((-dw0 * q[1] - dw1 * q[2] - dw2 * q[3]) + (-w[0] * d1 - w[1] * d2 - w[2] * d3));
        K[S * 4 + c] = 0.5 * ((dw0 * q[0] + dw1 * q[3] - dw2 * q[2]) + (w[0] * d0 + w[1] * d3 - w[2] * d2));
        K[S * 5 + c] = 0.5 * ((-dw0 * q[3] + dw1 * q[0] + dw2 * q[1]) + (-w[0] * d3 + w[1] * d0 + w[2] * d1));
        K[S * 6 + c] = 0.5 * ((dw0 * q[2] - dw1 * q[1] + dw2 * q[0]) + (w[0] * d2 - w[1] * d1 + w[2] * d0));
    }
    for (int r = 0; r < 6; ++r) {
        V row[S];
        for (int c = 0; c < S; ++c) row[c] = c >= DIR_F ? ja[S * r + c] : V(0.0);
        for (int m = 0; m < STATE_DIRECTIONS; ++m) {
            const V a = ja[S * r + m];
            for (int c = 0; c < S; ++c) row[c] += a * Z[m][c];
        }
        for (int c = 0; c < S; ++c) K[S * (7 + r) + c] = row[c];
    }
}

// One control step of `steps` RK4 substeps of dt seconds (forces F and wrench W held) from
// (t, R, v, w) of one platform (V = double) or one per lane (V = lanes::Lanes, prm the lanes'
// rows; the quaternions q0 (4,) of the start, rk4::matrix_to_quat's of R): the next state into
// (t_next, R_next, v_next, w_next) and its Jacobian jac (12,18) (rows: the next state's dt,
// dtheta, v, w; columns: the state's, then F).  The values are rk4::step_state's, operation for
// operation (started as rk4::rollout_row starts them), their tangents carried beside them
// (stage_tangent).  Returns, lane by lane, whether all are finite.  docs/physics.md sections 5.6
// and 11.
template <typename V>
inline auto step_jacobian(const V* prm, int64_t flags, const V* t, const V* q0, const V* v, const V* w, const V* F,
                          const V* W, const V* m_r, double dt, int64_t steps, V* t_next, V* R_next, V* v_next,
                          V* w_next, V* jac) {
    constexpr int S = DIRECTIONS;
    // the row does not change over the step: the value kernels' legs read it spread once
    const kernels::SpreadFor<V> spread(prm);
    StepInputs<V> in;
    constant_params<V>(prm, in.P);
    for (int i = 0; i < 6; ++i) in.mr[i] = DualOf<V>(m_r == nullptr ? V(0.0) : m_r[i]);
    in.prm = prm;
    in.flags = flags;
    in.forces = F;
    in.wrench = W;
    in.m_r = m_r;
    V x[13], X[13 * S], xs[13], Xs[13 * S], k[4][13], K[4][13 * S];
    for (int j = 0; j < 3; ++j) {
        x[j] = t[j];
        x[7 + j] = v[j];
        x[10 + j] = w[j];
    }
    for (int j = 0; j < 4; ++j) x[3 + j] = q0[j];
    for (int j = 0; j < 13 * S; ++j) X[j] = V(0.0);
    for (int j = 0; j < 3; ++j) {
        X[S * j + DIR_T + j] = V(1.0);
        X[S * (7 + j) + DIR_V + j] = V(1.0);
        X[S * (10 + j) + DIR_W + j] = V(1.0);
    }
    const V* q = x + 3;
    for (int c = 0; c < 3; ++c) {  // dq/dtheta_c = (0, e_c)/2 * q
        double e[3] = {0.0, 0.0, 0.0};
        e[c] = 1.0;
        const V ex[3] = {e[1] * q[3] - e[2] * q[2], e[2] * q[1] - e[0] * q[3], e[0] * q[2] - e[1] * q[1]};
        X[S * 3 + DIR_THETA + c] = -0.5 * q[1 + c];
        for (int j = 0; j < 3; ++j) X[S * (4 + j) + DIR_THETA + c] = 0.5 * (q[0] * e[j] + ex[j]);
    }
    auto finite = lanes::finite(V(0.0));  // true in every lane
    for (int64_t step = 0; step < steps && lanes::any(finite); ++step) {
        // rk4::step_state's sums, the tangents beside the values
        stage_tangent<V>(in, x, X, k[0], K[0]);
        for (int j = 0; j < 13; ++j) xs[j] = x[j] + 0.5 * dt * k[0][j];
        for (int j = 0; j < 13 * S; ++j) Xs[j] = X[j] + 0.5 * dt * K[0][j];
        stage_tangent<V>(in, xs, Xs, k[1], K[1]);
        for (int j = 0; j < 13; ++j) xs[j] = x[j] + 0.5 * dt * k[1][j];
        for (int j = 0; j < 13 * S; ++j) Xs[j] = X[j] + 0.5 * dt * K[1][j];
        stage_tangent<V>(in, xs, Xs, k[2], K[2]);
        for (int j = 0; j < 13; ++j) xs[j] = x[j] + dt * k[2][j];
        for (int j = 0; j < 13 * S; ++j) Xs[j] = X[j] + dt * K[2][j];
        stage_tangent<V>(in, xs, Xs, k[3], K[3]);
        for (int j = 0; j < 13; ++j) {
            x[j] = x[j] + dt / 6.0 * (k[0][j] + 2.0 * k[1][j] + 2.0 * k[2][j] + k[3][j]);
            finite = finite && lanes::finite(x[j]);
        }
        for (int j = 0; j < 13 * S; ++j) X[j] = X[j] + dt / 6.0 * (K[0][j] + 2.0 * K[1][j] + 2.0 * K[2][j] + K[3][j]);
        // the quaternion renormalised, q / |q|, and its tangent (dq - q_unit (q_unit . dq)) / |q|
        const V nq = lanes::sqrt_of(x[3] * x[3] + x[4] * x[4] + x[5] * x[5] + x[6] * x[6]);
        for (int j = 3; j < 7; ++j) x[j] /= nq;
        for (int c = 0; c < S; ++c) {
            const V along = x[3] * X[S * 3 + c] + x[4] * X[S * 4 + c] + x[5] * X[S * 5 + c] + x[6] * X[S * 6 + c];
            for (int j = 3; j < 7; ++j) X[S * j + c] = (X[S * j + c] - x[j] * along) / nq;
        }
    }
    rk4::quat_to_matrix<V>(x + 3, R_next);
    for (int j = 0; j < 3; ++j) {
        t_next[j] = x[j];
        v_next[j] = x[7 + j];
        w_next[j] = x[10 + j];
    }
    const V* qn = x + 3;
    for (int c = 0; c < S; ++c) {
        // dtheta_next = 2 vec(dq q*), q* = (q0, -q_vec): the left rotation that moves q by dq
        const V d0 = X[S * 3 + c], d1 = X[S * 4 + c], d2 = X[S * 5 + c], d3 = X[S * 6 + c];
        const V theta[3] = {
            2.0 * (-d0 * qn[1] + d1 * qn[0] - d2 * qn[3] + d3 * qn[2]),
            2.0 * (-d0 * qn[2] + d1 * qn[3] + d2 * qn[0] - d3 * qn[1]),
            2.0 * (-d0 * qn[3] - d1 * qn[2] + d2 * qn[1] + d3 * qn[0]),
        };
        for (int j = 0; j < 3; ++j) {
            jac[S * j + c] = X[S * j + c];
            jac[S * (3 + j) + c] = theta[j];
            jac[S * (6 + j) + c] = X[S * (7 + j) + c];
            jac[S * (9 + j) + c] = X[S * (10 + j) + c];
        }
    }
    unsigned_zeros<V>(jac, 12 * S);
    return finite && all_finite<V>(x, 13) && all_finite<V>(jac, 12 * S);
}

// The NaN a row that is not finite gets throughout (a partly finite Jacobian is no Jacobian).
inline void fill_nan(double* x, int size) {
    for (int j = 0; j < size; ++j) x[j] = std::numeric_limits<double>::quiet_NaN();
}

// Rows b, b + 1, ... of acceleration_jacobian_batch, as many as V carries: acceleration_jacobian
// on the rows' numbers loaded into V, written back, a row NaN throughout where not finite.
template <typename V>
inline void acceleration_jacobian_rows(const kernels::ParamRows& prm, int64_t flags, const double* t,
                                       const double* R, const double* v, const double* w, const double* F,
                                       const double* W, const double* m_r, int64_t n_mr, double* acc, double* jac,
                                       bool* finite, int64_t b) {
    constexpr int S = DIRECTIONS;
    kernels::ParamScratch<V> scratch;
    V tl[3], Rl[9], vl[3], wl[3], Fl[6], Wl[6], mr[6], al[6], jl[6 * S];
    lanes::load(t, 3, b, 3, tl);
    lanes::load(R, 9, b, 9, Rl);
    lanes::load(v, 3, b, 3, vl);
    lanes::load(w, 3, b, 3, wl);
    lanes::load(F, 6, b, 6, Fl);
    lanes::load(W, 6, b, 6, Wl);
    if (m_r != nullptr) lanes::load(m_r, n_mr == 1 ? 0 : 6, n_mr == 1 ? 0 : b, 6, mr);
    const auto ok = acceleration_jacobian<V>(prm.rows(b, scratch.rows), flags, tl, Rl, vl, wl, Fl, Wl,
                                             m_r == nullptr ? nullptr : mr, al, jl);
    lanes::store(al, 6, acc, 6, b);
    lanes::store(jl, 6 * S, jac, 6 * S, b);
    for (int k = 0; k < lanes::width<V>; ++k) {
        finite[b + k] = lanes::lane(ok, k);
        if (!finite[b + k]) {
            fill_nan(acc + 6 * (b + k), 6);
            fill_nan(jac + 6 * S * (b + k), 6 * S);
        }
    }
}

// acceleration_jacobian over a batch of n rows: prm (n_prm, N_PARAMS) with n_prm 1 or n; t, v, w
// (n,3); R (n,3,3); F, W (n,6); m_r (n_mr, 6) with n_mr 1 or n, or nullptr; acc (n,6), jac
// (n,6,18), a row NaN throughout where not finite; finite (n,) whether it is.  Blocks of rows run
// in vector lanes and on every core (lanes::for_rows), the rows left over one by one, each row's
// numbers those it has alone.
inline void acceleration_jacobian_batch(const double* prm, int64_t n_prm, int64_t flags, const double* t,
                                        const double* R, const double* v, const double* w, const double* F,
                                        const double* W, const double* m_r, int64_t n_mr, double* acc, double* jac,
                                        bool* finite, int64_t n) {
    const kernels::ParamRows rows(prm, n_prm, n);
    // a row costs about 30 forward evaluations
    lanes::for_rows(n, 30, [&](int64_t b, auto tag) {
        acceleration_jacobian_rows<decltype(tag)>(rows, flags, t, R, v, w, F, W, m_r, n_mr, acc, jac, finite, b);
    });
}

// Rows b, b + 1, ... of step_jacobian_batch, as many as V carries (as acceleration_jacobian_rows),
// each started from the quaternion of its R as rk4::rollout_row starts (rk4::matrix_to_quat).
template <typename V>
inline void step_jacobian_rows(const kernels::ParamRows& prm, int64_t flags, const double* t, const double* R,
                               const double* v, const double* w, const double* F, const double* W,
                               const double* m_r, int64_t n_mr, double dt, int64_t steps, double* t_next,
                               double* R_next, double* v_next, double* w_next, double* jac, bool* finite,
                               int64_t b) {
    constexpr int S = DIRECTIONS;
    kernels::ParamScratch<V> scratch;
    V tl[3], ql[4], vl[3], wl[3], Fl[6], Wl[6], mr[6], tn[3], Rn[9], vn[3], wn[3], jl[12 * S];
    lanes::load(t, 3, b, 3, tl);
    lanes::load(v, 3, b, 3, vl);
    lanes::load(w, 3, b, 3, wl);
    lanes::load(F, 6, b, 6, Fl);
    lanes::load(W, 6, b, 6, Wl);
    if (m_r != nullptr) lanes::load(m_r, n_mr == 1 ? 0 : 6, n_mr == 1 ? 0 : b, 6, mr);
    for (int k = 0; k < lanes::width<V>; ++k) {
        double q[4];
        rk4::matrix_to_quat(R + 9 * (b + k), q);
        for (int j = 0; j < 4; ++j) lanes::put(ql[j], k, q[j]);
    }
    const auto ok = step_jacobian<V>(prm.rows(b, scratch.rows), flags, tl, ql, vl, wl, Fl, Wl,
                                     m_r == nullptr ? nullptr : mr, dt, steps, tn, Rn, vn, wn, jl);
    lanes::store(tn, 3, t_next, 3, b);
    lanes::store(Rn, 9, R_next, 9, b);
    lanes::store(vn, 3, v_next, 3, b);
    lanes::store(wn, 3, w_next, 3, b);
    lanes::store(jl, 12 * S, jac, 12 * S, b);
    for (int k = 0; k < lanes::width<V>; ++k) {
        finite[b + k] = lanes::lane(ok, k);
        if (!finite[b + k]) {
            fill_nan(t_next + 3 * (b + k), 3);
            fill_nan(R_next + 9 * (b + k), 9);
            fill_nan(v_next + 3 * (b + k), 3);
            fill_nan(w_next + 3 * (b + k), 3);
            fill_nan(jac + 12 * S * (b + k), 12 * S);
        }
    }
}

// step_jacobian over a batch (shapes as acceleration_jacobian_batch; t_next, v_next, w_next
// (n,3), R_next (n,3,3), jac (n,12,18)).
inline void step_jacobian_batch(const double* prm, int64_t n_prm, int64_t flags, const double* t, const double* R,
                                const double* v, const double* w, const double* F, const double* W,
                                const double* m_r, int64_t n_mr, double dt, int64_t steps, double* t_next,
                                double* R_next, double* v_next, double* w_next, double* jac, bool* finite,
                                int64_t n) {
    const kernels::ParamRows rows(prm, n_prm, n);
    lanes::for_rows(n, 120 * steps, [&](int64_t b, auto tag) {
        step_jacobian_rows<decltype(tag)>(rows, flags, t, R, v, w, F, W, m_r, n_mr, dt, steps, t_next, R_next,
                                          v_next, w_next, jac, finite, b);
    });
}

}  // namespace derivatives
