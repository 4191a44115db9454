"""The model-mismatch study on a tiny budget: the matrix's shape, its entries, its files."""

from __future__ import annotations

import argparse
import csv

import numpy as np
import pytest

# PPO runs here are a rollout or two of 2 platforms, smaller than the config's minibatch on purpose.
pytestmark = pytest.mark.filterwarnings("ignore:You have specified a mini-batch size:UserWarning")

from stewart_env.agents import mismatch  # noqa: E402
from stewart_env.agents.mismatch import run_mismatch  # noqa: E402
from stewart_env.agents.training import TrainingError  # noqa: E402
from stewart_env.dynamics.model import SIMPLIFICATIONS  # noqa: E402

TEST_MODELS = ["classical", "improved", "improved_centroidal"]
# Metrics defined for every episode (settling time and overshoot are NaN by definition when an
# episode never settles, as in 40 steps of an untrained agent).
ALWAYS_DEFINED = ("success", "rms_position_error", "rms_orientation_error", "steady_state_position_error",
                  "steady_state_orientation_error", "peak_leg_force", "control_energy")
EXPECTED_ROWS = ["PD + gravity comp.", "CT [classical]", "CT [improved]", "CT [improved+c2]",
                 "PPO [classical]", "PPO [improved]", "PPO [improved+c2]", "PPO [improved + DR]"]


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("mismatch")
    # PPO's smallest run: one rollout of 2 platforms x 128 steps per agent; 40-step episodes
    result = run_mismatch(out, ["classical", "improved"], TEST_MODELS, algo="ppo", timesteps=200, n_envs=2,
                          episodes=2, seed=0, domain_randomization=True, simplifications=["c2"], max_steps=40,
                          progress=False)
    return out, result


def test_matrix_has_a_row_per_controller_and_a_column_per_plant(study):
    out, result = study
    assert [r.label for r in result.rows] == EXPECTED_ROWS
    assert result.test_models == TEST_MODELS
    for key in ALWAYS_DEFINED:
        m = result.matrix(key)
        assert m.shape == (len(EXPECTED_ROWS), len(TEST_MODELS))
        assert np.all(np.isfinite(m)), key

    with open(out / "matrix.csv") as f:
        lines = list(csv.DictReader(f))
    assert len(lines) == len(EXPECTED_ROWS) * len(TEST_MODELS)
    assert [(x["controller"], x["test_model"]) for x in lines] == [(r, m) for r in EXPECTED_ROWS for m in TEST_MODELS]
    for x in lines:
        for key in ALWAYS_DEFINED:
            assert np.isfinite(float(x[key])), (x["controller"], x["test_model"], key)

    text = (out / "matrix.md").read_text()
    for label in EXPECTED_ROWS:
        assert f"| {label} |" in text
    assert "Which simplification costs most: CT" in text and f"| C2: {SIMPLIFICATIONS['c2']} |" in text
    for key in ALWAYS_DEFINED:
        assert (out / f"heatmap_{key}.png").stat().st_size > 10_000, key  # a real figure, not an empty file
    assert (out / "agents" / "improved_dr" / "run.json").is_file()


def test_columns_are_the_plants_they_name(study):
    """improved and improved_centroidal are one dynamics in two forms: equal columns; classical
    differs.  So the columns are neither mixed up nor all the same plant."""
    _, result = study
    ct = result.summary["CT [improved]"]
    a, b = ct["improved"]["rms_position_error"], ct["improved_centroidal"]["rms_position_error"]
    # the two forms agree to ~1e-13 per evaluation; 40 steps of a stable loop keep that far below 1e-9
    assert a == pytest.approx(b, rel=1e-9)
    # the classical plant's leg dynamics differ by newtons at these accelerations: far above rounding
    assert abs(ct["classical"]["rms_position_error"] - a) > 1e-6 * a


def test_second_run_loads_the_agents_instead_of_training(study):
    out, _ = study
    model = out / "agents" / "classical" / "model.zip"
    before = model.stat().st_mtime_ns
    again = run_mismatch(out, ["classical"], ["improved"], algo="ppo", timesteps=200, n_envs=2, episodes=1,
                         simplifications=[], max_steps=5, progress=False)
    assert model.stat().st_mtime_ns == before
    assert [r.label for r in again.rows] == ["PD + gravity comp.", "CT [classical]", "PPO [classical]"]


@pytest.mark.parametrize("change", [{"env_kwargs": {"observation_noise": 0.01}}, {"seed": 1}, {"algo": "sac"}])
def test_an_agent_trained_differently_is_not_silently_reused(study, change):
    out, _ = study
    kwargs = {"algo": "ppo", "episodes": 1, "simplifications": [], "max_steps": 5, "progress": False, **change}
    with pytest.raises(TrainingError, match="trained differently"):
        run_mismatch(out, ["classical"], ["improved"], **kwargs)


