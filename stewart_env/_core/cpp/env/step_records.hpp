// The compiled step's contract (docs/layout.md, "The compiled step's contract"): the parts of the
// environment's control step (env_step::Batch) as typed records, each built once by its owner on
// the Python side and bound here (module.cpp):
//
//   StateRecord        the batch's state, start state, clock, sensors, reference, errors (envs/core.py)
//   PlantRecord        the plant's parameters and its integration (envs/plant.py ClosedFormPlant)
//   ActuatorRecord     the actuators' force map, lag, applied action and leg forces (envs/core.py)
//   ActuationRecord    the action mode's inner loop and the actuator model at the physics rate, with the
//                      actuators' state (envs/core.py; optional: none, the forces held over the step)
//   TaskRecord         the task's limits, reward weights and failure codes (tasks/base.py Task)
//   ObservationRecord  the observation's layout, scaling, error integral, delay ring (envs/observation.py)
//   OutputRecord       where a step's outcome goes: codes, reward terms, reward, bad rows, float32 observation
//
// Every record checks each array it is given (dtype, shape, C-contiguity: never converted, since the
// step writes into them or reads them after the call) and holds it: an nb::ndarray member keeps its
// Python array alive, so no pointer a record hands to the step outlives its array.  A record fills
// its own fields of the Batch (fill); adding a part is a new record with its fill and one argument
// of BatchStep.
#pragma once

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include <cstdint>
#include <string>

#include "physics/array_checks.hpp"
#include "env/env_step.hpp"
#include "physics/kernels.hpp"

namespace step_records {

namespace nb = nanobind;

using In = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;
using Out = nb::ndarray<double, nb::c_contig, nb::device::cpu>;
using Flags = nb::ndarray<bool, nb::c_contig, nb::device::cpu>;
using InFlags = nb::ndarray<const bool, nb::c_contig, nb::device::cpu>;
using Codes = nb::ndarray<int64_t, nb::c_contig, nb::device::cpu>;
using Singles = nb::ndarray<float, nb::c_contig, nb::device::cpu>;

// The array h as A, checked (dtype, C-contiguity, shape; -1 any size) and never converted: the
// returned ndarray holds h's memory.  Raises ValueError naming the argument.
template <typename A>
A take(nb::handle h, const char* name, std::initializer_list<int64_t> shape) {
    A a;
    if (!nb::try_cast<A>(h, a, false))
        throw nb::value_error((std::string(name) + ": expected a C-contiguous array of the step's dtype").c_str());
    array_checks::expect(a, name, shape);
    return a;
}

// 1 or n packed parameter rows, checked.
inline In parameter_rows(nb::handle h, const char* name, int64_t n) {
    In prm = take<In>(h, name, {-1, kernels::N_PARAMS});
    if (!(prm.shape(0) == 1 || static_cast<int64_t>(prm.shape(0)) == n))
        throw nb::value_error((std::string(name) + ": expected 1 or N parameter rows").c_str());
    return prm;
}

// The batch's own arrays (n rows): state (position, rotation, velocity, angular_velocity), the start
// state of the step, the external wrench, the clock, the non-finite flags, the leg sensors (and
// the nominal parameters they use), the reference and the tracking errors.
struct StateRecord {
    int64_t n;
    Out t, R, v, w, t0, R0, v0, w0, W, time, lengths, rates, condition, rt, rR, rv, rw, errors, norms;
    Codes steps;
    Flags non_finite;
    In sensor_prm;
    double control_dt, max_condition;

    StateRecord(nb::tuple state, nb::tuple start, nb::handle external_wrench, nb::handle steps_, nb::handle time_,
                nb::handle non_finite_, nb::handle leg_lengths, nb::handle leg_rates, nb::handle condition_,
                nb::tuple reference, nb::handle error_vectors, nb::handle error_norms, nb::handle sensor_prm_,
                double control_dt_, double max_condition_)
        : control_dt(control_dt_), max_condition(max_condition_) {
        if (state.size() != 4 || start.size() != 4 || reference.size() != 4)
            throw nb::value_error("state, start, reference: expected (position, rotation, velocity, angular_velocity)");
        t = take<Out>(state[0], "position", {-1, 3});
        n = static_cast<int64_t>(t.shape(0));
        if (n < 1) throw nb::value_error("position: expected at least one row");
        R = take<Out>(state[1], "rotation", {n, 3, 3});
        v = take<Out>(state[2], "velocity", {n, 3});
        w = take<Out>(state[3], "angular_velocity", {n, 3});
        t0 = take<Out>(start[0], "start position", {n, 3});
        R0 = take<Out>(start[1], "start rotation", {n, 3, 3});
        v0 = take<Out>(start[2], "start velocity", {n, 3});
        w0 = take<Out>(start[3], "start angular_velocity", {n, 3});
        W = take<Out>(external_wrench, "external_wrench", {n, 6});
        steps = take<Codes>(steps_, "steps", {n});
        time = take<Out>(time_, "time", {n});
        non_finite = take<Flags>(non_finite_, "non_finite", {n});
        lengths = take<Out>(leg_lengths, "leg_lengths", {n, 6});
        rates = take<Out>(leg_rates, "leg_rates", {n, 6});
        condition = take<Out>(condition_, "condition", {n});
        rt = take<Out>(reference[0], "reference position", {n, 3});
        rR = take<Out>(reference[1], "reference rotation", {n, 3, 3});
        rv = take<Out>(reference[2], "reference velocity", {n, 3});
        rw = take<Out>(reference[3], "reference angular_velocity", {n, 3});
        errors = take<Out>(error_vectors, "error_vectors", {4, n, 3});
        norms = take<Out>(error_norms, "error_norms", {4, n});
        sensor_prm = parameter_rows(sensor_prm_, "sensor_prm", n);
    }

