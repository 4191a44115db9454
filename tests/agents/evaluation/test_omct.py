"""The OMCT on the whole chain (``stewart_env.agents.evaluation.omct``) and its command,
``stewart-env evaluate --task cueing --omct``: a sine per channel and frequency, fitted."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from stewart_env.agents.controllers.washout import WashoutPolicy
from stewart_env.agents.evaluation.cueing import environment_chain, sine_motion
from stewart_env.agents.evaluation.omct import OMCT_COLUMNS, omct_markdown, omct_rows, write_omct
from stewart_env.cli import main


def washout(env):
    return WashoutPolicy(env, "washout")


class HoldHome:
    """A pose-mode policy that commands home all the time."""

    def predict(self, obs, deterministic=True):
        return np.zeros(6, dtype=np.float32), None


@pytest.fixture(scope="module")
def washout_rows():
    # a short budget: 2 s to settle, one period at each of two high frequencies
    return omct_rows(washout, {"action_mode": "pose"}, ("omega_z", "f_y"), (10.0, 15.849), periods=1.0, settle=2.0)


def test_rows_hold_each_channel_and_frequency_once(washout_rows):
    assert [(r["channel"], r["frequency"]) for r in washout_rows] == [
        ("omega_z", 10.0),
        ("omega_z", 15.849),
        ("f_y", 10.0),
        ("f_y", 15.849),
    ]
    assert all(set(OMCT_COLUMNS) <= set(r) for r in washout_rows)
    assert all(r["played"] == 1.0 for r in washout_rows)


def test_yaw_is_cued_near_the_washout_scale_at_high_frequency(washout_rows):
    # the tuned yaw scale is 0.914; above its high-pass (0.11 rad/s) the yaw cue passes with the
    # scale, less what the pose loop loses at 10 rad/s (measured 0.91 on the kinematic chain)
    gain = washout_rows[0]["gain"]
    assert 0.6 < gain < 1.0


def test_perceived_gain_is_the_physical_one_where_the_chain_is_linear(washout_rows):
    # the vestibular models are linear and the same on both sides: their ratio cancels; 1 % and
    # 1 degree for the otolith's transient (its 5.3 s lag) still there 2 s after the start
    for row in washout_rows:
        assert row["perceived_gain"] == pytest.approx(row["gain"], rel=1e-2)
        assert row["perceived_phase"] == pytest.approx(row["phase"], abs=1.0)


def test_a_platform_held_at_home_cues_nothing():
    rows = omct_rows(HoldHome(), {"action_mode": "pose"}, ("f_x",), (10.0,), periods=1.0, settle=1.0)
    assert rows[0]["gain"] < 1e-6  # the head at rest: the fitted harmonic is rounding only


def test_environment_chain_reports_the_steps_played():
    chain = environment_chain(HoldHome(), {"action_mode": "pose"})
    motion = sine_motion("f_x", 10.0, 1.0, 0.01, periods=1.0, settle=0.5)
    f, w = chain(motion)
    assert chain.played == motion.n_samples - 1
    assert f.shape == w.shape == (motion.n_samples, 3)


def test_write_omct_writes_the_csv_and_the_report(washout_rows, tmp_path):
    table, report = write_omct(washout_rows, tmp_path / "omct", "washout on the improved model", machine="test machine")
    lines = list(csv.reader(table.open()))
    assert tuple(lines[0]) == OMCT_COLUMNS
    assert [line[0] for line in lines[1:]] == ["omega_z", "omega_z", "f_y", "f_y"]
    assert float(lines[1][2]) == pytest.approx(washout_rows[0]["gain"], rel=1e-5)
    text = report.read_text()
    assert text.startswith("# OMCT: washout on the improved model\n\nRun on test machine, ")
    assert "| w (rad/s) | omega_z gain | omega_z phase (deg) | f_y gain | f_y phase (deg) |" in text
    assert "Ended by the platform's limits: none." in text


def test_the_report_names_the_sines_the_limits_ended():
    rows = [{"channel": "f_x", "frequency": 0.1, "gain": 0.5, "phase": 1.0, "played": 0.25}]
    assert "Ended by the platform's limits: f_x at 0.1 rad/s (25 %)." in omct_markdown(rows, "t", machine="m")


def test_the_command_writes_the_table(tmp_path, capsys):
    argv = ["evaluate", "--task", "cueing", "--omct", "omega_z", "--omct-frequencies", "15.849", "--out", str(tmp_path)]
    assert main(argv) == 0
    assert "| 15.849 |" in capsys.readouterr().out
    rows = list(csv.DictReader((tmp_path / "omct.csv").open()))
    assert [(r["channel"], float(r["frequency"])) for r in rows] == [("omega_z", 15.849)]
    assert float(rows[0]["played"]) == 1.0


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--omct"], "argument --omct: the objective motion cueing test drives the cueing task: give --task cueing"),
        (["--task", "cueing", "--omct-frequencies", "1"], "argument --omct-frequencies: give --omct too"),
        (["--task", "cueing", "--omct", "f_x", "f_x"], "argument --omct: f_x given twice"),
        (
            ["--task", "cueing", "--omct", "--omct-frequencies", "0"],
            "expected a frequency from 0.01 to 50 rad/s, got 0",
        ),
        (["--task", "cueing", "--omct", "surge"], "argument --omct: invalid choice: 'surge'"),
    ],
)
def test_bad_omct_options_are_one_line_errors(argv, message, capsys):
    with pytest.raises(SystemExit) if "invalid" in message or "expected" in message else _no_exit():
        assert main(["evaluate", *argv]) != 0
    err = capsys.readouterr().err
    assert message in err
    assert "Traceback" not in err


class _no_exit:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False
