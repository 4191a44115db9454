// Python bindings of the compiled kernels (stewart_env._core): every function checks the
// shapes of the arrays it is given, so no call from Python can read or write outside them, and
// hands the raw pointers to kernels.hpp, rk4.hpp and laws.hpp.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include <cstdint>
#include <string>
#include <vector>

#include "physics/array_checks.hpp"
#include "env/env_step.hpp"
#include "env/reset_draws.hpp"
#include "physics/kernels.hpp"
#include "physics/laws.hpp"
#include "physics/rk4.hpp"
#include "env/step_records.hpp"
#include "tasks/task_kernels.hpp"

namespace nb = nanobind;
using namespace nb::literals;

void bind_regressor(nb::module_& m);  // regressor_bindings.cpp
void bind_constraints(nb::module_& m);  // tasks/constraints_bindings.cpp
void bind_actuators(nb::module_& m);  // actuators/actuator_bindings.cpp
void bind_derivatives(nb::module_& m);  // physics/derivatives_bindings.cpp

using In = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;
using Out = nb::ndarray<double, nb::c_contig, nb::device::cpu>;
using Flags = nb::ndarray<bool, nb::c_contig, nb::device::cpu>;
using InFlags = nb::ndarray<const bool, nb::c_contig, nb::device::cpu>;
using Codes = nb::ndarray<int64_t, nb::c_contig, nb::device::cpu>;
using InSingles = nb::ndarray<const float, nb::c_contig, nb::device::cpu>;
using InCodes = nb::ndarray<const int64_t, nb::c_contig, nb::device::cpu>;
using Singles = nb::ndarray<float, nb::c_contig, nb::device::cpu>;

namespace {

using array_checks::expect;

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

//: numpy.ndarray, set when the module is imported.
PyTypeObject* ndarray_type = nullptr;

// A float64 C-contiguous buffer of a given shape, borrowed from a numpy array for one call (the
// fast path of the checked single-platform calls): take() says whether the object is one, and
// leaves no Python error behind when it is not.  Only a plain numpy.ndarray qualifies: a
// subclass's buffer need not be its numbers (a masked array's holds the values under its mask
// too), so a subclass takes the checked path of the Python caller.
class Doubles {
public:
    Doubles() = default;
    Doubles(const Doubles&) = delete;
    Doubles& operator=(const Doubles&) = delete;
    ~Doubles() {
        if (held_) PyBuffer_Release(&view_);
    }
    bool take(nb::handle obj, std::initializer_list<Py_ssize_t> shape, bool writable = false) {
        if (Py_TYPE(obj.ptr()) != ndarray_type) return false;
        const int want = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
        if (PyObject_GetBuffer(obj.ptr(), &view_, want) != 0) {
            PyErr_Clear();
            return false;
        }
        held_ = true;
        if (view_.itemsize != 8 || view_.format == nullptr || view_.format[0] != 'd' || view_.format[1] != 0 ||
            view_.ndim != static_cast<int>(shape.size()))
            return false;
        int d = 0;
        for (Py_ssize_t s : shape)
            if (view_.shape[d++] != s) return false;
        return true;
    }
    double* data() const { return static_cast<double*>(view_.buf); }

private:
    Py_buffer view_{};
    bool held_ = false;
};

// Whether the state and the 6-vector x of one platform are all finite numbers and R a rotation
// within tolerance: the checks of model.batch_args, passed.
bool checked(const Doubles& t, const Doubles& R, const Doubles& v, const Doubles& w, const Doubles& x,
             const Doubles& W, double tolerance) {
    return kernels::all_finite(t.data(), 3) && kernels::all_finite(R.data(), 9) && kernels::all_finite(v.data(), 3) &&
           kernels::all_finite(w.data(), 3) && kernels::all_finite(x.data(), 6) && kernels::all_finite(W.data(), 6) &&
           kernels::largest_rotation_error(R.data(), 1) <= tolerance;
}

//: The arrays of a Workspace (stewart_env.dynamics.workspace), bound once: its calls hand the
//: kernels these pointers with no argument to convert.  The struct holds every array it points
//: into (an ndarray holds its memory), so no pointer outlives its array: a prm that nanobind
//: converted (a strided, Fortran-ordered or float32 array) is a copy this struct owns.
struct BoundWorkspace {
    In prm_array;
    Out t_array, R_array, v_array, w_array, F_array, W_array, acc_array, M_array, h_array;
    const double* prm;
    int64_t n_prm, flags, n;
    double *t, *R, *v, *w, *F, *W, *acc, *M, *h;

    BoundWorkspace(In prm_, int64_t flags_, Out t_, Out R_, Out v_, Out w_, Out F_, Out W_, Out acc_, Out M_,
                   Out h_)
        : prm_array(prm_), t_array(t_), R_array(R_), v_array(v_), w_array(w_), F_array(F_), W_array(W_),
          acc_array(acc_), M_array(M_), h_array(h_), prm(prm_.data()), n_prm(static_cast<int64_t>(prm_.shape(0))),
          flags(flags_), n(static_cast<int64_t>(t_.shape(0))), t(t_.data()), R(R_.data()), v(v_.data()),
          w(w_.data()), F(F_.data()), W(W_.data()), acc(acc_.data()), M(M_.data()), h(h_.data()) {}
};

}  // namespace

void def_env_kernels(nb::module_& m);

