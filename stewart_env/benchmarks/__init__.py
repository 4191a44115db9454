"""Benchmark of the compiled core (and, with ``--env``, of the environments).

    stewart-env bench

For each model: forward-dynamics evaluations per second at N = 1 and N = 1024 platforms, through
``Dynamics.forward`` (argument checks included) and through the compiled kernel alone; and
the wall time of ``rollout`` over 1 s of simulated time at dt = 1 ms (4000 evaluations per
platform with RK4) for N = 1 and N = 1024.  Also the time a fresh Python process takes from
start to its first forward evaluation (the kernels are compiled when the package is installed,
so this is the import and the first call).  Timings are the best of several repeats, so other load on the machine shows
as little as possible.

The scaling table (:func:`bench_scaling`) gives, for N = 1, 16, 256, 1024 and 8192 platforms, the
batched forward evaluations per second, the 10 ms platform-steps per second (10 RK4 substeps of
1 ms, 40 evaluations) and the fraction of the machine's vector peak each reaches, with the flop
count of one evaluation it assumes (counted by running the kernel once on a number type that counts
its operations); ``--plot PATH`` draws it to a PNG.

The last row (:func:`resets_row`) is the native vector env's platform-step at N = 1024 under
uniformly random actions, resets included, beside its step alone, nominal and randomised, as
ratios with their spread over three runs.

With ``--mujoco`` (needs the extra ``mujoco``), MuJoCo times the same mechanism in the same run
(:func:`bench_mujoco`): one forward and one inverse evaluation, a 10 ms control step of RK4
substeps for one platform and for a batch of 1024, and the vector env's reset with and without
domain randomisation; the table gives each beside MuJoCo's and their ratio.

The package, one module per job: :mod:`~stewart_env.benchmarks.measurements` (the compiled core's
figures: evaluations, rollouts, the scaling over batch sizes, the machine),
:mod:`~stewart_env.benchmarks.envs` (the single and vector environments, their resets),
:mod:`~stewart_env.benchmarks.mujoco_comparison` (MuJoCo on the same mechanism) and
:mod:`~stewart_env.benchmarks.report` (the tables, the figure and :func:`run_bench`, which prints
them); its command line is ``stewart_env/cli/bench.py``.
"""

from stewart_env.benchmarks.envs import RESET_RANDOMIZATION, bench_env, bench_reset, bench_resets_in_steps
from stewart_env.benchmarks.measurements import (
    PEAK_FLOPS_PER_CYCLE,
    SCALING_SIZES,
    bench_model,
    bench_scaling,
    first_evaluation_seconds,
    forward_flops,
    machine,
    vector_peak_flops,
)
from stewart_env.benchmarks.mujoco_comparison import bench_mujoco
from stewart_env.benchmarks.report import mujoco_table, plot_scaling, resets_row, run_bench, scaling_table
from stewart_env.dynamics import MODEL_NAMES

__all__ = [
    "MODEL_NAMES",
    "PEAK_FLOPS_PER_CYCLE",
    "RESET_RANDOMIZATION",
    "SCALING_SIZES",
    "bench_env",
    "bench_model",
    "bench_mujoco",
    "bench_reset",
    "bench_resets_in_steps",
    "bench_scaling",
    "first_evaluation_seconds",
    "forward_flops",
    "machine",
    "mujoco_table",
    "plot_scaling",
    "resets_row",
    "run_bench",
    "scaling_table",
    "vector_peak_flops",
]
