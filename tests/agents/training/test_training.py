"""Training on StewartPlatform-v1: zoo configs, runs that load and evaluate, resuming, errors."""

from __future__ import annotations

import argparse
import inspect
import json
import pickle
import subprocess
import sys
import threading

import numpy as np
import pytest
import yaml

# PPO runs here are a rollout or two of 2 platforms, smaller than the config's minibatch on purpose.
# Every test here trains or loads an agent: stable-baselines3 and torch (the rl extra).
pytestmark = [
    pytest.mark.extra("rl"),
    pytest.mark.filterwarnings("ignore:You have specified a mini-batch size:UserWarning"),
]

import stewart_env  # noqa: E402,F401  (registers the environment)
from stewart_env.agents import training  # noqa: E402
from stewart_env.agents.evaluation.evaluation import evaluate  # noqa: E402
from stewart_env.agents.training import (  # noqa: E402
    ALGORITHMS,
    CONFIG_DIR,
    ENV_ID,
    TrainingError,
    load_agent,
    parse_env_kwargs,
    parse_hyperparameters,
    read_hyperparameters,
    train,
)

# Keys rl_zoo3 consumes itself before the rest goes to the algorithm's constructor (rl_zoo3
# ExperimentManager._preprocess_hyperparameters), written out here independently of the training package.
ZOO_OWN_KEYS = {
    "n_timesteps",
    "policy",
    "normalize",
    "n_envs",
    "frame_stack",
    "env_wrapper",
    "vec_env_wrapper",
    "callback",
    "env_kwargs",
    "monitor_kwargs",
    "noise_type",
    "noise_std",
}


#: every shipped hyperparameter file and the algorithm it configures
CONFIGS = [(algo, f"{algo}.yml") for algo in ALGORITHMS] + [("ppo", "ppo_6m.yml"), ("ppo", "ppo_integral_6m.yml")]


@pytest.mark.parametrize("algo, name", CONFIGS)
def test_zoo_config_names_only_valid_hyperparameters(algo, name):
    import torch

    with open(CONFIG_DIR / name) as f:
        entries = yaml.safe_load(f)
    assert list(entries) == [ENV_ID]
    entry = entries[ENV_ID]
    valid = set(inspect.signature(training.algorithm_class(algo).__init__).parameters) - {"self", "env"}
    assert not set(entry) - valid - ZOO_OWN_KEYS, "keys neither the zoo's nor the algorithm's"
    for key in ("n_timesteps", "policy", "n_envs", "normalize"):
        assert key in entry
    # policy_kwargs is a string the zoo evaluates with torch.nn in scope
    assert isinstance(entry["policy_kwargs"], str)
    policy_kwargs = eval(entry["policy_kwargs"], {"nn": torch.nn, "dict": dict})
    assert isinstance(policy_kwargs, dict)
    if isinstance(entry["normalize"], str):
        assert isinstance(eval(entry["normalize"], {"dict": dict}), dict)


@pytest.mark.parametrize("algo, name", CONFIGS)
def test_zoo_config_builds_the_algorithm(algo, name):
    """The parsed entry, environment kwargs included, is accepted by the algorithm's constructor on
    the native batch."""
    hp = parse_hyperparameters(algo, read_hyperparameters(algo, CONFIG_DIR / name))
    env = training.make_training_env(2, hp.env_kwargs, seed=0, normalize=hp.normalize)
    kwargs = dict(hp.algorithm_kwargs)
    if "buffer_size" in kwargs:
        kwargs["buffer_size"] = 1000  # the construction is the check, not the allocation
    try:
        model = training.algorithm_class(algo)(env=env, device="cpu", **kwargs)
        assert model.n_envs == 2
    finally:
        env.close()


def test_rl_zoo3_trains_from_the_config(tmp_path):
    """`python -m rl_zoo3.train --gym-packages stewart_env --conf-file configs/agents/sac.yml` runs."""
    cmd = [
        sys.executable,
        "-m",
        "rl_zoo3.train",
        "--algo",
        "sac",
        "--env",
        ENV_ID,
        "--gym-packages",
        "stewart_env",
        "--conf-file",
        str(CONFIG_DIR / "sac.yml"),
        "-n",
        "200",
        "-f",
        str(tmp_path),
        "--seed",
        "0",
    ]
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    assert (tmp_path / "sac" / f"{ENV_ID}_1" / f"{ENV_ID}.zip").is_file()
    assert (tmp_path / "sac" / f"{ENV_ID}_1" / ENV_ID / "vecnormalize.pkl").is_file()