NB_MODULE(STEWART_ENV_CORE_MODULE, m) {  // _core_<instruction-set target> (CMakeLists.txt)
    m.doc() = "The compiled kernels of the Stewart platform's kinematics, dynamics and integrator.";
    {
        nb::object ndarray = nb::module_::import_("numpy").attr("ndarray");
        ndarray_type = reinterpret_cast<PyTypeObject*>(ndarray.ptr());  // numpy keeps its type alive
    }
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

    m.def("forward_one_checked", [](nb::handle prm, int64_t flags, nb::handle t, nb::handle R, nb::handle v,
                                    nb::handle w, nb::handle F, nb::handle W, double tolerance, nb::handle out) {
        Doubles P, tv, Rv, vv, wv, Fv, Wv, ov;
        if (!(P.take(prm, {1, kernels::N_PARAMS}) && tv.take(t, {3}) && Rv.take(R, {3, 3}) && vv.take(v, {3}) &&
              wv.take(w, {3}) && Fv.take(F, {6}) && Wv.take(W, {6}) && ov.take(out, {6}, true) &&
              checked(tv, Rv, vv, wv, Fv, Wv, tolerance)))
            return false;
        double M[36], h[6];
        kernels::forward_one<double>(P.data(), flags, tv.data(), Rv.data(), vv.data(), wv.data(), Fv.data(), Wv.data(),
                                     M, h, ov.data());
        return true;
    }, "prm"_a, "flags"_a, "t"_a.none(), "R"_a.none(), "v"_a.none(), "w"_a.none(), "F"_a.none(), "W"_a.none(),
       "tolerance"_a, "out"_a,
       "Forward dynamics of one platform into out (6,) when every argument is a float64 C-contiguous array of one "
       "platform's shape, finite, and R a rotation within tolerance; otherwise (None too) False and nothing "
       "computed (the caller then checks the arguments itself and reports what is wrong).");

    m.def("inverse_one_checked", [](nb::handle prm, int64_t flags, nb::handle t, nb::handle R, nb::handle v,
                                    nb::handle w, nb::handle lin, nb::handle ang, nb::handle W, double tolerance,
                                    nb::handle out) {
        Doubles P, tv, Rv, vv, wv, lv, av, Wv, ov;
        if (!(P.take(prm, {1, kernels::N_PARAMS}) && tv.take(t, {3}) && Rv.take(R, {3, 3}) && vv.take(v, {3}) &&
              wv.take(w, {3}) && lv.take(lin, {3}) && av.take(ang, {3}) && Wv.take(W, {6}) && ov.take(out, {6}, true)))
            return false;
        const double acc[6] = {lv.data()[0], lv.data()[1], lv.data()[2], av.data()[0], av.data()[1], av.data()[2]};
        if (!(kernels::all_finite(acc, 6) && kernels::all_finite(tv.data(), 3) && kernels::all_finite(Rv.data(), 9) &&
              kernels::all_finite(vv.data(), 3) && kernels::all_finite(wv.data(), 3) &&
              kernels::all_finite(Wv.data(), 6) && kernels::largest_rotation_error(Rv.data(), 1) <= tolerance))
            return false;
        double M[36], h[6];
        kernels::inverse_one<double>(P.data(), flags, tv.data(), Rv.data(), vv.data(), wv.data(), acc, Wv.data(), M, h,
                                     ov.data());
        return true;
    }, "prm"_a, "flags"_a, "t"_a.none(), "R"_a.none(), "v"_a.none(), "w"_a.none(), "lin_acc"_a.none(),
       "ang_acc"_a.none(), "W"_a.none(), "tolerance"_a, "out"_a,
       "Inverse dynamics of one platform into out (6,), on the terms of forward_one_checked.");

    m.def("forward_flops", [](In prm, int64_t flags, In t, In R, In v, In w, In F) {
        expect(prm, "prm", {1, kernels::N_PARAMS});
        expect(t, "position", {3});
        expect(R, "rotation", {3, 3});
        expect(v, "velocity", {3});
        expect(w, "angular_velocity", {3});
        expect(F, "leg_forces", {6});
        using lanes::Counted;
        Counted P[kernels::N_PARAMS], tc[3], Rc[9], vc[3], wc[3], Fc[6], Wc[6], M[36], h[6], out[6];
        for (int k = 0; k < kernels::N_PARAMS; ++k) P[k] = prm.data()[k];
        for (int k = 0; k < 3; ++k) tc[k] = t.data()[k], vc[k] = v.data()[k], wc[k] = w.data()[k];
        for (int k = 0; k < 9; ++k) Rc[k] = R.data()[k];
        for (int k = 0; k < 6; ++k) Fc[k] = F.data()[k], Wc[k] = 0.0;
        Counted::flops = 0;
        kernels::forward_one<Counted>(P, flags, tc, Rc, vc, wc, Fc, Wc, M, h, out);
        return Counted::flops;
    }, "prm"_a, "flags"_a, "t"_a, "R"_a, "v"_a, "w"_a, "F"_a,
       "The floating-point operations (+, -, *, /, sqrt) of one forward evaluation at this state: the kernel run on "
       "a number type that counts them.");

    nb::class_<BoundWorkspace>(m, "BoundWorkspace",
                               "The arrays of a Workspace bound once, for its calls without argument conversion.")
        .def("__init__", [](BoundWorkspace* self, In prm, int64_t flags, Out t, Out R, Out v, Out w, Out F, Out W,
                            Out acc, Out M, Out h) {
            const int64_t n = batch(prm, In(t));
            state(t, R, v, w, n);
            expect(F, "leg_forces", {n, 6});
            expect(W, "external_wrench", {n, 6});
            expect(acc, "acceleration", {n, 6});
            expect(M, "mass_matrix", {n, 6, 6});
            expect(h, "bias", {n, 6});
            new (self) BoundWorkspace(prm, flags, t, R, v, w, F, W, acc, M, h);
        }, "prm"_a, "flags"_a, "t"_a.noconvert(), "R"_a.noconvert(), "v"_a.noconvert(), "w"_a.noconvert(),
           "F"_a.noconvert(), "W"_a.noconvert(), "acc"_a.noconvert(), "M"_a.noconvert(), "h"_a.noconvert())
        .def("forward", [](BoundWorkspace& s) {
            kernels::forward_batch(s.prm, s.n_prm, s.flags, s.t, s.R, s.v, s.w, s.F, s.W, s.acc, s.n);
        })
        .def("inverse", [](BoundWorkspace& s) {
            kernels::inverse_batch(s.prm, s.n_prm, s.flags, s.t, s.R, s.v, s.w, s.acc, s.W, s.F, s.n);
        })
        .def("mass_and_bias", [](BoundWorkspace& s) {
            kernels::mass_bias_batch(s.prm, s.n_prm, s.flags, s.t, s.R, s.v, s.w, s.W, s.M, s.h, s.n);
        })
        .def("step", [](BoundWorkspace& s, double dt, int64_t steps) {
            nb::gil_scoped_release release;
            rk4::rollout_batch(s.prm, s.n_prm, s.flags, s.t, s.R, s.v, s.w, s.F, s.W, dt, steps, s.n);
        }, "dt"_a, "steps"_a);


    m.attr("MAX_THREADS") = lanes::MAX_THREADS;
    m.def("set_num_threads", [](int total) {
        if (total < 1 || total > lanes::MAX_THREADS)
            throw nb::value_error(("n: expected an integer in [1, " + std::to_string(lanes::MAX_THREADS) + "], got " +
                                   std::to_string(total)).c_str());
        nb::gil_scoped_release release;  // waits for a batch running on another thread
        return lanes::Helpers::set_threads(total);
    }, "total"_a,
       "Use `total` threads (the caller included) for the batches from now on; returns the threads the pool has "
       "(fewer where the operating system refused some).");
    m.def("get_num_threads", [] {
        nb::gil_scoped_release release;
        return lanes::Helpers::pool().threads();
    }, "The threads the batches use (the caller included), the pool started if it was not.");
    m.def("set_default_threads", [](int total) {
        if (total < 1 || total > lanes::MAX_THREADS)
            throw nb::value_error("total: expected an integer in [1, MAX_THREADS]");
        lanes::Helpers::request(total);
    }, "total"_a, "The thread count the pool is made with when first needed (STEWART_ENV_THREADS); nothing starts.");

    bind_regressor(m);
    bind_constraints(m);
    bind_actuators(m);
    bind_derivatives(m);
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

    def_env_kernels(m);
}

