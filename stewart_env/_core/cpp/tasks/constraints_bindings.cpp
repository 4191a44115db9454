// Python binding of the constraint evaluation (constraints.hpp): ConstraintBounds, a platform's
// bounds held by value, and evaluate_constraints over a batch, with the shapes of its arrays checked
// so no call from Python can read or write outside them.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <new>
#include <string>
#include <utility>

#include "physics/array_checks.hpp"
#include "tasks/constraints.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace {

using In = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;
using Out = nb::ndarray<double, nb::c_contig, nb::device::cpu>;
using Flags = nb::ndarray<bool, nb::c_contig, nb::device::cpu>;
using Codes = nb::ndarray<int64_t, nb::c_contig, nb::device::cpu>;
using array_checks::expect;

void copy(const In& a, const char* name, std::initializer_list<int64_t> shape, double* to) {
    expect(a, name, shape);
    for (size_t k = 0; k < a.size(); ++k) to[k] = a.data()[k];
}

// A bound that may be absent (inf): positive, or inf.
double bound(double x, const char* name) {
    if (!(x > 0.0)) throw nb::value_error((std::string(name) + ": expected a bound > 0 or inf").c_str());
    return x;
}

// An interval (lo, hi) with lo < hi, both finite.
void interval(double lo, double hi, const char* name) {
    if (!(std::isfinite(lo) && std::isfinite(hi) && lo < hi))
        throw nb::value_error((std::string(name) + ": expected finite (min, max) with min < max").c_str());
}

// The rows N of a batch's state (t, R, v, w) and its parameter rows (1 or N), each array checked.
std::pair<int64_t, int64_t> checked_rows(const In& prm, const In& t, const In& R, const In& v, const In& w) {
    expect(t, "position (N, 3)", {-1, 3});
    const int64_t n = static_cast<int64_t>(t.shape(0));
    expect(prm, "prm (1 or N, N_PARAMS)", {-1, kernels::N_PARAMS});
    const int64_t np = static_cast<int64_t>(prm.shape(0));
    if (!(np == 1 || np == n)) throw nb::value_error("prm: expected 1 or N parameter rows");
    expect(R, "rotation (N, 3, 3)", {n, 3, 3});
    expect(v, "velocity (N, 3)", {n, 3});
    expect(w, "angular_velocity (N, 3)", {n, 3});
    return {n, np};
}

}  // namespace

