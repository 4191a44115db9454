"""``stewart-env bench``'s scaling table: its code path on a tiny budget (no timing asserts)."""

import math

import stewart_env as se
from stewart_env import benchmarks as bench


def test_the_flop_count_is_the_kernels_and_the_same_at_every_call(dasgupta):
    improved = bench.forward_flops(se.make_dynamics("improved", dasgupta))
    # the derivation's few thousand operations: six legs of a few hundred, the 6x6 solve, the platform
    assert 3000 < improved < 20000
    assert improved == bench.forward_flops(se.make_dynamics("improved", dasgupta))
    # the centroidal form does the legs' parallel-axis products the joint form folds into I_B
    assert bench.forward_flops(se.make_dynamics("improved_centroidal", dasgupta)) != improved


def test_scaling_table_and_plot(dasgupta, tmp_path):
    r = bench.bench_scaling(dasgupta, sizes=(1, 9), repeats=1, seconds=1e-3, substeps=2)
    assert [row["n"] for row in r["rows"]] == [1, 9]
    for row in r["rows"]:
        for key in (
            "evals_per_s",
            "evals_per_cpu_s",
            "evals_peak",
            "evals_core_peak",
            "steps_per_s",
            "steps_per_cpu_s",
            "steps_peak",
            "steps_core_peak",
        ):
            assert math.isfinite(row[key]) and row[key] > 0, key
    table = bench.scaling_table(r)
    assert f"{r['flops']:,} flops per forward evaluation" in table
    assert "| 9 |" in table
    assert len(table.splitlines()) == 2 + 2 + 2  # assumptions, blank, header, rule, two rows
    path = tmp_path / "scaling.png"
    bench.plot_scaling(r, path)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
