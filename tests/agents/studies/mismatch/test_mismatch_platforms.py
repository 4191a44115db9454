"""Controllers built on another platform than the plant's (``--controller-platform``, e.g. an
identified platform): their rows, their costs and shares, and the checks of the flag."""

from __future__ import annotations

import argparse
import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from stewart_env.agents.evaluation.statistics import share_removed
from stewart_env.agents.studies import mismatch
from stewart_env.agents.studies.mismatch import MismatchError, MismatchSettings, run_mismatch
from stewart_env.agents.studies.mismatch.rows import build_rows, training_keywords
from stewart_env.cli import mismatch as mismatch_cli

CONFIG_DIR = Path(__file__).resolve().parents[4] / "configs" / "platforms"
# CT only, on the truth's plant: 2 episodes of 40 steps per cell
TINY = dict(
    train_models=["classical", "improved"],
    test_models=["improved"],
    task="tracking",
    algo=None,
    simplifications=(),
    episodes=2,
    max_steps=40,
    progress=False,
)


def _platform(path: Path, platform_mass: float) -> Path:
    """A copy of dasgupta1998 with another platform mass (kg): a stand-in for a perturbed truth or
    an identified platform."""
    text = (CONFIG_DIR / "dasgupta1998.yaml").read_text()
    assert "  mass: 40.0 " in text
    path.write_text(text.replace("  mass: 40.0 ", f"  mass: {platform_mass} ", 1))
    return path


@pytest.fixture
def platforms(tmp_path):
    """truth.yaml (platform 44 kg), identified.yaml (the truth's own parameters: a perfect
    identification), nominal.yaml (the shipped 40 kg)."""
    truth = _platform(tmp_path / "truth.yaml", 44.0)
    identified = tmp_path / "identified.yaml"
    shutil.copyfile(truth, identified)
    return truth, identified, _platform(tmp_path / "nominal.yaml", 40.0)


def _rows(out):
    with open(out / "matrix.csv") as f:
        return {r["controller"]: r for r in csv.DictReader(f)}


@pytest.mark.slow  # twelve rows of two short episodes: about 10-30 s on a loaded 2-core machine
def test_ct_on_an_identified_platform_is_compared_on_the_truth_s_plant(tmp_path, platforms):
    truth, identified, nominal = platforms
    out = tmp_path / "study"
    result = run_mismatch(
        out, platform=str(truth), controller_platforms=[f"identified={identified}", str(nominal)], **TINY
    )
    labels = [r.label for r in result.rows]
    assert labels == [
        "PD + gravity comp. [classical]",
        "PD + gravity comp. [improved]",
        "CT [classical]",
        "CT [improved]",
        "PD + gravity comp. [classical @ identified]",
        "PD + gravity comp. [improved @ identified]",
        "CT [classical @ identified]",
        "CT [improved @ identified]",
        "PD + gravity comp. [classical @ nominal]",
        "PD + gravity comp. [improved @ nominal]",
        "CT [classical @ nominal]",
        "CT [improved @ nominal]",
    ]
    rows = _rows(out)
    assert set(rows) == set(labels)
    # the identified platform is the truth's parameters: the same controller, the same episodes, bit for bit
    for key in ("rms_position_error", "peak_leg_force", "control_energy"):
        assert rows["CT [improved @ identified]"][key] == rows["CT [improved]"][key]
    # the nominal platform's 4 kg too little leaves CT a steady error in height that the exact model has not
    assert float(rows["CT [improved @ nominal]"]["rms_position_error"]) > 5 * float(
        rows["CT [improved]"]["rms_position_error"]
    )
    spec = json.loads((out / "cells" / "ct_improved_identified" / "improved" / "model_based.json").read_text())["spec"]
    assert spec["design_platform"] == str(identified) and spec["env_kwargs"]["platform"] == str(truth)
    # the plain rows' cells name no controller platform: studies from before it resume unchanged
    assert (
        "design_platform"
        not in json.loads((out / "cells" / "ct_improved" / "improved" / "model_based.json").read_text())["spec"]
    )

    shares = {
        (d.family, d.simplification, d.metric): d for d in result.differences if d.measure == mismatch.SHARE_REMOVED
    }
    costs = {(d.family, d.simplification, d.metric): d for d in result.differences if d.measure == mismatch.COST}
    assert costs["CT", "platform identified", "rms_position_error"].interval.estimate == 0.0
    # a perfect identification removes all of the classical model's cost, in every resample
    share = shares["CT", "platform identified", "rms_position_error"].interval
    assert (share.estimate, share.low, share.high) == pytest.approx((1.0, 1.0, 1.0), rel=1e-12)  # rounding only
    assert costs["CT", "platform nominal", "rms_position_error"].interval.estimate > 0
    text = (out / "matrix.md").read_text()
    assert "## Share of the classical model's cost removed on the improved plant" in text
    assert "| platform identified | 100 [100, 100] |" in text
    recorded = json.loads((out / mismatch.STUDY_FILE).read_text())["controller_platforms"]
    assert [(p["name"], p["platform"]) for p in recorded] == [
        ("identified", str(identified)),
        ("nominal", str(nominal)),
    ]