def test_unknown_hyperparameter_is_refused():
    entry = read_hyperparameters("sac")
    entry["learning_rat"] = 1e-3
    with pytest.raises(TrainingError, match="learning_rat"):
        parse_hyperparameters("sac", entry)


def test_zoo_only_keys_are_refused_with_a_pointer_to_rl_zoo3():
    entry = {**read_hyperparameters("ppo"), "frame_stack": 4}
    with pytest.raises(TrainingError, match="rl_zoo3"):
        parse_hyperparameters("ppo", entry)


def test_zoo_schedule_and_noise_are_converted():
    entry = {**read_hyperparameters("td3"), "learning_rate": "lin_1e-3"}
    hp = parse_hyperparameters("td3", entry)
    lr = hp.algorithm_kwargs["learning_rate"]
    assert lr(1.0) == pytest.approx(1e-3) and lr(0.5) == pytest.approx(5e-4)  # linear to 0 over training
    noise = hp.algorithm_kwargs["action_noise"]
    assert np.allclose(noise._sigma, entry["noise_std"])


def test_parse_env_kwargs_json_and_pairs():
    assert parse_env_kwargs(['{"observation_noise": 0.01, "task_options": {"randomize": false}}']) == {
        "observation_noise": 0.01,
        "task_options": {"randomize": False},
    }
    assert parse_env_kwargs(["control_dt=0.02", "platform=dasgupta1998", "observation_delay=2"]) == {
        "control_dt": 0.02,
        "platform": "dasgupta1998",
        "observation_delay": 2,
    }
    with pytest.raises(TrainingError, match="key=value"):
        parse_env_kwargs(["control_dt"])


@pytest.fixture(scope="module")
def ppo_run(tmp_path_factory):
    """A PPO run of five rollouts of 2 platforms x 32 steps (the config's n_steps)."""
    out = tmp_path_factory.mktemp("ppo")
    result = train("ppo", out, timesteps=300, seed=3, n_envs=2, checkpoint_freq=256, progress_bar=False)
    return out, result


def test_a_run_s_files_name_no_module_of_the_package(ppo_run):
    """The model zip, the statistics and the manifests hold no module path of stewart_env (``stewart_env.<module>``), so a
    run stays loadable when the package's modules move (agents/ was regrouped by job)."""
    import zipfile

    out, _ = ppo_run
    named = []
    for path in sorted(p for p in out.rglob("*") if p.is_file() and "tensorboard" not in p.parts):
        parts = (
            [zipfile.ZipFile(path).read(n) for n in zipfile.ZipFile(path).namelist()]
            if path.suffix == ".zip"
            else [path.read_bytes()]
        )
        named += [str(path.relative_to(out)) for data in parts if b"stewart_env." in data]
    assert len(list(out.rglob("*.zip"))) >= 2, "the run's model files were not found"
    assert named == []


def test_training_writes_a_run_that_loads_and_evaluates(ppo_run):
    out, result = ppo_run
    # PPO collects whole rollouts: 300 requested steps are 5 rollouts of 2 x 32
    assert result.num_timesteps == 320
    for name in ("model.zip", "vecnormalize.pkl", "run.json", "monitor.csv"):
        assert (out / name).is_file(), name
    assert list((out / "tensorboard").rglob("events.out.tfevents*"))
    assert (out / "checkpoints" / "step_320" / "model.zip").is_file()
    assert (out / "checkpoints" / "progress.csv").read_text().startswith("num_timesteps,wall_time_s\n")
    manifest = json.loads((out / "run.json").read_text())
    assert manifest["algo"] == "ppo" and manifest["seed"] == 3 and manifest["num_timesteps"] == 320
    # the config's environment keywords, then the run's
    assert manifest["env_kwargs"] == {
        "error_integral": True,
        "error_integral_band": 0.01,
        "model": "improved",
        "task": "setpoint",
    }
    assert manifest["finished"] and {"torch", "stable_baselines3", "stewart_env"} <= set(manifest["versions"])
    assert set(manifest["files"]) == {"model.zip", "vecnormalize.pkl"}

    agent = load_agent(out)
    assert agent.num_timesteps == 320
    result = evaluate(agent, agent.env_kwargs, episodes=2, seed=0, max_steps=20, progress=False)
    summary = result.summary()
    for key in ("rms_position_error", "steady_state_position_error", "peak_leg_force", "control_energy"):
        assert np.isfinite(summary[key]), key


