"""``stewart-env bench --mujoco``: the side-by-side benchmark's code path on a tiny budget."""

import math

import pytest

import stewart_env as se
from stewart_env import benchmarks as bench

MEASURES = (
    "forward_mujoco",
    "forward_api",
    "forward_workspace",
    "inverse_mujoco",
    "inverse_api",
    "inverse_workspace",
    "mass_and_bias_workspace",
    "step_mujoco",
    "step_plant",
    "step_rollout",
    "step_workspace",
    "step_env",
    "step_env_mujoco",
    "batch_mujoco",
    "batch_vector_env",
    "batch_rollout",
    "reset_randomized",
    "reset_nominal",
)


def test_bench_mujoco_times_every_call_and_tabulates_the_ratios(dasgupta):
    pytest.importorskip("mujoco")
    r = bench.bench_mujoco(dasgupta, n_batch=4, repeats=1, calls=4)
    for key in MEASURES:
        assert math.isfinite(r[key]) and r[key] > 0, key
    table = bench.mujoco_table(r)
    assert "| forward dynamics, 1 platform | mj_forward |" in table
    assert "| 10 ms step (10 RK4 substeps), 4 platforms, per platform | mujoco.rollout |" in table
    assert "randomised / nominal" in table
    assert "| inverse dynamics, 1 platform | mj_inverse |" in table
    # clock note, header, forward, inverse, mass matrix, single step, plant, env, batch, reset
    assert len(table.splitlines()) == 2 + 2 + 2 + 2 + 1 + 3 + 1 + 1 + 2 + 1


def test_bench_mujoco_without_mujoco_names_the_extra(monkeypatch, capsys):
    from stewart_env import mujoco as twin

    monkeypatch.setattr(twin.library, "_mj", None)
    from stewart_env.cli import main

    assert main(["bench", "--mujoco"]) == 2
    assert "argument --mujoco" in capsys.readouterr().err


def test_bench_reset_is_per_row():
    from stewart_env.benchmarks import bench_reset

    assert 0 < bench_reset(2, repeats=1, platform=se.load_platform("dasgupta1998")) < 1.0  # s per row
