// What the environment's reset draws and builds for its rows in one compiled pass
// (envs/core.py PlatformBatch.reset_rows): each row's numbers of random() taken straight from its
// own numpy Generator, and the set-point task's candidate poses, measured and checked
// (tasks/setpoint.py SetpointTask._candidates).  Each number is the one the Python path gives.
#pragma once

#include <cstdint>
#include <vector>

#include "env/actuation.hpp"
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

}  // namespace reset_draws
