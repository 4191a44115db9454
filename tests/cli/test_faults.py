"""The user's machine misbehaving: two commands on one output folder, a full disk while a run
writes, and special files (named pipes, devices, directories) where a run's files should be.
Every case ends in one line naming the folder or file and the cause, never a lost run, a hang or
a traceback."""

from __future__ import annotations

import errno
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import yaml

# PPO runs here are rollouts of 2 platforms x 16 steps, smaller than any sensible minibatch on purpose.
pytestmark = pytest.mark.filterwarnings("ignore:You have specified a mini-batch size:UserWarning")

import stewart_env  # noqa: E402,F401  (registers the environment)
from stewart_env import files  # noqa: E402
from stewart_env.agents import training  # noqa: E402
from stewart_env.agents.studies import mismatch  # noqa: E402
from stewart_env.agents.training import ENV_ID, PAUSE_IN_CHECKPOINT_ENV, load_agent, train  # noqa: E402
from stewart_env.cli import main  # noqa: E402
from stewart_env.files import FileError, FolderBusy, WriteError, lock_folder  # noqa: E402

FILES_MODULE = Path(files.__file__)
TINY_PPO = {
    "n_timesteps": 1000,
    "policy": "MlpPolicy",
    "n_envs": 2,
    "normalize": "dict(norm_obs=True, norm_reward=True)",
    "n_steps": 16,
    "batch_size": 32,
    "n_epochs": 1,
    "policy_kwargs": "dict(net_arch=dict(pi=[16], vf=[16]))",
}
BUSY = re.compile(
    r"output directory '(?P<folder>[^']+)' is in use by another stewart-env command "
    r"\(PID (?P<pid>\d+)\); wait for it to end, or choose another output directory"
)
# A hostile file must be refused well within this (a FIFO would block for ever, /dev/zero never ends).
REFUSAL_SECONDS = 10.0


