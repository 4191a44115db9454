"""``stewart-env bench --derivatives``: the derivatives' table, its figures and the flag's way to it."""

import stewart_env as se
from stewart_env.benchmarks.derivatives import bench_derivatives, derivatives_table

from conftest import exit_code


def test_the_derivatives_table_gives_each_cost_beside_the_values(dasgupta):
    r = bench_derivatives(dasgupta, n_batch=8, repeats=1, calls=2, substeps=2)
    # timings only: two calls under whatever load the machine has order nothing (the bench's own
    # runs compare them), so each is a positive, finite time
    keys = ("forward", "acceleration_jacobians", "step", "step_jacobians", "batch_step", "batch_step_jacobians")
    assert all(0.0 < r[k] < 1.0 for k in keys)
    table = derivatives_table(r)
    assert table.count("\n") >= 5 and "control step, 2 x 1 ms RK4" in table
    assert ("mjd_transitionFD" in table) == (r["mujoco_transition_fd"] is not None)


def test_the_flag_reaches_run_bench(monkeypatch):
    seen = {}
    monkeypatch.setattr(se.benchmarks, "run_bench", lambda *a, **kw: seen.update(kw))
    assert exit_code(["bench", "--derivatives"]) == 0
    assert seen["derivatives"] is True
