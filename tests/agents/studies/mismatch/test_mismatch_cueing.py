"""The mismatch study refuses the cueing task: its cells hold the setpoint tasks' metrics (the
position error, success within a tolerance of home), which would score a cueing agent by how far
it moved from home.  What a model costs a cueing agent is the cueing study's (`cueing-results
--agent-models`), which the message names."""

from __future__ import annotations

import pytest

from stewart_env.agents.studies.mismatch import run_mismatch
from stewart_env.agents.studies.mismatch.settings import MismatchError
from stewart_env.cli import main


def test_the_study_refuses_the_cueing_task_before_any_work(tmp_path):
    with pytest.raises(MismatchError, match="task: the study scores the position error and success of the setpoint"):
        run_mismatch(tmp_path / "study", task="cueing", algo=None)
    assert not (tmp_path / "study").exists()


def test_the_command_names_the_task_in_one_line(tmp_path, capsys):
    assert main(["mismatch", "--task", "cueing", "--algo", "none", "--out", str(tmp_path / "study")]) != 0
    err = capsys.readouterr().err
    assert "task: the study scores the position error and success of the setpoint tasks" in err
    assert "stewart-env cueing-results --agent-models classical" in err  # where the question is answered
    assert "Traceback" not in err
