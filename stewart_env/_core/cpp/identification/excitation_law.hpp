// The computed-torque law that drives a plant along an excitation trajectory for identification:
// a finite Fourier series in task space (docs/guides/identification.md).
//
// Reference, each of the six task coordinates q = [x, y, z, roll, pitch, yaw] ({B}, m and rad,
// roll-pitch-yaw as in stewart_env.rotations):
//   q_j(t) = q0_j + sum_k a_jk / (k wf) sin(k wf t) - b_jk / (k wf) cos(k wf t),  k = 1..H,
// whose rates and accelerations follow term by term.  The law asks the controller's model for
// the leg forces of the commanded accelerations
//   a_cmd = a_d + Kd (v_d - v) + Kp (t_d - t),
//   alpha_cmd = E(theta) thetaddot_cmd + Edot(theta, thetadot) thetadot,
//   thetaddot_cmd = thetaddot_d + Kd (thetadot_d - thetadot) + Kp (theta_d - theta),
// with omega = E(theta) thetadot (E as in laws::rpy_and_rates): F = inverse_one(...).
#pragma once

#include <cmath>
#include <cstdint>

#include "physics/kernels.hpp"
#include "physics/laws.hpp"

namespace excitation {

// Parameter row: kp (6), kd (6), flags, wf (rad/s), H, q0 (6), a (6 H, row j = coordinate), b
// (6 H), then the controller's packed platform row (N_PARAMS).
constexpr int KP = 0, KD = 6, FLAGS = 12, WF = 13, NH = 14, Q0 = 15, COEF = 21;

// Length of the parameter row for H harmonics.
constexpr int64_t row_length(int64_t harmonics) { return COEF + 12 * harmonics + kernels::N_PARAMS; }

// The series at time t: q, qdot, qddot (6 each) of the coefficients a, b (6 H, row j =
// coordinate) about q0 (6), base angular frequency wf (rad/s).  The one evaluation of the series:
// the law below and stewart_env.identification.excitation (through the binding fourier_series)
// both call it.  The harmonics are summed first and q0 added last, in index order.
inline void fourier_series(double wf, int H, const double* q0, const double* a, const double* b, double time,
                           double* q, double* qd, double* qdd) {
    for (int j = 0; j < 6; ++j) {
        double x = 0.0, xd = 0.0, xdd = 0.0;
        for (int k = 1; k <= H; ++k) {
            const double wk = wf * k, s = std::sin(wk * time), c = std::cos(wk * time);
            const double ajk = a[H * j + k - 1], bjk = b[H * j + k - 1];
            x += (ajk * s - bjk * c) / wk;
            xd += ajk * c + bjk * s;
            xdd += wk * (bjk * c - ajk * s);
        }
        q[j] = q0[j] + x;
        qd[j] = xd;
        qdd[j] = xdd;
    }
}

// The reference q, qdot, qddot (6 each) at time t of the series in the law's parameter row.
inline void reference(const double* params, double time, double* q, double* qd, double* qdd) {
    const int H = static_cast<int>(params[NH]);
    fourier_series(params[WF], H, params + Q0, params + COEF, params + COEF + 6 * H, time, q, qd, qdd);
}

// The law (rk4::ControlLaw): the six leg forces, N; NaN when the row's length does not fit H.
extern "C" inline void fourier_computed_torque(double time, const double* position, const double* rotation,
                                               const double* velocity, const double* angular_velocity,
                                               const double* params, int64_t n_params, double* forces) {
    if (n_params < COEF || n_params != row_length(static_cast<int64_t>(params[NH]))) {
        for (int i = 0; i < 6; ++i) forces[i] = std::nan("");
        return;
    }
    double q[6], qd[6], qdd[6], th[6];
    reference(params, time, q, qd, qdd);
    laws::rpy_and_rates(rotation, angular_velocity, th);
    const double* kp = params + KP;
    const double* kd = params + KD;
    double acc[6], thdd[3];
    for (int j = 0; j < 3; ++j) {
        acc[j] = qdd[j] + kd[j] * (qd[j] - velocity[j]) + kp[j] * (q[j] - position[j]);
        thdd[j] = qdd[3 + j] + kd[3 + j] * (qd[3 + j] - th[3 + j]) + kp[3 + j] * (q[3 + j] - th[j]);
    }
    // omega = E thetadot, E = [[cy cp, -sy, 0], [sy cp, cy, 0], [-sp, 0, 1]] (pitch p, yaw y)
    const double cp = std::cos(th[1]), sp = std::sin(th[1]), cy = std::cos(th[2]), sy = std::sin(th[2]);
    const double pd = th[4], yd = th[5], rd = th[3];
    const double E[9] = {cy * cp, -sy, 0.0, sy * cp, cy, 0.0, -sp, 0.0, 1.0};
    const double Ed[9] = {-sy * yd * cp - cy * sp * pd, -cy * yd, 0.0, cy * yd * cp - sy * sp * pd, -sy * yd, 0.0,
                          -cp * pd, 0.0, 0.0};
    const double rates[3] = {rd, pd, yd};
    for (int r = 0; r < 3; ++r) {
        double s = 0.0;
        for (int c = 0; c < 3; ++c) s += E[3 * r + c] * thdd[c] + Ed[3 * r + c] * rates[c];
        acc[3 + r] = s;
    }
    const double W[6] = {0.0};
    double M[36], h[6];
    kernels::inverse_one(params + COEF + 12 * static_cast<int>(params[NH]), static_cast<int64_t>(params[FLAGS]),
                         position, rotation, velocity, angular_velocity, acc, W, M, h, forces);
}

}  // namespace excitation