// ---- The tasks' and the environment's per-step kernels (task_kernels.hpp, env_step.hpp) ----------

namespace {

task_kernels::Limits limits_of(const In& position_min, const In& position_max, const In& home_rpy, double max_angle,
                               double length_min, double length_max, double max_condition) {
    expect(position_min, "position_min", {3});
    expect(position_max, "position_max", {3});
    expect(home_rpy, "home_rpy", {3});
    return {position_min.data(), position_max.data(), home_rpy.data(), max_angle, length_min, length_max,
            max_condition};
}

env_step::State state_of(Out& t, Out& R, Out& v, Out& w) { return {t.data(), R.data(), v.data(), w.data()}; }

}  // namespace

// The compiled batch of the environment (env_step::Batch), made of the step's records
// (step_records.hpp), each built once by its owner and held while the step lives; the per-step
// call then passes only the action and the step's fresh inputs.  Without an observation record
// the observation is left to the caller.
class BatchStep {
public:
    BatchStep(nb::object state, nb::object plant, nb::object actuator, nb::object task, nb::object observation,
              nb::object outputs, nb::object actuation)
        : state_(nb::cast<step_records::StateRecord*>(state)), plant_(nb::cast<step_records::PlantRecord*>(plant)),
          actuator_(nb::cast<step_records::ActuatorRecord*>(actuator)),
          task_(nb::cast<step_records::TaskRecord*>(task)),
          observation_(observation.is_none() ? nullptr : nb::cast<step_records::ObservationRecord*>(observation)),
          outputs_(nb::cast<step_records::OutputRecord*>(outputs)),
          actuation_(actuation.is_none() ? nullptr : nb::cast<step_records::ActuationRecord*>(actuation)),
          held_{state, plant, actuator, task, observation, outputs, actuation} {
        if (!(state_ && plant_ && actuator_ && task_ && outputs_))
            throw nb::value_error("state, plant, actuator, task, outputs: expected a record each, not None");
        const int64_t n = state_->n;
        if (plant_->n != n) throw nb::value_error("plant: expected a record of the batch's rows");
        if (actuator_->rows() != n) throw nb::value_error("actuator: expected a record of the batch's rows");
        if (outputs_->rows() != n) throw nb::value_error("outputs: expected a record of the batch's rows");
        if (observation_ != nullptr) {
            if (observation_->rows() != n) throw nb::value_error("observation: expected a record of the batch's rows");
            if (static_cast<int64_t>(outputs_->observation.shape(1)) != observation_->dim())
                throw nb::value_error("outputs: expected an observation of the observation record's columns");
        }
        if (actuation_ != nullptr && actuation_->rows() != n)
            throw nb::value_error("actuation: expected a record of the batch's rows");
        state_->fill(b_);
        actuator_->fill(b_);
        if (actuation_ != nullptr) actuation_->fill(b_);
        task_->fill(b_);
        b_.observe = observation_ != nullptr;
        if (observation_ != nullptr) observation_->fill(b_);
        outputs_->fill(b_);
    }

    // One control step: the action (n,6), or (6,) for a batch of one, float64 or float32 (widened
    // exactly, as numpy's astype); noise (n,D) or None, skip (n,) or None.  The outcome goes into
    // the output record's arrays (and, with an observation record, its delay ring, whose head the
    // step advances).  An action that is not finite anywhere: NOT_FINITE_ACTION, nothing done
    // (the caller says why).
    int64_t step(nb::handle action, bool drive, nb::handle noise, nb::handle skip) {
        const int64_t n = b_.n;
        const double* a = nullptr;
        In wide;
        InSingles single;
        if (nb::try_cast<In>(action, wide, false) || (!nb::try_cast<InSingles>(action, single, false) &&
                                                      nb::try_cast<In>(action, wide, true))) {
            expect_action(wide, n);
            a = wide.data();
        } else if (single.is_valid()) {
            expect_action(single, n);
            action_.resize(6 * n);
            for (int64_t k = 0; k < 6 * n; ++k) action_[k] = static_cast<double>(single.data()[k]);
            a = action_.data();
        } else {
            throw nb::value_error("action: expected an array of real numbers");
        }
        if (!kernels::all_finite(a, 6 * n)) return env_step::NOT_FINITE_ACTION;
        if (b_.observe && !(*b_.head >= 0 && *b_.head < b_.slots))
            throw nb::value_error("head: outside the history ring");
        const double* noise_data = nullptr;
        const bool* skip_data = nullptr;
        In noise_array;
        InFlags skip_array;
        if (!noise.is_none()) {
            noise_array = nb::cast<In>(noise);
            expect(noise_array, "noise", {n, b_.observe ? b_.layout.dim : -1});
            noise_data = noise_array.data();
        }
        if (!skip.is_none()) {
            skip_array = nb::cast<InFlags>(skip);
            expect(skip_array, "skip", {n});
            skip_data = skip_array.data();
        }
        // the plant's parameters may have changed since the last call (PlantRecord.set_model)
        plant_->fill(b_);
        const step_records::OutputRecord& o = *outputs_;
        nb::gil_scoped_release release;
        return env_step::step(b_, a, drive, noise_data, skip_data, o.code.data(), o.terms.data(), o.reward.data(),
                              o.bad.data());
    }

