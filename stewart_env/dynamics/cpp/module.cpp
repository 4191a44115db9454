// Python bindings of the compiled kernels (stewart_env.dynamics._core): every function checks the
// shapes of the arrays it is given, so no call from Python can read or write outside them, and
// hands the raw pointers to kernels.hpp, rk4.hpp and laws.hpp.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include <cstdint>
#include <string>
#include <vector>

#include "kernels.hpp"
#include "laws.hpp"
#include "rk4.hpp"

namespace nb = nanobind;
using namespace nb::literals;

void bind_regressor(nb::module_& m);  // regressor_bindings.cpp

using In = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;
using Out = nb::ndarray<double, nb::c_contig, nb::device::cpu>;

namespace {

// Raise ValueError naming the array unless its shape is `shape` (-1: any size).
template <typename A>
void expect(const A& a, const char* name, std::initializer_list<int64_t> shape) {
    bool ok = a.ndim() == shape.size();
    size_t d = 0;
    for (int64_t s : shape) {
        if (!ok) break;
        ok = s < 0 || static_cast<int64_t>(a.shape(d)) == s;
        ++d;
    }
    if (!ok) {
        std::string got = "(";
        for (size_t k = 0; k < a.ndim(); ++k) got += (k ? ", " : "") + std::to_string(a.shape(k));
        got += ")";
        std::string want = "(";
        d = 0;
        for (int64_t s : shape) want += (d++ ? ", " : "") + (s < 0 ? std::string("N") : std::to_string(s));
        want += ")";
        throw nb::value_error((std::string(name) + ": expected shape " + want + ", got " + got).c_str());
    }
}

// The batch size of t (n,3) and the row count of prm (1 or n, N_PARAMS), checked.
int64_t batch(const In& prm, const In& t) {
    expect(t, "position", {-1, 3});
    expect(prm, "prm", {-1, kernels::N_PARAMS});
    const int64_t n = static_cast<int64_t>(t.shape(0));
    const int64_t np = static_cast<int64_t>(prm.shape(0));
    if (!(np == 1 || np == n)) throw nb::value_error("prm: expected 1 or N parameter rows");
    return n;
}

// The state arrays of a batch of n, checked.
template <typename T, typename R, typename V>
void state(const T& t, const R& rot, const V& v, const V& w, int64_t n) {
    expect(t, "position", {n, 3});
    expect(rot, "rotation", {n, 3, 3});
    expect(v, "velocity", {n, 3});
    expect(w, "angular_velocity", {n, 3});
}

//: kernels::forward_batch or kernels::inverse_batch: (prm, n_prm, flags, t, R, v, w, x, W, out, n).
using SolveBatch = void (*)(const double*, int64_t, int64_t, const double*, const double*, const double*,
                            const double*, const double*, const double*, double*, int64_t);

// Bind a SolveBatch as name(prm, flags, t, R, v, w, x, W, out): x (N,6) is the argument x_arg,
// named in errors as x_name (the leg forces of forward dynamics, the acceleration of inverse).
template <SolveBatch solve>
void def_solve_batch(nb::module_& m, const char* name, const char* x_arg, const char* x_name) {
    m.def(name, [x_name](In prm, int64_t flags, In t, In R, In v, In w, In x, In W, Out out) {
        const int64_t n = batch(prm, t);
        state(t, R, v, w, n);
        expect(x, x_name, {n, 6});
        expect(W, "external_wrench", {n, 6});
        expect(out, "out", {n, 6});
        solve(prm.data(), prm.shape(0), flags, t.data(), R.data(), v.data(), w.data(), x.data(), W.data(), out.data(),
              n);
    }, "prm"_a, "flags"_a, "t"_a, "R"_a, "v"_a, "w"_a, nb::arg(x_arg), "W"_a, "out"_a.noconvert());
}

nb::tuple layout() {
    nb::list entries;
    for (const auto& entry : kernels::PACKED_LAYOUT) {
        nb::list shape;
        for (int d = 0; d < entry.ndim; ++d) shape.append(entry.shape[d]);
        entries.append(nb::make_tuple(entry.key, nb::tuple(shape)));
    }
    return nb::tuple(entries);
}

nb::tuple pd_layout() {
    nb::list entries;
    for (const auto& entry : laws::PD_LAYOUT) entries.append(nb::make_tuple(entry.name, entry.size));
    return nb::tuple(entries);
}

}  // namespace