def tiny_config(path: Path) -> Path:
    path.write_text(yaml.safe_dump({ENV_ID: TINY_PPO}))
    return path


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file below ``folder`` with its bytes (the lock file's too)."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def hold_lock(folder: Path) -> subprocess.Popen:
    """A process that holds ``folder``'s lock until killed (stewart_env.files loaded on its own: fast)."""
    code = (
        "import importlib.util, sys, time\n"
        "spec = importlib.util.spec_from_file_location('files', sys.argv[1])\n"
        "files = importlib.util.module_from_spec(spec); spec.loader.exec_module(files)\n"
        "with files.lock_folder(sys.argv[2]):\n"
        "    print('locked', flush=True)\n"
        "    time.sleep(600)\n"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", code, str(FILES_MODULE), str(folder)], stdout=subprocess.PIPE, text=True
    )
    assert proc.stdout.readline().strip() == "locked"
    return proc


@pytest.fixture
def held(tmp_path):
    """A folder with a run's leftovers, locked by another process: (folder, its PID)."""
    folder = tmp_path / "out"
    folder.mkdir()
    (folder / "run.json").write_text("{}")
    proc = hold_lock(folder)
    yield folder, proc.pid
    proc.kill()
    proc.wait()


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """A finished PPO run of 2 platforms x 16 steps, checkpoints every 32 steps (32, 64, 96)."""
    base = tmp_path_factory.mktemp("faults")
    out = base / "run"
    train("ppo", out, timesteps=80, checkpoint_freq=32, config=tiny_config(base / "ppo.yml"), progress_bar=False)
    return out


def copy_run(run: Path, to: Path) -> Path:
    shutil.copytree(run, to)
    return to


# -- one writer per output folder -------------------------------------------------------------------


def test_a_locked_folder_is_refused_naming_the_holder_and_released_when_it_dies(tmp_path):
    folder = tmp_path / "out"
    proc = hold_lock(folder)
    try:
        with pytest.raises(FolderBusy) as caught:
            with lock_folder(folder):
                pass
        assert BUSY.fullmatch(str(caught.value)).group("folder") == str(folder)
        assert caught.value.pid == proc.pid
    finally:
        proc.send_signal(signal.SIGKILL)  # as a killed run: no chance to unlock
        proc.wait()
    with lock_folder(folder):  # the system released the dead process's lock
        with pytest.raises(FolderBusy, match=rf"\(PID {os.getpid()}\)"):  # and holds it for one holder only
            with lock_folder(folder):
                pass


@pytest.mark.extra("rl")
def test_train_on_a_locked_folder_touches_nothing(held):
    folder, pid = held
    before = snapshot(folder)
    with pytest.raises(FolderBusy, match=rf"\(PID {pid}\)"):
        train("ppo", folder, timesteps=10, progress_bar=False)
    with pytest.raises(FolderBusy, match=rf"\(PID {pid}\)"):
        train("ppo", folder, timesteps=10, resume=True, progress_bar=False)
    assert snapshot(folder) == before


@pytest.mark.extra("rl")
@pytest.mark.parametrize(
    "command",
    [
        ["train", "--algo", "ppo", "--timesteps", "10", "--no-progress"],
        ["train", "--algo", "ppo", "--timesteps", "10", "--resume", "--no-progress"],
        [
            "mismatch",
            "--algo",
            "none",
            "--train-models",
            "improved",
            "--test-models",
            "improved",
            "--simplifications",
            "none",
            "--episodes",
            "1",
            "--max-steps",
            "5",
            "--no-progress",
        ],
        ["evaluate", "--policy", "pd", "--episodes", "1", "--max-steps", "5"],
    ],
)
def test_a_command_on_a_locked_folder_exits_with_one_line(held, command, capsys):
    folder, pid = held
    before = snapshot(folder)
    assert main([*command, "--out", str(folder)]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert BUSY.search(err) and f"(PID {pid})" in err and str(folder) in err
    assert err.startswith(f"stewart-env {command[0]}: error: ")
    assert snapshot(folder) == before


def test_temporary_files_are_unique_and_the_writability_probe_leaves_nothing(tmp_path):
    names = set()

    def publish_one(i):
        with files.publishing(tmp_path / "run.json") as tmp:
            names.add(tmp.name)
            tmp.write_text(json.dumps({"seed": i}))
            time.sleep(0.05)  # both writers inside at once

    threads = [threading.Thread(target=publish_one, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(names) == 2  # each writer its own temporary file: neither renames the other's
    assert json.loads((tmp_path / "run.json").read_text())["seed"] in (0, 1)
    for _ in range(2):
        files.check_writable(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.json"]


def test_a_study_refuses_agents_shared_through_a_symbolic_link(tmp_path):
    shared = tmp_path / "shared_agents"
    shared.mkdir()
    out = tmp_path / "study"
    out.mkdir()
    (out / "agents").symlink_to(shared)
    with pytest.raises(mismatch.MismatchError, match=r"agents is a symbolic link: a study's agents are not shared"):
        mismatch.run_mismatch(
            out, ["improved"], ["improved"], algo=None, episodes=1, max_steps=5, simplifications=[], progress=False
        )
    assert not (out / mismatch.STUDY_FILE).exists()


def _cli(*args: str, env: dict | None = None) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "stewart_env.cli", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "MPLBACKEND": "Agg", **(env or {})},
    )


#: Seconds a command may take before a test calls it hung: a guard against a hang, not a speed
#: check (two training processes on a loaded 2-core machine take minutes).
HANG = 600


def _wait_for_holder(folder: Path, proc: subprocess.Popen, timeout: float = HANG) -> None:
    """Until ``proc`` holds ``folder``'s lock (its PID written into the lock file)."""
    deadline = time.monotonic() + timeout
    lock = folder / files.LOCK_FILE
    while not (lock.exists() and lock.read_text().strip() == str(proc.pid)):
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            raise AssertionError(f"no lock by {proc.pid}; stderr: {proc.communicate()[1][-2000:]}")
        time.sleep(0.05)


@pytest.mark.slow  # two training processes: about 30 s
def test_two_train_commands_on_one_folder_one_runs_the_other_is_refused(tmp_path):
    out, config = tmp_path / "run", tiny_config(tmp_path / "ppo.yml")
    common = [
        "train",
        "--algo",
        "ppo",
        "--config",
        str(config),
        "--timesteps",
        "64",
        "--checkpoint-freq",
        "32",
        "--out",
        str(out),
        "--no-progress",
    ]
    # the first pauses inside each checkpoint write, so the second surely starts while it runs
    first = _cli(*common, "--seed", "1", env={PAUSE_IN_CHECKPOINT_ENV: "10"})
    _wait_for_holder(out, first)
    second = _cli(*common, "--seed", "2")
    _, err2 = second.communicate(timeout=HANG)
    _, err1 = first.communicate(timeout=HANG)
    assert first.returncode == 0, err1[-2000:]
    assert second.returncode == 2
    last = err2.strip().splitlines()[-1]
    assert last.startswith("stewart-env train: error: ") and f"(PID {first.pid})" in last and BUSY.search(last)
    # one run, whole: the first's seed, each checkpoint logged once, one TensorBoard run
    assert json.loads((out / "run.json").read_text())["seed"] == 1
    steps = [line.split(",")[0] for line in (out / "checkpoints" / "progress.csv").read_text().splitlines()[1:]]
    assert steps == ["32", "64"]
    assert len(list((out / "tensorboard").iterdir())) == 1
    assert load_agent(out).num_timesteps == 64


@pytest.mark.slow  # two studies in two processes, one training a tiny agent: about 40 s
def test_two_mismatch_commands_on_one_folder_one_runs_the_other_is_refused(tmp_path):
    out, config = tmp_path / "study", tiny_config(tmp_path / "ppo.yml")
    common = [
        "mismatch",
        "--algo",
        "ppo",
        "--config",
        str(config),
        "--timesteps",
        "32",
        "--n-envs",
        "2",
        "--train-models",
        "improved",
        "--test-models",
        "improved",
        "--simplifications",
        "none",
        "--episodes",
        "1",
        "--max-steps",
        "5",
        "--out",
        str(out),
        "--no-progress",
    ]
    # the first pauses inside its agent's final checkpoint write, holding the study's lock
    first = _cli(*common, env={PAUSE_IN_CHECKPOINT_ENV: "15"})
    _wait_for_holder(out, first)
    second = _cli(*common)
    _, err2 = second.communicate(timeout=HANG)
    _, err1 = first.communicate(timeout=HANG)
    assert first.returncode == 0, err1[-2000:]
    assert second.returncode == 2
    last = err2.strip().splitlines()[-1]
    assert last.startswith("stewart-env mismatch: error: ") and f"(PID {first.pid})" in last
    agent = out / "agents" / "improved" / "seed_0"
    assert len(json.loads((agent / "run.json").read_text())["segments"]) == 1  # trained once
    cells = sorted((out / "cells").rglob("*.json"))
    assert len(cells) == 3  # PD, CT and PPO on the one plant
    ppo = json.loads((out / "cells" / "ppo_improved" / "improved" / "seed_0.json").read_text())
    assert ppo["spec"]["agent_sha256"] == files.sha256_file(agent / "model.zip", training.MAX_AGENT_FILE_BYTES)


# -- a full disk ------------------------------------------------------------------------------------


def _full_disk_at_checkpoint(monkeypatch, failing_step: int) -> None:
    """The statistics' writer of the checkpoint at ``failing_step`` writes a little, then finds
    the disk full, as a real writer would."""
    from stewart_env.agents.training import rundir

    writers = rundir.agent_file_writers

    def failing(model, replay_buffer):
        found = writers(model, replay_buffer)
        if int(model.num_timesteps) == failing_step:

            def full(path):
                Path(path).write_bytes(b"partial")
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

            found[training.VECNORMALIZE_FILE] = full
        return found

    monkeypatch.setattr(rundir, "agent_file_writers", failing)


@pytest.mark.extra("rl")
def test_a_full_disk_during_a_checkpoint_is_one_line_and_resume_continues(tmp_path, monkeypatch, capsys):
    out, config = tmp_path / "run", tiny_config(tmp_path / "ppo.yml")
    _full_disk_at_checkpoint(monkeypatch, 64)
    code = main(
        [
            "train",
            "--algo",
            "ppo",
            "--config",
            str(config),
            "--timesteps",
            "96",
            "--checkpoint-freq",
            "32",
            "--out",
            str(out),
            "--no-progress",
        ]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert err[-1] == (
        f"stewart-env train: error: cannot write {out / 'checkpoints' / 'step_64'}: No space left on "
        "device; the complete checkpoints are kept (--resume continues from the newest)"
    )
    assert not [p for p in (*out.iterdir(), *(out / "checkpoints").iterdir()) if p.name.startswith(".tmp")]
    assert sorted(p.name for p in (out / "checkpoints").glob("step_*")) == ["step_32"]
    assert training.checkpoint_problem(out / "checkpoints" / "step_32", 32, "ppo", True) is None
    monkeypatch.undo()
    said = []
    resumed = train("ppo", out, timesteps=32, resume=True, progress_bar=False, report=said.append)
    assert said == ["resuming from checkpoints/step_32 (32 steps)"]
    assert resumed.num_timesteps == 64 and load_agent(out).num_timesteps == 64


@pytest.mark.extra("rl")
def test_a_full_disk_at_the_final_save_keeps_the_checkpoint_and_resume_continues(tmp_path, monkeypatch):
    out, config = tmp_path / "run", tiny_config(tmp_path / "ppo.yml")
    train("ppo", out, timesteps=32, checkpoint_freq=32, config=config, progress_bar=False)
    real, manifests = Path.write_bytes, []

    def full(self, data):
        if self.name.startswith(".tmp-run-"):
            manifests.append(self)
            if len(manifests) == 2:  # run.json at the end of the run, the last file of the final save
                real(self, data[:10])
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(self, data)

    monkeypatch.setattr(Path, "write_bytes", full)
    with pytest.raises(WriteError) as caught:
        train("ppo", out, timesteps=32, resume=True, progress_bar=False)
    monkeypatch.undo()
    assert str(caught.value) == (
        f"cannot write {out / 'run.json'}: No space left on device; the complete checkpoints "
        "are kept (--resume continues from the newest)"
    )
    assert json.loads((out / "run.json").read_text())["num_timesteps"] == 32  # the one written before: whole
    assert not [p for p in out.iterdir() if p.name.startswith(".tmp")]
    said = []
    resumed = train("ppo", out, timesteps=32, resume=True, progress_bar=False, report=said.append)
    assert said == ["resuming from checkpoints/step_64 (64 steps)"]
    assert resumed.num_timesteps == 96 and load_agent(out).num_timesteps == 96


def test_a_full_disk_while_a_study_writes_a_cell_keeps_the_finished_cells(tmp_path, monkeypatch, capsys):
    kwargs = [
        "mismatch",
        "--algo",
        "none",
        "--train-models",
        "improved",
        "--test-models",
        "improved",
        "--simplifications",
        "c2",
        "--episodes",
        "1",
        "--max-steps",
        "5",
        "--no-progress",
        "--out",
        str(tmp_path),
    ]
    publish, written = files.publish, []

    def full_after_two(path, data):
        is_cell = Path(path).parent.parent.parent.name == mismatch.CELLS_DIR
        if is_cell and len(written) == 2:
            with files.publishing(path) as tmp:
                tmp.write_bytes(data[:5].encode())
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        publish(path, data)
        if is_cell:
            written.append(path)

    monkeypatch.setattr(files, "publish", full_after_two)
    assert main(kwargs) == 1
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert re.fullmatch(
        rf"stewart-env mismatch: error: cannot write {re.escape(str(tmp_path))}/cells/\S+\.json: No "
        rf"space left on device; finished agents and cells are kept in {re.escape(str(tmp_path))} "
        r"\(run the same command again to continue\)",
        err,
    ), err
    finished = sorted((tmp_path / "cells").rglob("*.json"))
    assert finished == sorted(written) and all(json.loads(p.read_text())["metrics"] for p in finished)
    assert not list(tmp_path.rglob(".tmp*"))
    monkeypatch.undo()
    assert main(kwargs) == 0
    assert len(list((tmp_path / "cells").rglob("*.json"))) == 4


# -- special files where a run's files should be -----------------------------------------------------


def _replace(path: Path, kind: str) -> None:
    if path.is_dir():
        shutil.rmtree(path)
    elif path.exists() or path.is_symlink():
        path.unlink()
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "zero":
        path.symlink_to("/dev/zero")
    else:
        path.mkdir()


def _in_time(fn, seconds: float = REFUSAL_SECONDS, fails: bool = True):
    """fn()'s exception (``fails``) or value, failing the test if fn blocks (a FIFO) or reads for
    ever (/dev/zero)."""
    caught, value = [], []

    def call():
        try:
            value.append(fn())
        except BaseException as exc:  # noqa: BLE001  (reported to the test)
            caught.append(exc)

    thread = threading.Thread(target=call, daemon=True)
    thread.start()
    thread.join(seconds)
    assert not thread.is_alive(), "blocked on a special file"
    if fails:
        assert caught, "a special file was accepted"
        return caught[0]
    assert not caught, caught
    return value[0]


PROBLEM = {
    "fifo": "not a regular file (a FIFO, socket or device)",
    "zero": "not a regular file (a FIFO, socket or device)",
    "directory": "a directory, not a",
}


@pytest.mark.extra("rl")
@pytest.mark.parametrize("kind", ["fifo", "zero", "directory"])
@pytest.mark.parametrize("name", ["run.json", "model.zip", "vecnormalize.pkl"])
def test_special_files_in_an_agent_folder_are_refused_at_once(tiny_run, tmp_path, name, kind, capsys):
    run = copy_run(tiny_run, tmp_path / "run")
    _replace(run / name, kind)
    error = _in_time(lambda: load_agent(run))
    assert isinstance(error, FileError)
    assert str(error).startswith(f"{run / name}: {PROBLEM[kind]}")
    # the command line says the same in one line
    assert main(["evaluate", "--agent", str(run), "--episodes", "1", "--max-steps", "5"]) == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == f"stewart-env evaluate: error: {error}"


@pytest.mark.extra("rl")
@pytest.mark.parametrize("kind", ["fifo", "zero", "directory"])
def test_special_files_in_a_checkpoint_are_passed_over_when_resuming(tiny_run, tmp_path, kind):
    run = copy_run(tiny_run, tmp_path / "run")
    _replace(run / "checkpoints" / "step_96" / "model.zip", kind)
    _replace(run / "checkpoints" / "step_64" / "manifest.json", kind)
    said = []
    resumed = _in_time(
        lambda: train("ppo", run, timesteps=16, resume=True, progress_bar=False, report=said.append),
        seconds=60,
        fails=False,
    )
    assert resumed.num_timesteps == 64  # one rollout of 2 x 16 steps after the 32 of step_32
    assert said[0].startswith(f"skipping checkpoints/step_96: incomplete or corrupt (model.zip: {PROBLEM[kind]}")
    assert said[1].startswith(f"skipping checkpoints/step_64: incomplete or corrupt (manifest.json: {PROBLEM[kind]}")
    assert said[2:] == ["resuming from checkpoints/step_32 (32 steps)"]


@pytest.mark.extra("rl")
def test_oversized_run_manifest_is_refused_before_reading(tiny_run, tmp_path):
    run = copy_run(tiny_run, tmp_path / "run")
    with open(run / "run.json", "r+b") as f:
        f.truncate(1 << 40)  # 1 TB on paper, no blocks on disk
    with pytest.raises(FileError, match=rf"run.json: larger than {training.MAX_MANIFEST_BYTES} bytes \({1 << 40} "):
        load_agent(run)


@pytest.mark.parametrize("kind", ["fifo", "zero", "directory"])
@pytest.mark.parametrize("which", ["study", "cell"])
def test_special_files_in_a_study_folder_are_refused_at_once(tmp_path, which, kind):
    kwargs = dict(
        train_models=["improved"],
        test_models=["improved"],
        algo=None,
        episodes=1,
        simplifications=[],
        max_steps=5,
        progress=False,
    )
    mismatch.run_mismatch(tmp_path, **kwargs)
    target = (
        tmp_path / mismatch.STUDY_FILE if which == "study" else next((tmp_path / mismatch.CELLS_DIR).rglob("*.json"))
    )
    _replace(target, kind)
    error = _in_time(lambda: mismatch.run_mismatch(tmp_path, **kwargs))
    assert isinstance(error, FileError) and str(error).startswith(f"{target}: {PROBLEM[kind]}")


@pytest.mark.parametrize("kind", ["fifo", "zero", "directory"])
def test_special_hyperparameter_file_is_refused_at_once(tmp_path, kind):
    config = tmp_path / "ppo.yml"
    _replace(config, kind)
    error = _in_time(lambda: training.read_hyperparameters("ppo", config))
    assert isinstance(error, (FileError, training.TrainingError))
    assert str(config) in str(error)


def test_a_huge_hyperparameter_file_is_refused_before_it_is_read(tmp_path):
    from stewart_env.params import MAX_CONFIG_BYTES

    config = tmp_path / "ppo.yml"
    with open(config, "wb") as f:
        f.truncate(1 << 40)  # 1 TB on paper, no blocks on disk
    with pytest.raises(FileError, match=rf"ppo.yml: larger than {MAX_CONFIG_BYTES} bytes"):
        training.read_hyperparameters("ppo", config)


@pytest.mark.extra("rl")
def test_a_start_killed_in_its_first_write_does_not_block_a_new_start(tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    (out / ".tmp-run-abc123.json").write_text('{"alg')  # what a kill inside the first run.json write leaves
    (out / files.LOCK_FILE).write_text("12345\n")  # and its lock file, no longer held
    train("ppo", out, timesteps=32, config=tiny_config(tmp_path / "ppo.yml"), progress_bar=False)
    assert not [p for p in out.iterdir() if p.name.startswith(".tmp")]
    assert load_agent(out).num_timesteps == 32
