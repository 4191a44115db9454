// The legs' actuator models: what turns a drive's command into the force along each leg, one
// function per equation of docs/physics.md section 10 (named as there), batched over rows x 6 legs.
//
// Every model advances its per-leg state over one step dt with the leg's length and rate held,
// and writes the force f (N, > 0 extends the leg) that the dynamics then holds over the step.  The
// functions allocate nothing, keep no state of their own and treat each leg alone, so a row's
// numbers do not depend on the batch it is in.  Parameters are packed rows of doubles, one set for
// the batch, in the order of the *_KEYS tables below (the one source of the order: the bindings
// export them and stewart_env.actuators packs by them).
//
// Arrays are C-contiguous float64 of n rows x 6 legs (the state of the hydraulic model: n x 6 x 3).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace actuators {

// ---- packed parameters --------------------------------------------------------------------------

//: The electric drive's packed parameters, in order (docs/physics.md section 10.4).
constexpr const char* ELECTRIC_KEYS[] = {
    "current_bandwidth",   // omega_c, rad/s
    "current_limit",       // i_max, A
    "bus_voltage",         // U, V
    "winding_resistance",  // R, ohm
    "back_emf_constant",   // K_e, V s/rad
    "ratio",               // k = 2 pi N / p, rad/m
    "efficiency",          // eta
    "torque_constant",     // K_t, N m/A
    "viscous_friction",    // b, N s/m (on the leg)
    "coulomb_friction",    // f_c, N (on the leg)
    "friction_speed",      // v_s, m/s: the tanh's speed scale
};
constexpr int N_ELECTRIC = sizeof(ELECTRIC_KEYS) / sizeof(ELECTRIC_KEYS[0]);

//: The hydraulic cylinder's packed parameters, in order (docs/physics.md section 10.5).
constexpr const char* HYDRAULIC_KEYS[] = {
    "valve_bandwidth",     // omega_v, rad/s
    "valve_max_opening",   // x_max, m
    "orifice_gain",        // K = C_d w sqrt(2 / rho), m^3/(s Pa^0.5) per m of spool
    "supply_pressure",     // P_s, Pa
    "return_pressure",     // P_r, Pa
    "area_a",              // A_A, m^2 (piston side)
    "area_b",              // A_B, m^2 (rod side)
    "bulk_modulus",        // beta, Pa
    "dead_volume_a",       // V_A0, m^3 (chamber A at the retracted end, lines included)
    "dead_volume_b",       // V_B0, m^3 (chamber B at the extended end, lines included)
    "retracted_length",    // l_0, m: the leg's length with the piston at the retracted end
    "stroke",              // s, m
    "internal_leakage",    // C_il, m^3/(s Pa)
    "external_leakage",    // C_el, m^3/(s Pa)
    "viscous_friction",    // b, N s/m
    "coulomb_friction",    // f_c, N
    "friction_speed",      // v_s, m/s
};
constexpr int N_HYDRAULIC = sizeof(HYDRAULIC_KEYS) / sizeof(HYDRAULIC_KEYS[0]);

//: The leg servo's packed gains, in order (docs/physics.md section 10.6).
constexpr const char* SERVO_KEYS[] = {
    "stiffness",       // K_p, N/m
    "damping",         // K_d, N s/m
    "integral",        // K_i, N/(m s)
    "force_per_unit",  // g, N per unit of the actuator's command (eta k K_t for a current command)
};
constexpr int N_SERVO = sizeof(SERVO_KEYS) / sizeof(SERVO_KEYS[0]);

// ---- shared equations ---------------------------------------------------------------------------

// The gain 1 - exp(-dt / tau) of a first-order lag's exact step with its input held over dt
// (zero-order hold): x_{k+1} = x_k + lag_gain (u_k - x_k).  docs/physics.md section 10.3 (no paper
// equation).
inline double lag_gain(double dt_over_tau) { return -std::expm1(-dt_over_tau); }

