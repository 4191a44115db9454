"""The model-mismatch study on a tiny budget: the matrix with its intervals, the simplifications'
costs, its files, resuming, and every bad request refused before any work."""

from __future__ import annotations

import argparse
import csv
import json
import math
import socket
import sys
import time

import numpy as np
import pytest

# PPO runs here are a rollout or two of 2 platforms, smaller than the config's minibatch on purpose.
pytestmark = pytest.mark.filterwarnings("ignore:You have specified a mini-batch size:UserWarning")

from stewart_env.agents.evaluation import evaluation  # noqa: E402
from stewart_env.agents.evaluation.evaluation import METRICS  # noqa: E402
from stewart_env.agents.evaluation.statistics import Interval, stratified_bootstrap  # noqa: E402
from stewart_env.agents.studies import mismatch  # noqa: E402
from stewart_env.agents.studies.mismatch import (  # noqa: E402
    RANKING_METRICS,
    MismatchError,
    MismatchSettings,
    run_mismatch,
    timing,
)
from stewart_env.agents.training import TrainingError  # noqa: E402
from stewart_env.cli import mismatch as mismatch_cli  # noqa: E402
from stewart_env.errors import UsageError  # noqa: E402

TEST_MODELS = ["classical", "improved", "improved_centroidal"]
# Metrics defined for every episode (settling time and overshoot are NaN by definition when an
# episode never settles, as in 40 steps of an untrained agent).
ALWAYS_DEFINED = (
    "success",
    "rms_position_error",
    "rms_orientation_error",
    "steady_state_position_error",
    "steady_state_orientation_error",
    "peak_leg_force",
    "control_energy",
)
EXPECTED_ROWS = [
    "PD + gravity comp. [classical]",
    "PD + gravity comp. [improved]",
    "PD + gravity comp. [improved+c2]",
    "CT [classical]",
    "CT [improved]",
    "CT [improved+c2]",
    "PPO [classical]",
    "PPO [improved]",
    "PPO [improved+c2]",
    "PPO [improved + DR]",
]
SEEDS = [0, 1]
# PPO's smallest run: one rollout of 2 platforms x 128 steps per agent; 40-step episodes
STUDY = dict(
    train_models=["classical", "improved"],
    test_models=TEST_MODELS,
    algo="ppo",
    timesteps=200,
    n_envs=2,
    episodes=3,
    seeds=SEEDS,
    domain_randomization=True,
    simplifications=["c2"],
    max_steps=40,
    progress=False,
)


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("mismatch")
    # four PPO rows of two seeds each: eight tiny agents
    result = run_mismatch(out, **STUDY)
    return out, result


def _rows(out):
    with open(out / "matrix.csv") as f:
        return list(csv.DictReader(f))


@pytest.mark.slow  # the study fixture trains eight agents: about 20 s
def test_matrix_has_a_row_per_controller_and_a_column_per_plant(study):
    out, result = study
    labels = [r.label for r in result.rows]
    assert labels == EXPECTED_ROWS
    assert result.test_models == TEST_MODELS
    for key in ALWAYS_DEFINED:
        m = result.matrix(key)
        assert m.shape == (len(labels), len(TEST_MODELS))
        assert np.all(np.isfinite(m)), key
    lines = _rows(out)
    assert [(x["controller"], x["test_model"]) for x in lines] == [(r, m) for r in labels for m in TEST_MODELS]
    for x in lines:
        assert x["seeds"] == ("2" if x["family"] == "PPO" else "1")
        assert x["episodes"] == "3"
        for key in ALWAYS_DEFINED:
            low, value, high = (float(x[f"{key}{s}"]) for s in ("_ci_low", "", "_ci_high"))
            assert low <= value <= high, (x["controller"], x["test_model"], key)
            assert int(x[f"{key}_n"]) == 3 * int(x["seeds"])
    text = (out / "matrix.md").read_text()
    for label in labels:
        assert f"| {label} |" in text
    assert "## The cost of each simplification on the improved plant" in text
    for name in ["forest.png"] + [f"heatmap_{key}.png" for key in ALWAYS_DEFINED]:
        assert (out / name).stat().st_size > 10_000, name  # a real figure, not an empty file
    for seed in SEEDS:
        assert (out / "agents" / "improved_dr" / f"seed_{seed}" / "run.json").is_file()


@pytest.mark.slow  # the study fixture trains eight agents: about 20 s
def test_every_cell_interval_is_the_bootstrap_of_its_stored_episodes(study):
    out, result = study
    row = next(r for r in result.rows if r.label == "PPO [improved]")
    values = mismatch.cell_values(out, row, "improved", "rms_position_error")
    assert values.shape == (2, 3)  # two agents, three episodes each
    assert result.summary[row.label]["improved"]["rms_position_error"] == stratified_bootstrap(values, "iqm")
    # the two seeds are two agents: not one agent's numbers twice
    assert not np.array_equal(values[0], values[1])


@pytest.mark.slow  # the study fixture trains eight agents: about 20 s
def test_columns_are_the_plants_they_name(study):
    """improved and improved_centroidal are one dynamics in two forms: equal columns; classical
    differs.  So the columns are neither mixed up nor all the same plant."""
    _, result = study
    ct = result.summary["CT [improved]"]
    a, b = ct["improved"]["rms_position_error"].estimate, ct["improved_centroidal"]["rms_position_error"].estimate
    # the two forms agree to ~1e-13 per evaluation; 40 steps of a stable loop keep that far below 1e-9
    assert a == pytest.approx(b, rel=1e-9)
    # the classical plant's leg dynamics differ by newtons at these accelerations: far above rounding
    assert abs(ct["classical"]["rms_position_error"].estimate - a) > 1e-6 * a


