// What the environment's reset draws and builds for its rows in one compiled pass
// (envs/core.py PlatformBatch.reset_rows): each row's numbers of random() taken straight from its
// own numpy Generator, the set-point task's candidate poses, measured and checked
// (tasks/setpoint.py SetpointTask._candidates), and the randomised rows' parameters, scaled and
// checked (randomization.Randomization.scale_packed_rows).  Each number is the one the Python path gives.
#pragma once

#include <cstdint>
#include <vector>

#include "env/actuation.hpp"
#include "env/env_step.hpp"
#include "physics/kernels.hpp"
#include "tasks/task_kernels.hpp"

namespace reset_draws {

// numpy's bitgen_t (numpy/random/bitgen.h), the interface every numpy BitGenerator hands out
// through its capsule named "BitGenerator": the state and the functions that draw from it.
struct BitGen {
    void* state;
    uint64_t (*next_uint64)(void* state);
    uint32_t (*next_uint32)(void* state);
    double (*next_double)(void* state);
    uint64_t (*next_raw)(void* state);
};

// k numbers of random() into out: what Generator.random(out=...) draws for float64, one
// next_double per number, in order (numpy's random_standard_uniform_fill).
inline void fill_unit(const BitGen& g, double* out, int64_t k) {
    for (int64_t i = 0; i < k; ++i) out[i] = g.next_double(g.state);
}

// The set-point task's candidate poses and what the task checks of them.
struct CandidateSpec {
    const double* home;   // (6,): home position (m) and home roll, pitch, yaw (rad)
    const double* range;  // (6,): position_range (m) and angle_range (rad)
    const double* prm;    // the nominal packed row(s) the leg sensors are measured with
    int64_t n_prm;
    task_kernels::Limits lim;
    double margin;  // the fraction of each half-range kept clear (tasks.pose_margins)
};

// M candidate poses from their draws unit (M,6) of random(): pose = home + (-1 + 2 u) range, the
// numbers of numpy's home + uniform(-1, 1) * range, as position (M,3), rpy (M,3) and rotation
// (M,3,3) (rotations.rpy_to_matrix); their leg lengths (M,6), rates (M,6) and condition numbers
// (M,) at rest (kernels::leg_sensors_batch, of the nominal row); and whether each lies safely
// inside the limits, ok (M,) (task_kernels::within_margins).
inline void setpoint_candidates(const CandidateSpec& c, const double* unit, double* position, double* rpy,
                                double* rotation, double* lengths, double* rates, double* condition, bool* ok,
                                int64_t M) {
    for (int64_t b = 0; b < M; ++b) {
        double pose[6];
        for (int j = 0; j < 6; ++j) pose[j] = c.home[j] + (-1.0 + 2.0 * unit[6 * b + j]) * c.range[j];
        for (int j = 0; j < 3; ++j) {
            position[3 * b + j] = pose[j];
            rpy[3 * b + j] = pose[3 + j];
        }
        actuation::rpy_to_matrix(pose + 3, rotation + 9 * b);
    }
    const std::vector<double> rest(static_cast<size_t>(3 * M), 0.0);
    kernels::leg_sensors_batch(c.prm, c.n_prm, position, rotation, rest.data(), rest.data(), c.lim.max_condition,
                               lengths, rates, condition, M);
    task_kernels::within_margins(position, rpy, lengths, condition, c.lim, c.margin, ok, M);
}

// What the randomised rows' parameters are scaled by and checked against
// (randomization.Randomization.scale_packed_rows).
struct ScaleSpec {
    const double* nominal;   // (N_PARAMS,): the nominal packed row
    const int64_t* part_of;  // (N_PARAMS,): 1 + the part of each entry, 0 where nothing is scaled
    const int64_t* columns;  // (parts, keys): each part's factor columns in the order multiplied, -1 past the last
    int64_t parts, keys;
    const double *lows, *highs;  // (k,): the factors' ranges
    int64_t k;
    int64_t mass_entry;      // the platform's mass in the packed row
    double min_mass;         // its least value (params.platform.MIN_PLATFORM_MASS)
    double max_magnitude;    // the largest magnitude of any number (params.checks.MAX_MAGNITUDE)
    int64_t inertia_part;    // the part of the platform's inertia
    double smallest_moment;  // the nominal platform inertia's smallest principal moment
    double min_inertia;      // its least value (params.platform.MIN_PLATFORM_INERTIA)
};

// The packed rows out (m, N_PARAMS) of m randomised rows from their factors (m, k): each part's
// multiplier the product of its keys' factors in their order (1 for a part without one), entry c of
// row j multiplier[part_of[c]] times the nominal entry (scale_parameter_rows); and ok[j] whether
// row j's factors lie in their ranges and its platform mass, largest magnitude and smallest
// inertia moment pass the checks of PlatformParams (the numbers and comparisons of numpy's).
inline void scale_randomized_rows(const ScaleSpec& s, const double* factors, double* out, bool* ok, int64_t m) {
    std::vector<double> multipliers(static_cast<size_t>(1 + s.parts));
    for (int64_t j = 0; j < m; ++j) {
        const double* f = factors + s.k * j;
        multipliers[0] = 1.0;
        for (int64_t p = 0; p < s.parts; ++p) {
            const int64_t* cols = s.columns + s.keys * p;
            double product = 1.0;
            if (cols[0] >= 0) {
                product = f[cols[0]];  // 1 x f is f: a part's product starts at its first factor
                for (int64_t c = 1; c < s.keys && cols[c] >= 0; ++c) product = product * f[cols[c]];
            }
            multipliers[static_cast<size_t>(p + 1)] = product;
        }
        double largest = 0.0;
        env_step::scale_parameter_rows(s.nominal, multipliers.data(), 1 + s.parts, s.part_of, kernels::N_PARAMS,
                                       out + kernels::N_PARAMS * j, &largest, 1);
        bool row_ok = true;
        for (int64_t c = 0; c < s.k; ++c) row_ok = row_ok && f[c] >= s.lows[c] && f[c] <= s.highs[c];
        const double smallest = multipliers[static_cast<size_t>(1 + s.inertia_part)] * s.smallest_moment;
        ok[j] = row_ok && out[kernels::N_PARAMS * j + s.mass_entry] >= s.min_mass && largest <= s.max_magnitude &&
                smallest >= s.min_inertia;
    }
}

}  // namespace reset_draws