def test_bad_requests_are_named(tmp_path):
    with pytest.raises(TrainingError, match="'clasical' is not a dynamics model"):
        run_mismatch(tmp_path, ["clasical"], ["improved"], algo=None)
    with pytest.raises(TrainingError, match="unknown c5"):
        run_mismatch(tmp_path, ["improved"], ["improved"], algo=None, simplifications=["c5"])
    with pytest.raises(TrainingError, match="set by the study"):
        run_mismatch(tmp_path, ["improved"], ["improved"], algo=None, env_kwargs={"model": "classical"})


def test_cli_model_based_rows_only(tmp_path, capsys):
    parser = argparse.ArgumentParser()
    mismatch.add_cli(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["mismatch", "--train-models", "improved", "--test-models", "classical,improved",
                              "--algo", "none", "--simplifications", "c1", "--episodes", "1", "--out",
                              str(tmp_path), "--no-progress"])
    # the full 500-step episodes: the CLI has no episode-length flag
    assert args.func(args) == 0
    assert "3 controllers x 2 plants" in capsys.readouterr().out
    with open(tmp_path / "matrix.csv") as f:
        assert len(list(csv.DictReader(f))) == 6


def _small_study(ppo_success: float) -> mismatch.MismatchResult:
    """CT and PPO, each on the exact model and with C2, on the improved plant; CT succeeds, PPO
    succeeds in ``ppo_success`` of the episodes with errors 1000 times CT's."""
    from stewart_env.agents.evaluation import METRICS

    rows = [mismatch.Row(f"{family} [{model}]", family, model) for family in ("CT", "PPO")
            for model in ("improved", "improved+c2")]
    summary = {}
    for row in rows:
        scale = 1e3 if row.family == "PPO" else 1.0
        scale *= 2.0 if row.model == "improved+c2" else 1.0
        metrics = {key: 1e-6 * scale for key, *_ in METRICS}
        metrics["success"] = ppo_success if row.family == "PPO" else 1.0
        summary[row.label] = {"improved": metrics}
    return mismatch.MismatchResult(rows, ["improved"], summary, 4)


def test_failed_agents_rank_no_simplification(tmp_path):
    from stewart_env.agents.evaluation import METRICS

    header = {"task": "setpoint", "eval_seed": 100_000, "wall_time": 1.0}
    mismatch.write_outputs(_small_study(ppo_success=0.25), tmp_path, METRICS, header)
    text = (tmp_path / "matrix.md").read_text()
    ct, ppo = text.split("## Which simplification costs most: PPO")
    assert "costliest first: C2 x2" in ct  # CT succeeds: its ranking stands
    assert "**Warning: no ranking.** PPO [improved], PPO [improved+c2] succeed in fewer than 50%" in ppo
    assert "costliest first" not in ppo
    # at the threshold the agents count as succeeding and are ranked
    mismatch.write_outputs(_small_study(ppo_success=0.5), tmp_path, METRICS, header)
    assert "Warning" not in (tmp_path / "matrix.md").read_text()


def test_heatmap_hatches_failed_cells_outside_the_colour_scale():
    study = _small_study(ppo_success=0.25)
    fig = mismatch.heatmap_figure(study, "steady_state_position_error", "steady-state pos. (mm)", 1e3, ".3g")
    ax = fig.axes[0]
    image = ax.get_images()[0]
    failed = np.array([[False], [False], [True], [True]])  # the PPO rows
    np.testing.assert_array_equal(np.ma.getmaskarray(image.get_array()), failed)
    # the colour scale spans the CT cells only (1e-3 and 2e-3 mm): the failed 1 and 2 mm are not "worst"
    assert image.norm.vmin == pytest.approx(1e-3) and image.norm.vmax == pytest.approx(2e-3)
    hatched = [p for p in ax.patches if p.get_hatch()]
    assert len(hatched) == 2
    cells = [t.get_text() for t in ax.texts]
    assert cells == ["0.001", "0.002", "failed (1)", "failed (2)"]
    assert "hatched: failed (success < 50%)" in ax.get_title()


def test_a_row_stopped_while_training_continues_from_its_checkpoint(study, tmp_path):
    import shutil

    from stewart_env.agents.training import MODEL_FILE, VECNORMALIZE_FILE, newest_checkpoint, read_manifest

    out, _ = study
    row = tmp_path / "improved"
    shutil.copytree(out / "agents" / "improved", row)
    # what a stop during the row's training leaves: the run and its checkpoint, no final model
    (row / MODEL_FILE).unlink()
    (row / VECNORMALIZE_FILE).unlink(missing_ok=True)
    manifest = read_manifest(row)
    steps, _ = newest_checkpoint(row, "ppo", bool(manifest["normalize"]))
    with pytest.raises(TrainingError, match="seed"):  # a row of another seed is not continued silently
        mismatch._agent("ppo", row, manifest["env_kwargs"], steps + 1, manifest["seed"] + 1, None, False)
    agent = mismatch._agent("ppo", row, manifest["env_kwargs"], steps + 1, manifest["seed"], None, False)
    assert (row / MODEL_FILE).is_file()
    assert agent.num_timesteps > steps  # it trained on from the checkpoint, not from scratch
    assert read_manifest(row)["segments"][-1]["start"] == steps