// The friction of a leg: viscous b l_dot plus Coulomb f_c tanh(l_dot / v_s), opposing l_dot.
// docs/physics.md section 10.4 (no paper equation).
inline double leg_friction(double viscous, double coulomb, double speed_scale, double l_dot) {
    return viscous * l_dot + coulomb * std::tanh(l_dot / speed_scale);
}

// ---- ideal and lag ------------------------------------------------------------------------------

// The lag actuator's step over a batch: force += lag_gain(dt / tau) (command - force), the exact
// discretisation of tau f_dot = u - f with u held over dt (tau = 0: force = command, the ideal
// actuator).  command and force (n, 6).  docs/physics.md section 10.3 (no paper equation).
inline void lag_batch(double tau, double dt, const double* command, double* force, int64_t n) {
    const double a = tau > 0.0 ? lag_gain(dt / tau) : 1.0;
    for (int64_t k = 0; k < 6 * n; ++k) force[k] = tau > 0.0 ? force[k] + a * (command[k] - force[k]) : command[k];
}

// ---- electric -----------------------------------------------------------------------------------

//: The electric drive's parameters (ELECTRIC_KEYS' order).
struct Electric {
    double omega_c, i_max, U, R, K_e, k, eta, K_t, b, f_c, v_s;
};

// The electric drive's parameters from their packed row (ELECTRIC_KEYS).  docs/physics.md section
// 10.4 (no paper equation).
inline Electric electric_from(const double* p) {
    return {p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8], p[9], p[10]};
}

// The current the bus voltage can drive at motor speed omega_m: (U - K_e |omega_m|) / R, at least
// 0 (the voltage envelope of the torque-speed curve).  docs/physics.md section 10.4 (no paper
// equation).
inline double voltage_current_limit(const Electric& d, double omega_m) {
    return std::max(0.0, (d.U - d.K_e * std::fabs(omega_m)) / d.R);
}

// The current set point the drive can follow: the command clipped to the current limit i_max and
// to the voltage envelope at the leg's rate.  docs/physics.md section 10.4 (no paper equation).
inline double current_reference(const Electric& d, double command, double l_dot) {
    const double motoring = std::min(d.i_max, voltage_current_limit(d, d.k * l_dot));
    // the back-EMF bounds the current that drives the motor with its speed; a current against
    // the speed (braking) is bounded by i_max alone, its power taken by the drive's braking resistor
    const double upper = l_dot > 0.0 ? motoring : d.i_max;
    const double lower = l_dot < 0.0 ? motoring : d.i_max;
    return std::clamp(command, -lower, upper);
}

// The leg force of a motor current: f = eta k K_t i minus the screw's friction at l_dot.
// docs/physics.md section 10.4 (no paper equation).
inline double electric_force(const Electric& d, double current, double l_dot) {
    return d.eta * d.k * d.K_t * current - leg_friction(d.b, d.f_c, d.v_s, l_dot);
}

// One electric leg over dt: the current loop, first order of bandwidth omega_c, steps exactly
// towards current_reference (held over dt), and the force follows from the new current.
// docs/physics.md section 10.4 (no paper equation).
inline double electric_leg(const Electric& d, double gain, double command, double l_dot, double& current) {
    current += gain * (current_reference(d, command, l_dot) - current);
    return electric_force(d, current, l_dot);
}

// The electric drive's step over a batch: command (n, 6) current set points, A; l_dot (n, 6) leg
// rates, m/s; current (n, 6) the motor currents, A, advanced; force (n, 6) written, N.
// docs/physics.md section 10.4 (no paper equation).
inline void electric_batch(const double* packed, double dt, const double* command, const double* l_dot,
                           double* current, double* force, int64_t n) {
    const Electric d = electric_from(packed);
    const double gain = lag_gain(d.omega_c * dt);
    for (int64_t k = 0; k < 6 * n; ++k) force[k] = electric_leg(d, gain, command[k], l_dot[k], current[k]);
}

// ---- hydraulic ----------------------------------------------------------------------------------