@pytest.mark.extra("rl")
def test_resuming_with_another_controller_platform_is_refused(tmp_path, platforms):
    truth, identified, nominal = platforms
    out = tmp_path / "study"
    kwargs = {**TINY, "train_models": ["improved"], "max_steps": 5, "episodes": 1}
    run_mismatch(out, platform=str(truth), controller_platforms=[f"identified={identified}"], **kwargs)
    for other in ([f"identified={nominal}"], [], [f"identified={identified}", str(nominal)]):
        with pytest.raises(MismatchError, match="holds a study with other settings(.|\n)*controller_platforms"):
            run_mismatch(out, platform=str(truth), controller_platforms=other, **kwargs)
    # the same file identified again, with other numbers: its cells would mean something else
    _platform(identified, 43.0)
    with pytest.raises(MismatchError, match="controller_platforms"):
        run_mismatch(out, platform=str(truth), controller_platforms=[f"identified={identified}"], **kwargs)


def test_studies_without_controller_platforms_record_what_they_did():
    assert "controller_platforms" not in MismatchSettings(algo=None).recorded()


def _parser():
    parser = argparse.ArgumentParser()
    mismatch_cli.add_parser(parser.add_subparsers(dest="command"))
    return parser


@pytest.mark.parametrize("value", ["no/such.yaml", "no_such_platform", "bad name=dasgupta1998"])
def test_cli_refuses_a_controller_platform_that_does_not_load_in_one_line(tmp_path, capsys, value):
    from stewart_env.cli import main

    with pytest.raises(SystemExit) as stop:  # refused while the command line is parsed, before any work
        main(
            [
                "mismatch",
                "--algo",
                "none",
                "--controller-platform",
                value,
                "--out",
                str(tmp_path / "out"),
                "--no-progress",
            ]
        )
    assert stop.value.code == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]  # argparse's usage lines, then the error
    assert last.startswith("stewart-env mismatch: error: argument --controller-platform: "), last
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    "platforms, message",
    [
        (["dasgupta1998", "dasgupta1998"], "two platforms named 'dasgupta1998'"),
        (["a=dasgupta1998", "A=motion_simulator"], "two platforms named 'A'"),  # one file name for their rows
        ([(".hidden", "dasgupta1998")], "cannot name a platform"),
        ("dasgupta1998", "expected a list of platforms"),
        ([3], "expected NAME=PLATFORM or PLATFORM"),
        (["c2=dasgupta1998"], "makes the rows of improved on it share their files"),  # [improved @ c2], [improved+c2]
    ],
)
def test_controller_platforms_are_checked(platforms, message):
    with pytest.raises(MismatchError, match=message):
        MismatchSettings(algo=None, controller_platforms=platforms)


def test_an_agent_on_a_controller_platform_is_trained_on_it(tmp_path):
    settings = MismatchSettings(algo="ppo", controller_platforms=["sim=motion_simulator"], simplifications=())
    rows = build_rows(
        tmp_path,
        settings.design_models,
        "ppo",
        (0,),
        False,
        settings.platform,
        None,
        settings.controller_platforms,
        settings.train_models,
    )
    agent = next(r for r in rows if r.label == "PPO [improved @ sim]")
    assert agent.agents[0] == tmp_path / "agents" / "improved_sim" / "seed_0"
    training = training_keywords("ppo", agent, 0, settings.env_kwargs, "setpoint", None)
    assert (
        training["env_kwargs"]["platform"] == "motion_simulator" and settings.env_kwargs["platform"] == "dasgupta1998"
    )


def test_share_removed_on_constructed_cells():
    rng = np.random.default_rng(0)
    exact = rng.lognormal(size=(1, 16))
    # the classical row 2 above the exact one in every episode, the identified one 0.5 above
    share = share_removed(exact + 2.0, exact + 0.5, exact, "iqm")
    assert (share.estimate, share.low, share.high) == pytest.approx((0.75, 0.75, 0.75), rel=1e-12)  # rounding only


@pytest.mark.slow  # trains two tiny PPO agents: about 15 s
@pytest.mark.filterwarnings("ignore:You have specified a mini-batch size:UserWarning")
def test_an_agent_on_a_controller_platform_runs_on_the_truth_s_plant(tmp_path, platforms):
    truth, identified, _ = platforms
    out = tmp_path / "study"
    kwargs = dict(
        platform=str(truth),
        controller_platforms=[f"identified={identified}"],
        train_models=["improved"],
        test_models=["improved"],
        algo="ppo",
        timesteps=200,
        n_envs=2,
        simplifications=(),
        episodes=1,
        max_steps=10,
        progress=False,
    )
    result = run_mismatch(out, **kwargs)
    assert [r.label for r in result.rows if r.kind == "agent"] == ["PPO [improved]", "PPO [improved @ identified]"]
    run = json.loads((out / "agents" / "improved_identified" / "seed_0" / "run.json").read_text())
    assert run["env_kwargs"]["platform"] == str(identified)
    cell = json.loads((out / "cells" / "ppo_improved_identified" / "improved" / "seed_0.json").read_text())
    assert cell["spec"]["env_kwargs"]["platform"] == str(truth)
    # a second run finds the agent trained on the controller platform finished: nothing is trained again
    before = (out / "agents" / "improved_identified" / "seed_0" / "model.zip").stat().st_mtime_ns
    run_mismatch(out, **kwargs)
    assert (out / "agents" / "improved_identified" / "seed_0" / "model.zip").stat().st_mtime_ns == before
