"""The mismatch study's LQR and MPC rows (``--controllers``): built on the classical model, on a
switch and on an identified platform, with their costs and intervals."""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import pytest

from stewart_env.agents.studies import mismatch
from stewart_env.agents.studies.mismatch import MismatchError, MismatchSettings, run_mismatch
from stewart_env.agents.studies.mismatch.rows import build_rows

from conftest import exit_code

CONFIG_DIR = Path(__file__).resolve().parents[4] / "configs" / "platforms"


@pytest.mark.slow  # eight rows of two short episodes, the MPC solving a QP a step: 10-40 s on a loaded machine
@pytest.mark.extra("mpc")
def test_lqr_and_mpc_rows_on_the_classical_model_a_switch_and_an_identified_platform(tmp_path):
    truth = tmp_path / "truth.yaml"
    text = (CONFIG_DIR / "dasgupta1998.yaml").read_text()
    assert "  mass: 40.0 " in text
    truth.write_text(text.replace("  mass: 40.0 ", "  mass: 44.0 ", 1))
    identified = tmp_path / "identified.yaml"
    shutil.copyfile(truth, identified)  # a perfect identification of the truth
    out = tmp_path / "study"
    result = run_mismatch(
        out,
        train_models=["classical", "improved"],
        test_models=["improved"],
        task="tracking",
        algo=None,
        simplifications=("c1",),
        episodes=2,
        max_steps=40,
        platform=str(truth),
        controller_platforms=[f"identified={identified}"],
        controllers=["lqr", "mpc"],
        progress=False,
    )
    labels = [r.label for r in result.rows]
    assert labels == [
        "LQR [classical]",
        "LQR [improved]",
        "LQR [improved+c1]",
        "MPC [classical]",
        "MPC [improved]",
        "MPC [improved+c1]",
        "LQR [classical @ identified]",
        "LQR [improved @ identified]",
        "MPC [classical @ identified]",
        "MPC [improved @ identified]",
    ]
    assert {r.family for r in result.rows} == {"LQR", "MPC"}
    with open(out / "matrix.csv") as f:
        rows = {r["controller"]: r for r in csv.DictReader(f)}
    # the identified platform is the truth's parameters: the same controller, the same episodes, bit for bit
    for label in ("LQR", "MPC"):
        assert (
            rows[f"{label} [improved @ identified]"]["rms_position_error"]
            == rows[f"{label} [improved]"]["rms_position_error"]
        )
    costs = {(d.family, d.simplification, d.metric): d for d in result.differences if d.measure == mismatch.COST}
    for family in ("LQR", "MPC"):
        for simplification in ("classical model", "platform identified"):
            interval = costs[family, simplification, "rms_position_error"].interval
            assert interval.low <= interval.estimate <= interval.high
        assert costs[family, "platform identified", "rms_position_error"].interval.estimate == 0.0
    assert "| LQR [classical] |" in (out / "matrix.md").read_text()


def test_default_rows_are_pd_and_ct_and_the_controllers_order_them(tmp_path):
    models = MismatchSettings(test_models=["improved"], algo=None).design_models[:2]
    default = [r.label for r in build_rows(tmp_path, models, None, (0,), False, "dasgupta1998")]
    assert default == [
        "PD + gravity comp. [classical]",
        "PD + gravity comp. [improved]",
        "CT [classical]",
        "CT [improved]",
    ]
    chosen = build_rows(tmp_path, models, None, (0,), False, "dasgupta1998", controllers=("mpc", "pd"))
    assert [(r.label, r.kind, r.family) for r in chosen] == [
        ("MPC [classical]", "mpc", "MPC"),
        ("MPC [improved]", "mpc", "MPC"),
        ("PD + gravity comp. [classical]", "pd", "PD"),
        ("PD + gravity comp. [improved]", "pd", "PD"),
    ]


def test_bad_controllers_are_named():
    with pytest.raises(MismatchError, match=r"controllers: unknown 'nmpc'; choose from pd, ct, lqr, mpc"):
        MismatchSettings(test_models=["improved"], algo=None, controllers=["ct", "nmpc"])
    with pytest.raises(MismatchError, match="controllers: ct given twice"):
        MismatchSettings(test_models=["improved"], algo=None, controllers=["ct", "ct"])
    assert MismatchSettings(test_models=["improved"], algo=None, controllers="lqr").controllers == ("lqr",)


def test_cli_controllers_flag(tmp_path, capsys):
    assert exit_code(["mismatch", "--out", str(tmp_path / "a"), "--algo", "none", "--controllers", "nmpc"]) == 2
    assert "argument --controllers: invalid choice: 'nmpc'" in capsys.readouterr().err
    assert exit_code(["mismatch", "--out", str(tmp_path / "b"), "--algo", "none", "--controllers", "ct", "ct"]) == 2
    assert "argument --controllers: ct given twice" in capsys.readouterr().err