@pytest.mark.slow  # the study fixture trains eight agents: about 20 s
def test_costs_of_the_simplifications(study):
    out, result = study
    costs = {(d.family, d.simplification, d.metric): d for d in result.differences if d.measure == mismatch.COST}
    families = {"PD", "CT", "PPO"}
    names = {"classical model", "C2"}
    assert set(costs) == {(f, s, m) for f in families for s in names for m in RANKING_METRICS} | {
        ("PPO", "domain randomisation", m) for m in RANKING_METRICS
    }
    # a double difference where the simplified model is a test plant: the classical model, not C2 or DR
    doubles = {
        (d.family, d.simplification, d.metric) for d in result.differences if d.measure == mismatch.DOUBLE_DIFFERENCE
    }
    assert doubles == {(f, "classical model", m) for f in families for m in RANKING_METRICS}
    # C2 is a static term: CT built on it stops off target, far outside the rounding of the exact CT
    c2 = costs["CT", "C2", "steady_state_orientation_error"]
    assert c2.resolved and c2.interval.low > 1e-5 and not c2.failed
    # untrained agents fail: marked, not ranked
    assert all(costs["PPO", s, m].failed for s in names for m in RANKING_METRICS)
    with open(out / "differences.csv") as f:
        lines = list(csv.DictReader(f))
    assert len(lines) == len(costs) + len(doubles)
    line = next(
        x
        for x in lines
        if (x["family"], x["simplification"], x["metric"], x["measure"])
        == ("CT", "C2", "steady_state_orientation_error", mismatch.COST)
    )
    assert float(line["difference"]) == pytest.approx(c2.interval.estimate, rel=1e-8)  # printed to 9 digits
    assert (line["resolved"], line["failed"], line["statistic"]) == ("1", "0", "iqm")
    assert line["seeds_to_resolve"] == ""  # resolved, and on one seed: no planning figure
    # a learned row's estimate per training seed: its cell's statistic on that seed's episodes alone
    row = next(r for r in result.rows if r.label == "PPO [improved]")
    values = mismatch.cell_values(out, row, "improved", "rms_position_error")
    per_seed = result.per_seed[row.label]["rms_position_error"]
    assert per_seed == [stratified_bootstrap(v, "iqm").estimate for v in values]
    assert set(result.per_seed) == {r.label for r in result.rows if r.kind == "agent"}
    text = (out / "matrix.md").read_text().split("## Per training seed on the improved plant")[1]
    assert "with 2 seeds a t interval on a mean of these values would be 9.2 times as wide" in text  # t 12.7
    assert text.count("| PPO [improved] |") == 2


@pytest.mark.slow  # the study fixture trains eight agents: about 20 s
def test_second_run_reuses_agents_and_cells_and_runs_only_what_is_missing(study):
    out, _ = study
    model = out / "agents" / "improved" / "seed_0" / "model.zip"
    cells = sorted((out / "cells").rglob("*.json"))
    before = {p: p.stat().st_mtime_ns for p in cells + [model]}
    removed = out / "cells" / "ct_improved" / "classical" / "model_based.json"
    removed.unlink()
    run_mismatch(out, **STUDY)
    after = {p: p.stat().st_mtime_ns for p in cells + [model]}
    assert removed.is_file()  # the missing cell ran again
    assert {p for p in before if before[p] != after[p]} == {removed}


@pytest.mark.slow  # the study fixture trains eight agents: about 20 s
def test_scale_out_is_scheduled_from_the_jobs_measured_times(study):
    out, _ = study
    times = run_mismatch(out, **STUDY).timing  # all reused: the timing of what is on disk now
    manifests = sorted((out / "agents").rglob("run.json"))
    assert len(manifests) == 8
    assert sorted(times.training) == sorted(json.loads(p.read_text())["wall_time"] for p in manifests)
    cells = sorted((out / "cells").rglob("*.json"))
    assert times.untimed_cells == 0
    assert sorted(times.evaluation) == sorted(json.loads(p.read_text())["wall_time"] for p in cells)
    assert all(t > 0 for t in times.evaluation)
    text = (out / "matrix.md").read_text().split("## Scale-out")[1]
    assert f"8 trainings, median {timing.duration(np.median(times.training))} (" in text
    assert f"{len(cells)} evaluations, median {timing.duration(np.median(times.evaluation))} (" in text
    table = [line for line in text.splitlines() if line.startswith("| ") and line[2].isdigit()]
    assert [line.split(" | ")[0] for line in table] == ["| 1", "| 2", "| 5", "| 10"]


@pytest.mark.slow  # the study fixture trains eight agents: about 20 s
def test_cells_written_without_their_time_are_named_not_projected(study, tmp_path):
    import shutil

    out, _ = study
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    cell = sorted((copy / "cells").rglob("*.json"))[0]
    stored = json.loads(cell.read_text())
    del stored["wall_time"]  # as an earlier version wrote it
    cell.write_text(json.dumps(stored))
    result = run_mismatch(copy, **STUDY)
    assert result.timing.untimed_cells == 1
    text = (copy / "matrix.md").read_text().split("## Scale-out")[1]
    assert "1 of them written without their time" in text
    assert "| 1 | " in text and text.count(" | - | - |") == 4  # no evaluation or total column


