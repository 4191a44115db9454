"""Checkpoints and resuming under signals and kills, refused resumes and output directories, configs
read as data, and agent folders whose pickles are checked before they are loaded."""

from __future__ import annotations

import io
import json
import os
import pickle
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

# PPO runs here are rollouts of 2 platforms x 16 steps, smaller than any sensible minibatch on purpose.
# Every test here trains or loads an agent: stable-baselines3 and torch (the rl extra).
pytestmark = [
    pytest.mark.extra("rl"),
    pytest.mark.filterwarnings("ignore:You have specified a mini-batch size:UserWarning"),
]

import stewart_env  # noqa: E402,F401  (registers the environment)
from stewart_env.agents import training  # noqa: E402
from stewart_env.agents.training import (  # noqa: E402
    CONFIG_DIR,
    ENV_ID,
    PAUSE_IN_CHECKPOINT_ENV,
    TrainingError,
    load_agent,
    parse_hyperparameters,
    read_hyperparameters,
    train,
    zoo_eval,
)
from stewart_env.files import sha256_file as _sha256_file  # noqa: E402

TINY = {
    "ppo": {
        "n_timesteps": 1000,
        "policy": "MlpPolicy",
        "n_envs": 2,
        "normalize": "dict(norm_obs=True, norm_reward=True)",
        "n_steps": 16,
        "batch_size": 32,
        "n_epochs": 1,
        "learning_rate": "lin_3e-4",
        "policy_kwargs": "dict(net_arch=dict(pi=[16], vf=[16]), activation_fn=nn.Tanh)",
    },
    "sac": {
        "n_timesteps": 1000,
        "policy": "MlpPolicy",
        "n_envs": 2,
        "normalize": "dict(norm_obs=True, norm_reward=False)",
        "buffer_size": 5000,
        "batch_size": 16,
        "learning_starts": 0,
        "policy_kwargs": "dict(net_arch=[16])",
    },
}


def sha256_file(path: Path) -> str:
    return _sha256_file(path, training.MAX_AGENT_FILE_BYTES)


def tiny_config(path: Path, algo: str, **changes) -> Path:
    """A zoo file with a small network and short rollouts, optionally with ``changes``."""
    path.write_text(yaml.safe_dump({ENV_ID: {**TINY[algo], **changes}}))
    return path


# -- configs are data ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    "name", ["ppo.yml", "ppo_6m.yml", "ppo_integral_6m.yml", "sac.yml", "td3.yml", "tqc.yml", "crossq.yml"]
)
def test_shipped_configs_parse_to_what_python_would_evaluate(name):
    import torch

    algo = name.split(".")[0].split("_")[0]
    entry = read_hyperparameters(algo, CONFIG_DIR / name)
    hp = parse_hyperparameters(algo, entry)
    # rl_zoo3 evaluates the string with torch.nn in scope: the parser must give the same value
    assert hp.algorithm_kwargs["policy_kwargs"] == eval(entry["policy_kwargs"], {"nn": torch.nn, "dict": dict})
    assert hp.normalize is not None and hp.normalize["norm_obs"] is True


def test_parser_accepts_the_zoo_vocabulary():
    import torch

    text = (
        "dict(activation_fn=th.nn.ReLU, net_arch=dict(pi=[64, 64], vf=[64]), log_std_init=-2.0, ortho_init=False, "
        "squash=None, shape=(1, -2), extra={'a': 1, 2: 'b'}, act=nn.LeakyReLU)"
    )
    assert zoo_eval(text, "policy_kwargs") == {
        "activation_fn": torch.nn.ReLU,
        "net_arch": {"pi": [64, 64], "vf": [64]},
        "log_std_init": -2.0,
        "ortho_init": False,
        "squash": None,
        "shape": (1, -2),
        "extra": {"a": 1, 2: "b"},
        "act": torch.nn.LeakyReLU,
    }