//: The hydraulic cylinder's parameters (HYDRAULIC_KEYS' order).
struct Hydraulic {
    double omega_v, x_max, K, P_s, P_r, A_A, A_B, beta, V_A0, V_B0, l_0, stroke, C_il, C_el, b, f_c, v_s;
};

// The cylinder's parameters from their packed row (HYDRAULIC_KEYS).  docs/physics.md section 10.5
// (no paper equation).
inline Hydraulic hydraulic_from(const double* p) {
    return {p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8], p[9], p[10], p[11], p[12], p[13], p[14], p[15],
            p[16]};
}

//: The two chambers' volumes at a piston position (chamber_volumes' value), m^3.
struct Volumes {
    double V_A, V_B;
};

// The chambers' volumes at leg length l: x_p = l - l_0 clipped to the stroke, V_A = V_A0 + A_A x_p,
// V_B = V_B0 + A_B (s - x_p).  docs/physics.md section 10.5 (no paper equation).
inline Volumes chamber_volumes(const Hydraulic& c, double l) {
    const double x_p = std::clamp(l - c.l_0, 0.0, c.stroke);
    return {c.V_A0 + c.A_A * x_p, c.V_B0 + c.A_B * (c.stroke - x_p)};
}

// The orifice flow Q = C_d w x sqrt(2 |dP| / rho) sign(dP) = K x sign(dP) sqrt(|dP|) into a
// chamber through a metering edge of opening x >= 0 from a port at P_port.  docs/physics.md
// section 10.5; Merritt (1967), the turbulent orifice (no paper equation).
inline double orifice_flow(double K, double x, double P_port, double P) {
    const double dP = P_port - P;
    return K * x * std::copysign(std::sqrt(std::fabs(dP)), dP);
}

// One chamber's pressure over h by the backward-Euler step of
// dP/dt = beta / V (Q(P) + q_piston - C_il (P - P_other) - C_el P), with Q(P) = orifice_flow
// through the open edge (K_x = K x, port P_port) at the new pressure and P_other held: solved in
// closed form, since with s = sign(P_port - P) sqrt(|P_port - P|) it is the quadratic
// a s|s| + c K_x s + D = 0.  Unconditionally stable, whatever the oil's stiffness; the pressure is
// floored at 0 (the oil cannot pull: cavitation).  docs/physics.md section 10.5 (no paper equation).
inline double chamber_pressure(double P, double c, double K_x, double P_port, double q_piston, double C_il,
                               double C_el, double P_other) {
    const double a = 1.0 + c * (C_il + C_el);
    const double D = P + c * q_piston + c * C_il * P_other - a * P_port;
    const double cK = c * K_x;
    const double den = cK + std::sqrt(cK * cK + 4.0 * a * std::fabs(D));
    const double s = den > 0.0 ? -2.0 * D / den : 0.0;
    return std::max(0.0, P_port - s * std::fabs(s));
}

// The cylinder's force: P_A A_A - P_B A_B minus the friction at l_dot.  docs/physics.md section
// 10.5 (no paper equation).
inline double hydraulic_force(const Hydraulic& c, double P_A, double P_B, double l_dot) {
    return P_A * c.A_A - P_B * c.A_B - leg_friction(c.b, c.f_c, c.v_s, l_dot);
}