    // Start new episodes in rows (int64 (m,), each in [0, n)): the start state (a tuple of the m
    // rows' position (m,3), rotation (m,3,3), velocity (m,3), angular velocity (m,3)), the leg
    // forces that hold it (m,6) or None (zeros), the reference at t = 0 (a tuple as the state); the
    // rows' leg lengths (m,6), rates (m,6), condition numbers (m,), tracking errors (4,m,3) and norms
    // (4,m) at the start are written into the last five (env_step::reset_rows); measured: the leg
    // sensors' three arrays already hold the start state's (read, not measured again).  observe
    // (with an observation record): the rows' first observation too, noise (m,D) or None added
    // (env_step::start_observation_rows); returns the rows whose start observation was not
    // finite (0 without observe).  Every array is checked (dtype, C-contiguity, shape, the rows'
    // range) before anything is written.
    int64_t reset(nb::handle rows_, nb::tuple start, nb::handle leg_forces, nb::tuple reference, nb::handle lengths_,
                  nb::handle rates_, nb::handle condition_, nb::handle errors_, nb::handle norms_, bool measured,
                  bool observe, nb::handle noise) {
        using step_records::take;
        const int64_t n = b_.n;
        const auto rows = take<InCodes>(rows_, "rows", {-1});
        const int64_t m = static_cast<int64_t>(rows.shape(0));
        for (int64_t j = 0; j < m; ++j)
            if (!(rows.data()[j] >= 0 && rows.data()[j] < n))
                throw nb::value_error(("rows: " + std::to_string(rows.data()[j]) + " is outside the batch of " +
                                       std::to_string(n) + " rows").c_str());
        if (start.size() != 4 || reference.size() != 4)
            throw nb::value_error("start, reference: expected (position, rotation, velocity, angular_velocity)");
        const auto t = take<In>(start[0], "start position", {m, 3});
        const auto R = take<In>(start[1], "start rotation", {m, 3, 3});
        const auto v = take<In>(start[2], "start velocity", {m, 3});
        const auto w = take<In>(start[3], "start angular_velocity", {m, 3});
        const auto rt = take<In>(reference[0], "reference position", {m, 3});
        const auto rR = take<In>(reference[1], "reference rotation", {m, 3, 3});
        const auto rv = take<In>(reference[2], "reference velocity", {m, 3});
        const auto rw = take<In>(reference[3], "reference angular_velocity", {m, 3});
        In forces;
        if (!leg_forces.is_none()) forces = take<In>(leg_forces, "leg_forces", {m, 6});
        auto lengths = take<Out>(lengths_, "leg_lengths", {m, 6});
        auto rates = take<Out>(rates_, "leg_rates", {m, 6});
        auto condition = take<Out>(condition_, "condition", {m});
        auto errors = take<Out>(errors_, "error_vectors", {4, m, 3});
        auto norms = take<Out>(norms_, "error_norms", {4, m});
        if (observe && !b_.observe) throw nb::value_error("observe: the step has no observation record");
        In noise_array;
        if (!noise.is_none()) {
            if (!observe) throw nb::value_error("noise: expected None without observe");
            noise_array = take<In>(noise, "noise", {m, b_.layout.dim});
        }
        const env_step::Start S{t.data(), R.data(), v.data(), w.data(), forces.is_valid() ? forces.data() : nullptr,
                                rt.data(), rR.data(), rv.data(), rw.data()};
        env_step::reset_rows(b_, rows.data(), m, S,
                             {lengths.data(), rates.data(), condition.data(), errors.data(), norms.data()},
                             measured);
        if (!observe) return 0;
        return env_step::start_observation_rows(b_, rows.data(), m,
                                                noise_array.is_valid() ? noise_array.data() : nullptr);
    }

    int64_t n_codes() const { return task_->n_codes(); }
    bool observes() const { return observation_ != nullptr; }

private:
    // The action's shape: (n,6), or (6,) for a batch of one.
    template <typename A>
    static void expect_action(const A& a, int64_t n) {
        if (a.ndim() == 1 && n == 1)
            expect(a, "action", {6});
        else
            expect(a, "action", {n, 6});
    }

    step_records::StateRecord* state_;
    step_records::PlantRecord* plant_;
    step_records::ActuatorRecord* actuator_;
    step_records::TaskRecord* task_;
    step_records::ObservationRecord* observation_;
    step_records::OutputRecord* outputs_;
    step_records::ActuationRecord* actuation_;
    // the records themselves, alive while the step points into them
    nb::object held_[7];
    env_step::Batch b_{};
    std::vector<double> action_;  // a float32 action widened
};