NB_MODULE(_core, m) {
    m.doc() = "The compiled kernels of the Stewart platform's kinematics, dynamics and integrator.";
    m.attr("C1") = kernels::C1;
    m.attr("C2") = kernels::C2;
    m.attr("C3") = kernels::C3;
    m.attr("C4") = kernels::C4;
    m.attr("CENTROIDAL") = kernels::CENTROIDAL;
    m.attr("N_PARAMS") = kernels::N_PARAMS;
    m.attr("PACKED_LAYOUT") = layout();
    m.attr("PD_LAYOUT") = pd_layout();
    m.attr("PD_N_PARAMS") = laws::PD_N_PARAMS;
    m.attr("CONSTANT_FORCES") = reinterpret_cast<uintptr_t>(&rk4::constant_forces);
    m.attr("PD_CONTROL_LAW") = reinterpret_cast<uintptr_t>(&laws::pd_control_law);
    m.attr("LAW_JACOBIAN") = reinterpret_cast<uintptr_t>(&rk4::law_jacobian);
    m.attr("LAW_INVERSE_DYNAMICS") = reinterpret_cast<uintptr_t>(&rk4::law_inverse_dynamics);

    bind_regressor(m);
    def_solve_batch<kernels::forward_batch>(m, "forward_batch", "F", "leg_forces");
    def_solve_batch<kernels::inverse_batch>(m, "inverse_batch", "acc", "acceleration");

    m.def("mass_bias_batch", [](In prm, int64_t flags, In t, In R, In v, In w, In W, Out M, Out h) {
        const int64_t n = batch(prm, t);
        state(t, R, v, w, n);
        expect(W, "external_wrench", {n, 6});
        expect(M, "M", {n, 6, 6});
        expect(h, "h", {n, 6});
        kernels::mass_bias_batch(prm.data(), prm.shape(0), flags, t.data(), R.data(), v.data(), w.data(), W.data(),
                                 M.data(), h.data(), n);
    }, "prm"_a, "flags"_a, "t"_a, "R"_a, "v"_a, "w"_a, "W"_a, "M"_a.noconvert(), "h"_a.noconvert());

    m.def("leg_kinematics_batch", [](In prm, int64_t flags, In t, In R, In v, In w, In acc, Out frames, Out lengths,
                                     Out rates, Out accels, Out omega_l, Out alpha_l, Out jac) {
        const int64_t n = batch(prm, t);
        state(t, R, v, w, n);
        expect(acc, "acceleration", {n, 6});
        expect(frames, "frames", {n, 6, 3, 3});
        expect(lengths, "lengths", {n, 6});
        expect(rates, "rates", {n, 6});
        expect(accels, "accels", {n, 6});
        expect(omega_l, "omega_l", {n, 6, 3});
        expect(alpha_l, "alpha_l", {n, 6, 3});
        expect(jac, "jac", {n, 6, 6});
        kernels::leg_kinematics_batch(prm.data(), prm.shape(0), flags, t.data(), R.data(), v.data(), w.data(),
                                      acc.data(), frames.data(), lengths.data(), rates.data(), accels.data(),
                                      omega_l.data(), alpha_l.data(), jac.data(), n);
    }, "prm"_a, "flags"_a, "t"_a, "R"_a, "v"_a, "w"_a, "acc"_a, "frames"_a.noconvert(), "lengths"_a.noconvert(),
       "rates"_a.noconvert(), "accels"_a.noconvert(), "omega_l"_a.noconvert(), "alpha_l"_a.noconvert(),
       "jac"_a.noconvert());

    m.def("jacobian_batch", [](In prm, In t, In R, Out J) {
        const int64_t n = batch(prm, t);
        expect(R, "rotation", {n, 3, 3});
        expect(J, "J", {n, 6, 6});
        kernels::jacobian_batch(prm.data(), prm.shape(0), t.data(), R.data(), J.data(), n);
    }, "prm"_a, "t"_a, "R"_a, "J"_a.noconvert());

    m.def("leg_sensors_batch", [](In prm, In t, In R, In v, In w, double max_condition, Out lengths, Out rates,
                                  Out condition) {
        const int64_t n = batch(prm, t);
        state(t, R, v, w, n);
        expect(lengths, "lengths", {n, 6});
        expect(rates, "rates", {n, 6});
        expect(condition, "condition", {n});
        kernels::leg_sensors_batch(prm.data(), prm.shape(0), t.data(), R.data(), v.data(), w.data(), max_condition,
                                   lengths.data(), rates.data(), condition.data(), n);
    }, "prm"_a, "t"_a, "R"_a, "v"_a, "w"_a, "max_condition"_a, "lengths"_a.noconvert(), "rates"_a.noconvert(),
       "condition"_a.noconvert());

    m.def("rotation_errors_batch", [](In R, Out orth, Out det) {
        expect(R, "rotation", {-1, 3, 3});
        const int64_t n = static_cast<int64_t>(R.shape(0));
        expect(orth, "orth", {n});
        expect(det, "det", {n});
        return kernels::rotation_errors_batch(R.data(), orth.data(), det.data(), n);
    }, "R"_a, "orth"_a.noconvert(), "det"_a.noconvert());

    m.def("largest_rotation_error", [](In R) {
        expect(R, "rotation", {-1, 3, 3});
        return kernels::largest_rotation_error(R.data(), static_cast<int64_t>(R.shape(0)));
    }, "R"_a);

    m.def("first_nonfinite", [](nb::sequence arrays) {
        int64_t k = 0;
        for (nb::handle item : arrays) {
            const In a = nb::cast<In>(item);
            if (!kernels::all_finite(a.data(), static_cast<int64_t>(a.size()))) return k;
            ++k;
        }
        return int64_t(-1);
    }, "arrays"_a,
       "Position in the sequence arrays of the first float64 array holding a NaN or inf, or -1: the finiteness "
       "check of every argument in one compiled call.");

    m.def("rollout_batch", [](In prm, int64_t flags, Out t, Out R, Out v, Out w, In F, In W, double dt,
                              int64_t steps) {
        const int64_t n = batch(prm, In(t));
        state(t, R, v, w, n);
        expect(F, "leg_forces", {n, 6});
        expect(W, "external_wrench", {n, 6});
        nb::gil_scoped_release release;
        rk4::rollout_batch(prm.data(), prm.shape(0), flags, t.data(), R.data(), v.data(), w.data(), F.data(),
                           W.data(), dt, steps, n);
    }, "prm"_a, "flags"_a, "t"_a.noconvert(), "R"_a.noconvert(), "v"_a.noconvert(), "w"_a.noconvert(), "F"_a, "W"_a,
       "dt"_a, "steps"_a);

    m.def("rollout_law_batch", [](In prm, int64_t flags, Out t, Out R, Out v, Out w, uintptr_t law, In ctrl, In W,
                                  double time, double dt, int64_t steps, int64_t every, Out rec_t, Out rec_R,
                                  Out rec_v, Out rec_w, Out rec_F) {
        const int64_t n = batch(prm, In(t));
        state(t, R, v, w, n);
        if (law == 0) throw nb::value_error("control_law: a null function pointer");
        if (ctrl.ndim() != 2 || !(ctrl.shape(0) == 1 || static_cast<int64_t>(ctrl.shape(0)) == n))
            throw nb::value_error("control_params: expected 1 or N rows");
        expect(W, "external_wrench", {n, 6});
        if (every < 0 || steps < 0) throw nb::value_error("record_every: expected a non-negative integer");
        const int64_t samples = every > 0 ? steps / every + 1 : 0;
        expect(rec_t, "rec_t", {n, samples, 3});
        expect(rec_R, "rec_R", {n, samples, 3, 3});
        expect(rec_v, "rec_v", {n, samples, 3});
        expect(rec_w, "rec_w", {n, samples, 3});
        expect(rec_F, "rec_F", {n, samples, 6});
        const rk4::Record rec{rec_t.data(), rec_R.data(), rec_v.data(), rec_w.data(), rec_F.data(), samples};
        nb::gil_scoped_release release;
        rk4::rollout_law_batch(prm.data(), prm.shape(0), flags, t.data(), R.data(), v.data(), w.data(),
                               reinterpret_cast<rk4::ControlLaw>(law), ctrl.data(), ctrl.shape(0), ctrl.shape(1),
                               W.data(), time, dt, steps, every, &rec, n);
    }, "prm"_a, "flags"_a, "t"_a.noconvert(), "R"_a.noconvert(), "v"_a.noconvert(), "w"_a.noconvert(), "law"_a,
       "ctrl"_a, "W"_a, "time"_a, "dt"_a, "steps"_a, "every"_a, "rec_t"_a.noconvert(), "rec_R"_a.noconvert(),
       "rec_v"_a.noconvert(), "rec_w"_a.noconvert(), "rec_F"_a.noconvert());

    m.def("law_forces_batch", [](uintptr_t law, double time, In t, In R, In v, In w, In params, Out out) {
        expect(t, "position", {-1, 3});
        const int64_t n = static_cast<int64_t>(t.shape(0));
        state(t, R, v, w, n);
        if (law == 0) throw nb::value_error("control_law: a null function pointer");
        if (params.ndim() != 2 || !(params.shape(0) == 1 || static_cast<int64_t>(params.shape(0)) == n))
            throw nb::value_error("control_params: expected 1 or N rows");
        expect(out, "out", {n, 6});
        nb::gil_scoped_release release;
        laws::law_forces_batch(reinterpret_cast<rk4::ControlLaw>(law), time, t.data(), R.data(), v.data(), w.data(),
                               params.data(), params.shape(0), params.shape(1), out.data(), n);
    }, "law"_a, "time"_a, "t"_a, "R"_a, "v"_a, "w"_a, "params"_a, "out"_a.noconvert());
}
