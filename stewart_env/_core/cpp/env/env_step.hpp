// The environment's per-step work over a batch of platforms (stewart_env/envs/core.py and
// observation.py): the actuators (action clipping and the first-order lag), the control step of
// the closed-form plant (the RK4 substeps of rk4.hpp with the forces held), the clock and the
// non-finite check, the leg sensors, and the observation's own passes.  control_step fuses the
// first four into one call, and step() a whole control step of the environment's Batch: those,
// the tracking errors, the termination codes, the reward and the observation.  Both hand blocks of
// rows to the cores once per step, each block going through all of it while its numbers are in
// cache.  Each row is computed as numpy would compute it, operation for operation, so a batch row
// equals a batch of one bit for bit.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>

#include "env/actuation.hpp"
#include "physics/kernels.hpp"
#include "physics/rk4.hpp"
#include "tasks/task_kernels.hpp"

namespace env_step {

// The actuators: clip the action (n,6) to [-1, 1] into clipped and map it onto the force range,
// command = a half + mid N, applied directly (lag 0) or through the exact first-order lag
// F += lag (command - F) (lag = 1 - exp(-control_dt / actuator_tau)).
inline void drive(const double* action, double half, double mid, double lag, double* clipped, double* forces,
                  int64_t n) {
    for (int64_t k = 0; k < 6 * n; ++k) {
        const double a = std::fmin(std::fmax(action[k], -1.0), 1.0);
        clipped[k] = a;
        const double command = a * half + mid;
        if (lag != 0.0)
            forces[k] += lag * (command - forces[k]);
        else
            forces[k] = command;
    }
}

// A batch state t (n,3), R (n,3,3), v (n,3), w (n,3) (each C-contiguous).
struct State {
    double* t;
    double* R;
    double* v;
    double* w;
};

// Copy the state of a batch into another's arrays.
inline void copy_state(const State& from, const State& to, int64_t n) {
    std::memcpy(to.t, from.t, sizeof(double) * 3 * n);
    std::memcpy(to.R, from.R, sizeof(double) * 9 * n);
    std::memcpy(to.v, from.v, sizeof(double) * 3 * n);
    std::memcpy(to.w, from.w, sizeof(double) * 3 * n);
}

// Advance row b's clock one control step (time = steps dt) and tell whether its state is still
// finite (non_finite[b]); a row whose state is not is put back to the state it started the step
// from (start).  Returns whether it was.
inline bool after_physics_row(const State& s, const State& start, int64_t* steps, double dt, double* time,
                              bool* non_finite, int64_t b) {
    steps[b] += 1;
    time[b] = static_cast<double>(steps[b]) * dt;
    const bool ok = kernels::all_finite(s.t + 3 * b, 3) && kernels::all_finite(s.v + 3 * b, 3) &&
                    kernels::all_finite(s.w + 3 * b, 3) && kernels::all_finite(s.R + 9 * b, 9);
    non_finite[b] = !ok;
    if (!ok) {
        std::memcpy(s.t + 3 * b, start.t + 3 * b, sizeof(double) * 3);
        std::memcpy(s.R + 9 * b, start.R + 9 * b, sizeof(double) * 9);
        std::memcpy(s.v + 3 * b, start.v + 3 * b, sizeof(double) * 3);
        std::memcpy(s.w + 3 * b, start.w + 3 * b, sizeof(double) * 3);
    }
    return !ok;
}

// after_physics_row of every row of a batch.  Returns whether any row's state stopped being finite.
inline bool after_physics(const State& s, const State& start, int64_t* steps, double dt, double* time,
                          bool* non_finite, int64_t n) {
    bool found = false;
    for (int64_t b = 0; b < n; ++b) found = after_physics_row(s, start, steps, dt, time, non_finite, b) || found;
    return found;
}

// What a control step of the closed-form plant works on: the plant's packed parameters (n_prm
// rows) and model flags, the nominal parameters of the leg sensors, the actuators, the clock.
struct ControlStep {
    const double* prm;
    int64_t n_prm;
    int64_t flags;
    const double* sensor_prm;  // the nominal model's packed row(s), n_sensor_prm of them
    int64_t n_sensor_prm;
    double force_half, force_mid, lag;  // drive()
    bool drive;                          // false: the forces were set before the call
    double physics_dt;
    int64_t substeps;
    double control_dt;
    double max_condition;
    // the actuation at the physics rate (actuation.hpp), or nullptr: the forces drive() gives,
    // held over the control step
    const actuation::Actuation* act = nullptr;
};

// The applied action of rows (n,6): the action clipped to [-1, 1] (drive's clip, no forces).
inline void clip_action(const double* action, double* clipped, int64_t n) {
    for (int64_t k = 0; k < 6 * n; ++k) clipped[k] = std::fmin(std::fmax(action[k], -1.0), 1.0);
}

// One control step of the rows b, b + 1, ... (as many as T carries) of the closed-form plant:
// drive the actuators (unless already driven), remember the start state, integrate substeps RK4
// steps of physics_dt with the leg forces F (n,6) and the external wrench W (n,6) held
// (rk4::rollout_row, a block of rk4::rollout_batch), advance the clock and put rows that stopped
// being finite back to their start state (after_physics_row), and measure the leg lengths (n,6),
// rates (n,6) and condition numbers (n,).  prm and sensor_prm: the plant's and the nominal
// parameter rows.
template <typename T>
inline void control_rows(const ControlStep& c, const kernels::ParamRows& prm, const kernels::ParamRows& sensor_prm,
                         const double* action, double* clipped, double* F, const double* W, const State& s,
                         const State& start, int64_t* steps, double* time, bool* non_finite, double* lengths,
                         double* rates, double* condition, int64_t n, int64_t b) {
    const int64_t rows = lanes::width<T>;
    const State from{s.t + 3 * b, s.R + 9 * b, s.v + 3 * b, s.w + 3 * b};
    if (c.act != nullptr) {
        // the actuation at the physics rate (actuation.hpp): per physics step, the inner loops and
        // the drives row by row (scalar laws), then one RK4 step of the block in the lanes
        const actuation::Actuation& A = *c.act;
        if (c.drive) clip_action(action + 6 * b, clipped + 6 * b, rows);
        copy_state(from, {start.t + 3 * b, start.R + 9 * b, start.v + 3 * b, start.w + 3 * b}, rows);
        actuation::SetPoint sp[lanes::width<T>];
        for (int64_t j = 0; j < rows; ++j)
            actuation::set_point(A, c.force_half, c.force_mid, kernels::params_row(c.sensor_prm, c.n_sensor_prm, b + j),
                                 clipped + 6 * (b + j), s.t + 3 * (b + j), s.R + 9 * (b + j), sp[j]);
        // the row does not change over the control step: one platform's spread into leg lanes once
        kernels::ParamScratch<T> scratch;
        const kernels::SpreadFor<T> spread(prm.rows(b, scratch.rows));
        for (int64_t k = 0; k < c.substeps; ++k) {
            for (int64_t j = 0; j < rows; ++j)
                actuation::substep_forces(A, kernels::params_row(c.sensor_prm, c.n_sensor_prm, b + j), sp[j],
                                          c.physics_dt, F, s.t, s.R, s.v, s.w, b + j);
            rk4::rollout_row<T>(prm, c.flags, s.t, s.R, s.v, s.w, nullptr, F, n, 6, W, 0.0, c.physics_dt, 1, 0,
                                nullptr, b, A.reflected ? A.m_r : nullptr);
        }
    } else {
        if (c.drive) drive(action + 6 * b, c.force_half, c.force_mid, c.lag, clipped + 6 * b, F + 6 * b, rows);
        copy_state(from, {start.t + 3 * b, start.R + 9 * b, start.v + 3 * b, start.w + 3 * b}, rows);
        rk4::rollout_row<T>(prm, c.flags, s.t, s.R, s.v, s.w, nullptr, F, n, 6, W, 0.0, c.physics_dt, c.substeps, 0,
                            nullptr, b);
    }
    for (int64_t r = b; r < b + rows; ++r) after_physics_row(s, start, steps, c.control_dt, time, non_finite, r);
    kernels::leg_sensors_row<T>(sensor_prm, s.t, s.R, s.v, s.w, c.max_condition, lengths, rates, condition, b);
}

// One control step of every row of the closed-form plant (control_rows).  A block of rows goes
// through all of it at once, in the lanes and on every core as rollout_batch's blocks (one
// hand-over to the helper threads per step, the rows' numbers still in cache for the sensors).
// Returns whether any row stopped being finite.
inline bool control_step(const ControlStep& c, const double* action, double* clipped, double* F, const double* W,
                         const State& s, const State& start, int64_t* steps, double* time, bool* non_finite,
                         double* lengths, double* rates, double* condition, int64_t n) {
    const kernels::ParamRows prm(c.prm, c.n_prm, n);
    const kernels::ParamRows sensor_prm(c.sensor_prm, c.n_sensor_prm, n);
    lanes::for_rows(n, 4 * c.substeps, [&](int64_t b, auto tag) {
        control_rows<decltype(tag)>(c, prm, sensor_prm, action, clipped, F, W, s, start, steps, time, non_finite,
                                    lengths, rates, condition, n, b);
    });
    for (int64_t b = 0; b < n; ++b)
        if (non_finite[b]) return true;
    return false;
}

// The pose observation's first 15 entries of every row into raw (n, dim): P, the first two
// columns of R, the velocity and the angular velocity.
inline void pose_block(const double* t, const double* R, const double* v, const double* w, double* raw, int64_t dim,
                       int64_t n) {
    for (int64_t b = 0; b < n; ++b) {
        double* o = raw + dim * b;
        for (int j = 0; j < 3; ++j) {
            o[j] = t[3 * b + j];
            o[3 + j] = R[9 * b + 3 * j];
            o[6 + j] = R[9 * b + 3 * j + 1];
            o[9 + j] = v[3 * b + j];
            o[12 + j] = w[3 * b + j];
        }
    }
}

// The observation's normalisation, raw = (raw - offset) * inv_scale, in place: raw (n, dim),
// offset and inv_scale (dim,).
inline void normalize(double* raw, const double* offset, const double* inv_scale, int64_t dim, int64_t n) {
    for (int64_t b = 0; b < n; ++b)
        for (int64_t k = 0; k < dim; ++k) raw[dim * b + k] = (raw[dim * b + k] - offset[k]) * inv_scale[k];
}

// Whether every entry of raw (size entries) is within +-largest (so finite) and every reward
// (n_reward,) finite.
inline bool within_float32(const double* raw, int64_t size, const double* reward, int64_t n_reward, double largest) {
    for (int64_t k = 0; k < size; ++k)
        if (!(std::fabs(raw[k]) <= largest)) return false;
    for (int64_t b = 0; b < n_reward; ++b)
        if (!std::isfinite(reward[b])) return false;
    return true;
}


// The observation's finite guard of one row (n_bad of them marked): an entry that is NaN becomes
// 0 and one beyond +-largest becomes +-largest (the float32 range).
inline void make_finite(double* row, int64_t dim, double largest) {
    for (int64_t k = 0; k < dim; ++k) {
        const double x = row[k];
        row[k] = std::isnan(x) ? 0.0 : std::fmin(std::fmax(x, -largest), largest);
    }
}

// The error integral's step (observation.ObservationPipeline._integrate): every component of
// (position error, orientation error) within its band (band null: no band) times control_dt
// added to the integral s (n,6), clipped to +-bound (anti-windup).
inline void integrate_errors(const double* ep, const double* eo, const double* band, const double* bound,
                             double control_dt, double* s, int64_t n) {
    for (int64_t b = 0; b < n; ++b)
        for (int k = 0; k < 6; ++k) {
            double e = k < 3 ? ep[3 * b + k] : eo[3 * b + k - 3];
            if (band != nullptr && std::fabs(e) > band[k]) e = 0.0;
            e *= control_dt;
            double& x = s[6 * b + k];
            x += e;
            x = std::fmin(std::fmax(x, -bound[k]), bound[k]);
        }
}

// Where the observation's terms sit in a row of D entries (-1: not observed).  pose: the pose
// block at 0 (else leg_lengths and leg_rates); the rest as the ObservationPipeline lays them out.
struct Layout {
    int64_t dim;
    bool pose;
    int64_t leg_lengths, leg_rates, leg_forces, position_error, orientation_error, error_integral;
};

// A whole batch of the environment (envs/core.py PlatformBatch and its ObservationPipeline), its
// arrays as pointers; everything a control step reads and writes.
struct Batch {
    int64_t n;
    ControlStep c;
    // state, start state, actuators, clock, sensors
    State s, start;
    double *clipped, *F, *W;
    int64_t* steps;
    double* time;
    bool* non_finite;
    double *lengths, *rates, *condition;
    // the reference (n, ...; the step reads it, a reset writes its rows) and the tracking errors:
    // vectors (4,n,3), norms (4,n)
    double *rt, *rR, *rv, *rw;
    double *errors, *norms;
    // the task: its limits, reward weights, and whether each termination code is a failure
    task_kernels::Limits limits;
    task_kernels::RewardWeights weights;
    double termination_cost;
    const bool* failure;  // (n_codes,)
    bool observe;         // whether the observation is made here (the task's terms are the errors)
    // the observation
    Layout layout;
    double* raw;            // (n, D)
    double* history;        // (delay + 1, n, D)
    int64_t slots;          // delay + 1
    int64_t* head;          // (1,): the history slot written last; step() advances it
    bool normalize;
    const double *offset, *inv_scale;  // (D,)
    double* integral;                  // (n,6) or null
    const double *band, *bound;        // (6,): band may be null
    bool* pending;                     // (n,) rows whose start observation was not finite
    double largest;                    // the float32 range
    float* latest;                     // (n, D): the observation returned, as float32
};

// The clean observation of rows b .. b + rows - 1 into raw: the pose block or the leg sensors, the
// lagged leg forces, the position and orientation errors, the error integral, normalised.
inline void measure(const Batch& B, int64_t b, int64_t rows) {
    const Layout& L = B.layout;
    const int64_t n = B.n, D = L.dim;
    double* raw = B.raw + D * b;
    if (L.pose) pose_block(B.s.t + 3 * b, B.s.R + 9 * b, B.s.v + 3 * b, B.s.w + 3 * b, raw, D, rows);
    const double* ep = B.errors;
    const double* eo = B.errors + 3 * n;
    for (int64_t r = b; r < b + rows; ++r) {
        double* o = B.raw + D * r;
        for (int i = 0; i < 6; ++i) {
            if (!L.pose) {
                o[L.leg_lengths + i] = B.lengths[6 * r + i];
                o[L.leg_rates + i] = B.rates[6 * r + i];
            }
            if (L.leg_forces >= 0) o[L.leg_forces + i] = B.F[6 * r + i];
            if (L.error_integral >= 0) o[L.error_integral + i] = B.integral[6 * r + i];
        }
        for (int j = 0; j < 3; ++j) {
            o[L.position_error + j] = ep[3 * r + j];
            o[L.orientation_error + j] = eo[3 * r + j];
        }
    }
    if (B.normalize) env_step::normalize(raw, B.offset, B.inv_scale, D, rows);
}

// What Batch::step found: bit 0 a row's state stopped being finite, bit 1 a row's observation or
// reward was not finite (or its start observation was not): the rows in bad (n,).
constexpr int64_t NON_FINITE_STATE = 1;
constexpr int64_t BAD_ROWS = 2;
// What the binding returns, having done nothing, for an action that is not finite (the caller's
// own check then says where).
constexpr int64_t NOT_FINITE_ACTION = -1;

// What follows the physics for rows b .. b + rows - 1 (see step): the tracking errors, the
// termination codes, the reward terms and the reward; when B.observe, the error integral, the
// observation with its noise, its finite guard, the history slot head and the float32 copy of the
// slot returned (head + 1).
inline void outcome_rows(Batch& B, const double* noise, const bool* skip, int64_t head, int64_t* code,
                         double* terms, double* reward, bool* bad, int64_t b, int64_t rows) {
    const int64_t n = B.n;
    double* e = B.errors;
    task_kernels::tracking_errors(B.s.t + 3 * b, B.s.R + 9 * b, B.s.v + 3 * b, B.s.w + 3 * b, B.rt + 3 * b,
                                  B.rR + 9 * b, B.rv + 3 * b, B.rw + 3 * b, e + 3 * b, e + 3 * n + 3 * b,
                                  e + 6 * n + 3 * b, e + 9 * n + 3 * b, B.norms + b, 1, n, rows);
    task_kernels::limit_codes(B.s.t + 3 * b, B.s.R + 9 * b, B.lengths + 6 * b, B.condition + b, B.non_finite + b,
                              B.limits, code + b, rows);
    // the four running terms of these rows (4, rows), then into terms (5, n)
    double running[4 * lanes::LANES];
    task_kernels::tracking_reward(B.norms + b, B.norms + n + b, B.norms + 2 * n + b, B.norms + 3 * n + b, 1,
                                  B.clipped + 6 * b, B.weights, running, rows);
    for (int64_t j = 0; j < rows; ++j) {
        const int64_t r = b + j;
        for (int k = 0; k < 4; ++k) terms[k * n + r] = running[k * rows + j];
        // as the Python sum of the terms in their order, from 0
        const double termination = -B.termination_cost * (B.failure[code[r]] ? 1.0 : 0.0);
        terms[4 * n + r] = termination;
        reward[r] = 0.0 + terms[r] + terms[n + r] + terms[2 * n + r] + terms[3 * n + r] + termination;
    }
    if (!B.observe) return;
    if (B.integral != nullptr)
        integrate_errors(e + 3 * b, e + 3 * n + 3 * b, B.band, B.bound, B.c.control_dt, B.integral + 6 * b, rows);
    measure(B, b, rows);
    const int64_t D = B.layout.dim;
    for (int64_t r = b; r < b + rows; ++r) {
        double* o = B.raw + D * r;
        if (noise != nullptr && (skip == nullptr || !skip[r]))
            for (int64_t k = 0; k < D; ++k) o[k] += noise[D * r + k];
        bool row_bad = !std::isfinite(reward[r]);
        for (int64_t k = 0; k < D; ++k) row_bad = row_bad || !(std::fabs(o[k]) <= B.largest);
        if (row_bad) make_finite(o, D, B.largest);
        bad[r] = row_bad || B.pending[r];
        B.pending[r] = false;
    }
    std::memcpy(B.history + (head * n + b) * D, B.raw + b * D, sizeof(double) * rows * D);
    if (B.latest != nullptr) {
        // the ring's oldest slot, the one after head, is the observation returned now
        const double* slot = B.history + (((head + 1) % B.slots) * n + b) * D;
        for (int64_t k = 0; k < rows * D; ++k) B.latest[b * D + k] = static_cast<float>(slot[k]);
    }
}

// One control step of the whole batch: control_rows (the actuators unless drive is false, the RK4
// substeps, the clock, the leg sensors), the tracking errors against the reference (set before the
// call for the step's end time), the termination codes of the platform's limits (code (n,)), the
// tracking-error reward's terms (terms (5,n): position, orientation, velocity, control,
// termination) and their sum (reward (n,)); then, when B.observe, the error integral, the
// observation with the noise (n,D) added to the rows not in skip (noise or skip null: none) and
// its finite guard (bad (n,)), pushed into history slot head, and the slot returned now as
// float32 (B.latest).  The history slot written is the one after *B.head, which then becomes it.
// A block of rows goes through all of it at once, on every core (lanes::for_rows); each row's
// numbers are those it has alone.  Returns NON_FINITE_STATE | BAD_ROWS as found.
inline int64_t step(Batch& B, const double* action, bool drive, const double* noise, const bool* skip,
                    int64_t* code, double* terms, double* reward, bool* bad) {
    const int64_t n = B.n;
    const int64_t head = B.observe ? (*B.head + 1) % B.slots : 0;
    B.c.drive = drive;
    const kernels::ParamRows prm(B.c.prm, B.c.n_prm, n);
    const kernels::ParamRows sensor_prm(B.c.sensor_prm, B.c.n_sensor_prm, n);
    lanes::for_rows(n, 4 * B.c.substeps, [&](int64_t b, auto tag) {
        using T = decltype(tag);
        control_rows<T>(B.c, prm, sensor_prm, action, B.clipped, B.F, B.W, B.s, B.start, B.steps, B.time,
                        B.non_finite, B.lengths, B.rates, B.condition, n, b);
        outcome_rows(B, noise, skip, head, code, terms, reward, bad, b, lanes::width<T>);
    });
    if (B.observe) *B.head = head;
    int64_t found = 0;
    for (int64_t b = 0; b < n; ++b) {
        if (B.non_finite[b]) found |= NON_FINITE_STATE;
        if (B.observe && bad[b]) found |= BAD_ROWS;
    }
    return found;
}

// The start of new episodes in m rows of the batch (envs/core.py PlatformBatch.reset_rows): row
// rows[j] takes the j-th row of each of these (m rows each, C-contiguous).
struct Start {
    const double *t, *R, *v, *w;      // the start state
    const double* F;                  // the leg forces (m,6) that hold it, or null: none (no actuator lag)
    const double *rt, *rR, *rv, *rw;  // the reference at t = 0
};

// What reset_rows measures of the m rows at their start (m rows each): the leg lengths (m,6),
// rates (m,6) and condition numbers (m,), the tracking errors (4,m,3) and their norms (4,m).
struct StartSensors {
    double *lengths, *rates, *condition, *errors, *norms;
};

// Start rows rows[0 .. m - 1] (each in [0, n)): measure the leg sensors (of the nominal
// parameters) and the tracking errors of the start state S into out, the m rows as one batch
// (kernels::leg_sensors_row over lanes::for_rows, task_kernels::tracking_errors: the numbers of
// kernels::leg_sensors_batch and of the step); then write into each row of the batch its state, a
// zero clock, external wrench and applied action, its leg forces and reference, and those sensors
// and errors.  measured: out's leg sensors already hold those of S (the task measured them when it
// checked the start poses, with the same kernel), so they are not measured again.  The first
// observation is the observation pipeline's (it draws the noise).
inline void reset_rows(const Batch& B, const int64_t* rows, int64_t m, const Start& S, const StartSensors& out,
                       bool measured = false) {
    const int64_t n = B.n;
    const kernels::ParamRows sensor_prm(B.c.sensor_prm, B.c.n_sensor_prm, m);
    if (!measured)
        lanes::for_rows(m, 1, [&](int64_t b, auto tag) {
            kernels::leg_sensors_row<decltype(tag)>(sensor_prm, S.t, S.R, S.v, S.w, B.c.max_condition, out.lengths,
                                                    out.rates, out.condition, b);
        });
    double* e = out.errors;
    task_kernels::tracking_errors(S.t, S.R, S.v, S.w, S.rt, S.rR, S.rv, S.rw, e, e + 3 * m, e + 6 * m, e + 9 * m,
                                  out.norms, 1, m, m);
    for (int64_t j = 0; j < m; ++j) {
        const int64_t r = rows[j];
        std::memcpy(B.s.t + 3 * r, S.t + 3 * j, sizeof(double) * 3);
        std::memcpy(B.s.R + 9 * r, S.R + 9 * j, sizeof(double) * 9);
        std::memcpy(B.s.v + 3 * r, S.v + 3 * j, sizeof(double) * 3);
        std::memcpy(B.s.w + 3 * r, S.w + 3 * j, sizeof(double) * 3);
        B.steps[r] = 0;
        B.time[r] = 0.0;
        for (int k = 0; k < 6; ++k) {
            B.W[6 * r + k] = 0.0;
            B.clipped[6 * r + k] = 0.0;
            B.F[6 * r + k] = S.F != nullptr ? S.F[6 * j + k] : 0.0;
        }
        std::memcpy(B.rt + 3 * r, S.rt + 3 * j, sizeof(double) * 3);
        std::memcpy(B.rR + 9 * r, S.rR + 9 * j, sizeof(double) * 9);
        std::memcpy(B.rv + 3 * r, S.rv + 3 * j, sizeof(double) * 3);
        std::memcpy(B.rw + 3 * r, S.rw + 3 * j, sizeof(double) * 3);
        std::memcpy(B.lengths + 6 * r, out.lengths + 6 * j, sizeof(double) * 6);
        std::memcpy(B.rates + 6 * r, out.rates + 6 * j, sizeof(double) * 6);
        B.condition[r] = out.condition[j];
        for (int term = 0; term < 4; ++term) {
            std::memcpy(B.errors + 3 * (term * n + r), e + 3 * (term * m + j), sizeof(double) * 3);
            B.norms[term * n + r] = out.norms[term * m + j];
        }
    }
}

// The first observation of rows rows[0 .. m - 1] (envs/observation.py
// ObservationPipeline.reset_rows), after reset_rows wrote their start into the batch: a zero error
// integral, the clean observation (measure), the noise (m,D) of row rows[j] in row j added (noise
// null: none), the finite guard (a row whose start observation is not finite is made finite and
// pending: its first step terminates), and the row in every slot of the delay ring (a delayed
// sensor has seen only the start).  Returns the rows made finite.
inline int64_t start_observation_rows(const Batch& B, const int64_t* rows, int64_t m, const double* noise) {
    const int64_t n = B.n, D = B.layout.dim;
    int64_t bad = 0;
    for (int64_t j = 0; j < m; ++j) {
        const int64_t r = rows[j];
        if (B.integral != nullptr)
            for (int k = 0; k < 6; ++k) B.integral[6 * r + k] = 0.0;
        measure(B, r, 1);
        double* o = B.raw + D * r;
        if (noise != nullptr)
            for (int64_t k = 0; k < D; ++k) o[k] += noise[D * j + k];
        bool row_bad = false;
        for (int64_t k = 0; k < D; ++k) row_bad = row_bad || !(std::fabs(o[k]) <= B.largest);
        if (row_bad) make_finite(o, D, B.largest);
        B.pending[r] = row_bad;
        bad += row_bad ? 1 : 0;
        for (int64_t slot = 0; slot < B.slots; ++slot)
            std::memcpy(B.history + (slot * n + r) * D, o, sizeof(double) * D);
    }
    return bad;
}

// The packed parameters of m randomised rows (randomization.Randomization.scale_packed_rows): entry
// c of row j is multipliers[j, part_of[c]] times nominal[c] (multipliers (m, parts), part_of (N,) in
// [0, parts); one multiplication, as numpy's), and largest[j] the largest magnitude in row j.
inline void scale_parameter_rows(const double* nominal, const double* multipliers, int64_t parts,
                                 const int64_t* part_of, int64_t n_params, double* out, double* largest, int64_t m) {
    for (int64_t j = 0; j < m; ++j) {
        const double* f = multipliers + parts * j;
        double* o = out + n_params * j;
        double most = 0.0;
        for (int64_t c = 0; c < n_params; ++c) {
            o[c] = f[part_of[c]] * nominal[c];
            // a plain comparison, not std::fmax's call: finite factors and parameters give no
            // NaN, and an overflow to inf is the largest
            const double size = std::fabs(o[c]);
            most = size > most ? size : most;
        }
        largest[j] = most;
    }
}

}  // namespace env_step