def test_loaded_agent_applies_the_saved_normalisation(ppo_run):
    out, _ = ppo_run
    agent = load_agent(out)
    with open(out / "vecnormalize.pkl", "rb") as f:
        stats = pickle.load(f).obs_rms
    env = agent.make_env()
    obs = np.stack([env.reset(seed=s)[0] for s in range(3)])
    # VecNormalize's documented transform, written out: clip((obs - mean) / sqrt(var + eps), +-10)
    normalized = np.clip((obs - stats.mean) / np.sqrt(stats.var + 1e-8), -10, 10).astype(np.float32)
    assert not np.allclose(normalized, obs)  # the statistics are not the identity
    expected, _ = agent.model.predict(normalized, deterministic=True)
    actions, state = agent.predict(obs)
    assert state is None and actions.shape == (3, 6)
    # float32 normalisation either way; the network maps equal inputs to equal outputs
    np.testing.assert_allclose(actions, expected, atol=1e-6)
    single, _ = agent.predict(obs[0])
    np.testing.assert_allclose(single, expected[0], atol=1e-6)


def test_resume_continues_the_step_count(tmp_path):
    out = tmp_path / "td3"
    first = train("td3", out, timesteps=120, seed=1, n_envs=1, checkpoint_freq=50, progress_bar=False)
    assert first.num_timesteps == 120
    # one platform, one step per env step: step counts are exact
    second = train("td3", out, timesteps=80, resume=True, progress_bar=False)
    assert second.num_timesteps == 200 and second.steps_this_run == 80
    manifest = json.loads((out / "run.json").read_text())
    assert manifest["num_timesteps"] == 200
    assert [(s["start"], s["end"]) for s in manifest["segments"]] == [(0, 120), (120, 200)]
    assert load_agent(out).num_timesteps == 200
    # the replay buffer came along: 120 transitions before, 80 after
    with open(out / "checkpoints" / "step_200" / "replay_buffer.pkl", "rb") as f:
        assert pickle.load(f).size() == 200
    # checkpoints at 50, 100, 120 (the end of the first call) and 200 (the end of the second, whose
    # default frequency is 50000): the newest 3 are kept
    assert sorted(p.name for p in (out / "checkpoints").glob("step_*")) == ["step_100", "step_120", "step_200"]
    assert (out / "resumed_120.monitor.csv").is_file()


def test_training_leaves_no_thread_behind(tmp_path):
    # A study's worker trains agent after agent in one process: every run must close what it opened.
    before = set(threading.enumerate())
    train("ppo", tmp_path / "run", timesteps=300, seed=3, n_envs=2, checkpoint_freq=256, progress_bar=False)
    assert set(threading.enumerate()) - before == set()


def test_bad_algorithm_fails_before_anything_is_written(tmp_path):
    out = tmp_path / "run"
    with pytest.raises(TrainingError, match="unknown algorithm 'dqn'"):
        train("dqn", out, timesteps=10)
    assert not out.exists()


