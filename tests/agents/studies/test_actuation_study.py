"""The actuation study on a tiny budget: its cells and tables, resuming and keeping finished cells,
the target commands of the pose and leg_length modes, agents read from a folder, bad requests
refused by name; and the mismatch study's test plants on another actuator than the controllers'."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from stewart_env.agents.studies import actuation
from stewart_env.agents.studies.actuation import ActuationError, ActuationSettings, run_actuation
from stewart_env.agents.studies.mismatch import MismatchError, MismatchSettings
from stewart_env.agents.studies.mismatch import jobs as mismatch_jobs
from stewart_env.cli import main

#: Two cells of the pose mode on set point, 2 episodes of 60 steps (0.6 s): enough to see the
#: 5 Hz inner loop move the platform towards its target, cheap enough for the fast suite.
TINY = dict(tasks=("setpoint",), modes=("pose",), actuators=("ideal", "electric"), episodes=2, max_steps=60)


def _tiny_controllers(monkeypatch):
    """The pose mode's ik and ct rows only (the pd-gc row runs the same code path)."""
    monkeypatch.setitem(actuation.CONTROLLERS, "pose", ("ik", "ct", "ppo"))


def test_the_study_writes_its_cells_and_tables_with_intervals(tmp_path, monkeypatch):
    _tiny_controllers(monkeypatch)
    result = run_actuation(tmp_path, ActuationSettings(**TINY), progress=False)
    cells = [r.cell for r in result["cells"]]
    assert cells == [
        ("setpoint", "pose", "ik", "ideal"),
        ("setpoint", "pose", "ik", "electric"),
        ("setpoint", "pose", "ct", "ideal"),
        ("setpoint", "pose", "ct", "electric"),
    ]
    for r in result["cells"]:
        estimate, low, high = r.intervals["rms_position_error"]
        assert 0 < low <= estimate <= high
        # 0.6 s of a set point: the platform moved, not yet there; every number finite
        assert all(math.isfinite(r.intervals[key][0]) for key, *_ in actuation.STUDY_METRICS)
    md = (tmp_path / "actuation.md").read_text()
    assert "| setpoint | pose | ct | electric |" in md and "cost rate" in md and "limit hits" in md
    rows = list(csv.DictReader((tmp_path / "actuation.csv").open()))
    assert len(rows) == 4 and {"cost_rate", "cost_rate_low", "limit_hits_high"} <= set(rows[0])
    record = json.loads((tmp_path / "results.json").read_text())
    assert record["platform"] == "motion_simulator" and len(record["cells"]) == 4
    # the electric drives' reflected masses and current loop change the response: not the ideal numbers
    by_cell = {r.cell: r for r in result["cells"]}
    assert (
        by_cell[("setpoint", "pose", "ik", "electric")].intervals["rms_position_error"]
        != by_cell[("setpoint", "pose", "ik", "ideal")].intervals["rms_position_error"]
    )