// One hydraulic leg over dt in `substeps` steps h: the spool x_v steps exactly towards the set
// point u x_max (first order of bandwidth omega_v, u in [-1, 1] held), then chamber A's pressure
// and chamber B's (with A's new one) by chamber_pressure; x_v >= 0 opens A to supply and B to
// return, x_v < 0 the other way (a critically lapped four-way valve).  state = (x_v, P_A, P_B).
// docs/physics.md section 10.5 (no paper equation).
inline double hydraulic_leg(const Hydraulic& c, double h, int64_t substeps, double valve_gain, double command,
                            double l, double l_dot, double* state) {
    const double x_ref = std::clamp(command, -1.0, 1.0) * c.x_max;
    const Volumes vol = chamber_volumes(c, l);
    const double c_A = h * c.beta / vol.V_A;
    const double c_B = h * c.beta / vol.V_B;
    double x_v = state[0], P_A = state[1], P_B = state[2];
    for (int64_t j = 0; j < substeps; ++j) {
        x_v += valve_gain * (x_ref - x_v);
        const bool forward = x_v >= 0.0;
        const double K_x = c.K * std::fabs(x_v);
        P_A = chamber_pressure(P_A, c_A, K_x, forward ? c.P_s : c.P_r, -c.A_A * l_dot, c.C_il, c.C_el, P_B);
        P_B = chamber_pressure(P_B, c_B, K_x, forward ? c.P_r : c.P_s, c.A_B * l_dot, c.C_il, c.C_el, P_A);
    }
    state[0] = x_v;
    state[1] = P_A;
    state[2] = P_B;
    return hydraulic_force(c, P_A, P_B, l_dot);
}

// The hydraulic cylinders' step over a batch: command (n, 6) spool set points in [-1, 1]; l, l_dot
// (n, 6) leg lengths, m, and rates, m/s, held over dt; state (n, 6, 3) (x_v m, P_A Pa, P_B Pa),
// advanced in `substeps` steps of dt / substeps; force (n, 6) written, N.  docs/physics.md section
// 10.5 (no paper equation).
inline void hydraulic_batch(const double* packed, double dt, int64_t substeps, const double* command,
                            const double* l, const double* l_dot, double* state, double* force, int64_t n) {
    const Hydraulic c = hydraulic_from(packed);
    const double h = dt / static_cast<double>(substeps);
    const double valve_gain = lag_gain(c.omega_v * h);
    for (int64_t k = 0; k < 6 * n; ++k)
        force[k] = hydraulic_leg(c, h, substeps, valve_gain, command[k], l[k], l_dot[k], state + 3 * k);
}

// ---- leg servo ----------------------------------------------------------------------------------

//: A servo's gains (SERVO_KEYS' order).
struct Servo {
    double K_p, K_d, K_i, g;
};

// The -3 dB bandwidth of the closed loop omega_n^2 / (s^2 + 2 zeta omega_n s + omega_n^2) over its
// natural frequency: omega_b / omega_n = sqrt(1 - 2 zeta^2 + sqrt((1 - 2 zeta^2)^2 + 1)).
// docs/physics.md section 10.6 (no paper equation).
inline double bandwidth_ratio(double zeta) {
    const double r = 1.0 - 2.0 * zeta * zeta;
    return std::sqrt(r + std::sqrt(r * r + 1.0));
}

// The servo's gains for a leg of mass m with viscous friction b: K_p = m omega_n^2 and
// K_d = 2 zeta omega_n m - b, omega_n = omega_b / bandwidth_ratio(zeta), so that the leg follows its
// set point with bandwidth omega_b and damping ratio zeta; K_i = 0; g the actuator's force per
// unit of command.  docs/physics.md section 10.6 (no paper equation).
inline Servo servo_gains(double omega_b, double zeta, double m, double b, double g) {
    const double omega_n = omega_b / bandwidth_ratio(zeta);
    return {m * omega_n * omega_n, 2.0 * zeta * omega_n * m - b, 0.0, g};
}

// The leg servo over a batch: the force K_p (l_ref - l) - K_d l_dot + K_i integral, divided by g
// into the actuator's command (n, 6); integral (n, 6) of the length error, m s, advanced by
// (l_ref - l) dt.  docs/physics.md section 10.6 (no paper equation).
inline void leg_servo_batch(const double* packed, double dt, const double* l_ref, const double* l,
                            const double* l_dot, double* integral, double* command, int64_t n) {
    const Servo s{packed[0], packed[1], packed[2], packed[3]};
    for (int64_t k = 0; k < 6 * n; ++k) {
        const double error = l_ref[k] - l[k];
        command[k] = (s.K_p * error - s.K_d * l_dot[k] + s.K_i * integral[k]) / s.g;
        integral[k] += error * dt;
    }
}

}  // namespace actuators
