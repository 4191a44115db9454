// Python bindings of the actuator models (actuators/actuator_models.hpp) and of the dynamics with
// the legs' reflected masses (physics/kernels.hpp, reflected_batch), with the shapes of their arrays
// checked so no call from Python can read or write outside them.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include <cmath>
#include <cstdint>
#include <string>

#include "actuators/actuator_models.hpp"
#include "physics/array_checks.hpp"
#include "physics/kernels.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace {

using array_checks::expect;
using In = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;
using Out = nb::ndarray<double, nb::c_contig, nb::device::cpu>;

// The row count n of a (n, 6) array, checked.
int64_t rows(const In& a, const char* name) {
    expect(a, name, {-1, 6});
    return static_cast<int64_t>(a.shape(0));
}

// A packed parameter row of `size` numbers, checked.
void packed(const In& p, const char* name, int size) { expect(p, name, {size}); }

// dt > 0 and finite, or ValueError naming it.
void positive_step(double dt) {
    if (!(dt > 0.0) || !std::isfinite(dt)) throw nb::value_error("dt: expected a finite step > 0 s");
}

template <size_t N>
nb::tuple keys(const char* const (&names)[N]) {
    nb::list out;
    for (const char* name : names) out.append(name);
    return nb::tuple(out);
}

// reflected_batch<forward> as a binding: x the drive forces (forward) or the acceleration.
template <bool forward>
void solve_reflected(In prm, int64_t flags, In t, In R, In v, In w, In x, In W, In m_r, Out out) {
    expect(t, "position", {-1, 3});
    const int64_t n = static_cast<int64_t>(t.shape(0));
    expect(prm, "prm", {-1, kernels::N_PARAMS});
    const int64_t np = static_cast<int64_t>(prm.shape(0));
    if (!(np == 1 || np == n)) throw nb::value_error("prm: expected 1 or N parameter rows");
    expect(R, "rotation", {n, 3, 3});
    expect(v, "velocity", {n, 3});
    expect(w, "angular_velocity", {n, 3});
    expect(x, forward ? "leg_forces" : "acceleration", {n, 6});
    expect(W, "external_wrench", {n, 6});
    expect(m_r, "reflected_mass", {-1, 6});
    const int64_t nm = static_cast<int64_t>(m_r.shape(0));
    if (!(nm == 1 || nm == n)) throw nb::value_error("reflected_mass: expected 1 or N rows");
    expect(out, "out", {n, 6});
    nb::gil_scoped_release release;
    kernels::reflected_batch<forward>(prm.data(), np, flags, t.data(), R.data(), v.data(), w.data(), x.data(),
                                      W.data(), m_r.data(), nm, out.data(), n);
}

}  // namespace