def test_a_second_run_reuses_finished_cells_and_an_interrupted_run_keeps_them(tmp_path, monkeypatch):
    _tiny_controllers(monkeypatch)
    calls = []
    real = actuation.evaluate_cell

    def interrupted(spec, agent):
        if len(calls) == 2:
            raise KeyboardInterrupt
        calls.append(spec["controller"] + "/" + spec["actuator"])
        return real(spec, agent)

    monkeypatch.setattr(actuation, "evaluate_cell", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_actuation(tmp_path, ActuationSettings(**TINY), progress=False)
    kept = sorted(p.relative_to(tmp_path).as_posix() for p in (tmp_path / "cells").rglob("*.json"))
    assert kept == ["cells/setpoint/pose/ik/electric/model_based.json", "cells/setpoint/pose/ik/ideal/model_based.json"]
    calls.clear()
    monkeypatch.setattr(
        actuation, "evaluate_cell", lambda spec, agent: (calls.append(spec["controller"]), real(spec, agent))[1]
    )
    run_actuation(tmp_path, ActuationSettings(**TINY), progress=False)
    assert calls == ["ct", "ct"]  # the two ik cells were reused
    calls.clear()
    run_actuation(tmp_path, ActuationSettings(**TINY), progress=False)
    assert calls == []
    # another episode length is another cell: computed again
    run_actuation(tmp_path, ActuationSettings(**{**TINY, "max_steps": 30}), progress=False)
    assert len(calls) == 4


@pytest.mark.parametrize("mode", ["pose", "leg_length"])
def test_the_target_commands_hold_the_platform_at_its_target(mode):
    """Commanding the target itself to the inner loop at the target: the platform stays there."""
    import gymnasium as gym

    env = gym.make("StewartPlatform-v1", **actuation.env_kwargs_of(mode, "ik", "ideal", "setpoint"))
    obs, _ = env.reset(seed=0)
    policy = actuation.make_policy(mode, "ik")(env)
    base = env.unwrapped
    for _ in range(300):  # 3 s: 15 time constants of the 5 Hz loops
        action, _ = policy.predict(obs)
        obs, _, terminated, _, _ = env.step(action)
        assert not terminated
    target = base.target
    # the leg servos' stiffness against the joints' damping leaves well under a millimetre
    assert np.linalg.norm(base.state.position - target.position) < 1e-3
    env.close()


def test_ppo_cells_without_an_agent_in_a_given_folder_are_left_out_and_listed(tmp_path, monkeypatch):
    _tiny_controllers(monkeypatch)
    agents = tmp_path / "agents"
    agents.mkdir()
    settings = ActuationSettings(
        **{**TINY, "actuators": ("ideal",)}, ppo_cells=["pose:ideal:setpoint"], seeds=(0, 1), agents=agents
    )
    result = run_actuation(tmp_path / "study", settings, progress=False)
    assert [r.cell[2] for r in result["cells"]] == ["ik", "ct"]
    assert result["missing"] == [(("setpoint", "pose", "ppo", "ideal"), 0), (("setpoint", "pose", "ppo", "ideal"), 1)]
    assert "PPO seeds without an agent" in (tmp_path / "study" / "actuation.md").read_text()


@pytest.mark.parametrize(
    "kwargs, argument, message",
    [
        ({"modes": ("torque",)}, "modes", "expected one or more of force, leg_length, pose"),
        ({"actuators": ()}, "actuators", "expected one or more of ideal, lag, electric, hydraulic"),
        ({"ppo_cells": ["pose:electric"]}, "ppo_cells", "expected MODE:ACTUATOR:TASK"),
        ({"ppo_cells": ["pose:pneumatic:setpoint"]}, "ppo_cells", "got 'pose:pneumatic:setpoint'"),
        ({"episodes": 0}, "episodes", "expected a positive integer, got 0"),
        ({"seeds": (1, 1)}, "seeds", "each seed once"),
        ({"agents": "/nonexistent/agents"}, "agents", "is not a folder of trained agents"),
        ({"ppo_trained_on": "pneumatic"}, "ppo_trained_on", "expected one of ideal, lag, electric, hydraulic"),
    ],
)
def test_bad_settings_name_themselves(kwargs, argument, message):
    with pytest.raises(ActuationError, match=message) as err:
        ActuationSettings(**kwargs)
    assert err.value.argument == argument


def test_the_command_line_runs_a_study_and_names_a_bad_flag(tmp_path, capsys, monkeypatch):
    _tiny_controllers(monkeypatch)
    out = tmp_path / "study"
    argv = ["actuation", "--out", str(out), "--tasks", "setpoint", "--modes", "pose", "--actuators", "ideal"]
    assert main([*argv, "--episodes", "2", "--max-steps", "20", "--no-progress"]) == 0
    assert "2 cells ->" in capsys.readouterr().out and (out / "actuation.md").is_file()
    assert main([*argv, "--ppo", "pose:ideal"]) == 2
    assert "stewart-env actuation: error: argument --ppo: expected MODE:ACTUATOR:TASK" in capsys.readouterr().err


# -- the mismatch study's test plants on another actuator ----------------------------------------------


def test_mismatch_plant_actuator_is_checked_by_name():
    with pytest.raises(
        MismatchError, match="plant actuator: .*motion_simulator|plant actuator: .*no 'electric'"
    ) as err:
        MismatchSettings(algo=None, plant_actuator="electric")  # dasgupta1998 has no electric set
    assert err.value.argument == "plant_actuator"
    with pytest.raises(
        MismatchError, match="plant actuator: expected one of 'ideal', 'lag', 'electric', 'hydraulic', got 'pneumatic'"
    ) as err:
        MismatchSettings(algo=None, plant_actuator="pneumatic")
    assert err.value.argument == "plant_actuator"
    settings = MismatchSettings(algo=None, platform="motion_simulator", plant_actuator="electric")
    assert settings.evaluation()["plant_actuator"] == "electric"
    # a study on one actuator records no plant actuator: its cells stay valid
    assert "plant_actuator" not in MismatchSettings(algo=None).evaluation()


def test_mismatch_controllers_built_on_ideal_actuators_run_on_electric_drives(monkeypatch):
    """PD and CT built on ideal force sources, run on the electric drives: the plant's
    environment gets the drives, and the numbers differ from the ideal plant's."""
    from stewart_env.agents.evaluation import evaluation

    seen = []
    original = evaluation.evaluate

    def spy(policy, env_kwargs, **kw):
        seen.append(env_kwargs.get("actuator"))
        return original(policy, env_kwargs, **kw)

    monkeypatch.setattr(evaluation, "evaluate", spy)  # the job imports it at its call
    ideal = MismatchSettings(algo=None, platform="motion_simulator", episodes=2, max_steps=40)
    electric = MismatchSettings(
        algo=None, platform="motion_simulator", episodes=2, max_steps=40, plant_actuator="electric"
    )
    peak = {}
    for name, settings in (("ideal", ideal), ("electric", electric)):
        spec = {
            "controller": "ct",
            "kind": "ct",
            "design_model": "improved",
            "plant": "improved",
            **settings.evaluation(),
        }
        numbers = mismatch_jobs.evaluate_job(spec, settings.models["improved"], settings.models["improved"])
        peak[name] = numbers["metrics"]["peak_leg_force"]
    assert seen == [None, "electric"]
    assert peak["ideal"] != peak["electric"]


def test_mismatch_matrix_says_the_plants_actuator(tmp_path):
    from stewart_env.agents.studies.mismatch import run_mismatch

    kwargs = dict(algo=None, platform="motion_simulator", train_models=["improved"], test_models=["improved"])
    kwargs.update(simplifications=(), cost_plant="improved", episodes=1, max_steps=10, progress=False)
    run_mismatch(tmp_path / "electric", plant_actuator="electric", **kwargs)
    text = (tmp_path / "electric" / "matrix.md").read_text()
    assert "The plants' actuators: electric; the controllers' (ideal) are not the plants'." in text
    run_mismatch(tmp_path / "same", **kwargs)
    assert "The plants' actuators" not in (tmp_path / "same" / "matrix.md").read_text()


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:You have specified a mini-batch size:UserWarning")
def test_ppo_agents_are_trained_into_the_study_and_reused(tmp_path, monkeypatch):
    _tiny_controllers(monkeypatch)
    trained = []
    real = actuation.train_agent

    def counted(folder, training, timesteps, progress=False):
        trained.append((folder.name, timesteps))
        return real(folder, {**training, "n_envs": 2}, timesteps, progress)

    monkeypatch.setattr(actuation, "train_agent", counted)
    settings = ActuationSettings(
        **{**TINY, "actuators": ("electric",)}, ppo_cells=["pose:electric:setpoint"], seeds=(3,), timesteps=64
    )
    result = run_actuation(tmp_path, settings, progress=False)
    assert trained == [("seed_3", 64)]
    assert (tmp_path / "agents" / "pose-electric-setpoint" / "seed_3" / "model.zip").is_file()
    ppo = [r for r in result["cells"] if r.cell[2] == "ppo"]
    assert len(ppo) == 1 and ppo[0].seeds == 1 and math.isfinite(ppo[0].intervals["rms_position_error"][0])
    assert (tmp_path / "cells/setpoint/pose/ppo/electric/seed_3.json").is_file()
    run_actuation(tmp_path, settings, progress=False)
    assert len(trained) == 1  # the finished agent is reused


def test_ppo_agents_trained_on_one_actuator_run_on_every_cell(tmp_path, monkeypatch):
    """ppo_trained_on="ideal": one agent per seed, trained on ideal force sources, runs both the
    ideal and the electric cell; the spec and the table say so."""
    _tiny_controllers(monkeypatch)
    trained = []
    real = actuation.train_agent

    def counted(folder, training, timesteps, progress=False):
        trained.append((folder.parent.name, training["env_kwargs"]["actuator"]))
        return real(folder, {**training, "n_envs": 2}, timesteps, progress)

    monkeypatch.setattr(actuation, "train_agent", counted)
    settings = ActuationSettings(
        **{**TINY, "actuators": ("ideal", "electric")},
        ppo_cells=["pose:ideal:setpoint", "pose:electric:setpoint"],
        seeds=(2,),
        timesteps=64,
        ppo_trained_on="ideal",
    )
    result = run_actuation(tmp_path, settings, progress=False)
    assert trained == [("pose-ideal-setpoint", "ideal")]  # one agent, trained once, on ideal sources
    assert not (tmp_path / "agents" / "pose-electric-setpoint").exists()
    ppo = {r.cell[3]: r for r in result["cells"] if r.cell[2] == "ppo"}
    assert sorted(ppo) == ["electric", "ideal"]
    electric = json.loads((tmp_path / "cells/setpoint/pose/ppo/electric/seed_2.json").read_text())
    assert electric["spec"]["agent_trained_on"] == "ideal"
    assert electric["spec"]["env_kwargs"]["actuator"] == "electric"  # it runs on the electric drives
    ideal = json.loads((tmp_path / "cells/setpoint/pose/ppo/ideal/seed_2.json").read_text())
    assert ideal["spec"]["agent_sha256"] == electric["spec"]["agent_sha256"]
    assert "trained on the ideal actuator" in (tmp_path / "actuation.md").read_text()


def test_agents_trained_on_one_actuator_cannot_run_where_the_observation_differs(tmp_path):
    """The lag actuator's observation carries the lagged forces (six numbers more): an agent
    trained on ideal sources cannot read it, and the study says so before it trains anything."""
    settings = ActuationSettings(
        **{**TINY, "actuators": ("ideal", "lag")}, ppo_cells=["pose:lag:setpoint"], seeds=(0,), ppo_trained_on="ideal"
    )
    with pytest.raises(ActuationError, match="observes 27 numbers, the lag actuator's observation has 33") as err:
        run_actuation(tmp_path, settings, progress=False)
    assert err.value.argument == "ppo_trained_on"
    assert not (tmp_path / "agents").exists()


def test_all_ppo_cells_are_every_mode_actuator_and_task_of_the_study():
    settings = ActuationSettings(**TINY, ppo_cells=["all", "pose:ideal:setpoint"])
    assert settings.ppo_cells == (("pose", "ideal", "setpoint"), ("pose", "electric", "setpoint"))