    void fill(env_step::Batch& B) const {
        B.n = n;
        B.s = {t.data(), R.data(), v.data(), w.data()};
        B.start = {t0.data(), R0.data(), v0.data(), w0.data()};
        B.W = W.data();
        B.steps = steps.data();
        B.time = time.data();
        B.non_finite = non_finite.data();
        B.lengths = lengths.data();
        B.rates = rates.data();
        B.condition = condition.data();
        B.rt = rt.data();
        B.rR = rR.data();
        B.rv = rv.data();
        B.rw = rw.data();
        B.errors = errors.data();
        B.norms = norms.data();
        B.c.sensor_prm = sensor_prm.data();
        B.c.n_sensor_prm = static_cast<int64_t>(sensor_prm.shape(0));
        B.c.control_dt = control_dt;
        B.c.max_condition = max_condition;
    }
};

// The closed-form plant: its packed parameters (1 or n rows) and model flags, integrated with
// substeps RK4 steps of physics_dt per control step.  set_model takes new parameters (domain
// randomisation at a reset); the step reads them at every call.
struct PlantRecord {
    int64_t n;
    In prm;
    int64_t flags = 0;
    double physics_dt;
    int64_t substeps;

    PlantRecord(int64_t n_, nb::handle prm_, int64_t flags_, double physics_dt_, int64_t substeps_)
        : n(n_), physics_dt(physics_dt_), substeps(substeps_) {
        if (n < 1) throw nb::value_error("n: expected a positive batch size");
        if (substeps < 0) throw nb::value_error("substeps: expected a non-negative integer");
        set_model(prm_, flags_);
    }

    void set_model(nb::handle prm_, int64_t flags_) {
        prm = parameter_rows(prm_, "prm", n);
        flags = flags_;
    }

    void fill(env_step::Batch& B) const {
        B.c.prm = prm.data();
        B.c.n_prm = static_cast<int64_t>(prm.shape(0));
        B.c.flags = flags;
        B.c.physics_dt = physics_dt;
        B.c.substeps = substeps;
    }
};

// The actuators: the action clipped to [-1, 1] (the applied action, (n,6)) mapped onto the force
// range (a force_half + force_mid N) into the leg forces (n,6), through the lag.
struct ActuatorRecord {
    double force_half, force_mid, lag;
    Out action, leg_forces;

    ActuatorRecord(double force_half_, double force_mid_, double lag_, nb::handle action_, nb::handle leg_forces_)
        : force_half(force_half_), force_mid(force_mid_), lag(lag_) {
        action = take<Out>(action_, "action", {-1, 6});
        leg_forces = take<Out>(leg_forces_, "leg_forces", {static_cast<int64_t>(action.shape(0)), 6});
    }

    int64_t rows() const { return static_cast<int64_t>(action.shape(0)); }

    void fill(env_step::Batch& B) const {
        B.c.force_half = force_half;
        B.c.force_mid = force_mid;
        B.c.lag = lag;
        B.clipped = action.data();
        B.F = leg_forces.data();
    }
};

// The actuation at the physics rate (actuation.hpp): the action mode, the pose law and the actuator
// (their codes), the nominal model's flags, the set points' maps, the loops' gains, the drives'
// packed parameters (actuator_models.hpp; empty when not that actuator) and the actuators' state
// (n, 6, 3), held.
struct ActuationRecord {
    actuation::Actuation a{};
    Out state;

