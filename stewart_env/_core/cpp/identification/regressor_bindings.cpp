// Python binding of the regressor (regressor.hpp): regressor_batch, and of the excitation's Fourier
// series (excitation_law.hpp): fourier_series, with the shapes of its arrays
// checked so no call from Python can read or write outside them.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include <cmath>
#include <cstdint>
#include <string>

#include "physics/array_checks.hpp"
#include "identification/excitation_law.hpp"
#include "identification/regressor.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace {

using In = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;
using Out = nb::ndarray<double, nb::c_contig, nb::device::cpu>;

}  // namespace

void bind_regressor(nb::module_& m) {
    m.attr("N_THETA") = regressor::N_THETA;
    m.attr("FRICTION_SPEED") = regressor::FRICTION_SPEED;
    m.attr("FOURIER_COMPUTED_TORQUE") = reinterpret_cast<uintptr_t>(&excitation::fourier_computed_torque);
    m.def("fourier_series", [](In q0, In a, In b, double wf, In times, Out out) {
        array_checks::expect(q0, "q0 (6,)", {6});
        array_checks::expect(a, "a (6, H)", {6, -1});
        const int64_t H = static_cast<int64_t>(a.shape(1));
        array_checks::expect(b, "b (6, H)", {6, H});
        array_checks::expect(times, "times (T,)", {-1});
        const int64_t n = static_cast<int64_t>(times.shape(0));
        array_checks::expect(out, "out (T, 3, 6)", {n, 3, 6});
        if (H < 1) throw nb::value_error("a: expected at least one harmonic");
        nb::gil_scoped_release release;
        double* o = out.data();
        for (int64_t i = 0; i < n; ++i, o += 18)
            excitation::fourier_series(wf, static_cast<int>(H), q0.data(), a.data(), b.data(), times.data()[i], o, o + 6,
                                       o + 12);
    }, "q0"_a, "a"_a, "b"_a, "wf"_a, "times"_a, "out"_a.noconvert(),
       "q, qdot, qddot (T, 3, 6) of the excitation's Fourier series at the times (excitation_law.hpp).");
    m.def("regressor_batch", [](In prm, int64_t flags, In t, In R, In v, In w, In acc, Out Y, double friction_speed) {
        if (!(friction_speed > 0.0 && std::isfinite(friction_speed)))
            throw nb::value_error("friction_speed: expected a finite speed > 0 (m/s)");
        array_checks::expect(t, "position (N, 3)", {-1, 3});
        const int64_t n = static_cast<int64_t>(t.shape(0));
        array_checks::expect(prm, "prm (1 or N, N_PARAMS)", {-1, kernels::N_PARAMS});
        const int64_t np = static_cast<int64_t>(prm.shape(0));
        if (!(np == 1 || np == n)) throw nb::value_error("prm: expected 1 or N parameter rows");
        array_checks::expect(R, "rotation (N, 3, 3)", {n, 3, 3});
        array_checks::expect(v, "velocity (N, 3)", {n, 3});
        array_checks::expect(w, "angular_velocity (N, 3)", {n, 3});
        array_checks::expect(acc, "acceleration (N, 6)", {n, 6});
        array_checks::expect(Y, "Y (N, 6, N_THETA)", {n, 6, regressor::N_THETA});
        nb::gil_scoped_release release;
        regressor::regressor_batch(prm.data(), np, flags, t.data(), R.data(), v.data(), w.data(), acc.data(),
                                   Y.data(), n, friction_speed);
    }, "prm"_a, "flags"_a, "t"_a, "R"_a, "v"_a, "w"_a, "acc"_a, "Y"_a.noconvert(),
       "friction_speed"_a = regressor::FRICTION_SPEED,
       "The regressor Y (N, 6, N_THETA) of J^T F + W = Y theta (docs/physics.md section 5.7).");
}