void bind_actuators(nb::module_& m) {
    m.attr("ELECTRIC_KEYS") = keys(actuators::ELECTRIC_KEYS);
    m.attr("HYDRAULIC_KEYS") = keys(actuators::HYDRAULIC_KEYS);
    m.attr("SERVO_KEYS") = keys(actuators::SERVO_KEYS);

    m.def("forward_reflected_batch", &solve_reflected<true>, "prm"_a, "flags"_a, "t"_a, "R"_a, "v"_a, "w"_a, "F"_a,
          "W"_a, "m_r"_a, "out"_a.noconvert(),
          "Forward dynamics with the legs' reflected masses m_r (1 or N, 6), kg: (M + J^T diag(m_r) J) [a; alpha] + "
          "h + J^T diag(m_r) Jdot [v; w] = J^T F + W (docs/physics.md section 10.2).");
    m.def("inverse_reflected_batch", &solve_reflected<false>, "prm"_a, "flags"_a, "t"_a, "R"_a, "v"_a, "w"_a,
          "acc"_a, "W"_a, "m_r"_a, "out"_a.noconvert(),
          "The drive forces F = f + m_r Lddot of the acceleration acc, with the legs' reflected masses m_r (1 or N, "
          "6), kg (docs/physics.md section 10.2).");

    m.def("lag_step", [](double tau, double dt, In command, Out force) {
        const int64_t n = rows(command, "command");
        expect(force, "force", {n, 6});
        positive_step(dt);
        if (!(tau >= 0.0) || !std::isfinite(tau)) throw nb::value_error("tau: expected a finite time constant >= 0 s");
        nb::gil_scoped_release release;
        actuators::lag_batch(tau, dt, command.data(), force.data(), n);
    }, "tau"_a, "dt"_a, "command"_a, "force"_a.noconvert(),
       "The lag actuator's exact step: force (N, 6) += (1 - exp(-dt / tau)) (command - force); tau = 0: the ideal "
       "actuator, force = command (docs/physics.md section 10.3).");

    m.def("electric_step", [](In params, double dt, In command, In l_dot, Out current, Out force) {
        packed(params, "params (N_ELECTRIC,)", actuators::N_ELECTRIC);
        const int64_t n = rows(command, "command");
        expect(l_dot, "leg_velocity", {n, 6});
        expect(current, "current", {n, 6});
        expect(force, "force", {n, 6});
        positive_step(dt);
        nb::gil_scoped_release release;
        actuators::electric_batch(params.data(), dt, command.data(), l_dot.data(), current.data(), force.data(), n);
    }, "params"_a, "dt"_a, "command"_a, "l_dot"_a, "current"_a.noconvert(), "force"_a.noconvert(),
       "The electric drive's step over dt: current (N, 6) A advanced by the current loop, force (N, 6) N written "
       "(docs/physics.md section 10.4).");

    m.def("hydraulic_step", [](In params, double dt, int64_t substeps, In command, In l, In l_dot, Out state,
                               Out force) {
        packed(params, "params (N_HYDRAULIC,)", actuators::N_HYDRAULIC);
        const int64_t n = rows(command, "command");
        expect(l, "leg_length", {n, 6});
        expect(l_dot, "leg_velocity", {n, 6});
        expect(state, "state", {n, 6, 3});
        expect(force, "force", {n, 6});
        positive_step(dt);
        if (substeps < 1) throw nb::value_error("substeps: expected an integer >= 1");
        nb::gil_scoped_release release;
        actuators::hydraulic_batch(params.data(), dt, substeps, command.data(), l.data(), l_dot.data(), state.data(),
                                   force.data(), n);
    }, "params"_a, "dt"_a, "substeps"_a, "command"_a, "l"_a, "l_dot"_a, "state"_a.noconvert(),
       "force"_a.noconvert(),
       "The hydraulic cylinders' step over dt in `substeps` steps: state (N, 6, 3) (spool m, P_A Pa, P_B Pa) "
       "advanced, force (N, 6) N written (docs/physics.md section 10.5).");

    m.def("servo_gains", [](double omega_b, double zeta, double mass, double viscous, double force_per_unit) {
        const actuators::Servo s = actuators::servo_gains(omega_b, zeta, mass, viscous, force_per_unit);
        return nb::make_tuple(s.K_p, s.K_d, s.K_i, s.g);
    }, "omega_b"_a, "zeta"_a, "mass"_a, "viscous"_a, "force_per_unit"_a,
       "The leg servo's gains (SERVO_KEYS' order) for bandwidth omega_b rad/s and damping ratio zeta on a leg of "
       "mass kg with viscous friction N s/m (docs/physics.md section 10.6).");
    m.def("bandwidth_ratio", &actuators::bandwidth_ratio, "zeta"_a,
          "omega_b / omega_n of a second-order loop of damping ratio zeta (docs/physics.md section 10.6).");

    m.def("leg_servo", [](In gains, double dt, In l_ref, In l, In l_dot, Out integral, Out command) {
        packed(gains, "gains (N_SERVO,)", actuators::N_SERVO);
        const int64_t n = rows(l_ref, "leg_length_setpoint");
        expect(l, "leg_length", {n, 6});
        expect(l_dot, "leg_velocity", {n, 6});
        expect(integral, "integral", {n, 6});
        expect(command, "command", {n, 6});
        positive_step(dt);
        nb::gil_scoped_release release;
        actuators::leg_servo_batch(gains.data(), dt, l_ref.data(), l.data(), l_dot.data(), integral.data(),
                                   command.data(), n);
    }, "gains"_a, "dt"_a, "l_ref"_a, "l"_a, "l_dot"_a, "integral"_a.noconvert(), "command"_a.noconvert(),
       "The leg servo: command (N, 6) = (K_p (l_ref - l) - K_d l_dot + K_i integral) / g, integral advanced "
       "(docs/physics.md section 10.6).");
}
