// The compiled control laws shipped with the package, and the kernels a user's law may call.
//
// Each law has the signature rk4::ControlLaw.  The task-space PD law of He et al. (2018), eq. 56:
// with the pose error e = [t_d - t; theta_d - theta] (position of P's origin in {B}, m;
// roll-pitch-yaw angles, rad) and its rate edot = [v_d - v; thetadot_d - thetadot] (angle rates
// from the angular velocity, thetadot = E(theta)^-1 omega), the controller asks for the platform
// wrench W = Kp e + Kd edot and realises it with the leg forces F = J^-T W, optionally adding the
// static holding forces of the current pose (gravity compensation).
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>

#include "physics/kernels.hpp"
#include "physics/rk4.hpp"

namespace laws {

constexpr double PI = 3.141592653589793;  // numpy's pi, the same double

//: One entry of a law's parameter row: its name and size.
struct ParamEntry {
    const char* name;
    int size;
};

//: The parameter row of pd_control_law, in order: (name, size).  kp, kd: gains [x, y, z, roll,
//: pitch, yaw]; position, rotation (row-major 3x3), velocity, angular_velocity: the reference in
//: {B} (m, -, m/s, rad/s); gravity_compensation: 1.0 adds the holding forces, 0.0 not;
//: gravity_flags: the kernel switch bits of the model giving them; platform: the controller's
//: packed platform row (model.pack_params), whose geometry gives J.
constexpr ParamEntry PD_LAYOUT[] = {
    {"kp", 6}, {"kd", 6}, {"position", 3}, {"rotation", 9}, {"velocity", 3}, {"angular_velocity", 3},
    {"gravity_compensation", 1}, {"gravity_flags", 1}, {"platform", kernels::N_PARAMS},
};
constexpr int N_PD_LAYOUT = sizeof(PD_LAYOUT) / sizeof(PD_LAYOUT[0]);

// Where entry k of PD_LAYOUT starts in the row (k == N_PD_LAYOUT: the row's length).
constexpr int pd_offset(int k) {
    int start = 0;
    for (int j = 0; j < k; ++j) start += PD_LAYOUT[j].size;
    return start;
}

constexpr int PD_N_PARAMS = pd_offset(N_PD_LAYOUT);
constexpr int PD_KP = pd_offset(0), PD_KD = pd_offset(1), PD_POS = pd_offset(2), PD_ROT = pd_offset(3);
constexpr int PD_VEL = pd_offset(4), PD_ANG = pd_offset(5), PD_GRAVITY = pd_offset(6), PD_GFLAGS = pd_offset(7);
constexpr int PD_PLATFORM = pd_offset(8);

// out[:3] = roll, pitch, yaw of R (rad, the convention of stewart_env.matrix_to_rpy); out[3:] =
// their rates thetadot = E(theta)^-1 w (rad/s, E of stewart_env.rotations.rpy_rate_matrix, inverted
// in closed form: E is [[cy cp, -sy, 0], [sy cp, cy, 0], [-sp, 0, 1]]).
inline void rpy_and_rates(const double* R, const double* w, double* out) {
    const double pitch = std::asin(std::fmin(std::fmax(-R[6], -1.0), 1.0));
    out[0] = std::atan2(R[7], R[8]);
    out[1] = pitch;
    out[2] = std::atan2(R[3], R[0]);
    const double cp = std::cos(pitch), sp = std::sin(pitch);
    const double cy = std::cos(out[2]), sy = std::sin(out[2]);
    const double roll_rate = (cy * w[0] + sy * w[1]) / cp;
    out[3] = roll_rate;
    out[4] = -sy * w[0] + cy * w[1];
    out[5] = w[2] + sp * roll_rate;
}

// a modulo b with the sign of b (Python's %): the angle wrap of the PD law.
inline double floor_mod(double a, double b) {
    double m = std::fmod(a, b);
    if (m != 0.0 && ((m < 0.0) != (b < 0.0))) m += b;
    return m;
}

// The task-space PD law F = J^-T (Kp e + Kd edot) [+ holding forces] (paper eq. 56) as a compiled
// control law (rk4::ControlLaw).  params: the row of PD_LAYOUT; writes the six leg forces, N (NaN
// when the row has another length).  Time-invariant: the reference is fixed in params.
extern "C" inline void pd_control_law(double, const double* position, const double* rotation, const double* velocity,
                                      const double* angular_velocity, const double* params, int64_t n_params,
                                      double* forces) {
    if (n_params != PD_N_PARAMS) {
        for (int i = 0; i < 6; ++i) forces[i] = std::numeric_limits<double>::quiet_NaN();
        return;
    }
    double now[6];
    double ref[6];
    rpy_and_rates(rotation, angular_velocity, now);
    rpy_and_rates(params + PD_ROT, params + PD_ANG, ref);
    double wrench[6];
    for (int j = 0; j < 3; ++j) {
        double e = params[PD_POS + j] - position[j];
        double edot = params[PD_VEL + j] - velocity[j];
        wrench[j] = params[PD_KP + j] * e + params[PD_KD + j] * edot;
        // the angle error wrapped to [-pi, pi): an error of 2 pi - d is one of -d
        e = floor_mod(ref[j] - now[j] + PI, 2.0 * PI) - PI;
        edot = ref[3 + j] - now[3 + j];
        wrench[3 + j] = params[PD_KP + 3 + j] * e + params[PD_KD + 3 + j] * edot;
    }
    const double* platform = params + PD_PLATFORM;
    double jac[36];
    kernels::jacobian_one(platform, position, rotation, jac);
    double jt[36];
    for (int r = 0; r < 6; ++r)
        for (int c = 0; c < 6; ++c) jt[6 * r + c] = jac[6 * c + r];
    kernels::solve6(jt, wrench, forces);
    if (params[PD_GRAVITY] != 0.0) {
        const double zero[6] = {0.0};
        double holding[6];
        rk4::law_inverse_dynamics(platform, static_cast<int64_t>(params[PD_GFLAGS]), position, rotation, zero, zero, zero,
                             zero, holding);
        for (int i = 0; i < 6; ++i) forces[i] += holding[i];
    }
}

// A law's forces (n,6) at n states (t, R, v, w), params (n, n_params) or (1, n_params) shared:
// the law evaluated outside a rollout (a policy's forces).  Unwritten forces are NaN.
inline void law_forces_batch(rk4::ControlLaw law, double time, const double* t, const double* R, const double* v,
                             const double* w, const double* params, int64_t n_param_rows, int64_t n_params,
                             double* out, int64_t n) {
    for (int64_t b = 0; b < n; ++b) {
        double* F = out + 6 * b;
        for (int i = 0; i < 6; ++i) F[i] = std::numeric_limits<double>::quiet_NaN();
        law(time, t + 3 * b, R + 9 * b, v + 3 * b, w + 3 * b, n_param_rows == 1 ? params : params + n_params * b,
            n_params, F);
    }
}

}  // namespace laws