@pytest.mark.parametrize(
    "text, what",
    [
        ("np.__builtins__['__import__']('os').system('touch {marker}')", "the call"),
        ("__import__('os').system('touch {marker}')", "the call __import__"),
        ("dict(a=nn.Module.__subclasses__)", "nn.Module.__subclasses__"),
        ("dict(a=nn.Tanh.__init__.__globals__)", "nn.Tanh.__init__.__globals__"),
        ("dict(a=open('{marker}', 'w'))", "the call open"),
        ("dict(a=nn.Linear)", "nn.Linear"),
        ("dict(a=th.load)", "th.load"),
        ("dict(a=lambda: 0)", "a lambda"),
        ("dict(a=[x for x in (1, 2)])", "a comprehension"),
        ("dict(**{'a': 1})", "the call dict"),
        ("{**{'a': 1}}", "the expression"),
        ("dict(a=1 + 2)", "the expression"),
        ("dict(a=os)", "the name os"),
    ],
)
def test_parser_refuses_code_naming_the_key(text, what, tmp_path):
    marker = tmp_path / "ran"
    entry = {**read_hyperparameters("ppo"), "policy_kwargs": text.replace("{marker}", str(marker))}
    with pytest.raises(TrainingError, match="hyperparameter policy_kwargs") as err:
        parse_hyperparameters("ppo", entry)
    assert what in str(err.value)
    assert not marker.exists()
    # the normaliser's string goes through the same parser
    with pytest.raises(TrainingError, match="hyperparameter normalize"):
        parse_hyperparameters(
            "ppo", {**read_hyperparameters("ppo"), "normalize": text.replace("{marker}", str(marker))}
        )
    assert not marker.exists()


# -- a tiny run, its files and their hashes -------------------------------------------------------


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """A PPO run of 2 platforms x 16 steps, 3 rollouts, checkpoints every 32 steps."""
    base = tmp_path_factory.mktemp("tiny")
    config = tiny_config(base / "ppo.yml", "ppo")
    out = base / "run"
    result = train("ppo", out, timesteps=80, checkpoint_freq=32, config=config, progress_bar=False)
    return out, config, result


def test_timesteps_are_rounded_up_to_whole_rollouts_and_said(tiny_run):
    out, _, result = tiny_run
    # 80 requested, rollouts of 2 x 16 = 32 steps: 3 rollouts
    assert (result.requested, result.rollout, result.steps_this_run, result.num_timesteps) == (80, 32, 96, 96)


def test_checkpoints_are_complete_folders_with_manifests_and_pruned(tiny_run):
    out, _, _ = tiny_run
    ckpt = out / "checkpoints"
    # checkpoints at 32, 64 and 96 steps: the default keeps all 3; no temporary folder is left
    assert sorted(p.name for p in ckpt.iterdir()) == ["progress.csv", "step_32", "step_64", "step_96"]
    manifest = json.loads((ckpt / "step_96" / "manifest.json").read_text())
    assert manifest["algo"] == "ppo" and manifest["num_timesteps"] == 96
    for name in ("model.zip", "vecnormalize.pkl"):
        assert manifest["files"][name] == sha256_file(ckpt / "step_96" / name)
    run = json.loads((out / "run.json").read_text())
    assert run["files"]["model.zip"] == sha256_file(out / "model.zip")
    assert not [p for p in out.iterdir() if p.name.startswith(".tmp") or p.name.endswith(".tmp")]


def test_keep_checkpoints_prunes_to_the_newest(tmp_path):
    config = tiny_config(tmp_path / "ppo.yml", "ppo")
    train(
        "ppo",
        tmp_path / "run",
        timesteps=128,
        checkpoint_freq=32,
        keep_checkpoints=2,
        config=config,
        progress_bar=False,
    )
    assert sorted(p.name for p in (tmp_path / "run" / "checkpoints").glob("step_*")) == ["step_128", "step_96"]