def test_durations_read_in_the_unit_they_need():
    assert [timing.duration(t) for t in (0.0123, 59.04, 894.0, 8000.0, None, math.inf)] == [
        "0.0123 s",
        "59 s",
        "14.9 min",
        "2.22 h",
        "-",
        "-",
    ]
    assert timing.describe([302.0, 894.0, 1460.0]) == "median 14.9 min (5.0 min to 24.3 min), 44.3 min in all"
    assert timing.describe([]) == "none"


def test_makespan_gives_each_job_to_the_first_free_worker_longest_first():
    assert mismatch.makespan([3, 3, 2, 2, 2], 2) == 7  # 3+2+2 | 3+2
    assert mismatch.makespan([1] * 10, 3) == 4  # ceil(10 / 3) rounds
    assert mismatch.makespan([5, 1], 10) == 5
    assert mismatch.makespan([], 4) == 0
    with pytest.raises(ValueError, match="slots"):
        mismatch.makespan([1], 0)
    times = mismatch.JobTimes(training=[300.0] * 20, evaluation=[2.0] * 60)
    rows = mismatch.scale_out(times, cpus_per_machine=2, machines=(1, 10))
    assert [(r["slots"], r["training"], r["evaluation"]) for r in rows] == [(2, 3000, 60), (20, 300, 6)]


@pytest.mark.slow  # the study fixture trains eight agents: about 20 s
def test_a_study_with_other_settings_is_refused(study):
    out, _ = study
    with pytest.raises(MismatchError, match=r"other settings(.|\n)*episodes: 3 -> 4"):
        run_mismatch(out, **{**STUDY, "episodes": 4})
    with pytest.raises(MismatchError, match="task: 'setpoint' -> 'tracking'"):
        run_mismatch(out, **{**STUDY, "task": "tracking"})


@pytest.mark.slow  # the study fixture trains eight agents: about 20 s
def test_an_agent_trained_differently_is_not_silently_reused(study, tmp_path):
    import shutil

    out, _ = study
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    (copy / mismatch.STUDY_FILE).unlink()  # settings forgotten: the agents' own records still say
    with pytest.raises(MismatchError, match="trained differently"):
        run_mismatch(copy, **{**STUDY, "env_kwargs": {"observation_noise": 0.01}})


def test_an_interrupted_study_keeps_its_finished_cells(tmp_path, monkeypatch):
    """Ctrl-C during the third evaluation: the two finished cells are on disk, whole; the next run
    computes only the rest."""
    calls = []
    evaluate = evaluation.evaluate

    def interrupted(policy, env_kwargs, **kwargs):
        calls.append(kwargs["label"])
        if len(calls) == 3:
            raise KeyboardInterrupt
        return evaluate(policy, env_kwargs, **kwargs)

    kwargs = dict(
        train_models=["improved"],
        test_models=["improved"],
        algo=None,
        episodes=1,
        simplifications=["c2"],
        max_steps=5,
        progress=False,
    )
    monkeypatch.setattr(evaluation, "evaluate", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_mismatch(tmp_path, **kwargs)
    finished = sorted((tmp_path / "cells").rglob("*.json"))
    assert len(finished) == 2 and all(json.loads(p.read_text())["metrics"] for p in finished)
    assert not list((tmp_path / "cells").rglob("*.tmp*"))
    monkeypatch.undo()
    calls.clear()
    result = run_mismatch(tmp_path, **kwargs)
    assert len(list((tmp_path / "cells").rglob("*.json"))) == len(result.rows) == 4


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"train_models": ["clasical"]}, "train models: 'clasical' is not a model"),
        ({"agent_models": ["nope"]}, "agent models: 'nope' is not a model"),
        ({"simplifications": ["c5"]}, "simplifications: unknown c5"),
        ({"env_kwargs": {"model": "classical"}}, "env kwargs: model is set by the study"),
        ({"task": "juggling"}, "task: unknown task 'juggling'"),
        ({"platform": "no_such_platform"}, "platform: "),
        ({"seeds": [0, 0]}, "seeds: each seed once"),
        ({"seeds": [-1]}, r"seeds: expected one or more integers in \[0, 4294967295\]"),
        ({"seeds": [2**32]}, r"seeds: expected one or more integers in \[0, 4294967295\]"),
        ({"max_steps": 10**7 + 1}, "max_steps: at most 10000000 control steps"),
        ({"episodes": 0}, "episodes: expected a positive integer"),
        ({"max_steps": 0}, "max_steps: expected a positive integer"),
        ({"backend": "dask"}, "backend: expected one of local, ray"),
        ({"ray_address": "auto"}, "--ray-address: only with --backend ray"),
        ({"backend": "ray", "ray_address": "localhost"}, "--ray-address: expected auto, HOST:PORT or ray://HOST:PORT"),
        ({"backend": "ray", "ray_address": "head:99999"}, "--ray-address: expected auto, HOST:PORT or ray://HOST:PORT"),
        (
            {"backend": "ray", "ray_address": "ray://:10001"},
            "--ray-address: expected auto, HOST:PORT or ray://HOST:PORT",
        ),
        ({"config": "configs/agents/ppo.yml"}, "config: only with an RL algorithm"),
        ({"position_tolerance": 0.0}, "position_tolerance: expected a finite positive number"),
        (
            {"cost_plant": "classical"},
            "cost plant: 'classical' is not one of the test models .improved.; pass --cost-plant",
        ),
        ({"orientation_tolerance": float("nan")}, "orientation_tolerance: expected a finite positive number"),
    ],
)
def test_bad_requests_are_named_before_any_work(tmp_path, kwargs, message):
    out = tmp_path / "study"
    with pytest.raises(MismatchError, match=message):
        run_mismatch(out, **{"train_models": ["improved"], "test_models": ["improved"], "algo": None, **kwargs})
    assert not (out / mismatch.STUDY_FILE).exists()