    ActuationRecord(int64_t mode, int64_t law, int64_t kind, int64_t nominal_flags, nb::handle force_range,
                    nb::handle length_map, nb::handle pose_mid, nb::handle pose_half, nb::handle servo,
                    nb::handle task_kp, nb::handle task_kd, double lag, nb::handle electric, double current_gain,
                    double force_per_amp, nb::handle hydraulic, double valve_gain, double force_gain,
                    nb::handle reflected_mass, nb::handle state_) {
        if (mode < actuation::FORCE || mode > actuation::POSE) throw nb::value_error("mode: expected 0, 1 or 2");
        if (law < actuation::IK || law > actuation::COMPUTED_TORQUE) throw nb::value_error("law: expected 0, 1 or 2");
        if (kind < actuation::IDEAL || kind > actuation::HYDRAULIC)
            throw nb::value_error("kind: expected 0, 1, 2 or 3");
        a.mode = mode;
        a.law = law;
        a.kind = kind;
        a.nominal_flags = nominal_flags;
        const auto copy = [](nb::handle h, const char* name, int64_t size, double* out) {
            In x = take<In>(h, name, {size});
            for (int64_t k = 0; k < size; ++k) out[k] = x.data()[k];
        };
        double pair[2];
        copy(force_range, "force_range", 2, pair);
        a.force_lo = pair[0];
        a.force_hi = pair[1];
        copy(length_map, "length_map", 2, pair);
        a.length_mid = pair[0];
        a.length_half = pair[1];
        copy(pose_mid, "pose_mid", 6, a.pose_mid);
        copy(pose_half, "pose_half", 6, a.pose_half);
        copy(servo, "servo", 2, pair);
        a.servo_kp = pair[0];
        a.servo_kd = pair[1];
        copy(task_kp, "task_kp", 6, a.task_kp);
        copy(task_kd, "task_kd", 6, a.task_kd);
        a.lag = lag;
        if (kind == actuation::ELECTRIC) {
            double p[actuators::N_ELECTRIC];
            copy(electric, "electric", actuators::N_ELECTRIC, p);
            a.electric = actuators::electric_from(p);
        }
        a.current_gain = current_gain;
        a.force_per_amp = force_per_amp;
        if (kind == actuation::HYDRAULIC) {
            double p[actuators::N_HYDRAULIC];
            copy(hydraulic, "hydraulic", actuators::N_HYDRAULIC, p);
            a.hydraulic = actuators::hydraulic_from(p);
        }
        a.valve_gain = valve_gain;
        a.force_gain = force_gain;
        copy(reflected_mass, "reflected_mass", 6, a.m_r);
        a.reflected = false;
        for (int i = 0; i < 6; ++i) a.reflected = a.reflected || a.m_r[i] != 0.0;
        state = take<Out>(state_, "actuator_state", {-1, 6, actuation::STATES});
        a.state = state.data();
    }

    int64_t rows() const { return static_cast<int64_t>(state.shape(0)); }

    void fill(env_step::Batch& B) const { B.c.act = &a; }
};

// The task's termination and reward as Task keeps them: the platform's limits, the eight reward
// weights (RewardWeights, in task_kernels order), the termination cost and whether each
// termination code is a failure (code 0 and one entry per reason).
struct TaskRecord {
    In position_min, position_max, home_rpy, weights;
    InFlags failure;
    double max_angle, length_min, length_max, max_condition, termination_cost;

    TaskRecord(nb::handle position_min_, nb::handle position_max_, nb::handle home_rpy_, double max_angle_,
               double length_min_, double length_max_, double max_condition_, nb::handle weights_,
               double termination_cost_, nb::handle failure_)
        : max_angle(max_angle_), length_min(length_min_), length_max(length_max_), max_condition(max_condition_),
          termination_cost(termination_cost_) {
        position_min = take<In>(position_min_, "position_min", {3});
        position_max = take<In>(position_max_, "position_max", {3});
        home_rpy = take<In>(home_rpy_, "home_rpy", {3});
        weights = take<In>(weights_, "weights", {8});
        failure = take<InFlags>(failure_, "failure", {-1});
        // code 0 and the four limits' codes that limit_codes gives
        if (failure.shape(0) < 5) throw nb::value_error("failure: expected an entry for code 0 and each limit's code");
    }

    int64_t n_codes() const { return static_cast<int64_t>(failure.shape(0)); }

    void fill(env_step::Batch& B) const {
        B.limits = {position_min.data(), position_max.data(), home_rpy.data(), max_angle, length_min, length_max,
                    max_condition};
        const double* c = weights.data();
        B.weights = {c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]};
        B.termination_cost = termination_cost;
        B.failure = failure.data();
    }
};