void def_env_kernels(nb::module_& m) {
    using step_records::ActuatorRecord, step_records::ObservationRecord, step_records::OutputRecord,
        step_records::PlantRecord, step_records::StateRecord, step_records::TaskRecord;
    m.attr("NON_FINITE_STATE") = env_step::NON_FINITE_STATE;
    m.attr("BAD_ROWS") = env_step::BAD_ROWS;
    m.attr("NOT_FINITE_ACTION") = env_step::NOT_FINITE_ACTION;
    nb::class_<StateRecord>(m, "StateRecord",
        "The batch's part of the compiled step (step_records.hpp): its state, start state, external wrench, clock, "
        "non-finite flags, leg sensors with their nominal parameters, reference and tracking errors.")
        .def(nb::init<nb::tuple, nb::tuple, nb::handle, nb::handle, nb::handle, nb::handle, nb::handle, nb::handle,
                      nb::handle, nb::tuple, nb::handle, nb::handle, nb::handle, double, double>(),
             "state"_a, "start"_a, "external_wrench"_a, "steps"_a, "time"_a, "non_finite"_a, "leg_lengths"_a,
             "leg_rates"_a, "condition"_a, "reference"_a, "error_vectors"_a, "error_norms"_a, "sensor_prm"_a,
             "control_dt"_a, "max_condition"_a)
        .def_ro("n", &StateRecord::n);
    nb::class_<PlantRecord>(m, "PlantRecord",
        "The closed-form plant's part of the compiled step: packed parameters (1 or n rows), model flags, "
        "physics_dt and substeps.")
        .def(nb::init<int64_t, nb::handle, int64_t, double, int64_t>(), "n"_a, "prm"_a, "flags"_a, "physics_dt"_a,
             "substeps"_a)
        .def("set_model", &PlantRecord::set_model, "prm"_a, "flags"_a,
             "New packed parameters (1 or n rows) and model flags, read by the step from its next call.")
        .def_ro("n", &PlantRecord::n)
        .def_ro("flags", &PlantRecord::flags)
        .def_ro("physics_dt", &PlantRecord::physics_dt)
        .def_ro("substeps", &PlantRecord::substeps);
    nb::class_<ActuatorRecord>(m, "ActuatorRecord",
        "The actuators' part of the compiled step: the force map (force_half, force_mid), the lag, the applied "
        "action (n,6) and the leg forces (n,6).")
        .def(nb::init<double, double, double, nb::handle, nb::handle>(), "force_half"_a, "force_mid"_a, "lag"_a,
             "action"_a, "leg_forces"_a)
        .def_ro("lag", &ActuatorRecord::lag);
    nb::class_<step_records::ActuationRecord>(m, "ActuationRecord",
        "The actuation at the physics rate (actuation.hpp): the action mode, pose law and actuator codes, the "
        "nominal model's flags, the set points' maps, the loops' gains, the drives' packed parameters and the "
        "actuators' state (n, 6, 3).")
        .def(nb::init<int64_t, int64_t, int64_t, int64_t, nb::handle, nb::handle, nb::handle, nb::handle, nb::handle,
                      nb::handle, nb::handle, double, nb::handle, double, double, nb::handle, double, double,
                      nb::handle, nb::handle>(),
             "mode"_a, "law"_a, "kind"_a, "nominal_flags"_a, "force_range"_a, "length_map"_a, "pose_mid"_a,
             "pose_half"_a, "servo"_a, "task_kp"_a, "task_kd"_a, "lag"_a, "electric"_a, "current_gain"_a,
             "force_per_amp"_a, "hydraulic"_a, "valve_gain"_a, "force_gain"_a, "reflected_mass"_a, "state"_a);
    nb::class_<TaskRecord>(m, "TaskRecord",
        "The task's part of the compiled step: the platform's limits, the reward weights (8,), the termination "
        "cost and whether each termination code is a failure.")
        .def(nb::init<nb::handle, nb::handle, nb::handle, double, double, double, double, nb::handle, double,
                      nb::handle>(),
             "position_min"_a, "position_max"_a, "home_rpy"_a, "max_angle"_a, "length_min"_a, "length_max"_a,
             "max_condition"_a, "weights"_a, "termination_cost"_a, "failure"_a)
        .def_prop_ro("n_codes", &TaskRecord::n_codes);
    nb::class_<ObservationRecord>(m, "ObservationRecord",
        "The observation's part of the compiled step: layout, clean rows, delay ring and its head, scaling, error "
        "integral, pending rows.")
        .def(nb::init<bool, int64_t, int64_t, int64_t, int64_t, int64_t, int64_t, nb::handle, nb::handle,
                      nb::handle, bool, nb::handle, nb::handle, nb::handle, nb::handle, nb::handle, nb::handle,
                      double>(),
             "pose"_a, "leg_lengths_at"_a, "leg_rates_at"_a, "leg_forces_at"_a, "position_error_at"_a,
             "orientation_error_at"_a, "error_integral_at"_a, "raw"_a, "history"_a, "head"_a, "normalize"_a,
             "offset"_a, "inv_scale"_a, "error_integral"_a.none(), "error_integral_bound"_a,
             "error_integral_band"_a.none(), "pending"_a, "largest"_a)
        .def_prop_ro("dim", &ObservationRecord::dim);
    nb::class_<OutputRecord>(m, "OutputRecord",
        "Where the compiled step's outcome goes: codes (n,), reward terms (5,n), reward (n,), bad rows (n,), the "
        "latest observation as float32 (n,D).")
        .def(nb::init<nb::handle, nb::handle, nb::handle, nb::handle, nb::handle>(), "code"_a, "terms"_a,
             "reward"_a, "bad"_a, "observation"_a);
    nb::class_<BatchStep>(m, "BatchStep",
        "The compiled control step of a batch of the environment (env_step.hpp): built once from the step's "
        "records (the observation's may be None: the caller makes the observation), then one call per step.")
        .def(nb::init<nb::object, nb::object, nb::object, nb::object, nb::object, nb::object, nb::object>(),
             "state"_a.none(), "plant"_a.none(), "actuator"_a.none(), "task"_a.none(), "observation"_a.none(),
             "outputs"_a.none(), "actuation"_a.none() = nb::none())
        .def_prop_ro("observes", &BatchStep::observes)
        .def("step", &BatchStep::step, "action"_a, "drive"_a, "noise"_a.none(), "skip"_a.none(),
             "One control step of every row into the output record; returns 1 | 2 as a row's state "
             "stopped being finite | a row's observation or reward was not (the rows in bad), or "
             "NOT_FINITE_ACTION (nothing done) for an action that is not finite.")
        .def("reset", &BatchStep::reset, "rows"_a, "start"_a, "leg_forces"_a.none(), "reference"_a,
             "leg_lengths"_a, "leg_rates"_a, "condition"_a, "error_vectors"_a, "error_norms"_a, "measured"_a = false,
             "observe"_a = false, "noise"_a.none() = nb::none(),
             "Start new episodes in rows (int64 (m,)): their start state, the leg forces that hold it (or None: "
             "zeros) and the reference at t = 0, each of m rows; a zero clock, external wrench and applied action; "
             "the rows' leg sensors and tracking errors at the start state, written into the batch and into the "
             "five arrays after the reference (m rows); measured=True: the leg sensors' arrays already hold the "
             "start state's.  observe=True (a step with an observation record): the rows' first observation too, "
             "with a zero error integral and noise (m, D) or None added, in every slot of the delay ring; returns "
             "the rows whose start observation was not finite (made finite and pending), 0 without observe.");

    m.def("rotation_error_rows", [](In r, In c, Out phi, Out angle) {
        expect(c, "rotation", {-1, 3, 3});
        const int64_t n = static_cast<int64_t>(c.shape(0));
        expect(r, "rotation_ref", {n, 3, 3});
        expect(phi, "phi", {n, 3});
        expect(angle, "angle", {n});
        task_kernels::rotation_error_rows(r.data(), c.data(), phi.data(), angle.data(), 1, n);
    }, "r"_a, "c"_a, "phi"_a.noconvert(), "angle"_a.noconvert(),
       "Rotation vector phi (N,3) of r c^T and its angle (N,), row by row (rotations.rotation_error).");

    m.def("tracking_errors", [](In t, In R, In v, In w, In rt, In rR, In rv, In rw, Out ep, Out eo, Out ev, Out ew,
                                Out norms) {
        expect(t, "position", {-1, 3});
        const int64_t n = static_cast<int64_t>(t.shape(0));
        state(t, R, v, w, n);
        state(rt, rR, rv, rw, n);
        expect(ep, "ep", {n, 3});
        expect(eo, "eo", {n, 3});
        expect(ev, "ev", {n, 3});
        expect(ew, "ew", {n, 3});
        expect(norms, "norms", {4, n});
        task_kernels::tracking_errors(t.data(), R.data(), v.data(), w.data(), rt.data(), rR.data(), rv.data(),
                                      rw.data(), ep.data(), eo.data(), ev.data(), ew.data(), norms.data(), 1, n, n);
    }, "t"_a, "R"_a, "v"_a, "w"_a, "rt"_a, "rR"_a, "rv"_a, "rw"_a, "ep"_a.noconvert(), "eo"_a.noconvert(),
       "ev"_a.noconvert(), "ew"_a.noconvert(), "norms"_a.noconvert(),
       "Reference minus actual of a batch: position, orientation, velocity, angular velocity (N,3) each, and "
       "their norms (4,N).");

    m.def("limit_codes", [](In t, In R, In lengths, In condition, InFlags non_finite, In position_min,
                            In position_max, In home_rpy, double max_angle, double length_min, double length_max,
                            double max_condition, Codes code) {
        expect(t, "position", {-1, 3});
        const int64_t n = static_cast<int64_t>(t.shape(0));
        expect(R, "rotation", {n, 3, 3});
        expect(lengths, "leg_lengths", {n, 6});
        expect(condition, "condition", {n});
        expect(non_finite, "non_finite", {n});
        expect(code, "code", {n});
        const auto lim = limits_of(position_min, position_max, home_rpy, max_angle, length_min, length_max,
                                   max_condition);
        task_kernels::limit_codes(t.data(), R.data(), lengths.data(), condition.data(), non_finite.data(), lim,
                                  code.data(), n);
    }, "t"_a, "R"_a, "lengths"_a, "condition"_a, "non_finite"_a, "position_min"_a, "position_max"_a, "home_rpy"_a,
       "max_angle"_a, "length_min"_a, "length_max"_a, "max_condition"_a, "code"_a.noconvert(),
       "Termination codes (N,) of the platform's limits, by priority (tasks.LIMIT_REASONS).");

    m.def("tracking_reward", [](In ep, In eo, In ev, In ew, In action, double wp, double sp, double wo, double so,
                                double wv, double sv, double sw, double wc, Out out) {
        expect(ep, "position_norm", {-1});
        const int64_t n = static_cast<int64_t>(ep.shape(0));
        expect(eo, "orientation_norm", {n});
        expect(ev, "velocity_norm", {n});
        expect(ew, "angular_velocity_norm", {n});
        expect(action, "action", {n, 6});
        expect(out, "out", {4, n});
        task_kernels::tracking_reward(ep.data(), eo.data(), ev.data(), ew.data(), 1, action.data(),
                                      {wp, sp, wo, so, wv, sv, sw, wc}, out.data(), n);
    }, "ep"_a, "eo"_a, "ev"_a, "ew"_a, "action"_a, "wp"_a, "sp"_a, "wo"_a, "so"_a, "wv"_a, "sv"_a, "sw"_a, "wc"_a,
       "out"_a.noconvert(),
       "The four running terms (4,N) of the tracking-error reward (tasks.RewardWeights).");

    m.def("within_margins", [](In position, In rpy, In lengths, In condition, In position_min, In position_max,
                               In home_rpy, double max_angle, double length_min, double length_max,
                               double max_condition, double margin, Flags ok) {
        expect(position, "position", {-1, 3});
        const int64_t n = static_cast<int64_t>(position.shape(0));
        expect(rpy, "rpy", {n, 3});
        expect(lengths, "leg_lengths", {n, 6});
        expect(condition, "condition", {n});
        expect(ok, "ok", {n});
        const auto lim = limits_of(position_min, position_max, home_rpy, max_angle, length_min, length_max,
                                   max_condition);
        task_kernels::within_margins(position.data(), rpy.data(), lengths.data(), condition.data(), lim, margin,
                                     ok.data(), n);
    }, "position"_a, "rpy"_a, "lengths"_a, "condition"_a, "position_min"_a, "position_max"_a, "home_rpy"_a,
       "max_angle"_a, "length_min"_a, "length_max"_a, "max_condition"_a, "margin"_a, "ok"_a.noconvert(),
       "Whether poses lie inside the limits shrunk by margin (tasks.pose_margins).");

    m.def("drive", [](In action, double half, double mid, double lag, Out clipped, Out forces) {
        expect(action, "action", {-1, 6});
        const int64_t n = static_cast<int64_t>(action.shape(0));
        expect(clipped, "clipped", {n, 6});
        expect(forces, "leg_forces", {n, 6});
        env_step::drive(action.data(), half, mid, lag, clipped.data(), forces.data(), n);
    }, "action"_a, "half"_a, "mid"_a, "lag"_a, "clipped"_a.noconvert(), "forces"_a.noconvert(),
       "The actuators: the action clipped to [-1, 1] and mapped onto the force range, through the lag.");

    m.def("after_physics", [](Out t, Out R, Out v, Out w, Out t0, Out R0, Out v0, Out w0, Codes steps, double dt,
                              Out time, Flags non_finite) {
        expect(t, "position", {-1, 3});
        const int64_t n = static_cast<int64_t>(t.shape(0));
        state(t, R, v, w, n);
        state(t0, R0, v0, w0, n);
        expect(steps, "steps", {n});
        expect(time, "time", {n});
        expect(non_finite, "non_finite", {n});
        return env_step::after_physics(state_of(t, R, v, w), state_of(t0, R0, v0, w0), steps.data(), dt,
                                       time.data(), non_finite.data(), n);
    }, "t"_a.noconvert(), "R"_a.noconvert(), "v"_a.noconvert(), "w"_a.noconvert(), "t0"_a.noconvert(),
       "R0"_a.noconvert(), "v0"_a.noconvert(), "w0"_a.noconvert(), "steps"_a.noconvert(), "dt"_a,
       "time"_a.noconvert(), "non_finite"_a.noconvert(),
       "Advance the clock; put rows whose state stopped being finite back to their start state.");

    m.def("copy_state", [](Out t, Out R, Out v, Out w, Out t0, Out R0, Out v0, Out w0) {
        expect(t, "position", {-1, 3});
        const int64_t n = static_cast<int64_t>(t.shape(0));
        state(t, R, v, w, n);
        state(t0, R0, v0, w0, n);
        env_step::copy_state(state_of(t, R, v, w), state_of(t0, R0, v0, w0), n);
    }, "t"_a, "R"_a, "v"_a, "w"_a, "t0"_a.noconvert(), "R0"_a.noconvert(), "v0"_a.noconvert(), "w0"_a.noconvert(),
       "Copy a batch state (t, R, v, w) into another's arrays (t0, R0, v0, w0).");

    m.def("control_step", [](In prm, int64_t flags, In sensor_prm, double half, double mid, double lag, bool drive,
                             double physics_dt, int64_t substeps, double control_dt, double max_condition, In action,
                             Out clipped, Out F, In W, Out t, Out R, Out v, Out w, Out t0, Out R0, Out v0, Out w0,
                             Codes steps, Out time, Flags non_finite, Out lengths, Out rates, Out condition,
                             nb::handle actuation) {
        const int64_t n = batch(prm, In(t));
        state(t, R, v, w, n);
        state(t0, R0, v0, w0, n);
        expect(sensor_prm, "sensor_prm", {-1, kernels::N_PARAMS});
        if (!(sensor_prm.shape(0) == 1 || static_cast<int64_t>(sensor_prm.shape(0)) == n))
            throw nb::value_error("sensor_prm: expected 1 or N parameter rows");
        expect(action, "action", {n, 6});
        expect(clipped, "clipped", {n, 6});
        expect(F, "leg_forces", {n, 6});
        expect(W, "external_wrench", {n, 6});
        expect(steps, "steps", {n});
        expect(time, "time", {n});
        expect(non_finite, "non_finite", {n});
        expect(lengths, "lengths", {n, 6});
        expect(rates, "rates", {n, 6});
        expect(condition, "condition", {n});
        if (substeps < 0) throw nb::value_error("substeps: expected a non-negative integer");
        env_step::ControlStep c{prm.data(), static_cast<int64_t>(prm.shape(0)), flags, sensor_prm.data(),
                                static_cast<int64_t>(sensor_prm.shape(0)), half, mid, lag, drive, physics_dt,
                                substeps, control_dt, max_condition};
        if (!actuation.is_none()) {
            const auto* record = nb::cast<step_records::ActuationRecord*>(actuation);
            if (record->rows() != n) throw nb::value_error("actuation: expected a record of the batch's rows");
            c.act = &record->a;
        }
        nb::gil_scoped_release release;
        return env_step::control_step(c, action.data(), clipped.data(), F.data(), W.data(), state_of(t, R, v, w),
                                      state_of(t0, R0, v0, w0), steps.data(), time.data(), non_finite.data(),
                                      lengths.data(), rates.data(), condition.data(), n);
    }, "prm"_a, "flags"_a, "sensor_prm"_a, "half"_a, "mid"_a, "lag"_a, "drive"_a, "physics_dt"_a, "substeps"_a,
       "control_dt"_a, "max_condition"_a, "action"_a, "clipped"_a.noconvert(), "F"_a.noconvert(), "W"_a,
       "t"_a.noconvert(), "R"_a.noconvert(), "v"_a.noconvert(), "w"_a.noconvert(), "t0"_a.noconvert(),
       "R0"_a.noconvert(), "v0"_a.noconvert(), "w0"_a.noconvert(), "steps"_a.noconvert(), "time"_a.noconvert(),
       "non_finite"_a.noconvert(), "lengths"_a.noconvert(), "rates"_a.noconvert(), "condition"_a.noconvert(),
       "actuation"_a.none() = nb::none(),
       "One control step of the closed-form plant for every row: actuators (with an ActuationRecord, the action "
       "mode's inner loop and the actuator model at the physics rate), RK4 substeps, clock and non-finite check, "
       "leg sensors (env_step.hpp).  Returns whether any row stopped being finite.");

    m.def("scale_parameter_rows", [](In nominal, In multipliers, InCodes part_of, Out out, Out largest) {
        expect(nominal, "nominal_row", {kernels::N_PARAMS});
        expect(multipliers, "multipliers", {-1, -1});
        const int64_t m = static_cast<int64_t>(multipliers.shape(0));
        const int64_t parts = static_cast<int64_t>(multipliers.shape(1));
        expect(part_of, "part_of", {kernels::N_PARAMS});
        for (int64_t c = 0; c < kernels::N_PARAMS; ++c)
            if (!(part_of.data()[c] >= 0 && part_of.data()[c] < parts))
                throw nb::value_error("part_of: expected indices of the multipliers' columns");
        expect(out, "out", {m, kernels::N_PARAMS});
        expect(largest, "largest", {m});
        env_step::scale_parameter_rows(nominal.data(), multipliers.data(), parts, part_of.data(), kernels::N_PARAMS,
                                       out.data(), largest.data(), m);
    }, "nominal_row"_a, "multipliers"_a, "part_of"_a, "out"_a.noconvert(), "largest"_a.noconvert(),
       "The packed rows of m randomised platforms: out[j, c] = multipliers[j, part_of[c]] * nominal_row[c], "
       "and largest[j] the largest magnitude of row j (Randomization.scale_packed_rows).");

    m.def("draw_uniform_rows", [](nb::list rngs, nb::handle generator_type, Out out) {
        const int64_t m = static_cast<int64_t>(nb::len(rngs));
        expect(out, "out", {m, -1});
        const int64_t k = static_cast<int64_t>(out.shape(1));
        if (!PyType_Check(generator_type.ptr())) throw nb::type_error("generator_type: expected a type");
        const auto* type = reinterpret_cast<PyTypeObject*>(generator_type.ptr());
        // the attribute and method names, made once and kept for the process (interned strings, found
        // by pointer; never released, so nothing is freed after the interpreter's end)
        static PyObject* const bit_generator_name = PyUnicode_InternFromString("bit_generator");
        static PyObject* const capsule_name = PyUnicode_InternFromString("capsule");
        static PyObject* const lock_name = PyUnicode_InternFromString("lock");
        static PyObject* const acquire_name = PyUnicode_InternFromString("acquire");
        static PyObject* const release_name = PyUnicode_InternFromString("release");
        for (int64_t j = 0; j < m; ++j) {
            nb::object rng = rngs[static_cast<size_t>(j)];
            // only numpy's own Generator is known to draw random() as next_double of its bit generator
            if (Py_TYPE(rng.ptr()) != type) return j;
            nb::object bit_generator = nb::steal(PyObject_GetAttr(rng.ptr(), bit_generator_name));
            if (!bit_generator.is_valid()) throw nb::python_error();
            nb::object capsule = nb::steal(PyObject_GetAttr(bit_generator.ptr(), capsule_name));
            if (!capsule.is_valid()) throw nb::python_error();
            if (!PyCapsule_IsValid(capsule.ptr(), "BitGenerator")) return j;
            const auto* g = static_cast<const reset_draws::BitGen*>(PyCapsule_GetPointer(capsule.ptr(), "BitGenerator"));
            // the generator's lock, as Generator.random holds it (another thread may draw from it); its
            // acquire() waits without the GIL
            nb::object lock = nb::steal(PyObject_GetAttr(bit_generator.ptr(), lock_name));
            if (!lock.is_valid()) throw nb::python_error();
            nb::object acquired = nb::steal(PyObject_CallMethodNoArgs(lock.ptr(), acquire_name));
            if (!acquired.is_valid()) throw nb::python_error();
            reset_draws::fill_unit(*g, out.data() + k * j, k);
            nb::object released = nb::steal(PyObject_CallMethodNoArgs(lock.ptr(), release_name));
            if (!released.is_valid()) throw nb::python_error();
        }
        return m;
    }, "rngs"_a, "generator_type"_a, "out"_a.noconvert(),
       "Row j of out (m, k) the k numbers rngs[j].random(k) would draw, taken from each generator's bit "
       "generator (its capsule, under its lock); stops at the first row whose generator is not of "
       "generator_type with a BitGenerator capsule and returns its index (m: every row drawn).  No pointer is "
       "kept past the call.");

    m.def("setpoint_candidates", [](In unit, In home, In range, In prm, In position_min, In position_max,
                                    In home_rpy, double max_angle, double length_min, double length_max,
                                    double max_condition, double margin, Out position, Out rpy, Out rotation,
                                    Out lengths, Out rates, Out condition, Flags ok) {
        expect(unit, "unit", {-1, 6});
        const int64_t M = static_cast<int64_t>(unit.shape(0));
        expect(home, "home", {6});
        expect(range, "range", {6});
        expect(prm, "prm", {1, kernels::N_PARAMS});
        expect(position, "position", {M, 3});
        expect(rpy, "rpy", {M, 3});
        expect(rotation, "rotation", {M, 3, 3});
        expect(lengths, "lengths", {M, 6});
        expect(rates, "rates", {M, 6});
        expect(condition, "condition", {M});
        expect(ok, "ok", {M});
        const reset_draws::CandidateSpec c{
            home.data(), range.data(), prm.data(), 1,
            limits_of(position_min, position_max, home_rpy, max_angle, length_min, length_max, max_condition),
            margin};
        reset_draws::setpoint_candidates(c, unit.data(), position.data(), rpy.data(), rotation.data(),
                                         lengths.data(), rates.data(), condition.data(), ok.data(), M);
    }, "unit"_a, "home"_a, "range"_a, "prm"_a, "position_min"_a, "position_max"_a, "home_rpy"_a, "max_angle"_a,
       "length_min"_a, "length_max"_a, "max_condition"_a, "margin"_a, "position"_a.noconvert(),
       "rpy"_a.noconvert(), "rotation"_a.noconvert(), "lengths"_a.noconvert(), "rates"_a.noconvert(),
       "condition"_a.noconvert(), "ok"_a.noconvert(),
       "The set-point task's candidate poses of draws unit (M,6): home + (-1 + 2 u) range as position, rpy "
       "and rotation, their leg sensors at rest (the nominal row prm) and whether each lies inside the limits "
       "shrunk by margin (tasks.setpoint.SetpointTask._candidates).");

    m.def("scale_randomized_rows", [](In nominal, In factors, InCodes part_of, InCodes columns, In lows, In highs,
                                      int64_t mass_entry, double min_mass, double max_magnitude,
                                      int64_t inertia_part, double smallest_moment, double min_inertia, Out out,
                                      Flags ok) {
        expect(nominal, "nominal_row", {kernels::N_PARAMS});
        expect(factors, "factors", {-1, -1});
        const int64_t m = static_cast<int64_t>(factors.shape(0));
        const int64_t k = static_cast<int64_t>(factors.shape(1));
        expect(part_of, "part_of", {kernels::N_PARAMS});
        expect(columns, "columns", {-1, -1});
        const int64_t parts = static_cast<int64_t>(columns.shape(0));
        const int64_t keys = static_cast<int64_t>(columns.shape(1));
        if (keys < 1) throw nb::value_error("columns: expected at least one column");
        for (int64_t c = 0; c < kernels::N_PARAMS; ++c)
            if (!(part_of.data()[c] >= 0 && part_of.data()[c] <= parts))
                throw nb::value_error("part_of: expected 0 or 1 + a part of columns");
        for (int64_t c = 0; c < parts * keys; ++c)
            if (!(columns.data()[c] >= -1 && columns.data()[c] < k))
                throw nb::value_error("columns: expected columns of factors, or -1");
        expect(lows, "lows", {k});
        expect(highs, "highs", {k});
        if (!(mass_entry >= 0 && mass_entry < kernels::N_PARAMS))
            throw nb::value_error("mass_entry: expected an entry of the packed row");
        if (!(inertia_part >= 0 && inertia_part < parts))
            throw nb::value_error("inertia_part: expected a part of columns");
        expect(out, "out", {m, kernels::N_PARAMS});
        expect(ok, "ok", {m});
        const reset_draws::ScaleSpec s{nominal.data(), part_of.data(), columns.data(), parts, keys, lows.data(),
                                       highs.data(), k, mass_entry, min_mass, max_magnitude, inertia_part,
                                       smallest_moment, min_inertia};
        reset_draws::scale_randomized_rows(s, factors.data(), out.data(), ok.data(), m);
    }, "nominal_row"_a, "factors"_a, "part_of"_a, "columns"_a, "lows"_a, "highs"_a, "mass_entry"_a, "min_mass"_a,
       "max_magnitude"_a, "inertia_part"_a, "smallest_moment"_a, "min_inertia"_a, "out"_a.noconvert(),
       "ok"_a.noconvert(),
       "The packed rows of m randomised platforms from their factors (m, k) and whether each passes the "
       "checks of PlatformParams (Randomization.scale_packed_rows): each part's multiplier the product of its "
       "factor columns, out[j, c] = multiplier[part_of[c]] * nominal_row[c].");

    m.def("pose_block", [](In t, In R, In v, In w, Out raw) {
        expect(t, "position", {-1, 3});
        const int64_t n = static_cast<int64_t>(t.shape(0));
        state(t, R, v, w, n);
        expect(raw, "raw", {n, -1});
        const int64_t dim = static_cast<int64_t>(raw.shape(1));
        if (dim < 15) throw nb::value_error("raw: expected at least 15 columns");
        env_step::pose_block(t.data(), R.data(), v.data(), w.data(), raw.data(), dim, n);
    }, "t"_a, "R"_a, "v"_a, "w"_a, "raw"_a.noconvert(),
       "The pose observation's first 15 entries of every row: P, R's first two columns, v, omega.");

    m.def("normalize", [](Out raw, In offset, In inv_scale) {
        expect(raw, "raw", {-1, -1});
        const int64_t dim = static_cast<int64_t>(raw.shape(1));
        expect(offset, "offset", {dim});
        expect(inv_scale, "inv_scale", {dim});
        env_step::normalize(raw.data(), offset.data(), inv_scale.data(), dim, static_cast<int64_t>(raw.shape(0)));
    }, "raw"_a.noconvert(), "offset"_a, "inv_scale"_a, "raw = (raw - offset) * inv_scale, in place.");

    m.def("within_float32", [](In raw, In reward, double largest) {
        return env_step::within_float32(raw.data(), static_cast<int64_t>(raw.size()), reward.data(),
                                        static_cast<int64_t>(reward.size()), largest);
    }, "raw"_a, "reward"_a, "largest"_a,
       "Whether every entry of raw is within +-largest and every reward finite.");
}