def test_an_address_where_nothing_answers_is_refused_at_once(tmp_path):
    pytest.importorskip("ray")
    with socket.socket() as probe:  # a port that was free a moment ago: connections to it are refused
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    start = time.perf_counter()
    with pytest.raises(MismatchError, match=rf"--ray-address 127.0.0.1:{port}: nothing answers there"):
        run_mismatch(
            tmp_path / "study", ["improved"], ["improved"], algo=None, backend="ray", ray_address=f"127.0.0.1:{port}"
        )
    # Ray itself would retry for ever; the study gives up after its connect timeout at most
    assert time.perf_counter() - start < mismatch.RAY_CONNECT_TIMEOUT + 5.0


def test_ray_backend_without_ray_names_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray fails as if not installed
    with pytest.raises(MismatchError, match=r"--backend ray needs ray: install the distributed extra"):
        run_mismatch(tmp_path, ["improved"], ["improved"], algo=None, backend="ray")
    assert not list(tmp_path.iterdir())


def _parser():
    parser = argparse.ArgumentParser()
    mismatch_cli.add_parser(parser.add_subparsers(dest="command"))
    return parser


@pytest.mark.parametrize(
    "flag, value, message",
    [
        ("--seeds", "0,0", "argument --seeds: expected comma-separated distinct integers"),
        ("--seeds", "4294967296", "argument --seeds: expected comma-separated distinct integers in [0, 4294967295]"),
        ("--max-steps", "99999999999", "argument --max-steps: expected an integer in [1, 10000000]"),
        ("--seeds", "a", "argument --seeds: expected comma-separated distinct integers"),
        ("--task", "juggling", "argument --task: invalid choice: 'juggling'"),
        ("--platform", "no_such_platform", "argument --platform: "),
        ("--backend", "dask", "argument --backend: invalid choice: 'dask'"),
        ("--episodes", "0", "argument --episodes: expected a positive integer"),
        ("--max-steps", "-3", "argument --max-steps: expected an integer in [1, 10000000]"),
        ("--timesteps", "x", "argument --timesteps: expected a positive integer"),
        ("--algo", "dqn", "argument --algo: invalid choice: 'dqn'"),
        ("--position-tolerance", "0", "argument --position-tolerance: expected a finite positive number"),
        ("--config", "no/such.yml", "argument --config: hyperparameter file not found: no/such.yml"),
    ],
)
def test_cli_rejects_bad_flag_values(tmp_path, capsys, flag, value, message):
    with pytest.raises(SystemExit):
        _parser().parse_args(["mismatch", "--out", str(tmp_path), flag, value])
    assert message in capsys.readouterr().err


@pytest.mark.extra("rl")
def test_cli_reports_a_failed_cluster_and_how_to_continue(tmp_path, capsys, monkeypatch):
    def lost(*args, **kwargs):
        raise mismatch.BackendError("the Ray cluster failed: LocalRayletDiedError: The task's local raylet died")

    monkeypatch.setattr(mismatch_cli, "run_mismatch", lost)
    args = _parser().parse_args(["mismatch", "--out", str(tmp_path)])
    assert args.func(args) == 1
    assert capsys.readouterr().err == (
        "stewart-env mismatch: error: the Ray cluster failed: LocalRayletDiedError: The task's local raylet died; "
        f"finished agents and cells are kept in {tmp_path} (run the same command again to continue)\n"
    )


def test_cli_model_based_rows_on_another_task_and_platform(tmp_path, capsys):
    args = _parser().parse_args(
        [
            "mismatch",
            "--train-models",
            "improved",
            "--test-models",
            "classical,improved",
            "--algo",
            "none",
            "--simplifications",
            "c1",
            "--episodes",
            "2",
            "--max-steps",
            "20",
            "--task",
            "tracking",
            "--platform",
            "motion_simulator",
            "--out",
            str(tmp_path),
            "--no-progress",
        ]
    )
    assert args.func(args) == 0
    assert "4 controllers x 2 plants" in capsys.readouterr().out
    assert len(_rows(tmp_path)) == 8
    text = (tmp_path / "matrix.md").read_text()
    assert text.startswith("# Model mismatch on the tracking task, platform motion_simulator")
    assert "ends within 2 mm and 10 mrad over its final window" in text
    settings = json.loads((tmp_path / mismatch.STUDY_FILE).read_text())
    assert settings["env_kwargs"]["platform"] == "motion_simulator" and settings["task"] == "tracking"


