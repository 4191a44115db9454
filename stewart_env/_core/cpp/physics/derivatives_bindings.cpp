// Python bindings of the exact derivatives of the dynamics (physics/derivatives.hpp), with the
// shapes of their arrays checked so no call from Python can read or write outside them.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>

#include <cmath>
#include <cstdint>
#include <optional>

#include "physics/derivatives.hpp"  // first: it includes dual.hpp before the kernels
#include "physics/array_checks.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace {

using array_checks::expect;
using In = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;
using Out = nb::ndarray<double, nb::c_contig, nb::device::cpu>;
using Flags = nb::ndarray<bool, nb::c_contig, nb::device::cpu>;

// The batch size n of the state arrays and their shapes, prm's rows (1 or n) and the reflected
// masses' rows (1 or n), checked; returns n.
int64_t checked_batch(const In& prm, const In& t, const In& R, const In& v, const In& w, const In& F, const In& W,
                      const std::optional<In>& m_r) {
    expect(t, "position", {-1, 3});
    const int64_t n = static_cast<int64_t>(t.shape(0));
    expect(prm, "prm", {-1, kernels::N_PARAMS});
    const int64_t np = static_cast<int64_t>(prm.shape(0));
    if (!(np == 1 || np == n)) throw nb::value_error("prm: expected 1 or N parameter rows");
    expect(R, "rotation", {n, 3, 3});
    expect(v, "velocity", {n, 3});
    expect(w, "angular_velocity", {n, 3});
    expect(F, "leg_forces", {n, 6});
    expect(W, "external_wrench", {n, 6});
    if (m_r) {
        expect(*m_r, "reflected_mass", {-1, 6});
        const int64_t nm = static_cast<int64_t>(m_r->shape(0));
        if (!(nm == 1 || nm == n)) throw nb::value_error("reflected_mass: expected 1 or N rows");
    }
    return n;
}

}  // namespace

void bind_derivatives(nb::module_& m) {
    m.attr("DERIVATIVE_DIRECTIONS") = derivatives::DIRECTIONS;

    m.def("acceleration_jacobian_batch", [](In prm, int64_t flags, In t, In R, In v, In w, In F, In W,
                                            std::optional<In> m_r, Out acc, Out jac, Flags finite) {
        const int64_t n = checked_batch(prm, t, R, v, w, F, W, m_r);
        expect(acc, "acc", {n, 6});
        expect(jac, "jac", {n, 6, derivatives::DIRECTIONS});
        expect(finite, "finite", {n});
        const double* mr = m_r ? m_r->data() : nullptr;
        const int64_t nm = m_r ? static_cast<int64_t>(m_r->shape(0)) : 0;
        nb::gil_scoped_release release;
        derivatives::acceleration_jacobian_batch(prm.data(), prm.shape(0), flags, t.data(), R.data(), v.data(),
                                                 w.data(), F.data(), W.data(), mr, nm, acc.data(), jac.data(),
                                                 finite.data(), n);
    }, "prm"_a, "flags"_a, "t"_a, "R"_a, "v"_a, "w"_a, "F"_a, "W"_a, "m_r"_a.none(), "acc"_a.noconvert(),
       "jac"_a.noconvert(), "finite"_a.noconvert(),
       "The forward dynamics' acceleration acc (N,6) and its exact Jacobian jac (N,6,18), columns (dt, dtheta, v, w, "
       "F), by forward-mode automatic differentiation of the kernel; m_r (1 or N, 6) the legs' reflected masses or "
       "None; rows not finite are NaN, finite[b] False (docs/physics.md section 11).");

    m.def("step_jacobian_batch", [](In prm, int64_t flags, In t, In R, In v, In w, In F, In W, std::optional<In> m_r,
                                    double dt, int64_t steps, Out t_next, Out R_next, Out v_next, Out w_next, Out jac,
                                    Flags finite) {
        const int64_t n = checked_batch(prm, t, R, v, w, F, W, m_r);
        if (!(dt > 0.0) || !std::isfinite(dt)) throw nb::value_error("dt: expected a finite step > 0 s");
        if (steps < 1) throw nb::value_error("steps: expected an integer >= 1");
        expect(t_next, "t_next", {n, 3});
        expect(R_next, "R_next", {n, 3, 3});
        expect(v_next, "v_next", {n, 3});
        expect(w_next, "w_next", {n, 3});
        expect(jac, "jac", {n, 12, derivatives::DIRECTIONS});
        expect(finite, "finite", {n});
        const double* mr = m_r ? m_r->data() : nullptr;
        const int64_t nm = m_r ? static_cast<int64_t>(m_r->shape(0)) : 0;
        nb::gil_scoped_release release;
        derivatives::step_jacobian_batch(prm.data(), prm.shape(0), flags, t.data(), R.data(), v.data(), w.data(),
                                         F.data(), W.data(), mr, nm, dt, steps, t_next.data(), R_next.data(),
                                         v_next.data(), w_next.data(), jac.data(), finite.data(), n);
    }, "prm"_a, "flags"_a, "t"_a, "R"_a, "v"_a, "w"_a, "F"_a, "W"_a, "m_r"_a.none(), "dt"_a, "steps"_a,
       "t_next"_a.noconvert(), "R_next"_a.noconvert(), "v_next"_a.noconvert(), "w_next"_a.noconvert(),
       "jac"_a.noconvert(), "finite"_a.noconvert(),
       "`steps` RK4 steps of dt s (F, W held) from (t, R, v, w): the next state into the *_next arrays and its exact "
       "Jacobian jac (N,12,18), rows the next state's (dt, dtheta, v, w), columns the state's then F, by forward-mode "
       "automatic differentiation of the integrator and the kernel; rows not finite NaN, finite[b] False "
       "(docs/physics.md section 11).");
}
