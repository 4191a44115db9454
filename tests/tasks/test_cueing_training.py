"""The shipped PPO config trains a cueing agent through the command line (a smoke run, not a result)."""

from __future__ import annotations

import json

import pytest

from stewart_env.cli import main


@pytest.mark.slow
@pytest.mark.extra("rl")
def test_the_shipped_cueing_config_trains_through_the_command_line(tmp_path, capsys):
    out = tmp_path / "run"
    argv = ["train", "--algo", "ppo", "--task", "cueing", "--config", "ppo_cueing", "--timesteps", "256"]
    argv += ["--n-envs", "2", "--seed", "0", "--out", str(out), "--no-progress"]
    assert main(argv) == 0
    # 2 platforms x 128 steps a rollout: 256 steps are one rollout
    assert "ran 256" in capsys.readouterr().out
    assert (out / "model.zip").is_file()
    run = json.loads((out / "run.json").read_text())
    assert "cueing" in json.dumps(run)