def test_missing_config_file_and_entry(tmp_path):
    with pytest.raises(TrainingError, match="not found"):
        train("sac", tmp_path / "a", timesteps=10, config=tmp_path / "nope.yml")
    other = tmp_path / "other.yml"
    other.write_text("Pendulum-v1:\n  n_timesteps: 100\n  policy: MlpPolicy\n")
    with pytest.raises(TrainingError, match="no entry for 'StewartPlatform-v1'.*Pendulum-v1"):
        train("sac", tmp_path / "b", timesteps=10, config=other)
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_unwritable_output_directory(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")  # a directory cannot be made below a file, even by root
    with pytest.raises(ValueError, match="not writable"):  # stewart_env.files.NotWritable
        train("ppo", blocker / "run", timesteps=10)


def test_existing_run_needs_resume_and_resume_needs_a_run(ppo_run, tmp_path):
    out, _ = ppo_run
    with pytest.raises(TrainingError, match="already holds a trained agent"):
        train("ppo", out, timesteps=10)
    with pytest.raises(TrainingError, match="no run.json"):
        train("ppo", tmp_path, timesteps=10, resume=True)
    with pytest.raises(TrainingError, match="holds a ppo run, not sac"):
        train("sac", out, timesteps=10, resume=True)


def test_bad_environment_kwarg_is_named_before_training(tmp_path):
    with pytest.raises(ValueError, match="contol_dt"):
        train("ppo", tmp_path / "run", timesteps=10, env_kwargs={"contol_dt": 0.02}, progress_bar=False)
    with pytest.raises(ValueError, match="observation_noise"):
        train("ppo", tmp_path / "run", timesteps=10, env_kwargs={"observation_noise": 1e300}, progress_bar=False)
    assert not (tmp_path / "run").exists()  # nothing written for a request that cannot run


def test_the_training_batch_s_time_limit_is_an_environment_keyword(tmp_path):
    # the cueing task's motions outlast the default 500 steps: the batch's limit is a keyword
    out = tmp_path / "run"
    train("ppo", out, timesteps=64, seed=0, n_envs=2, env_kwargs={"max_episode_steps": 7}, progress_bar=False)
    lengths = [int(line.split(",")[1]) for line in (out / "monitor.csv").read_text().splitlines()[2:]]
    assert lengths and max(lengths) <= 7
    with pytest.raises(ValueError, match="max_episode_steps"):
        train("ppo", tmp_path / "bad", timesteps=10, env_kwargs={"max_episode_steps": 0}, progress_bar=False)
    assert not (tmp_path / "bad").exists()


def test_cli_reports_errors_with_exit_code(tmp_path, capsys):
    from stewart_env.cli import train as train_verb

    parser = argparse.ArgumentParser()
    train_verb.add_parser(parser.add_subparsers(dest="command"))
    with pytest.raises(SystemExit) as stop:
        parser.parse_args(["train", "--algo", "a2c", "--out", str(tmp_path / "run")])
    assert stop.value.code == 2
    assert "argument --algo: invalid choice: 'a2c'" in capsys.readouterr().err
    args = parser.parse_args(
        [
            "train",
            "--algo",
            "ppo",
            "--out",
            str(tmp_path / "run"),
            "--env-kwargs",
            "contol_dt=0.02",
            "--timesteps",
            "10",
        ]
    )
    assert train_verb.run(args) == 2
    assert "contol_dt" in capsys.readouterr().err
    assert not (tmp_path / "run" / "run.json").exists()


def _interrupt_after(original):
    """``original`` that raises KeyboardInterrupt (a Ctrl-C) once it has done its work."""

    def interrupted(*args, **kwargs):
        original(*args, **kwargs)
        raise KeyboardInterrupt

    return interrupted


@pytest.mark.parametrize("point", ["make_training_env", "publish"])
def test_a_start_interrupted_before_the_first_checkpoint_leaves_a_folder_a_rerun_accepts(
    point, tmp_path, monkeypatch, capsys
):
    """Ctrl-C once the environment wrote its monitor file (before the run's manifest), or once the
    manifest is published (before the first checkpoint): the same command starts the run again,
    and --resume says to run it without --resume."""
    from stewart_env.agents.training import trainer
    from stewart_env.cli import main

    out = tmp_path / "run"
    argv = ["train", "--algo", "ppo", "--out", str(out), "--timesteps", "10", "--n-envs", "2", "--no-progress"]
    with monkeypatch.context() as patch:
        patch.setattr(trainer, point, _interrupt_after(getattr(trainer, point)))
        assert main(argv) == 130
    assert (
        "interrupted before training started; nothing saved (run the same command to start it again)"
        in capsys.readouterr().err
    )
    assert main([*argv, "--resume"]) == 2
    assert "start it again without --resume" in capsys.readouterr().err
    assert main(argv) == 0
    assert json.loads((out / "run.json").read_text())["finished"] is True
