"""Time to a precise agent: points, the target, the budget, the files and the command's errors."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
import yaml

from stewart_env.agents.evaluation.evaluation import evaluate
from stewart_env.agents.studies.time_to_agent import AGENTS_DIR, EVALUATION_SEED, FILES, TimeToAgentError, time_to_agent
from stewart_env.agents.training import ENV_ID, load_agent
from stewart_env.cli import main

# The runs here are a rollout or two of 2 platforms, smaller than a minibatch of the shipped config.
pytestmark = [
    pytest.mark.extra("rl"),
    pytest.mark.filterwarnings("ignore:You have specified a mini-batch size:UserWarning"),
]

#: PPO on 2 platforms, 8-step rollouts (16 environment steps a rollout), one epoch.
N_ENVS, N_STEPS = 2, 8
ROLLOUT = N_ENVS * N_STEPS


@pytest.fixture
def tiny(tmp_path):
    path = tmp_path / "tiny.yml"
    path.write_text(
        yaml.safe_dump(
            {
                ENV_ID: {
                    "n_timesteps": 10**6,
                    "policy": "MlpPolicy",
                    "n_envs": N_ENVS,
                    "normalize": True,
                    "n_steps": N_STEPS,
                    "batch_size": ROLLOUT,
                    "n_epochs": 1,
                    "policy_kwargs": "dict(net_arch=[8])",
                }
            }
        )
    )
    return path


def test_a_target_met_at_once_is_reached_at_the_first_point(tiny, tmp_path):
    out = tmp_path / "out"
    result = time_to_agent(
        "ppo",
        out,
        config=tiny,
        seeds=[3],
        target_success=0.0,
        target_error_mm=1e9,
        budget=60.0,
        interval=1e-3,
        episodes=2,
        progress_bar=False,
    )
    (seed,) = result.seeds
    assert seed.seed == 3 and seed.reached and len(seed.points) == 1
    # the first point comes after the first update: one rollout trained on
    assert seed.steps == seed.points[0].steps == ROLLOUT
    assert seed.wall_time == seed.points[0].wall_time < 60.0
    assert seed.collection_steps == ROLLOUT and seed.learning_steps == ROLLOUT
    assert seed.collection_rate > 0 and seed.learning_rate > 0 and math.isfinite(seed.rate)
    assert seed.evaluation_time == pytest.approx(seed.points[0].evaluation_time)
    assert result.median_time() == seed.wall_time
    saved = json.loads((out / FILES["json"]).read_text())
    assert saved["summary"] == {"reached": 1, "seeds": 1, "running": 0, "median_time_to_target_s": seed.wall_time}
    assert saved["settings"]["config"] == str(tiny) and saved["seeds"][0]["steps"] == ROLLOUT
    rows = list(csv.DictReader((out / FILES["csv"]).open()))
    assert [(r["seed"], r["steps"], r["target_met"]) for r in rows] == [("3", str(ROLLOUT), "1")]
    assert (out / FILES["png"]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "| 3 | " in (out / FILES["markdown"]).read_text()
    # the agent of the reaching point, loadable as a run of `stewart-env train`, acts as it did there
    agent = load_agent(out / AGENTS_DIR / "seed_3")
    assert agent.manifest["num_timesteps"] == ROLLOUT and agent.manifest["seed"] == 3
    again = evaluate(agent, agent.manifest["env_kwargs"], 2, EVALUATION_SEED, progress=False).episodes
    error = 1e3 * float(np.median([ep.metrics["steady_state_position_error"] for ep in again]))
    assert error == seed.points[0].median_error_mm  # the same policy, the same episodes


def test_an_unreachable_target_stops_at_the_budget_and_writes_the_files(tiny, tmp_path):
    out = tmp_path / "out"
    budget, interval = 1.5, 0.4
    result = time_to_agent(
        "ppo",
        out,
        config=tiny,
        seeds=[0, 1],
        target_success=1.0,
        target_error_mm=0.0,
        budget=budget,
        interval=interval,
        episodes=2,
        progress_bar=False,
    )
    assert result.reached == 0 and result.median_time() == math.inf
    for seed in result.seeds:
        assert not seed.reached and seed.wall_time is None and seed.steps is None
        times = [p.wall_time for p in seed.points]
        assert times == sorted(times) and times[-1] >= budget
        # every point but the last is at or past its scheduled time, k x interval
        assert all(t >= (k + 1) * interval for k, t in enumerate(times[:-1]))
        assert seed.training_time >= budget
        assert seed.total_steps >= seed.points[-1].steps > 0
    saved = json.loads((out / FILES["json"]).read_text())
    assert saved["summary"]["median_time_to_target_s"] is None and saved["summary"]["reached"] == 0
    rows = list(csv.DictReader((out / FILES["csv"]).open()))
    assert len(rows) == sum(len(s.points) for s in result.seeds) and {r["target_met"] for r in rows} == {"0"}
    assert "not reached (> 1.5)" in (out / FILES["markdown"]).read_text()


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"budget": -1.0}, "budget"),
        ({"budget": 0.0}, "budget"),
        ({"interval": math.inf}, "interval"),
        ({"target_error_mm": math.nan}, "target_error_mm"),
        ({"target_success": 1.5}, "target_success"),
        ({"episodes": 0}, "episodes"),
        ({"seeds": [1, 1]}, "seeds"),
        ({"config": "no_such_config"}, "config"),
    ],
)
def test_bad_arguments_are_refused_by_name_before_anything_is_written(kwargs, name, tmp_path):
    out = tmp_path / "out"
    with pytest.raises(TimeToAgentError, match=rf"^{name}: ") as err:
        time_to_agent("ppo", out, **kwargs)
    # the argument is data, so the command line says it of its flag without reading the text
    assert err.value.argument == name and not err.value.problem.startswith(f"{name}: ")
    assert not out.exists()


def test_another_measurement_s_folder_is_not_overwritten(tmp_path):
    (tmp_path / FILES["json"]).write_text("{}")
    with pytest.raises(TimeToAgentError, match="^out: .* is not empty") as err:
        time_to_agent("ppo", tmp_path)
    assert err.value.argument == "out" and err.value.problem.endswith("choose a new or empty output directory")
    assert (tmp_path / FILES["json"]).read_text() == "{}"


def test_the_command_s_exit_codes(tiny, tmp_path, capsys):
    out = tmp_path / "out"
    common = ["time-to-agent", "--algo", "ppo", "--episodes", "2", "--no-progress"]
    assert (
        main(
            [
                *common,
                "--config",
                str(tiny),
                "--target-success",
                "0",
                "--target-error-mm",
                "1e9",
                "--interval",
                "0.001",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    captured = capsys.readouterr()
    assert "1/1 seeds reached the target" in captured.out and "seed 0: target reached" in captured.err
    # the folder now holds a measurement: refused, one line naming --out
    assert main([*common, "--config", str(tiny), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "argument --out: " in err
    assert main([*common, "--config", "no_such_config", "--out", str(tmp_path / "other")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("stewart-env time-to-agent: error: argument --config: ")
    for flag, value in (
        ("--budget", "-1"),
        ("--target-error-mm", "nan"),
        ("--interval", "0"),
        ("--target-success", "2"),
    ):
        with pytest.raises(SystemExit) as exit_:
            main([*common, flag, value, "--out", str(tmp_path / "other")])
        assert exit_.value.code == 2
        assert f"error: argument {flag}: " in capsys.readouterr().err
    assert not (tmp_path / "other").exists()


def test_the_files_hold_every_point_while_a_seed_trains(tiny, tmp_path, monkeypatch):
    """A run stopped in the middle of a seed keeps its points: the files are written at each one."""
    from stewart_env.agents.studies import time_to_agent as module

    seen = []
    write = module.write_files

    def spy(result, out):
        seen.append([(r.seed, r.finished, len(r.points)) for r in result.seeds])
        return write(result, out)

    monkeypatch.setattr(module, "write_files", spy)
    result = time_to_agent(
        "ppo",
        tmp_path / "out",
        config=tiny,
        seeds=[0],
        target_success=1.0,
        target_error_mm=0.0,
        budget=1.0,
        interval=0.3,
        episodes=1,
        progress_bar=False,
    )
    n = len(result.seeds[0].points)
    assert n >= 2
    # one write per point while training, then the finished seed
    assert seen == [[(0, False, k)] for k in range(1, n + 1)] + [[(0, True, n)]]


def test_the_settings_are_one_record_completed_from_the_config():
    """Built once by time_to_agent and read by every seed: the config's platforms and environment
    keywords filled in, and the JSON record's keys as the measurement's file has them."""
    from stewart_env.agents.studies.time_to_agent import TimeToAgentSettings
    from stewart_env.agents.training import parse_hyperparameters, read_hyperparameters

    settings = TimeToAgentSettings("ppo", seeds=[2, 1], task="tracking", env_kwargs={"control_dt": 0.02})
    hp = parse_hyperparameters("ppo", read_hyperparameters("ppo"))
    assert settings.n_envs == hp.n_envs and settings.seeds == (2, 1)
    assert settings.env_kwargs == {**hp.env_kwargs, "control_dt": 0.02, "model": "improved", "task": "tracking"}
    recorded = settings.as_dict()
    assert list(recorded) == [
        "algo",
        "config",
        "task",
        "model",
        "env_kwargs",
        "n_envs",
        "seeds",
        "target_success",
        "target_error_mm",
        "budget_s",
        "interval_s",
        "episodes",
        "evaluation_seed",
        "hyperparameters",
    ]
    assert recorded["config"].endswith("ppo.yml") and recorded["evaluation_seed"] == EVALUATION_SEED