def _constructed_study(ppo_success: float, shift: float = 1.0):
    """CT and PPO, each on the exact model and with C2, on the improved plant, 2 seeds x 8
    episodes.  Episode errors are the same per episode for every row (the episodes' difficulty)
    plus a row's offset: CT's C2 row ``shift`` micrometres worse than its exact row; PPO's rows
    1000 times CT's, and PPO succeeds in ``ppo_success`` of the episodes."""
    rng = np.random.default_rng(0)
    difficulty = rng.lognormal(0.0, 0.5, size=(2, 8)) * 1e-6
    rows = [
        mismatch.Row(
            f"{family} [{model}]",
            family,
            model,
            "ct" if family == "CT" else "agent",
            seeds=() if family == "CT" else (0, 1),
        )
        for family in ("CT", "PPO")
        for model in ("improved", "improved+c2")
    ]
    cells = {}
    for row in rows:
        scale = 1e3 if row.family == "PPO" else 1.0
        offset = shift * 1e-6 if row.model == "improved+c2" else 0.0
        base = difficulty if row.family == "PPO" else difficulty[:1]
        cells[row.label] = {key: scale * (base + offset) for key, *_ in METRICS}
        success = ppo_success if row.family == "PPO" else 1.0
        cells[row.label]["success"] = (np.arange(base.size).reshape(base.shape) < success * base.size).astype(float)
    summary = {
        r.label: {"improved": {k: stratified_bootstrap(v, mismatch.statistic(k)) for k, v in cells[r.label].items()}}
        for r in rows
    }
    result = mismatch.MismatchResult(rows, ["improved"], summary, 8)
    result.differences = mismatch.simplification_costs(result, values=lambda r, plant, key: cells[r.label][key])
    return result


def test_resolved_costs_on_constructed_cells():
    resolved = _constructed_study(ppo_success=1.0, shift=1.0)
    ct = next(d for d in resolved.differences if d.family == "CT" and d.metric == "rms_position_error")
    # every episode 1 um worse: the paired difference is exactly that, in every resample
    assert ct.interval.estimate == pytest.approx(1e-6, rel=1e-9) and ct.resolved  # rounding of x + 1e-6 - x
    # no model offset: the same episodes give a difference of exactly zero, not resolved
    unresolved = _constructed_study(ppo_success=1.0, shift=0.0)
    assert not any(d.resolved for d in unresolved.differences)


def test_failed_agents_rank_no_simplification(tmp_path):
    settings = MismatchSettings(test_models=["improved"], algo=None)
    mismatch.write_tables(_constructed_study(ppo_success=0.25), tmp_path, settings)
    text = (tmp_path / "matrix.md").read_text()
    ct, ppo = text.split("### PPO")
    assert "steady-state pos. (mm), resolved costs, largest first: C2 (+0.001)" in ct  # CT: 1 um = 0.001 mm
    assert "none resolved; failed, not ranked: C2" in ppo
    assert "| C2: " in ppo and "*failed*" in ppo
    # at the threshold the agents count as succeeding and are ranked
    mismatch.write_tables(_constructed_study(ppo_success=0.5), tmp_path, settings)
    ppo = (tmp_path / "matrix.md").read_text().split("### PPO")[1]
    assert "failed" not in ppo and "resolved costs, largest first: C2 (+1)" in ppo