void bind_constraints(nb::module_& m) {
    m.attr("N_CONSTRAINTS") = static_cast<int>(constraints::N_CONSTRAINTS);
    nb::list names;
    for (const char* name : constraints::NAMES) names.append(name);
    m.attr("CONSTRAINT_NAMES") = nb::tuple(names);

    nb::class_<constraints::Bounds>(m, "ConstraintBounds",
                                    "A platform's bounds for evaluate_constraints, held by value (constraints.hpp).")
        .def("__init__",
             [](constraints::Bounds* self, double length_min, double length_max, double max_velocity,
                double max_acceleration, double force_min, double force_max, double max_force_rate,
                double max_universal_angle, double max_spherical_angle, In universal_axes, In spherical_axes,
                In position_min, In position_max, In home_rpy, double max_angle) {
                 constraints::Bounds b;
                 interval(length_min, length_max, "leg_length");
                 interval(force_min, force_max, "leg_force");
                 b.length_min = length_min;
                 b.length_max = length_max;
                 b.max_velocity = bound(max_velocity, "max_leg_velocity");
                 b.max_acceleration = bound(max_acceleration, "max_leg_acceleration");
                 b.force_min = force_min;
                 b.force_max = force_max;
                 b.max_force_rate = bound(max_force_rate, "max_force_rate");
                 b.max_universal_angle = bound(max_universal_angle, "max_universal_angle");
                 b.max_spherical_angle = bound(max_spherical_angle, "max_spherical_angle");
                 copy(universal_axes, "universal_axes (6, 3)", {6, 3}, b.universal_axes);
                 copy(spherical_axes, "spherical_axes (6, 3)", {6, 3}, b.spherical_axes);
                 copy(position_min, "position_min (3,)", {3}, b.position_min);
                 copy(position_max, "position_max (3,)", {3}, b.position_max);
                 copy(home_rpy, "home_rpy (3,)", {3}, b.home_rpy);
                 for (int j = 0; j < 3; ++j)
                     if (!(b.position_min[j] < b.position_max[j]))
                         throw nb::value_error("position_min: expected below position_max on every axis");
                 b.max_angle = bound(max_angle, "max_angle");
                 new (self) constraints::Bounds(b);
             },
             "length_min"_a, "length_max"_a, "max_velocity"_a, "max_acceleration"_a, "force_min"_a, "force_max"_a,
             "max_force_rate"_a, "max_universal_angle"_a, "max_spherical_angle"_a, "universal_axes"_a,
             "spherical_axes"_a, "position_min"_a, "position_max"_a, "home_rpy"_a, "max_angle"_a);

    m.def("evaluate_constraints",
          [](const constraints::Bounds& b, int64_t terminate, In prm, In t, In R, In v, In w, In rates_prev,
             In forces_prev, In forces, double control_dt, Out value, Out margin, Out cost, Flags violated,
             Out total, Codes code) {
              const auto [n, np] = checked_rows(prm, t, R, v, w);
              expect(rates_prev, "previous_rates (N, 6)", {n, 6});
              expect(forces_prev, "previous_forces (N, 6)", {n, 6});
              expect(forces, "forces (N, 6)", {n, 6});
              constexpr int64_t K = constraints::N_CONSTRAINTS;
              expect(value, "values (N, N_CONSTRAINTS, 6)", {n, K, constraints::N_ENTRIES});
              expect(margin, "margins (N, N_CONSTRAINTS, 6)", {n, K, constraints::N_ENTRIES});
              expect(cost, "costs (N, N_CONSTRAINTS)", {n, K});
              expect(violated, "violated (N, N_CONSTRAINTS)", {n, K});
              expect(total, "cost (N,)", {n});
              expect(code, "code (N,)", {n});
              if (!(std::isfinite(control_dt) && control_dt > 0.0))
                  throw nb::value_error("control_dt: expected a finite number > 0");
              if (terminate < 0 || terminate >= (int64_t{1} << K))
                  throw nb::value_error("terminate: expected a bit mask of the constraints");
              nb::gil_scoped_release release;
              constraints::evaluate_batch(prm.data(), np, t.data(), R.data(), v.data(), w.data(), rates_prev.data(),
                                          forces_prev.data(), forces.data(), control_dt, b, terminate, value.data(),
                                          margin.data(), cost.data(), violated.data(), total.data(), code.data(), n);
          },
          "bounds"_a, "terminate"_a, "prm"_a, "t"_a, "R"_a, "v"_a, "w"_a, "previous_rates"_a, "previous_forces"_a,
          "forces"_a, "control_dt"_a, "values"_a.noconvert(), "margins"_a.noconvert(), "costs"_a.noconvert(),
          "violated"_a.noconvert(), "cost"_a.noconvert(), "code"_a.noconvert(),
          "Each constraint's value and margin per row and leg, its indicator cost and violation per row, the "
          "summed cost and the first violated constraint of the terminate mask (constraints.hpp).");
    m.def("constraint_costs",
          [](const constraints::Bounds& b, int64_t terminate, In prm, In t, In R, In v, In w, Out rates,
             Out forces_prev, In forces, Flags fresh, double control_dt, Out cost, Flags violated, Out total,
             Codes code) {
              const auto [n, np] = checked_rows(prm, t, R, v, w);
              expect(rates, "previous_rates (N, 6)", {n, 6});
              expect(forces_prev, "previous_forces (N, 6)", {n, 6});
              expect(forces, "forces (N, 6)", {n, 6});
              expect(fresh, "fresh (N,)", {n});
              constexpr int64_t K = constraints::N_CONSTRAINTS;
              expect(cost, "costs (N, N_CONSTRAINTS)", {n, K});
              expect(violated, "violated (N, N_CONSTRAINTS)", {n, K});
              expect(total, "cost (N,)", {n});
              expect(code, "code (N,)", {n});
              if (!(std::isfinite(control_dt) && control_dt > 0.0))
                  throw nb::value_error("control_dt: expected a finite number > 0");
              if (terminate < 0 || terminate >= (int64_t{1} << K))
                  throw nb::value_error("terminate: expected a bit mask of the constraints");
              nb::gil_scoped_release release;
              constraints::costs_batch(prm.data(), np, t.data(), R.data(), v.data(), w.data(), rates.data(),
                                       forces_prev.data(), forces.data(), fresh.data(), control_dt, b, terminate,
                                       cost.data(), violated.data(), total.data(), code.data(), n);
          },
          "bounds"_a, "terminate"_a, "prm"_a, "t"_a, "R"_a, "v"_a, "w"_a, "previous_rates"_a.noconvert(),
          "previous_forces"_a.noconvert(), "forces"_a, "fresh"_a.noconvert(), "control_dt"_a,
          "costs"_a.noconvert(), "violated"_a.noconvert(), "cost"_a.noconvert(), "code"_a.noconvert(),
          "The costs of evaluate_constraints alone, bit for bit, without values or margins, with the previous leg "
          "rates and forces overwritten by this step's in place (a fresh row's force rate 0) (constraints.hpp).");

    m.def("constraint_leg_rates",
          [](In prm, In t, In R, In v, In w, nb::ndarray<const int64_t, nb::c_contig, nb::device::cpu> rows,
             Out rates) {
              expect(t, "position (M, 3)", {-1, 3});
              const int64_t mrows = static_cast<int64_t>(t.shape(0));
              expect(prm, "prm (1 or M, N_PARAMS)", {-1, kernels::N_PARAMS});
              const int64_t np = static_cast<int64_t>(prm.shape(0));
              if (!(np == 1 || np == mrows)) throw nb::value_error("prm: expected 1 or M parameter rows");
              expect(R, "rotation (M, 3, 3)", {mrows, 3, 3});
              expect(v, "velocity (M, 3)", {mrows, 3});
              expect(w, "angular_velocity (M, 3)", {mrows, 3});
              expect(rows, "rows (M,)", {mrows});
              expect(rates, "rates (N, 6)", {-1, 6});
              const int64_t n = static_cast<int64_t>(rates.shape(0));
              for (int64_t j = 0; j < mrows; ++j)
                  if (rows.data()[j] < 0 || rows.data()[j] >= n)
                      throw nb::index_error("rows: expected rows of rates, 0 <= row < N");
              nb::gil_scoped_release release;
              constraints::leg_rates_into(prm.data(), np, t.data(), R.data(), v.data(), w.data(), rows.data(), mrows,
                                          rates.data());
          },
          "prm"_a, "t"_a, "R"_a, "v"_a, "w"_a, "rows"_a, "rates"_a.noconvert(),
          "The leg rates (eq. L1) of M states written into rows rows of rates, as evaluate_constraints' values "
          "(constraints.hpp).");
}
