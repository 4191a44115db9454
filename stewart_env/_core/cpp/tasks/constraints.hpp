// The platform's constraints over a batch of platforms: per row and leg each constraint's value and
// margin, per row each constraint's indicator cost and whether it is violated, the summed cost and
// the first violated constraint that ends an episode (stewart_env/tasks/constraints.py gives them
// in Python terms; docs/physics.md, "Limits and constraint costs", the definitions and units).
// Each row is computed by itself, in a fixed order, so a batch row equals a batch of one bit for bit.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>

#include "physics/kernels.hpp"
#include "tasks/task_kernels.hpp"

namespace constraints {

//: The constraints, in the order of every array: leg stroke, leg rate, leg acceleration, leg force,
//: force rate, universal-joint cone, spherical-joint cone, workspace (box and angles about home).
enum Constraint : int {
    LEG_LENGTH = 0,
    LEG_VELOCITY,
    LEG_ACCELERATION,
    LEG_FORCE,
    FORCE_RATE,
    UNIVERSAL_JOINT,
    SPHERICAL_JOINT,
    WORKSPACE,
    N_CONSTRAINTS
};
//: Their names (info["cost_<name>"]), in that order.
constexpr const char* NAMES[N_CONSTRAINTS] = {"leg_length",      "leg_velocity",    "leg_acceleration",
                                              "leg_force",       "force_rate",      "universal_joint",
                                              "spherical_joint", "workspace"};
//: Entries of one constraint in a row: one per leg (the workspace's: x, y, z, roll, pitch, yaw).
constexpr int N_ENTRIES = 6;
constexpr double INF = std::numeric_limits<double>::infinity();

//: The bounds of a platform (stewart_env.params.Limits), held by value.  An absent bound is inf.
struct Bounds {
    double length_min, length_max;      // m
    double max_velocity;                // m/s, on |Ldot_i|
    double max_acceleration;            // m/s^2, on |Lddot_i|
    double force_min, force_max;        // N
    double max_force_rate;              // N/s, on |Fdot_i|
    double max_universal_angle;         // rad
    double max_spherical_angle;         // rad
    double universal_axes[18];          // (6,3) unit a_i in {B}
    double spherical_axes[18];          // (6,3) unit c_i in {P}
    double position_min[3], position_max[3];  // m, {B}
    double home_rpy[3];                 // rad
    double max_angle;                   // rad, on each of roll, pitch, yaw about home
};

// Margin of v in [lo, hi]: min(v - lo, hi - v), > 0 inside; +inf when both bounds are absent.
inline double interval_margin(double v, double lo, double hi) {
    if (lo == -INF && hi == INF) return INF;
    return std::fmin(v - lo, hi - v);
}

// Margin of |v| <= bound: bound - |v|; +inf when the bound is absent (inf), whatever v is.
inline double magnitude_margin(double v, double bound) { return bound == INF ? INF : bound - std::fabs(v); }

// Cone angle between the unit leg axis e and the unit mounting axis a: atan2(|a x e|, a . e), rad in
// [0, pi] (accurate near 0 and pi, where acos is not).  docs/physics.md eq. (L4).
inline double cone_angle(const double* a, const kernels::V3<double>& e) {
    const auto [c0, c1, c2] = kernels::cross<double>(a[0], a[1], a[2], e[0], e[1], e[2]);
    return std::atan2(std::sqrt(c0 * c0 + c1 * c1 + c2 * c2), a[0] * e[0] + a[1] * e[1] + a[2] * e[2]);
}

// (L5) the workspace: P in the box, each of roll, pitch, yaw (rotations.matrix_to_rpy, wrapped to
// [-pi, pi) about home) within max_angle, as task_kernels::limit_codes decides it.  Out: value,
// margin (6,), x, y, z then roll, pitch, yaw.
inline void workspace_row(const double* t, const double* R, const Bounds& b, double* value, double* margin) {
    const double s = std::fmin(std::fmax(-R[6], -1.0), 1.0);
    const double rpy[3] = {std::atan2(R[7], R[8]), std::asin(s), std::atan2(R[3], R[0])};
    for (int j = 0; j < 3; ++j) {
        value[j] = t[j];
        margin[j] = interval_margin(t[j], b.position_min[j], b.position_max[j]);
        const double d =
            task_kernels::python_mod(rpy[j] - b.home_rpy[j] + task_kernels::PI, 2.0 * task_kernels::PI) -
            task_kernels::PI;
        value[3 + j] = d;
        margin[3 + j] = magnitude_margin(d, b.max_angle);
    }
}

// Whether a margin is violated: below 0, or no number (a value that is none), as evaluate_row counts it.
inline bool outside(double margin) { return !(margin >= 0.0); }

// One row.  prm: the row's packed parameters (kernels::PACKED_LAYOUT); t (3,), R (3,3), v (3,),
// w (3,) its state; rates_prev, forces_prev: the previous control step's leg rates (m/s) and leg
// forces (N), forces: the leg forces applied over this step (6,) each; dt the control period, s;
// terminate: bit k set when constraint k ends an episode.  Out: value, margin (8,6), cost (8,),
// violated (8,), *total and *code (0, or 1 + the first violated constraint whose bit is set).
// docs/physics.md, "Limits and constraint costs", eqs. (L1)-(L7).
inline void evaluate_row(const double* prm, const double* t, const double* R, const double* v, const double* w,
                         const double* rates_prev, const double* forces_prev, const double* forces, double dt,
                         const Bounds& b, int64_t terminate, double* value, double* margin, double* cost,
                         bool* violated, double* total, int64_t* code) {
    double* val[N_CONSTRAINTS];
    double* mar[N_CONSTRAINTS];
    for (int k = 0; k < N_CONSTRAINTS; ++k) {
        val[k] = value + N_ENTRIES * k;
        mar[k] = margin + N_ENTRIES * k;
    }
    for (int i = 0; i < 6; ++i) {
        const kernels::LegFrame<double> fr = kernels::leg_frame<double>(prm, i, t, R);
        const kernels::Row6<double> row = kernels::jacobian_row<double>(fr);
        // (L1) Ldot_i = J_i [v; w], J_i = [e_i, (R p_i) x e_i]
        const double rate = row[0] * v[0] + row[1] * v[1] + row[2] * v[2] + row[3] * w[0] + row[4] * w[1] +
                            row[5] * w[2];
        // (L2), (L3) the step's mean leg acceleration and force rate
        const double acceleration = (rate - rates_prev[i]) / dt;
        const double force_rate = (forces[i] - forces_prev[i]) / dt;
        // (L4) the cones: a_i in {B}; R c_i, the platform's mounting axis in {B}
        const double* c = b.spherical_axes + 3 * i;
        const double rc[3] = {R[0] * c[0] + R[1] * c[1] + R[2] * c[2], R[3] * c[0] + R[4] * c[1] + R[5] * c[2],
                              R[6] * c[0] + R[7] * c[1] + R[8] * c[2]};
        val[LEG_LENGTH][i] = fr.L;
        val[LEG_VELOCITY][i] = rate;
        val[LEG_ACCELERATION][i] = acceleration;
        val[LEG_FORCE][i] = forces[i];
        val[FORCE_RATE][i] = force_rate;
        val[UNIVERSAL_JOINT][i] = cone_angle(b.universal_axes + 3 * i, fr.e);
        val[SPHERICAL_JOINT][i] = cone_angle(rc, fr.e);
        mar[LEG_LENGTH][i] = interval_margin(fr.L, b.length_min, b.length_max);
        mar[LEG_VELOCITY][i] = magnitude_margin(rate, b.max_velocity);
        mar[LEG_ACCELERATION][i] = magnitude_margin(acceleration, b.max_acceleration);
        mar[LEG_FORCE][i] = interval_margin(forces[i], b.force_min, b.force_max);
        mar[FORCE_RATE][i] = magnitude_margin(force_rate, b.max_force_rate);
        mar[UNIVERSAL_JOINT][i] = magnitude_margin(val[UNIVERSAL_JOINT][i], b.max_universal_angle);
        mar[SPHERICAL_JOINT][i] = magnitude_margin(val[SPHERICAL_JOINT][i], b.max_spherical_angle);
    }
    workspace_row(t, R, b, val[WORKSPACE], mar[WORKSPACE]);
    // (L6) the indicator cost of each constraint, (L7) their sum; a margin that is no number (a
    // value that is none) counts as violated and is reported as -inf, so no cost is ever NaN
    double sum = 0.0;
    int64_t first = 0;
    for (int k = 0; k < N_CONSTRAINTS; ++k) {
        bool any = false;
        for (int i = 0; i < N_ENTRIES; ++i) {
            if (std::isnan(mar[k][i])) mar[k][i] = -INF;
            any |= mar[k][i] < 0.0;
        }
        violated[k] = any;
        cost[k] = any ? 1.0 : 0.0;
        sum += cost[k];
        if (any && first == 0 && ((terminate >> k) & 1)) first = k + 1;
    }
    *total = sum;
    *code = first;
}

// evaluate_row over n rows: prm (1 or n rows, N_PARAMS), t (n,3), R (n,3,3), v, w (n,3),
// rates_prev, forces_prev, forces (n,6) -> value, margin (n,8,6), cost (n,8), violated (n,8),
// total (n,), code (n,).  Serial: a row costs a few hundred flops.
inline void evaluate_batch(const double* prm, int64_t n_prm, const double* t, const double* R, const double* v,
                           const double* w, const double* rates_prev, const double* forces_prev, const double* forces,
                           double dt, const Bounds& b, int64_t terminate, double* value, double* margin,
                           double* cost, bool* violated, double* total, int64_t* code, int64_t n) {
    constexpr int64_t block = N_CONSTRAINTS * N_ENTRIES;
    for (int64_t r = 0; r < n; ++r)
        evaluate_row(kernels::params_row(prm, n_prm, r), t + 3 * r, R + 9 * r, v + 3 * r, w + 3 * r,
                     rates_prev + 6 * r, forces_prev + 6 * r, forces + 6 * r, dt, b, terminate, value + block * r,
                     margin + block * r, cost + N_CONSTRAINTS * r, violated + N_CONSTRAINTS * r, total + r,
                     code + r);
}

// The costs of one row alone, as evaluate_row gives them bit for bit, with the bookkeeping of a batch
// done in place: no values or margins are written, and a constraint whose bound is absent (inf, which
// no value violates) is not computed.  rates, forces_prev (6,) the previous control step's leg rates
// and forces, overwritten with this step's (the next step's previous ones); when *fresh (the row's
// episode's first step: no force was applied before it) the previous forces are this step's, so the
// force rate is 0, and *fresh is cleared.  Out: cost, violated (8,), *total and *code as evaluate_row's.
inline void costs_row(const double* prm, const double* t, const double* R, const double* v, const double* w,
                      double* rates, double* forces_prev, const double* forces, bool* fresh, double dt,
                      const Bounds& b, int64_t terminate, double* cost, bool* violated, double* total,
                      int64_t* code) {
    const bool first_step = *fresh;
    *fresh = false;
    const bool acceleration_bound = b.max_acceleration != INF, force_rate_bound = b.max_force_rate != INF;
    const bool universal_bound = b.max_universal_angle != INF, spherical_bound = b.max_spherical_angle != INF;
    bool any[N_CONSTRAINTS] = {};
    for (int i = 0; i < 6; ++i) {
        const kernels::LegFrame<double> fr = kernels::leg_frame<double>(prm, i, t, R);
        const kernels::Row6<double> row = kernels::jacobian_row<double>(fr);
        // (L1)-(L3) as evaluate_row
        const double rate = row[0] * v[0] + row[1] * v[1] + row[2] * v[2] + row[3] * w[0] + row[4] * w[1] +
                            row[5] * w[2];
        const double force_before = first_step ? forces[i] : forces_prev[i];
        if (acceleration_bound)
            any[LEG_ACCELERATION] |= outside(magnitude_margin((rate - rates[i]) / dt, b.max_acceleration));
        if (force_rate_bound)
            any[FORCE_RATE] |= outside(magnitude_margin((forces[i] - force_before) / dt, b.max_force_rate));
        rates[i] = rate;
        forces_prev[i] = forces[i];
        any[LEG_LENGTH] |= outside(interval_margin(fr.L, b.length_min, b.length_max));
        any[LEG_VELOCITY] |= outside(magnitude_margin(rate, b.max_velocity));
        any[LEG_FORCE] |= outside(interval_margin(forces[i], b.force_min, b.force_max));
        if (universal_bound)
            any[UNIVERSAL_JOINT] |=
                outside(magnitude_margin(cone_angle(b.universal_axes + 3 * i, fr.e), b.max_universal_angle));
        if (spherical_bound) {
            const double* c = b.spherical_axes + 3 * i;
            const double rc[3] = {R[0] * c[0] + R[1] * c[1] + R[2] * c[2], R[3] * c[0] + R[4] * c[1] + R[5] * c[2],
                                  R[6] * c[0] + R[7] * c[1] + R[8] * c[2]};
            any[SPHERICAL_JOINT] |= outside(magnitude_margin(cone_angle(rc, fr.e), b.max_spherical_angle));
        }
    }
    double value[N_ENTRIES], margin[N_ENTRIES];
    workspace_row(t, R, b, value, margin);
    for (int j = 0; j < N_ENTRIES; ++j) any[WORKSPACE] |= outside(margin[j]);
    double sum = 0.0;
    int64_t first = 0;
    for (int k = 0; k < N_CONSTRAINTS; ++k) {
        violated[k] = any[k];
        cost[k] = any[k] ? 1.0 : 0.0;
        sum += cost[k];
        if (any[k] && first == 0 && ((terminate >> k) & 1)) first = k + 1;
    }
    *total = sum;
    *code = first;
}

// costs_row over n rows, the arrays as evaluate_batch's; rates, forces_prev (n,6) in place, fresh (n,).
inline void costs_batch(const double* prm, int64_t n_prm, const double* t, const double* R, const double* v,
                        const double* w, double* rates, double* forces_prev, const double* forces, bool* fresh,
                        double dt, const Bounds& b, int64_t terminate, double* cost, bool* violated, double* total,
                        int64_t* code, int64_t n) {
    for (int64_t r = 0; r < n; ++r)
        costs_row(kernels::params_row(prm, n_prm, r), t + 3 * r, R + 9 * r, v + 3 * r, w + 3 * r, rates + 6 * r,
                  forces_prev + 6 * r, forces + 6 * r, fresh + r, dt, b, terminate, cost + N_CONSTRAINTS * r,
                  violated + N_CONSTRAINTS * r, total + r, code + r);
}

// The leg rates Ldot_i = J_i [v; w] (eq. L1) of m states into rows rows[j] of rates (n,6), m/s, as
// evaluate_row's values: prm (1 or m rows), t (m,3), R (m,3,3), v, w (m,3).
inline void leg_rates_into(const double* prm, int64_t n_prm, const double* t, const double* R, const double* v,
                           const double* w, const int64_t* rows, int64_t m, double* rates) {
    for (int64_t j = 0; j < m; ++j) {
        const double* p = kernels::params_row(prm, n_prm, j);
        const double *tj = t + 3 * j, *Rj = R + 9 * j, *vj = v + 3 * j, *wj = w + 3 * j;
        for (int i = 0; i < 6; ++i) {
            const kernels::Row6<double> row = kernels::jacobian_row<double>(kernels::leg_frame<double>(p, i, tj, Rj));
            rates[6 * rows[j] + i] = row[0] * vj[0] + row[1] * vj[1] + row[2] * vj[2] + row[3] * wj[0] +
                                     row[4] * wj[1] + row[5] * wj[2];
        }
    }
}

}  // namespace constraints
