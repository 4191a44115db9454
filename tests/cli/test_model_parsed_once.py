"""A model name is parsed once, where it enters (a flag, the environment's ``model``), and the
ModelSpec is passed on from there: counted by wrapping ``ModelSpec.parse``."""

from __future__ import annotations

import collections

import gymnasium as gym
import pytest

import stewart_env  # noqa: F401  (registers StewartPlatform-v1)
from stewart_env.cli import main
from stewart_env.dynamics import ModelSpec, Switch
from stewart_env.identification.base import IdentificationError


@pytest.fixture
def parses(monkeypatch):
    """The names ``ModelSpec.parse`` parsed (a spec passed through is no parse), counted by name."""
    counted = collections.Counter()
    parse = ModelSpec.parse.__func__

    def counting(cls, model, *args, **kwargs):
        if not isinstance(model, ModelSpec):
            counted[model] += 1
        return parse(cls, model, *args, **kwargs)

    monkeypatch.setattr(ModelSpec, "parse", classmethod(counting))
    return counted


def test_gym_make_parses_the_model_once_and_takes_a_spec_unparsed(parses):
    gym.make("StewartPlatform-v1", model="improved+C1").close()
    assert parses["improved+C1"] == 1
    spec = ModelSpec.parse("improved+c3")
    env = gym.make("StewartPlatform-v1", model=spec)
    assert env.unwrapped._core.model.spec == spec and parses["improved+c3"] == 1
    env.close()


def test_evaluate_parses_each_model_once(parses, capsys):
    command = ["evaluate", "--policy", "pd", "ct", "--model", "classical", "improved+c1"]
    command += ["--internal-model", "improved+c2", "--episodes", "1", "--max-steps", "3"]
    assert main(command) == 0
    out = capsys.readouterr().out
    assert "| CT (improved+c2) | improved+c1 |" in out
    # every name once, at its flag, though two controllers run on each plant (four environments)
    assert (parses["classical"], parses["improved+c1"], parses["improved+c2"]) == (1, 1, 1)


def test_identify_parses_the_plant_and_the_model_once(parses, monkeypatch, tmp_path, capsys):
    from stewart_env.dynamics import Dynamics
    from stewart_env.identification import experiment

    built = []

    def run(settings, nominal, predicted_by=None):
        # run()'s start: the settings checked, the plant's and the model's dynamics built
        plant, model = settings.check()
        built.extend([Dynamics(plant, nominal), Dynamics(model, nominal)])
        raise IdentificationError("stopped after the settings")

    monkeypatch.setattr(experiment, "run", run)
    assert main(["identify", "--plant", "Improved+C1", "--model", "improved+c3", "--out", str(tmp_path / "i")]) == 2
    assert "stopped after the settings" in capsys.readouterr().err
    assert [m.spec.name for m in built] == ["improved+c1", "improved+c3"]
    assert parses == {"Improved+C1": 1, "improved+c3": 1}  # not again by their canonical names


@pytest.mark.extra("rl")
def test_train_parses_the_model_once_and_records_its_canonical_name(parses, monkeypatch, tmp_path, capsys):
    from stewart_env.agents.training import TrainingError, trainer
    from stewart_env.envs import StewartPlatformEnv

    built = []

    def make_training_env(n_envs, env_kwargs, *args, **kwargs):
        # the training environment built from the run's keywords, then the run stopped
        env = StewartPlatformEnv(**env_kwargs)
        built.append(env.unwrapped._core.model.spec)
        env.close()
        raise TrainingError("stopped after the environment")

    monkeypatch.setattr(trainer, "make_training_env", make_training_env)
    out = tmp_path / "run"
    assert main(["train", "--algo", "ppo", "--model", "Improved+C2+c1", "--out", str(out), "--no-progress"]) == 2
    assert "stopped after the environment" in capsys.readouterr().err
    assert [spec.name for spec in built] == ["improved+c1+c2"]
    assert parses == {"Improved+C2+c1": 1}  # the check environment and the training one take the spec


def test_bench_parses_each_model_once(parses, monkeypatch, capsys):
    import stewart_env as se
    from stewart_env.benchmarks import report

    class Stop(Exception):
        """Ends the benchmark after its models' table, before the scaling's timings."""

    timed = []

    def bench_model(model, params):
        timed.append(se.make_dynamics(model, params).spec)
        keys = ("forward_per_s_N1", "kernel_per_s_N1", "forward_per_s_N1024", "kernel_per_s_N1024")
        return dict.fromkeys(keys + ("rollout_1s_N1", "rollout_1s_N1024"), 1.0)

    def bench_scaling(params):
        raise Stop

    monkeypatch.setattr(report, "first_evaluation_seconds", lambda: 0.0)
    monkeypatch.setattr(report, "bench_model", bench_model)
    monkeypatch.setattr(report, "bench_scaling", bench_scaling)
    with pytest.raises(Stop):
        main(["bench", "--models", "Classical,improved+C4"])
    assert [spec.name for spec in timed] == ["classical", "improved+c4"]
    assert parses == {"Classical": 1, "improved+C4": 1}
    out = capsys.readouterr().out
    assert "| classical | 1 / 1 |" in out and "| improved+c4 | 1 / 1 |" in out


def test_mismatch_parses_each_model_once_and_its_jobs_take_the_specs(parses, tmp_path, capsys):
    import json

    out = tmp_path / "study"
    command = ["mismatch", "--algo", "none", "--train-models", "Improved", "--test-models", "classical,improved"]
    command += ["--cost-plant", "CLASSICAL", "--simplifications", "c1", "--episodes", "1", "--max-steps", "3"]
    assert main([*command, "--no-progress", "--out", str(out)]) == 0
    assert "4 controllers x 2 plants" in capsys.readouterr().out
    # each name once, at its flag: not again by the check environments, the rows, the jobs or the tables
    assert parses == {"Improved": 1, "classical": 1, "improved": 1, "CLASSICAL": 1}
    cell = json.loads((out / "cells" / "ct_improved_c1" / "classical" / "model_based.json").read_text())
    assert (cell["spec"]["design_model"], cell["spec"]["plant"]) == ("improved+c1", "classical")


@pytest.mark.extra("rl")
def test_mismatch_gives_its_trainings_the_spec(parses, monkeypatch, tmp_path, capsys):
    from stewart_env.agents.studies.mismatch import rows
    from stewart_env.agents.training import TrainingError

    given = []

    def train(**keywords):
        given.append(keywords["model"])
        raise TrainingError("stopped before training")

    monkeypatch.setattr(rows, "train", train)
    command = ["mismatch", "--train-models", "Improved+C3", "--test-models", "improved", "--cost-plant", "Improved"]
    command += ["--simplifications", "none", "--timesteps", "64", "--no-progress", "--out", str(tmp_path / "s")]
    assert main(command) == 2
    assert "stopped before training" in capsys.readouterr().err
    assert given == [ModelSpec("improved", Switch.C3)]
    assert parses == {"Improved+C3": 1, "improved": 1, "Improved": 1}