def test_text_report_draws_no_figure(tmp_path, monkeypatch):
    """matrix.md, matrix.csv and differences.csv alone: no figure is drawn (any attempt fails here)."""

    def no_figure(*args, **kwargs):
        raise AssertionError("a figure was drawn")

    monkeypatch.setattr(evaluation, "new_figure", no_figure)
    study = _constructed_study(ppo_success=1.0)
    settings = MismatchSettings(test_models=["improved"], algo=None, seeds=[0, 1])
    files = mismatch.write_outputs(study, tmp_path, settings, wall_time=3.0, figures=False)
    assert set(files) == {"csv", "markdown", "differences"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["differences.csv", "matrix.csv", "matrix.md"]
    text = files["markdown"].read_text()
    assert text.startswith("# Model mismatch on the setpoint task, platform dasgupta1998")
    assert (
        "training seeds (0, 1; one for the model-based rows) and the 8 episodes (evaluation seeds "
        "100000..100007" in text
    )
    assert text.endswith("Backend: local. Wall time of this run: 3 s.\n")
    lines = _rows(tmp_path)
    assert [(x["controller"], x["test_model"]) for x in lines] == [(r.label, "improved") for r in study.rows]
    ct = next(x for x in lines if x["controller"] == "CT [improved+c2]")
    # the CSV holds the interval in SI units to 9 digits
    interval = study.summary["CT [improved+c2]"]["improved"]["rms_position_error"]
    assert float(ct["rms_position_error"]) == pytest.approx(interval.estimate, rel=1e-8)
    assert ct["rms_position_error_n"] == "8" and ct["seeds"] == "1"
    with open(files["differences"]) as f:
        assert len(list(csv.DictReader(f))) == len(study.differences)


def test_the_study_s_errors_are_usage_errors():
    assert issubclass(MismatchError, UsageError) and issubclass(mismatch.BackendError, UsageError)
    assert not issubclass(MismatchError, TrainingError)


def test_settings_are_one_checked_frozen_record():
    settings = MismatchSettings(test_models=["improved"], algo=None, seeds=[3, 1], episodes=np.int64(2))
    assert settings.seeds == (3, 1) and type(settings.episodes) is int
    assert settings.env_kwargs == {"platform": "dasgupta1998"}
    assert settings.recorded() == {**settings.evaluation(), "algo": None, "timesteps": None, "n_envs": None}
    with pytest.raises(AttributeError):
        settings.episodes = 3  # frozen
    with pytest.raises(MismatchError, match="episodes: expected a positive integer"):
        MismatchSettings(test_models=["improved"], episodes=0)


@pytest.mark.slow  # draws the forest plot and ten heatmaps (the text-only report is tested fast above)
def test_report_with_figures_draws_the_forest_and_a_heatmap_per_metric(tmp_path):
    settings = MismatchSettings(test_models=["improved"], algo=None)
    files = mismatch.write_outputs(_constructed_study(ppo_success=0.25), tmp_path, settings)
    assert set(files) == {"csv", "markdown", "differences", "forest"} | {f"heatmap {m.key}" for m in METRICS}
    for name in ["forest.png"] + [f"heatmap_{m.key}.png" for m in METRICS]:
        assert (tmp_path / name).stat().st_size > 10_000, name  # a real figure, not an empty file


def _two_plant_cells(shift: float = 0.2) -> dict:
    """The cells of :func:`_two_plant_study`: {(row label, plant): {metric: (4 seeds, 20 episodes)}}."""
    rng = np.random.default_rng(1)
    difficulty = rng.lognormal(0.0, 0.3, size=(1, 20)) * 1e-3
    biases = {"improved": [-1.0, -0.3, 0.3, 1.0], "improved+c2": [0.9, -0.9, 0.4, -0.4]}
    cells = {}
    for model, bias in biases.items():
        for plant in biases:
            values = 5e-3 + difficulty + np.array(bias)[:, None] * 1e-3 + (shift * 1e-3 if plant != model else 0.0)
            cells[f"PPO [{model}]", plant] = {key: values for key, *_ in METRICS} | {"success": np.ones((4, 20))}
    return cells


def _two_plant_study(shift: float):
    """PPO on the exact model and with C2, 4 seeds x 20 episodes, on the improved and the
    improved+c2 plant.  Each seed has a bias (within +-1 mm) it keeps on both plants; each agent is
    ``shift`` mm worse on the other model's plant than on its own, and nothing else differs."""
    plants = ["improved", "improved+c2"]
    rows = [mismatch.Row(f"PPO [{m}]", "PPO", m, "agent", seeds=(0, 1, 2, 3)) for m in plants]
    cells = _two_plant_cells(shift)
    summary = {
        r.label: {
            p: {k: stratified_bootstrap(v, mismatch.statistic(k)) for k, v in cells[r.label, p].items()} for p in plants
        }
        for r in rows
    }
    result = mismatch.MismatchResult(rows, plants, summary, 20)
    result.differences = mismatch.simplification_costs(result, values=lambda r, plant, key: cells[r.label, plant][key])
    return result


def test_double_difference_resolves_what_the_seeds_hide():
    result = _two_plant_study(shift=0.2)
    by_measure = {d.measure: d for d in result.differences if d.metric == "rms_position_error"}
    assert set(by_measure) == {mismatch.COST, mismatch.DOUBLE_DIFFERENCE}
    cost, double = by_measure[mismatch.COST], by_measure[mismatch.DOUBLE_DIFFERENCE]
    # the seeds' 1 mm spread hides a 0.2 mm cost ...
    assert not cost.resolved and cost.interval.high - cost.interval.low > 1e-3
    # ... which each agent, compared with itself, shows both ways: 0.2 + 0.2 mm, exactly in every resample
    assert double.resolved and double.interval.estimate == pytest.approx(0.4e-3, rel=1e-9)  # rounding only
    assert double.interval.low == pytest.approx(0.4e-3, rel=1e-9)
    # no shift: zero, not resolved
    assert not any(d.resolved for d in _two_plant_study(shift=0.0).differences)


def test_every_learned_difference_gets_a_welch_test_on_its_seeds():
    from scipy.stats import ttest_ind

    result = _two_plant_study(shift=0.2)
    cost = next(d for d in result.differences if d.measure == mismatch.COST and d.metric == "rms_position_error")
    # the per-seed IQMs: 5 mm + the seed's bias + the episodes' common difficulty (+ 0.2 mm for C2 on the exact plant)
    rows = {r.model: r for r in result.rows}
    per_seed = {
        m: [
            stratified_bootstrap(v, "iqm").estimate
            for v in _two_plant_cells()[rows[m].label, "improved"]["rms_position_error"]
        ]
        for m in rows
    }
    expected = ttest_ind(per_seed["improved+c2"], per_seed["improved"], equal_var=False).pvalue
    assert cost.seed_p == pytest.approx(expected, rel=1e-12)  # the same numbers, the same test
    assert 0.05 < cost.seed_p  # the seeds' spread hides the 0.2 mm here too
    ct = _constructed_study(ppo_success=1.0).differences
    assert all(d.seed_p is None for d in ct if d.family == "CT")  # one "seed": nothing to test


def test_double_differences_are_written_apart_and_not_ranked(tmp_path):
    settings = MismatchSettings(test_models=["improved", "improved+c2"], algo=None)
    files = mismatch.write_tables(_two_plant_study(shift=0.2), tmp_path, settings)
    costs, doubles = files["markdown"].read_text().split("## Double differences on the improved plant")
    # the cost's interval at 4 seeds, sized for half the double difference, 0.2 mm
    line = next(x for x in costs.splitlines() if x.startswith("- RMS pos. err. (mm), resolved costs"))
    cost = next(
        d
        for d in _two_plant_study(shift=0.2).differences
        if d.measure == mismatch.COST and d.metric == "rms_position_error"
    )
    seeds = math.ceil(4 * (0.5 * (cost.interval.high - cost.interval.low) / 0.2e-3) ** 2)
    assert seeds > 4 and line.endswith(
        f"not resolved: C2 (about {seeds} seeds a row would resolve it, at half the double difference, 0.2)."
    )
    assert "**0.4 [0.4, 0.4]**" in doubles and "largest first" not in doubles
    with open(files["differences"]) as f:
        lines = list(csv.DictReader(f))
    assert {x["measure"] for x in lines} == {mismatch.COST, mismatch.DOUBLE_DIFFERENCE}
    assert all(x["seeds_to_resolve"] == "" for x in lines if x["resolved"] == "1")
    fig = mismatch.forest_figure(_two_plant_study(shift=0.2), METRICS)
    assert [t.get_text() for t in fig.axes[0].get_yticklabels()] == ["PPO: C2", "PPO: C2 (double diff.)"]


def test_forest_plot_draws_every_cost():
    result = _constructed_study(ppo_success=0.25)
    fig = mismatch.forest_figure(result, METRICS)
    assert len(fig.axes) == len(RANKING_METRICS)
    ax = fig.axes[0]
    assert [t.get_text() for t in ax.get_yticklabels()] == ["CT: C2", "PPO: C2"]
    markers = [line for line in ax.get_lines() if line.get_marker() in ("o", "x")]
    # CT resolved: a filled red dot; PPO failed: a grey cross
    assert [(m.get_marker(), m.get_color()) for m in markers] == [("o", "C3"), ("x", "0.6")]


def test_heatmap_hatches_failed_cells_outside_the_colour_scale():
    study = _constructed_study(ppo_success=0.25)
    metric = next(m for m in METRICS if m.key == "steady_state_position_error")
    fig = mismatch.heatmap_figure(study, metric)
    ax = fig.axes[0]
    image = ax.get_images()[0]
    failed = np.array([[False], [False], [True], [True]])  # the PPO rows
    np.testing.assert_array_equal(np.ma.getmaskarray(image.get_array()), failed)
    # the colour scale spans the CT cells only: the failed agents' larger errors are not "worst"
    ct = study.matrix("steady_state_position_error")[:2, 0] * 1e3
    assert image.norm.vmin == pytest.approx(ct.min()) and image.norm.vmax == pytest.approx(ct.max())
    assert len([p for p in ax.patches if p.get_hatch()]) == 2
    assert [t.get_text().startswith("failed (") for t in ax.texts] == [False, False, True, True]


@pytest.mark.slow  # the study fixture trains eight agents: about 20 s
def test_a_row_stopped_while_training_continues_from_its_checkpoint(study, tmp_path):
    import shutil

    from stewart_env.agents.training import MODEL_FILE, VECNORMALIZE_FILE, newest_checkpoint, read_manifest

    out, _ = study
    row = tmp_path / "improved"
    shutil.copytree(out / "agents" / "improved" / "seed_0", row)
    # what a stop during the row's training leaves: the run and its checkpoint, no final model
    (row / MODEL_FILE).unlink()
    (row / VECNORMALIZE_FILE).unlink(missing_ok=True)
    manifest = read_manifest(row)
    steps, _ = newest_checkpoint(row, "ppo", bool(manifest["normalize"]))
    training = dict(
        algo="ppo",
        model=manifest["model"],
        task=manifest["task"],
        seed=manifest["seed"],
        n_envs=2,
        checkpoint_freq=0,
        env_kwargs={k: v for k, v in manifest["env_kwargs"].items() if k not in ("model", "task")},
    )
    with pytest.raises(TrainingError, match="seed"):  # a row of another seed is not continued silently
        mismatch.train_agent(row, {**training, "seed": manifest["seed"] + 1}, steps + 1)
    mismatch.train_agent(row, training, steps + 1)
    assert (row / MODEL_FILE).is_file()
    assert read_manifest(row)["num_timesteps"] > steps  # it trained on from the checkpoint, not from scratch
    assert read_manifest(row)["segments"][-1]["start"] == steps


def test_interval_formatting():
    assert mismatch.format_interval(Interval(1e-3, 5e-4, 2e-3, 1, 5), 1e3, ".3g") == "1 [0.5, 2]"
    assert mismatch.format_interval(Interval(float("nan"), float("nan"), float("nan"), 1, 5), 1e3, ".3g") == "-"


def test_agent_models_pick_the_learned_rows(tmp_path):
    rows = mismatch.build_rows(
        tmp_path,
        ["classical", "improved", "improved+c2"],
        "ppo",
        [0, 3],
        True,
        "dasgupta1998",
        agent_models=["improved"],
    )
    assert [r.label for r in rows if r.kind == "agent"] == ["PPO [improved]", "PPO [improved + DR]"]
    assert [r.label for r in rows if r.kind == "ct"] == ["CT [classical]", "CT [improved]", "CT [improved+c2]"]
    agent = next(r for r in rows if r.kind == "agent")
    assert agent.seeds == (0, 3) and agent.agents[3] == tmp_path / "agents" / "improved" / "seed_3"


@pytest.mark.extra("rl")
def test_config_file_is_part_of_the_study(tmp_path):
    """The agents' hyperparameters go into study.json; a bad config fails before any work."""
    from stewart_env.agents.training import config_path

    bad = tmp_path / "bad.yml"
    bad.write_text("SomethingElse-v0: {}\n")
    with pytest.raises(TrainingError, match="StewartPlatform-v1"):
        run_mismatch(tmp_path / "study", ["improved"], ["improved"], algo="ppo", config=bad)
    assert not (tmp_path / "study").exists()
    parser_args = _parser().parse_args(
        ["mismatch", "--out", str(tmp_path), "--config", str(config_path("ppo", None).with_name("ppo_integral_6m.yml"))]
    )
    assert parser_args.config.endswith("ppo_integral_6m.yml")
    # the agents train on the config's environment: ppo_integral_6m.yml observes the error integral
    run_mismatch(
        tmp_path / "integral",
        ["improved"],
        ["improved"],
        algo="ppo",
        timesteps=100,
        n_envs=2,
        episodes=1,
        simplifications=[],
        max_steps=5,
        config=parser_args.config,
        progress=False,
    )
    manifest = json.loads((tmp_path / "integral" / "agents" / "improved" / "seed_0" / "run.json").read_text())
    assert manifest["env_kwargs"]["error_integral"] is True
    settings = json.loads((tmp_path / "integral" / mismatch.STUDY_FILE).read_text())
    assert settings["config"]["hyperparameters"]["env_kwargs"]["error_integral_band"] == 0.01


@pytest.mark.slow  # trains an agent in MuJoCo and steps MuJoCo plants: about 20-45 s
def test_mujoco_as_a_test_plant_and_a_training_model(tmp_path):
    """Cross-engine: CT on each closed-form model and an agent trained in MuJoCo, run on MuJoCo's
    plant and on the exact one; the costs measured on the MuJoCo plant."""
    pytest.importorskip("mujoco")
    result = run_mismatch(
        tmp_path,
        ["classical", "improved"],
        ["improved", "mujoco"],
        algo="ppo",
        timesteps=100,
        n_envs=2,
        episodes=2,
        simplifications=[],
        max_steps=10,
        agent_models=["mujoco"],
        cost_plant="mujoco",
        progress=False,
    )
    labels = [r.label for r in result.rows]
    # no PD or CT row is built on MuJoCo (it has no closed-form inverse dynamics); an agent is trained in it
    assert labels == [
        "PD + gravity comp. [classical]",
        "PD + gravity comp. [improved]",
        "CT [classical]",
        "CT [improved]",
        "PPO [mujoco]",
    ]
    ct = result.summary["CT [improved]"]
    # MuJoCo is another simulation of the same mechanism: close to the exact plant, not equal to it
    a, b = ct["improved"]["rms_position_error"].estimate, ct["mujoco"]["rms_position_error"].estimate
    assert a != b and b == pytest.approx(a, rel=0.05)  # soft loop closure: errors differ by far less than 5 %
    assert {d.plant for d in result.differences} == {"mujoco"}
    assert "## The cost of each simplification on the mujoco plant" in (tmp_path / "matrix.md").read_text()
    manifest = json.loads((tmp_path / "agents" / "mujoco" / "seed_0" / "run.json").read_text())
    assert manifest["model"] == "mujoco"


def test_help_formats(capsys):
    with pytest.raises(SystemExit):
        _parser().parse_args(["mismatch", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "--position-tolerance" in text and "fewer than 50% of its episodes" in text
    assert "(95 % intervals)" in text and "%%" not in text


@pytest.mark.slow  # the study fixture trains eight agents: about 20 s
def test_an_agent_stopped_by_a_signal_is_continued_not_reused(study, tmp_path):
    """A signal stops training with a checkpoint and a model.zip, and run.json says finished: false;
    such an agent is trained on, not evaluated as finished."""
    import shutil

    from stewart_env.agents.training import MANIFEST, read_manifest

    out, _ = study
    row = tmp_path / "seed_0"
    shutil.copytree(out / "agents" / "improved" / "seed_0", row)
    manifest = read_manifest(row)
    env_kwargs = manifest["env_kwargs"]
    assert mismatch.finished_agent(row, "ppo", 0, env_kwargs)
    (row / MANIFEST).write_text(json.dumps({**manifest, "finished": False}))
    assert not mismatch.finished_agent(row, "ppo", 0, env_kwargs)


def test_plant_model_name_takes_mujoco_and_names_it_when_refusing():
    from stewart_env.cli.arguments import plant_model_name
    from stewart_env.dynamics import ModelSpec, Switch

    assert plant_model_name("mujoco") == "mujoco"
    assert plant_model_name("Improved+C2") == ModelSpec("improved", Switch.C2)  # the spec, parsed once
    with pytest.raises(argparse.ArgumentTypeError, match="or 'mujoco' .MuJoCo simulating the same mechanism."):
        plant_model_name("mujoko")
