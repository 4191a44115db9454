// Python binding of the regressor (regressor.hpp): regressor_batch, with the shapes of its arrays
// checked so no call from Python can read or write outside them.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include <cstdint>
#include <string>

#include "array_checks.hpp"
#include "excitation_law.hpp"
#include "regressor.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace {

using In = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;
using Out = nb::ndarray<double, nb::c_contig, nb::device::cpu>;

}  // namespace

void bind_regressor(nb::module_& m) {
    m.attr("N_THETA") = regressor::N_THETA;
    m.attr("FOURIER_COMPUTED_TORQUE") = reinterpret_cast<uintptr_t>(&excitation::fourier_computed_torque);
    m.def("fourier_reference", [](In params, double time, Out out) {
        array_checks::expect(params, "params", {-1});
        array_checks::expect(out, "out (3, 6)", {3, 6});
        if (params.shape(0) < excitation::COEF ||
            static_cast<int64_t>(params.shape(0)) != excitation::row_length(static_cast<int64_t>(params.data()[excitation::NH])))
            throw nb::value_error("params: not a Fourier excitation row");
        excitation::reference(params.data(), time, out.data(), out.data() + 6, out.data() + 12);
    }, "params"_a, "time"_a, "out"_a.noconvert());
    m.def("regressor_batch", [](In prm, int64_t flags, In t, In R, In v, In w, In acc, Out Y) {
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
                                   Y.data(), n);
    }, "prm"_a, "flags"_a, "t"_a, "R"_a, "v"_a, "w"_a, "acc"_a, "Y"_a.noconvert(),
       "The regressor Y (N, 6, N_THETA) of J^T F + W = Y theta (docs/physics.md section 5.7).");
}
