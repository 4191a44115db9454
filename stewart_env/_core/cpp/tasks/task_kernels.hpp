// The tasks' per-step arithmetic over a batch of platforms: the tracking errors, the platform's
// limits as termination codes, the tracking-error reward, and the pose margins of the episode
// draws (stewart_env/tasks/base.py gives each in Python terms; the environment card gives the
// frames and units).  Each row is computed as numpy would compute it, operation for operation, so
// a batch row equals a batch of one bit for bit.
#pragma once

#include <cmath>
#include <cstdint>

namespace task_kernels {

constexpr double PI = 3.141592653589793;

// x mod y with the sign of y, as Python's float % (the wrap of an angle about home).
inline double python_mod(double x, double y) {
    double r = std::fmod(x, y);
    if (r != 0.0) {
        if ((r < 0.0) != (y < 0.0)) r += y;
    } else {
        r = std::copysign(0.0, y);
    }
    return r;
}

// The rotation vector phi (3,) of R_ref R^T and its angle, for one row: with M = R_ref R^T =
// sum_k r_k c_k^T (r_k, c_k the k-th columns of R_ref and R), trace(M) = sum(R_ref * R) and half
// the axial vector of M - M^T is s = 0.5 sum_k c_k x r_k = sin(angle) axis; angle =
// atan2(|s|, (trace - 1) / 2) and phi = s angle / |s| (angle / |s| -> 1 as the rotation vanishes).
inline void rotation_error_row(const double* r, const double* c, double* phi, double* angle) {
    double trace = 0.0;
    for (int i = 0; i < 3; ++i)
        for (int k = 0; k < 3; ++k) trace += r[3 * i + k] * c[3 * i + k];
    double s0 = 0.0, s1 = 0.0, s2 = 0.0;
    for (int k = 0; k < 3; ++k) {
        s0 += c[3 + k] * r[6 + k] - c[6 + k] * r[3 + k];
        s1 += c[6 + k] * r[k] - c[k] * r[6 + k];
        s2 += c[k] * r[3 + k] - c[3 + k] * r[k];
    }
    s0 *= 0.5;
    s1 *= 0.5;
    s2 *= 0.5;
    const double sin = std::sqrt(s0 * s0 + s1 * s1 + s2 * s2);
    const double a = std::atan2(sin, 0.5 * (trace - 1.0));
    const double ratio = sin > 1e-12 ? a / sin : 1.0;
    phi[0] = s0 * ratio;
    phi[1] = s1 * ratio;
    phi[2] = s2 * ratio;
    *angle = a;
}

// rotation_error_row over n rows: r, c (n,3,3), phi (n,3), angle (n,) (angle_stride apart).
inline void rotation_error_rows(const double* r, const double* c, double* phi, double* angle, int64_t angle_stride,
                                int64_t n) {
    for (int64_t b = 0; b < n; ++b) rotation_error_row(r + 9 * b, c + 9 * b, phi + 3 * b, angle + angle_stride * b);
}

// The tracking errors of a batch, reference minus actual in {B} (tasks.Errors): ep, eo, ev, ew
// (n,3) and the norms (n,4) [|ep|, angle of eo, |ev|, |ew|] (norms_stride between a row's norms,
// norm_stride between rows).  The state t, R, v, w and the reference rt, rR, rv, rw as the batch.
inline void tracking_errors(const double* t, const double* R, const double* v, const double* w, const double* rt,
                            const double* rR, const double* rv, const double* rw, double* ep, double* eo,
                            double* ev, double* ew, double* norms, int64_t row_stride, int64_t term_stride,
                            int64_t n) {
    rotation_error_rows(rR, R, eo, norms + term_stride, row_stride, n);
    for (int64_t b = 0; b < n; ++b) {
        double sp = 0.0, sv = 0.0, sw = 0.0;
        for (int j = 0; j < 3; ++j) {
            const int64_t k = 3 * b + j;
            ep[k] = rt[k] - t[k];
            ev[k] = rv[k] - v[k];
            ew[k] = rw[k] - w[k];
            sp += ep[k] * ep[k];
            sv += ev[k] * ev[k];
            sw += ew[k] * ew[k];
        }
        norms[row_stride * b] = std::sqrt(sp);
        norms[row_stride * b + 2 * term_stride] = std::sqrt(sv);
        norms[row_stride * b + 3 * term_stride] = std::sqrt(sw);
    }
}

// The platform's limits (tasks.LIMIT_REASONS) of a task: the workspace box, the home
// roll-pitch-yaw, the largest angle from it, the stroke and the largest condition number.
struct Limits {
    const double* position_min;  // (3,) m
    const double* position_max;  // (3,) m
    const double* home_rpy;      // (3,) rad
    double max_angle;            // rad
    double length_min;           // m
    double length_max;           // m
    double max_condition;
};

// Termination code of every row by priority: 1 the state stopped being finite, 2 the leg
// Jacobian's condition number above max_condition, 3 a leg outside its stroke, 4 P outside the
// workspace box or a roll-pitch-yaw angle (as rotations.matrix_to_rpy, wrapped to [-pi, pi)
// about home) further than max_angle from home; 0 none.  t (n,3), R (n,3,3), lengths (n,6),
// condition (n,), non_finite (n,) -> code (n,).
inline void limit_codes(const double* t, const double* R, const double* lengths, const double* condition,
                        const bool* non_finite, const Limits& lim, int64_t* code, int64_t n) {
    for (int64_t b = 0; b < n; ++b) {
        int64_t c = 0;
        const double* Rb = R + 9 * b;
        if (non_finite[b]) {
            c = 1;
        } else if (condition[b] > lim.max_condition) {
            c = 2;
        } else {
            for (int i = 0; i < 6; ++i)
                if (lengths[6 * b + i] < lim.length_min || lengths[6 * b + i] > lim.length_max) c = 3;
            if (c == 0) {
                for (int j = 0; j < 3; ++j)
                    if (t[3 * b + j] < lim.position_min[j] || t[3 * b + j] > lim.position_max[j]) c = 4;
                const double s = std::fmin(std::fmax(-Rb[6], -1.0), 1.0);
                const double rpy[3] = {std::atan2(Rb[7], Rb[8]), std::asin(s), std::atan2(Rb[3], Rb[0])};
                for (int j = 0; j < 3; ++j) {
                    const double d = python_mod(rpy[j] - lim.home_rpy[j] + PI, 2.0 * PI) - PI;
                    if (std::fabs(d) > lim.max_angle) c = 4;
                }
            }
        }
        code[b] = c;
    }
}

// The weights and scales of the tracking-error reward (tasks.RewardWeights).
struct RewardWeights {
    double position_weight, position_scale;
    double orientation_weight, orientation_scale;
    double velocity_weight, velocity_scale, angular_velocity_scale;
    double ctrl_weight;
};

// The four running terms of the tracking-error reward of every row into out (4, n): position
// w_p exp(-|e_p| / s_p), orientation w_o exp(-|e_o| / s_o), velocity -w_v (1 - exp(-(|e_v| / s_v
// + |e_w| / s_w))) and control -w_c mean(a^2).  ep, eo, ev, ew: the error norms (n,) each
// (norm_stride apart); action (n,6).
inline void tracking_reward(const double* ep, const double* eo, const double* ev, const double* ew,
                            int64_t norm_stride, const double* action, const RewardWeights& wt, double* out,
                            int64_t n) {
    for (int64_t b = 0; b < n; ++b) {
        const int64_t k = norm_stride * b;
        out[b] = wt.position_weight * std::exp(-ep[k] / wt.position_scale);
        out[n + b] = wt.orientation_weight * std::exp(-eo[k] / wt.orientation_scale);
        const double rates = ev[k] / wt.velocity_scale + ew[k] / wt.angular_velocity_scale;
        out[2 * n + b] = -wt.velocity_weight * -std::expm1(-rates);
        double a2 = 0.0;
        for (int i = 0; i < 6; ++i) a2 += action[6 * b + i] * action[6 * b + i];
        out[3 * n + b] = -wt.ctrl_weight * (a2 / 6.0);
    }
}

// Whether poses lie safely inside the limits shrunk by margin (tasks.pose_margins), their leg
// lengths (m,6) and condition numbers (m,) known: position (m,3), rpy (m,3) -> ok (m,).
inline void within_margins(const double* position, const double* rpy, const double* lengths, const double* condition,
                           const Limits& lim, double margin, bool* ok, int64_t m) {
    const double stroke_margin = margin * 0.5 * (lim.length_max - lim.length_min);
    for (int64_t b = 0; b < m; ++b) {
        bool safe = condition[b] <= lim.max_condition;
        for (int j = 0; j < 3; ++j) {
            const double half = 0.5 * (lim.position_max[j] - lim.position_min[j]);
            const double p = position[3 * b + j];
            safe &= lim.position_min[j] + margin * half <= p && p <= lim.position_max[j] - margin * half;
            safe &= std::fabs(rpy[3 * b + j] - lim.home_rpy[j]) <= (1.0 - margin) * lim.max_angle;
        }
        for (int i = 0; i < 6; ++i) {
            const double L = lengths[6 * b + i];
            safe &= lim.length_min + stroke_margin <= L && L <= lim.length_max - stroke_margin;
        }
        ok[b] = safe;
    }
}

}  // namespace task_kernels