// The observation made in the step: its layout (the pose block or the leg sensors' columns, the
// first column of each further term, -1 when absent), the clean rows raw (n,D), the delay ring
// history (delay + 1, n, D) and its head (int64 (1,): the slot written last; the step advances
// it), the scaling, the error integral (n,6) with its bound and band (or None), the rows whose
// start observation was not finite (n,) and the float32 range.
struct ObservationRecord {
    env_step::Layout layout{};
    Out raw, history, integral;
    Codes head;
    In offset, inv_scale, bound, band;
    Flags pending;
    bool normalize, has_integral = false, has_band = false;
    double largest;

    ObservationRecord(bool pose, int64_t leg_lengths_at, int64_t leg_rates_at, int64_t leg_forces_at,
                      int64_t position_error_at, int64_t orientation_error_at, int64_t error_integral_at,
                      nb::handle raw_, nb::handle history_, nb::handle head_, bool normalize_, nb::handle offset_,
                      nb::handle inv_scale_, nb::handle error_integral, nb::handle error_integral_bound,
                      nb::handle error_integral_band, nb::handle pending_, double largest_)
        : normalize(normalize_), largest(largest_) {
        env_step::Layout& L = layout;
        L.pose = pose;
        L.leg_lengths = leg_lengths_at;
        L.leg_rates = leg_rates_at;
        L.leg_forces = leg_forces_at;
        L.position_error = position_error_at;
        L.orientation_error = orientation_error_at;
        L.error_integral = error_integral_at;
        raw = take<Out>(raw_, "raw", {-1, -1});
        const int64_t n = static_cast<int64_t>(raw.shape(0));
        L.dim = static_cast<int64_t>(raw.shape(1));
        const int64_t D = L.dim;
        // every term's columns inside the row
        const auto fits = [D](int64_t at, int64_t size, bool on) { return !on || (at >= 0 && at + size <= D); };
        if (!(fits(0, 15, L.pose) && fits(L.leg_lengths, 6, !L.pose) && fits(L.leg_rates, 6, !L.pose) &&
              fits(L.leg_forces, 6, L.leg_forces >= 0) && fits(L.position_error, 3, true) &&
              fits(L.orientation_error, 3, true) && fits(L.error_integral, 6, L.error_integral >= 0)))
            throw nb::value_error("layout: a term outside the observation row");
        history = take<Out>(history_, "history", {-1, n, D});
        if (history.shape(0) < 1) throw nb::value_error("history: expected at least one slot");
        head = take<Codes>(head_, "head", {1});
        offset = take<In>(offset_, "offset", {D});
        inv_scale = take<In>(inv_scale_, "inv_scale", {D});
        if (L.error_integral >= 0) {
            integral = take<Out>(error_integral, "error_integral", {n, 6});
            bound = take<In>(error_integral_bound, "error_integral_bound", {6});
            has_integral = true;
            if (!error_integral_band.is_none()) {
                band = take<In>(error_integral_band, "error_integral_band", {6});
                has_band = true;
            }
        }
        pending = take<Flags>(pending_, "pending", {n});
    }

    int64_t rows() const { return static_cast<int64_t>(raw.shape(0)); }
    int64_t dim() const { return layout.dim; }

    void fill(env_step::Batch& B) const {
        B.observe = true;
        B.layout = layout;
        B.raw = raw.data();
        B.history = history.data();
        B.slots = static_cast<int64_t>(history.shape(0));
        B.head = head.data();
        B.normalize = normalize;
        B.offset = offset.data();
        B.inv_scale = inv_scale.data();
        B.integral = has_integral ? integral.data() : nullptr;
        B.bound = has_integral ? bound.data() : nullptr;
        B.band = has_band ? band.data() : nullptr;
        B.pending = pending.data();
        B.largest = largest;
    }
};

// Where a step's outcome goes: termination codes (n,), reward terms (5,n), reward (n,), the rows
// made finite (n,), and the latest observation as float32 (n,D) (written when the step makes it).
struct OutputRecord {
    Codes code;
    Out terms, reward;
    Flags bad;
    Singles observation;

    OutputRecord(nb::handle code_, nb::handle terms_, nb::handle reward_, nb::handle bad_, nb::handle observation_) {
        code = take<Codes>(code_, "code", {-1});
        const int64_t n = static_cast<int64_t>(code.shape(0));
        terms = take<Out>(terms_, "terms", {5, n});
        reward = take<Out>(reward_, "reward", {n});
        bad = take<Flags>(bad_, "bad", {n});
        observation = take<Singles>(observation_, "observation", {n, -1});
    }

    int64_t rows() const { return static_cast<int64_t>(code.shape(0)); }

    void fill(env_step::Batch& B) const { B.latest = observation.data(); }
};

}  // namespace step_records