class _Payload:
    """A pickle that runs code when loaded: what a malicious vecnormalize.pkl would hold."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (Path.touch, (Path(self.marker),))


def _copy(run: Path, to: Path) -> Path:
    shutil.copytree(run, to)
    return to


def test_tampered_statistics_and_model_are_refused_before_unpickling(tiny_run, tmp_path):
    out, _, _ = tiny_run
    assert load_agent(out).num_timesteps == 96
    assert load_agent(out, checkpoint=64).num_timesteps == 64

    run = _copy(out, tmp_path / "stats")
    marker = tmp_path / "unpickled"
    (run / "vecnormalize.pkl").write_bytes(pickle.dumps(_Payload(marker)))
    with pytest.raises(TrainingError, match="vecnormalize.pkl: its sha256 does not match run.json"):
        load_agent(run)
    assert not marker.exists()

    run = _copy(out, tmp_path / "model")
    with open(run / "model.zip", "ab") as f:
        f.write(b"\0")
    with pytest.raises(TrainingError, match="model.zip: its sha256 does not match run.json"):
        load_agent(run)
    (run / "checkpoints" / "step_64" / "vecnormalize.pkl").write_bytes(pickle.dumps(_Payload(marker)))
    with pytest.raises(TrainingError, match="checkpoint at 64 steps: vecnormalize.pkl does not match"):
        load_agent(run, checkpoint=64)
    with pytest.raises(TrainingError, match=r"no such checkpoint \(checkpoints: 96, 64, 32\)"):
        load_agent(run, checkpoint=50)
    assert not marker.exists()

    run = _copy(out, tmp_path / "nohash")
    manifest = json.loads((run / "run.json").read_text())
    del manifest["files"]
    (run / "run.json").write_text(json.dumps(manifest))
    with pytest.raises(TrainingError, match="records no sha256"):
        load_agent(run)
    (run / "run.json").write_text(json.dumps({"algo": "ppo", "files": ["model.zip"]}))
    with pytest.raises(TrainingError, match=r"not a run manifest .*\(env_kwargs missing or not a dict\)"):
        load_agent(run)


def test_thread_counts_are_restored_after_training_and_inference(tiny_run):
    import numba
    import numpy as np
    import torch

    out, _, _ = tiny_run
    torch.set_num_threads(2)
    numba.set_num_threads(2)
    agent = load_agent(out)
    agent.predict(np.zeros((3, agent.model.observation_space.shape[0]), dtype=np.float32))
    assert (torch.get_num_threads(), numba.get_num_threads()) == (2, 2)


# -- refused runs -------------------------------------------------------------------------------


def test_resume_with_changed_settings_is_refused_listing_each_key(tiny_run, tmp_path):
    out, _, _ = tiny_run
    run = _copy(out, tmp_path / "run")
    before = (run / "run.json").read_text()
    changed = tiny_config(
        tmp_path / "changed.yml", "ppo", normalize=False, n_steps=64, learning_rate=0.1, n_timesteps=5
    )
    with pytest.raises(TrainingError) as err:
        train("ppo", run, config=changed, resume=True, seed=4, model="classical", timesteps=10)
    message = str(err.value)
    for line in (
        'hyperparameter normalize: "dict(norm_obs=True, norm_reward=True)" -> false',
        "hyperparameter n_steps: 16 -> 64",
        'hyperparameter learning_rate: "lin_3e-4" -> 0.1',
        'environment kwarg model: "improved" -> "classical"',
        "seed: 0 -> 4",
    ):
        assert line in message
    assert "n_timesteps" not in message  # the budget may change
    assert (run / "run.json").read_text() == before
    assert not (run / "resumed_96.monitor.csv").exists()


def test_new_run_refuses_a_directory_holding_anything_else(tiny_run, tmp_path):
    out, config, _ = tiny_run
    other = tmp_path / "notes"
    other.mkdir()
    (other / "thesis.tex").write_text("x")
    with pytest.raises(TrainingError, match="not empty and holds no run"):
        train("ppo", other, timesteps=10, config=config)
    assert sorted(os.listdir(other)) == ["thesis.tex"]

    run = _copy(out, tmp_path / "run")
    before = {p.name: p.read_bytes() for p in run.iterdir() if p.is_file()}
    with pytest.raises(TrainingError, match="holds a ppo run; refusing to overwrite it with a sac run"):
        train("sac", run, timesteps=10)
    with pytest.raises(TrainingError, match="already holds a trained agent; pass --resume"):
        train("ppo", run, timesteps=10, config=config)
    assert {p.name: p.read_bytes() for p in run.iterdir() if p.is_file()} == before


# -- signals and kills while a checkpoint is written ------------------------------------------------


def _start(out: Path, config: Path, algo: str, pause: float) -> subprocess.Popen:
    """`stewart-env train` in a child process that pauses ``pause`` s inside every checkpoint write,
    in its own session with the default signal dispositions (whatever the test runner's are)."""

    def defaults():
        for s in (signal.SIGINT, signal.SIGTERM):
            signal.signal(s, signal.SIG_DFL)

    env = {**os.environ, PAUSE_IN_CHECKPOINT_ENV: str(pause)}
    cmd = [
        sys.executable,
        "-m",
        "stewart_env.cli",
        "train",
        "--algo",
        algo,
        "--config",
        str(config),
        "--timesteps",
        "10000000",
        "--checkpoint-freq",
        "64",
        "--out",
        str(out),
        "--no-progress",
    ]
    return subprocess.Popen(
        cmd, env=env, stderr=subprocess.PIPE, text=True, preexec_fn=defaults, start_new_session=True
    )


def _wait_for(path: Path, proc: subprocess.Popen, timeout: float = 60) -> None:
    """Wait for a file or folder matching ``path`` (its name may be a glob pattern)."""
    deadline = time.monotonic() + timeout
    while not list(path.parent.glob(path.name)):
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            raise AssertionError(f"{path} did not appear; stderr: {proc.communicate()[1][-2000:]}")
        time.sleep(0.02)


def _signal_during_writes(
    out: Path, algo: str, pause: float, sig: signal.Signals, *waits: str, timeout: float
) -> tuple[int, str]:
    """Start `stewart-env train` (see _start), wait for each of ``waits`` under out/checkpoints in
    turn, send ``sig`` and wait up to ``timeout`` s for the exit: its return code and stderr."""
    proc = _start(out, tiny_config(out.parent / f"{algo}.yml", algo), algo, pause=pause)
    try:
        for name in waits:
            _wait_for(out / "checkpoints" / name, proc)
        proc.send_signal(sig)
        err = proc.communicate(timeout=timeout)[1]
    finally:
        proc.kill()
    return proc.returncode, err


@pytest.mark.slow
@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_signal_during_a_checkpoint_write_saves_and_resumes(sig, code, tmp_path):
    out = tmp_path / "run"
    returncode, err = _signal_during_writes(out, "ppo", 0.5, sig, ".tmp-step_64-*", timeout=60)
    assert returncode == code, err[-2000:]
    # the checkpoint being written completes; training stops at the next step (+2) and saves that
    assert (out / "checkpoints" / "step_64" / "manifest.json").is_file()
    assert err.rstrip().endswith(f"checkpoint saved in {out / 'checkpoints' / 'step_66'} (continue with --resume)")
    manifest = json.loads((out / "run.json").read_text())
    assert manifest["num_timesteps"] == 66 and not manifest["finished"]
    assert manifest["files"]["model.zip"] == sha256_file(out / "model.zip")

    said = []
    resumed = train("ppo", out, timesteps=20, resume=True, progress_bar=False, report=said.append)
    assert said == ["resuming from checkpoints/step_66 (66 steps)"]
    assert resumed.num_timesteps == 66 + 32  # one whole rollout of 2 x 16 covers the 20 requested


@pytest.mark.slow
def test_kill_during_a_checkpoint_write_resumes_from_the_newest_complete(tmp_path):
    out = tmp_path / "run"
    returncode, _ = _signal_during_writes(out, "sac", 3.0, signal.SIGKILL, "step_64", ".tmp-step_128-*", timeout=30)
    assert returncode == -signal.SIGKILL
    ckpt = out / "checkpoints"
    # killed somewhere inside the write of the checkpoint at 128 steps: no manifest, so not a checkpoint
    (unfinished,) = ckpt.glob(".tmp-step_128-*")
    assert unfinished.is_dir() and not (unfinished / "manifest.json").exists()
    # a newer checkpoint with a damaged replay buffer, as a failing disk would leave it
    shutil.copytree(ckpt / "step_64", ckpt / "step_100")
    manifest = json.loads((ckpt / "step_100" / "manifest.json").read_text())
    (ckpt / "step_100" / "manifest.json").write_text(json.dumps({**manifest, "num_timesteps": 100}))
    with open(ckpt / "step_100" / "replay_buffer.pkl", "r+b") as f:
        f.truncate(100)

    said = []
    resumed = train("sac", out, timesteps=6, resume=True, progress_bar=False, report=said.append)
    assert said == [
        f"skipping checkpoints/{unfinished.name}: a checkpoint write that did not finish",
        "skipping checkpoints/step_100: incomplete or corrupt (replay_buffer.pkl does not match its sha256)",
        "resuming from checkpoints/step_64 (64 steps)",
    ]
    assert resumed.num_timesteps == 70 and not unfinished.exists()
    with open(ckpt / "step_70" / "replay_buffer.pkl", "rb") as f:
        assert pickle.load(f).size() == 70 // 2  # rows of 2 platforms: the 64 saved steps and 6 more


@pytest.mark.slow
def test_a_second_signal_exits_at_once_without_claiming_a_save(tmp_path):
    out = tmp_path / "run"
    proc = _start(out, tiny_config(tmp_path / "ppo.yml", "ppo"), "ppo", pause=60.0)
    try:
        _wait_for(out / "checkpoints" / ".tmp-step_64-*", proc)
        proc.send_signal(signal.SIGTERM)
        time.sleep(0.5)
        start = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        err = proc.communicate(timeout=30)[1]
        waited = time.monotonic() - start
    finally:
        proc.kill()
    assert proc.returncode == 143, err[-2000:]
    assert waited < 10  # well inside the 60 s pause: it did not finish the write
    assert "second signal (SIGTERM); exiting now without saving" in err and "checkpoint saved" not in err
    assert not (out / "checkpoints" / "step_64").exists()


def test_progress_bar_only_on_a_terminal_with_tqdm_and_rich(monkeypatch):
    class Terminal:
        def isatty(self):
            return True

    monkeypatch.setattr(sys, "stderr", Terminal())
    assert training.progress_bar_available()
    monkeypatch.setitem(sys.modules, "rich", None)  # find_spec: not installed
    assert not training.progress_bar_available()
    monkeypatch.delitem(sys.modules, "rich")
    monkeypatch.setattr(sys, "stderr", io.StringIO())
    assert not training.progress_bar_available()


def test_resume_without_a_complete_checkpoint_is_refused(tiny_run, tmp_path):
    out, _, _ = tiny_run
    run = _copy(out, tmp_path / "run")
    for folder in (run / "checkpoints").glob("step_*"):
        (folder / "manifest.json").unlink()
    said = []
    with pytest.raises(TrainingError, match="no complete checkpoint"):
        train("ppo", run, timesteps=10, resume=True, report=said.append)
    assert said == [f"skipping checkpoints/step_{n}: incomplete or corrupt (no manifest.json)" for n in (96, 64, 32)]
