// The environment's actuation at the physics rate (docs/physics.md section 10.8): what turns the
// policy's action into the leg forces the dynamics holds over each RK4 substep, when the action is
// not a leg force applied directly (action_mode "leg_length" or "pose") or the actuator is a drive
// with states of its own (actuator "electric" or "hydraulic").  Per substep of a row: the leg
// sensors of the nominal model, the inner loop (the action's set point into leg-force set points),
// the actuator (the set points into the forces the legs feel), one RK4 step with those forces
// held (and the electric drive's reflected masses in the dynamics).  No state but the actuators'
// (Actuation::state), so a row's numbers do not depend on the batch it is in.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "actuators/actuator_models.hpp"
#include "physics/kernels.hpp"
#include "physics/laws.hpp"
#include "physics/rk4.hpp"
#include "tasks/task_kernels.hpp"

namespace actuation {

//: The action modes (envs/config.py ACTION_MODES' order).
enum : int64_t { FORCE = 0, LEG_LENGTH = 1, POSE = 2 };
//: The pose mode's inner loops (envs/config.py POSE_LAWS' order).
enum : int64_t { IK = 0, PD_GRAVITY = 1, COMPUTED_TORQUE = 2 };
//: The actuators (envs/config.py ACTUATORS' order).
enum : int64_t { IDEAL = 0, LAG = 1, ELECTRIC = 2, HYDRAULIC = 3 };
//: Numbers of state per leg: the electric drive's current (A) and two unused; the hydraulic
//: cylinder's spool position (m) and chamber pressures P_A, P_B (Pa).
constexpr int STATES = 3;

//: Everything the actuation of a batch reads (one set for every row) and its state.
struct Actuation {
    int64_t mode = FORCE, law = IK, kind = IDEAL;
    int64_t nominal_flags = 0;           // the nominal model's switch bits (the inner loops' model)
    double force_lo = 0.0, force_hi = 0.0;    // the leg-force set points' range, N
    double length_mid = 0.0, length_half = 0.0;  // leg_length: l = mid + a half, m
    double pose_mid[6] = {}, pose_half[6] = {};  // pose: [t; rpy] = mid + a half, m and rad
    double servo_kp = 0.0, servo_kd = 0.0;       // the leg servo, N/m and N s/m
    double task_kp[6] = {}, task_kd[6] = {};     // the pose laws' gains (pd: N/m, N m/rad; ct: 1/s^2)
    double lag = 0.0;                            // the lag's gain per physics step
    actuators::Electric electric{};
    double current_gain = 0.0;    // the current loop's gain per physics step
    double force_per_amp = 1.0;   // eta k K_t, N/A
    actuators::Hydraulic hydraulic{};
    double valve_gain = 0.0;      // the spool's gain per physics step
    double force_gain = 0.0;      // the force loop's spool command per N of force error
    double m_r[6] = {};           // the reflected masses, kg
    bool reflected = false;       // whether m_r enters the dynamics
    double* state = nullptr;      // (n, 6, STATES)
};

// Roll-pitch-yaw angles (rad) to a rotation matrix R (3,3) row-major, R = Rz(yaw) Ry(pitch)
// Rx(roll) (stewart_env.rotations.rpy_to_matrix; docs/physics.md section 1).
inline void rpy_to_matrix(const double* rpy, double* R) {
    const double cr = std::cos(rpy[0]), sr = std::sin(rpy[0]);
    const double cp = std::cos(rpy[1]), sp = std::sin(rpy[1]);
    const double cy = std::cos(rpy[2]), sy = std::sin(rpy[2]);
    R[0] = cy * cp;
    R[1] = cy * sp * sr - sy * cr;
    R[2] = cy * sp * cr + sy * sr;
    R[3] = sy * cp;
    R[4] = sy * sp * sr + cy * cr;
    R[5] = sy * sp * cr - cy * sr;
    R[6] = -sp;
    R[7] = cp * sr;
    R[8] = cp * cr;
}

//: A row's set point for a control step, from its applied action.
struct SetPoint {
    double target[6];  // force: leg-force set points, N; leg_length and pose ik: leg lengths, m
    double hold[6];    // leg_length and pose ik: the leg servos' feedforward, N
    double t[3], R[9];  // pose: the platform's pose set point
    double pd[laws::PD_N_PARAMS];  // pose pd_gravity: the compiled PD law's parameter row
};

// The set point of action a (6,) in [-1, 1]: force a half + mid N; leg lengths over the stroke;
// a pose over the workspace box and the angles' range, into leg lengths by the nominal model's
// inverse kinematics (ik) or into the PD law's row (pd_gravity).  The leg servos' feedforward: the
// forces that hold the commanded pose at rest (ik), or the row's pose (t, R) at the control step's
// start (leg_length, whose commanded pose is not known), so that either holds its set point
// without a steady error.  nominal: the nominal model's row.
inline void set_point(const Actuation& A, double force_half, double force_mid, const double* nominal,
                      const double* a, const double* t, const double* R, SetPoint& sp) {
    static const double zero[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    if (A.mode == FORCE) {
        for (int i = 0; i < 6; ++i) sp.target[i] = a[i] * force_half + force_mid;
        return;
    }
    if (A.mode == LEG_LENGTH) {
        for (int i = 0; i < 6; ++i) sp.target[i] = A.length_mid + a[i] * A.length_half;
        rk4::law_inverse_dynamics(nominal, A.nominal_flags, t, R, zero, zero, zero, zero, sp.hold);
        return;
    }
    double pose[6];
    for (int j = 0; j < 6; ++j) pose[j] = A.pose_mid[j] + a[j] * A.pose_half[j];
    for (int j = 0; j < 3; ++j) sp.t[j] = pose[j];
    rpy_to_matrix(pose + 3, sp.R);
    if (A.law == IK) {
        // the inverse kinematics of the package (paper eq. 7): the legs' lengths at the pose
        for (int i = 0; i < 6; ++i) sp.target[i] = kernels::leg_frame<double>(nominal, i, sp.t, sp.R).L;
        rk4::law_inverse_dynamics(nominal, A.nominal_flags, sp.t, sp.R, zero, zero, zero, zero, sp.hold);
    } else if (A.law == PD_GRAVITY) {
        double* p = sp.pd;
        for (int j = 0; j < 6; ++j) {
            p[laws::PD_KP + j] = A.task_kp[j];
            p[laws::PD_KD + j] = A.task_kd[j];
        }
        for (int j = 0; j < 3; ++j) {
            p[laws::PD_POS + j] = sp.t[j];
            p[laws::PD_VEL + j] = 0.0;
            p[laws::PD_ANG + j] = 0.0;
        }
        for (int j = 0; j < 9; ++j) p[laws::PD_ROT + j] = sp.R[j];
        p[laws::PD_GRAVITY] = 1.0;
        p[laws::PD_GFLAGS] = static_cast<double>(A.nominal_flags);
        for (int k = 0; k < kernels::N_PARAMS; ++k) p[laws::PD_PLATFORM + k] = nominal[k];
    }
}

// The inner loop's leg-force set points f (6,), N, at a substep's state (t, R, v, w) with the
// legs' lengths L and rates Ldot: the set point itself (force); the leg servo
// K_p (l_ref - L) - K_d Ldot plus the set point's feedforward (leg_length, pose ik);
// the task-space PD law with gravity compensation (laws::pd_control_law); computed torque
// F = inverse dynamics at a = K_p e - K_d [v; w] (e: the position error and the rotation vector of
// R_ref R^T), the reflected masses' forces included.  All on the nominal model.  Clipped to the
// leg-force range.  docs/physics.md section 10.8.
inline void inner_loop(const Actuation& A, const double* nominal, const SetPoint& sp, const double* t,
                       const double* R, const double* v, const double* w, const double* L, const double* Ldot,
                       double* f) {
    static const double zero[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    if (A.mode == FORCE) {
        for (int i = 0; i < 6; ++i) f[i] = sp.target[i];
    } else if (A.mode == LEG_LENGTH || A.law == IK) {
        for (int i = 0; i < 6; ++i) f[i] = sp.hold[i] + A.servo_kp * (sp.target[i] - L[i]) - A.servo_kd * Ldot[i];
    } else if (A.law == PD_GRAVITY) {
        laws::pd_control_law(0.0, t, R, v, w, sp.pd, laws::PD_N_PARAMS, f);
    } else {
        double phi[3], angle, acc[6];
        task_kernels::rotation_error_rows(sp.R, R, phi, &angle, 1, 1);
        for (int j = 0; j < 3; ++j) {
            acc[j] = A.task_kp[j] * (sp.t[j] - t[j]) - A.task_kd[j] * v[j];
            acc[3 + j] = A.task_kp[3 + j] * phi[j] - A.task_kd[3 + j] * w[j];
        }
        rk4::law_inverse_dynamics(nominal, A.nominal_flags, t, R, v, w, acc, zero, f);
        if (A.reflected) kernels::add_reflected_force<double>(nominal, A.nominal_flags, t, R, v, w, acc, A.m_r, f);
    }
    for (int i = 0; i < 6; ++i) f[i] = std::fmin(std::fmax(f[i], A.force_lo), A.force_hi);
}

// The actuators of one row over one physics step: the leg-force set points f (6,) into the forces
// F (6,) the legs feel, N.  ideal: F = f; lag: F += lag (f - F); electric: the current set point
// f / (eta k K_t) through the current loop (actuators::electric_leg); hydraulic: a force loop
// onto the valve, spool command force_gain (f - (P_A A_A - P_B A_B)), through the spool and the
// chambers (actuators::hydraulic_leg).  state (6, STATES).  docs/physics.md section 10.8.
inline void drive_legs(const Actuation& A, double dt, const double* f, const double* L, const double* Ldot,
                       double* state, double* F) {
    for (int i = 0; i < 6; ++i) {
        double* s = state + STATES * i;
        switch (A.kind) {
            case LAG:
                F[i] += A.lag * (f[i] - F[i]);
                break;
            case ELECTRIC:
                F[i] = actuators::electric_leg(A.electric, A.current_gain, f[i] / A.force_per_amp, Ldot[i], s[0]);
                break;
            case HYDRAULIC: {
                const actuators::Hydraulic& c = A.hydraulic;
                const double command = A.force_gain * (f[i] - (s[1] * c.A_A - s[2] * c.A_B));
                F[i] = actuators::hydraulic_leg(c, dt, 1, A.valve_gain, command, L[i], Ldot[i], s);
                break;
            }
            default:
                F[i] = f[i];
        }
    }
}

// The forces of row r for its next physics step: the leg sensors of the nominal model at the
// row's state, the inner loop towards the set point sp, the actuators (their state advanced by
// dt) into the row's forces F (n,6).  nominal: the nominal model's row; (t, R, v, w) the batch's
// state arrays.  docs/physics.md section 10.8.
inline void substep_forces(const Actuation& A, const double* nominal, const SetPoint& sp, double dt, double* F,
                           const double* t, const double* R, const double* v, const double* w, int64_t r) {
    const double *tr = t + 3 * r, *Rr = R + 9 * r, *vr = v + 3 * r, *wr = w + 3 * r;
    double L[6], Ldot[6], f[6];
    for (int i = 0; i < 6; ++i) {
        const auto leg = kernels::leg_state<double>(nominal, i, 0, tr, Rr, vr, wr);
        L[i] = leg.frame.L;
        Ldot[i] = leg.Ldot;
    }
    inner_loop(A, nominal, sp, tr, Rr, vr, wr, L, Ldot, f);
    drive_legs(A, dt, f, L, Ldot, A.state + 6 * STATES * r, F + 6 * r);
}

}  // namespace actuation
