"""``stewart-env evaluate --task cueing``: washout by default, the cueing metrics' table and CSV columns."""

from __future__ import annotations

import pytest

from stewart_env.cli import main


def test_evaluate_cueing_runs_washout_and_shows_the_cueing_table(tmp_path, capsys):
    argv = ["evaluate", "--task", "cueing", "--episodes", "1", "--max-steps", "20", "--out", str(tmp_path)]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "| washout | improved | cueing |" in out
    assert "| controller | model | RMS f err. (m/s²) |" in out
    assert "rms_specific_force_error" in (tmp_path / "episodes.csv").read_text().splitlines()[0]


def test_washout_needs_the_cueing_task(capsys):
    assert main(["evaluate", "--policy", "washout", "--episodes", "1", "--max-steps", "5"]) != 0
    err = capsys.readouterr().err
    assert "argument --policy: washout cues vehicle motion: give --task cueing" in err
    assert "Traceback" not in err


@pytest.mark.parametrize("task", ["setpoint"])
def test_default_policy_elsewhere_stays_pd(task, capsys):
    assert main(["evaluate", "--task", task, "--episodes", "1", "--max-steps", "3"]) == 0
    assert "| PD |" in capsys.readouterr().out
