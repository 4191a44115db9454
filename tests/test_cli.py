"""The ``stewart-env`` command."""

import shutil
import subprocess
import sys
import types

import pytest

from stewart_env.cli import main


@pytest.mark.parametrize("command, expected", [
    ("demo", "--episodes"),
    ("evaluate", "--internal-model"),
    ("reproduce", "--duration"),
])
def test_subcommand_help(command, expected, capsys):
    with pytest.raises(SystemExit) as stop:
        main([command, "--help"])
    assert stop.value.code == 0
    assert expected in capsys.readouterr().out


def test_top_level_help_lists_the_subcommands(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    for command in ("demo", "evaluate", "reproduce", "train", "mismatch", "bench"):
        assert command in out


def test_bench_is_dispatched_with_its_arguments(monkeypatch):
    seen = []
    fake = types.ModuleType("stewart_env.bench")
    fake.main = lambda argv: seen.append(argv) or 0
    monkeypatch.setitem(sys.modules, "stewart_env.bench", fake)
    import stewart_env

    monkeypatch.setattr(stewart_env, "bench", fake, raising=False)
    assert main(["bench", "--help", "--num-envs", "4"]) == 0
    assert seen == [["--help", "--num-envs", "4"]]


def test_demo_prints_the_comparison_table(capsys):
    assert main(["demo", "--episodes", "1"]) == 0
    out = capsys.readouterr().out
    # without compensation the platform sags 27 mm, outside the 2 mm success band; with it, it settles
    assert "| PD | classical | setpoint | 1 | 0% |" in out and "| PD | improved | setpoint | 1 | 0% |" in out
    assert "| PD + gravity comp. | classical | setpoint | 1 | 100% |" in out
    assert "| PD + gravity comp. | improved | setpoint | 1 | 100% |" in out


def test_evaluate_writes_a_report(tmp_path, capsys):
    assert main(["evaluate", "--policy", "pd", "ct", "--internal-model", "classical", "--model", "improved",
                 "--task", "tracking", "--episodes", "1", "--max-steps", "10", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "| PD | improved | tracking |" in out and "| CT (classical) | improved | tracking |" in out
    assert (tmp_path / "results.md").exists() and (tmp_path / "episodes.csv").exists()
    assert (tmp_path / "error_norms.png").exists()


@pytest.mark.filterwarnings("ignore:You have specified a mini-batch size")  # the config's batch, our tiny run
def test_evaluate_a_trained_agent_beside_a_baseline(tmp_path, capsys):
    from stewart_env.agents.training import train

    # a few hundred steps of PPO: an untrained agent, enough to test loading and evaluating it
    train("ppo", tmp_path / "agent", timesteps=64, n_envs=2, checkpoint_freq=0, progress_bar=False)
    assert main(["evaluate", "--agent", str(tmp_path / "agent"), "--policy", "pd", "--model", "classical",
                 "--episodes", "1", "--max-steps", "5"]) == 0
    out = capsys.readouterr().out
    assert "| PPO (improved) | classical | setpoint | 1 |" in out and "| PD | classical | setpoint | 1 |" in out
    # two agents of one algorithm and model: their rows are named by run directory
    shutil.copytree(tmp_path / "agent", tmp_path / "agent_b")
    assert main(["evaluate", "--agent", str(tmp_path / "agent"), str(tmp_path / "agent_b"), "--episodes", "1",
                 "--max-steps", "2"]) == 0
    out = capsys.readouterr().out
    assert "| PPO (improved) agent | improved |" in out and "| PPO (improved) agent_b | improved |" in out
    assert main(["evaluate", "--agent", str(tmp_path / "missing")]) == 2
    assert "missing" in capsys.readouterr().err


def test_bad_model_name_is_refused(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["evaluate", "--model", "newtonian"])
    assert stop.value.code == 2
    assert "newtonian" in capsys.readouterr().err


@pytest.mark.skipif(shutil.which("stewart-env") is None, reason="the console script is not installed")
def test_console_script():
    done = subprocess.run(["stewart-env", "reproduce", "--help"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and "--out" in done.stdout
