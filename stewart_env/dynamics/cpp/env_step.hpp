// The environment's per-step work over a batch of platforms (stewart_env/envs/core.py and
// observation.py): the actuators (action clipping and the first-order lag), the control step of
// the closed-form plant (the RK4 substeps of rk4.hpp with the forces held), the clock and the
// non-finite check, the leg sensors, and the observation's own passes.  control_step fuses the
// first four into one call.  Each row is computed as numpy would compute it, operation for
// operation, so a batch row equals a batch of one bit for bit.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>

#include "kernels.hpp"
#include "rk4.hpp"

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

// Advance every row's clock one control step (time = steps dt) and find the rows whose state is
// no longer finite (non_finite (n,)), putting them back to the state they started the step from
// (start).  Returns whether any row was.
inline bool after_physics(const State& s, const State& start, int64_t* steps, double dt, double* time,
                          bool* non_finite, int64_t n) {
    bool found = false;
    for (int64_t b = 0; b < n; ++b) {
        steps[b] += 1;
        time[b] = static_cast<double>(steps[b]) * dt;
        bool ok = kernels::all_finite(s.t + 3 * b, 3) && kernels::all_finite(s.v + 3 * b, 3) &&
                  kernels::all_finite(s.w + 3 * b, 3) && kernels::all_finite(s.R + 9 * b, 9);
        non_finite[b] = !ok;
        if (!ok) {
            found = true;
            std::memcpy(s.t + 3 * b, start.t + 3 * b, sizeof(double) * 3);
            std::memcpy(s.R + 9 * b, start.R + 9 * b, sizeof(double) * 9);
            std::memcpy(s.v + 3 * b, start.v + 3 * b, sizeof(double) * 3);
            std::memcpy(s.w + 3 * b, start.w + 3 * b, sizeof(double) * 3);
        }
    }
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
};

// One control step of every row of the closed-form plant: drive the actuators (unless already
// driven), remember the start state, integrate substeps RK4 steps of physics_dt with the leg
// forces F (n,6) and the external wrench W (n,6) held (rk4::rollout_batch), advance the clock
// and put rows that stopped being finite back to their start state (after_physics), and
// measure the leg lengths (n,6), rates (n,6) and condition numbers (n,).  Returns whether any
// row stopped being finite.
inline bool control_step(const ControlStep& c, const double* action, double* clipped, double* F, const double* W,
                         const State& s, const State& start, int64_t* steps, double* time, bool* non_finite,
                         double* lengths, double* rates, double* condition, int64_t n) {
    if (c.drive) drive(action, c.force_half, c.force_mid, c.lag, clipped, F, n);
    copy_state(s, start, n);
    rk4::rollout_batch(c.prm, c.n_prm, c.flags, s.t, s.R, s.v, s.w, F, W, c.physics_dt, c.substeps, n);
    const bool found = after_physics(s, start, steps, c.control_dt, time, non_finite, n);
    kernels::leg_sensors_batch(c.sensor_prm, c.n_sensor_prm, s.t, s.R, s.v, s.w, c.max_condition, lengths, rates,
                               condition, n);
    return found;
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

}  // namespace env_step
