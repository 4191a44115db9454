"""The run directory of ``stewart-env train``: its files, manifest, checkpoints and their hashes.

One run lives in one directory ``DIR``:

====================================  ==========================================================
``DIR/run.json``                      the run manifest: algorithm, dynamics model, task, seed,
                                      steps, environment kwargs, hyperparameters, versions and
                                      the sha256 of the final model and statistics
``DIR/model.zip``                     the trained model (SB3 ``save``)
``DIR/vecnormalize.pkl``              the VecNormalize statistics the model was trained with
``DIR/checkpoints/step_<steps>/``     one checkpoint: ``model.zip``, ``vecnormalize.pkl``, the
                                      replay buffer ``replay_buffer.pkl`` (off-policy algorithms)
                                      and ``manifest.json`` (step count, algorithm, sha256 of
                                      each file); the last ``keep_checkpoints`` are kept
``DIR/checkpoints/progress.csv``      steps and wall time of each checkpoint
``DIR/tensorboard/``                  TensorBoard logs (``tensorboard --logdir DIR/tensorboard``)
``DIR/monitor.csv``                   per-episode return, length, wall time and termination code
                                      (the environment's ``info["termination"]``: 0 for the time
                                      limit, else an index into its ``termination_reasons``;
                                      ``resumed_<steps>.monitor.csv`` for a resumed part)
====================================  ==========================================================

Every file is published atomically through :mod:`stewart_env.files` (temporary name, flush,
rename), and every file read back goes through its bounded reader of regular files.  A checkpoint
is written into ``checkpoints/.tmp-step_<steps>-<random>/`` and renamed to ``step_<steps>/`` once
complete, so a run killed at any moment leaves its newest complete checkpoint, which
:func:`newest_checkpoint` finds by its manifest and hashes.
"""

from __future__ import annotations

import hashlib
import json
import os
import pickle
import platform as _platform
import re
import shutil
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from stewart_env.agents.training.errors import TrainingError
from stewart_env.agents.training.hyperparameters import ALGORITHMS, OFF_POLICY
from stewart_env.files import (
    LOCK_FILE,
    TMP_PREFIX,
    FileError,
    publish,
    publishing,
    publishing_folder,
    read_json,
    read_regular,
    sha256_file,
    write_error,
)
from stewart_env.registration import ENV_ID

__all__ = [
    "sha256_hex",
    "CHECKPOINT_DIR",
    "CHECKPOINT_MANIFEST",
    "DEFAULT_KEEP_CHECKPOINTS",
    "MANIFEST",
    "MAX_AGENT_FILE_BYTES",
    "MAX_MANIFEST_BYTES",
    "MODEL_FILE",
    "PAUSE_IN_CHECKPOINT_ENV",
    "REPLAY_BUFFER_FILE",
    "VECNORMALIZE_FILE",
    "START_UP_FILES",
    "agent_file_writers",
    "check_fresh_directory",
    "checkpoint_hashes",
    "checkpoint_problem",
    "holds_no_run",
    "log_progress",
    "remove_start_up_files",
    "newest_checkpoint",
    "publish_final",
    "read_manifest",
    "remove_unfinished_writes",
    "run_manifest",
    "save_agent",
    "save_checkpoint",
    "step_dirs",
    "unpickle_statistics",
    "verified_bytes",
    "versions",
]

MANIFEST = "run.json"
MODEL_FILE = "model.zip"
VECNORMALIZE_FILE = "vecnormalize.pkl"
REPLAY_BUFFER_FILE = "replay_buffer.pkl"
CHECKPOINT_DIR = "checkpoints"
CHECKPOINT_MANIFEST = "manifest.json"
DEFAULT_KEEP_CHECKPOINTS = 3
_STEP_DIR_RE = re.compile(r"^step_(\d+)$")
#: Bound of a run's or a checkpoint's manifest read from disk (they hold settings and hashes).
MAX_MANIFEST_BYTES = 16 << 20
#: Bound of a model, statistics or replay-buffer file read from disk: well above a replay buffer
#: of millions of transitions, far below a file that never ends.
MAX_AGENT_FILE_BYTES = 16 << 30
#: Seconds to pause inside every checkpoint write, before its rename: lets the tests signal or kill
#: a training process while a checkpoint is being written.
PAUSE_IN_CHECKPOINT_ENV = "STEWART_ENV_TEST_CHECKPOINT_PAUSE"


def agent_file_writers(model, replay_buffer: bool) -> dict[str, Callable[[Path], None]]:
    """{file name: a function writing it to a path} for ``model``, its VecNormalize statistics
    and (``replay_buffer``) its replay buffer.

    Args:
        model: the SB3 model.
        replay_buffer: also the replay buffer (off-policy algorithms).
    """
    writers = {MODEL_FILE: model.save}
    vn = model.get_vec_normalize_env()
    if vn is not None:
        writers[VECNORMALIZE_FILE] = lambda path: vn.save(str(path))
    if replay_buffer and getattr(model, "replay_buffer", None) is not None:
        writers[REPLAY_BUFFER_FILE] = model.save_replay_buffer
    return writers


def sha256_hex(data: bytes) -> str:
    """The sha256 of ``data`` as a manifest records it and :func:`verified_bytes` checks it.

    Args:
        data: a file's bytes.
    """
    return hashlib.sha256(data).hexdigest()


def verified_bytes(folder: Path, hashes: Mapping[str, str], name: str, what: str) -> bytes:
    """The bytes of ``folder/name`` if their sha256 is ``hashes[name]``; TrainingError otherwise.
    Reading once and unpickling these bytes leaves no gap between the check and the load.

    Args:
        folder: the folder of the file.
        hashes: the expected sha256 of each file name.
        name: the file's name.
        what: the manifest the hashes come from, named in the error.
    """
    path = folder / name
    if name not in hashes:
        raise TrainingError(f"{path}: not listed in {what}; refusing to load an unrecorded file")
    if not os.path.lexists(path):
        raise TrainingError(f"{path}: missing ({what} lists it)")
    data = read_regular(path, MAX_AGENT_FILE_BYTES)
    if sha256_hex(data) != hashes[name]:
        raise TrainingError(
            f"{path}: its sha256 does not match {what}: the file was changed, truncated or "
            "replaced after it was written; refusing to unpickle it"
        )
    return data


def unpickle_statistics(data: bytes):
    """The VecNormalize statistics pickled in ``data``; TrainingError if they are something else.

    Args:
        data: the bytes of vecnormalize.pkl, their hash already checked (:func:`verified_bytes`).
    """
    normalizer = pickle.loads(data)  # SB3's VecNormalize.save format; the bytes' hash was checked
    from stable_baselines3.common.vec_env import VecNormalize

    if not isinstance(normalizer, VecNormalize):
        raise TrainingError(f"{VECNORMALIZE_FILE} does not hold VecNormalize statistics")
    return normalizer


def read_manifest(directory: str | os.PathLike) -> dict[str, Any]:
    """DIR/run.json as a dict; TrainingError if missing or unreadable.

    Args:
        directory: the run directory.
    """
    path = Path(directory) / MANIFEST
    if not os.path.lexists(path):
        raise TrainingError(f"{directory}: no {MANIFEST}; not a directory written by `stewart-env train`")
    manifest = read_json(path, MAX_MANIFEST_BYTES, "run manifest")
    if not isinstance(manifest, dict) or manifest.get("algo") not in ALGORITHMS:
        raise TrainingError(f"{path}: not a run manifest of `stewart-env train` (no known algorithm)")
    for key, kind in (("env_kwargs", dict), ("hyperparameters", dict), ("seed", int), ("n_envs", int)):
        if not isinstance(manifest.get(key), kind):
            raise TrainingError(
                f"{path}: not a run manifest of `stewart-env train` ({key} missing or not a {kind.__name__})"
            )
    return manifest


def versions() -> dict[str, str]:
    """The versions of the package and of the libraries a run depends on, for run.json."""
    import gymnasium
    import stable_baselines3
    import torch

    import stewart_env

    return {
        "stewart_env": stewart_env.__version__,
        "stable_baselines3": stable_baselines3.__version__,
        "torch": torch.__version__,
        "gymnasium": gymnasium.__version__,
        "numpy": np.__version__,
        "python": _platform.python_version(),
    }


def run_manifest(
    *,
    algo: str,
    seed: int,
    n_envs: int,
    env_kwargs: Mapping[str, Any],
    config: str,
    hyperparameters: Mapping[str, Any],
    normalize: bool,
    num_timesteps: int,
    segments: list[dict[str, Any]],
    finished: bool,
    files: Mapping[str, str],
) -> dict[str, Any]:
    """A run's manifest (DIR/run.json) as :func:`read_manifest` reads it: what was trained, on
    what (``env_kwargs`` holds the model and the task), with what, how far (``segments``: one
    {start, end, wall_time, interrupted} per training segment), and the sha256 of each of the
    agent's ``files``.

    Args:
        algo: the algorithm's name.
        seed: the run's seed.
        n_envs: the number of platforms in the batch.
        env_kwargs: the environment kwargs.
        config: the hyperparameter file's path.
        hyperparameters: the zoo entry trained with.
        normalize: whether observations and rewards are normalised (VecNormalize).
        num_timesteps: the environment steps done.
        segments: the training segments.
        finished: whether the run is finished.
        files: the sha256 of each of the agent's files.
    """
    return {
        "env_id": ENV_ID,
        "algo": algo,
        "model": env_kwargs["model"],
        "task": env_kwargs["task"],
        "seed": seed,
        "n_envs": int(n_envs),
        "env_kwargs": dict(env_kwargs),
        "config": config,
        "hyperparameters": dict(hyperparameters),
        "normalize": bool(normalize),
        "versions": versions(),
        "num_timesteps": int(num_timesteps),
        "wall_time": sum(s["wall_time"] for s in segments),
        "segments": segments,
        "finished": finished,
        "files": dict(files),
    }


def save_agent(model, directory: Path, manifest: Mapping[str, Any]) -> None:
    """Write ``model`` as a finished run of :func:`~stewart_env.agents.training.train` into
    ``directory`` (created): its final files (:func:`publish_final`), then ``manifest`` with
    their hashes, written last, so that ``evaluate --agent DIR`` loads it.

    Args:
        model: the SB3 model.
        directory: the run directory.
        manifest: the run's manifest, without the hashes.
    """
    directory.mkdir(parents=True, exist_ok=True)
    files = publish_final(model, directory)
    publish(directory / MANIFEST, json.dumps({**manifest, "files": files}, indent=2) + "\n")


def step_dirs(directory: Path) -> list[tuple[int, Path]]:
    """The published checkpoint directories, newest first.

    Args:
        directory: the run directory.
    """
    root = directory / CHECKPOINT_DIR
    found = [
        (int(m.group(1)), root / name)
        for name in (os.listdir(root) if root.is_dir() else ())
        if (m := _STEP_DIR_RE.match(name))
    ]
    return sorted(found, reverse=True)


def _required_files(algo: str, normalize: bool) -> list[str]:
    return [MODEL_FILE] + [VECNORMALIZE_FILE] * normalize + [REPLAY_BUFFER_FILE] * (algo in OFF_POLICY)


def checkpoint_problem(folder: Path, steps: int, algo: str, normalize: bool) -> str | None:
    """Why the checkpoint in ``folder`` cannot be resumed from (None if it is complete: manifest
    present, its step count and algorithm, every file the run needs, every hash matching).

    Args:
        folder: the checkpoint's folder.
        steps: the step count its name gives.
        algo: the algorithm's name.
        normalize: whether the run normalises (its checkpoints hold VecNormalize statistics).
    """
    if not os.path.lexists(folder / CHECKPOINT_MANIFEST):
        return f"no {CHECKPOINT_MANIFEST}"
    try:
        manifest = read_json(folder / CHECKPOINT_MANIFEST, MAX_MANIFEST_BYTES, "checkpoint manifest")
    except FileError as err:
        return f"{CHECKPOINT_MANIFEST}: {err.problem}"
    if not isinstance(manifest, dict) or manifest.get("num_timesteps") != steps or manifest.get("algo") != algo:
        return f"{CHECKPOINT_MANIFEST} is not that of a {algo} checkpoint at {steps} steps"
    hashes = manifest.get("files")
    if not isinstance(hashes, dict):
        return f"{CHECKPOINT_MANIFEST} lists no file hashes"
    for name in _required_files(algo, normalize):
        if name not in hashes:
            return f"{name} missing from its manifest"
        if not os.path.lexists(folder / name):
            return f"{name} missing"
        try:
            digest = sha256_file(folder / name, MAX_AGENT_FILE_BYTES)
        except FileError as err:
            return f"{name}: {err.problem}"
        if digest != hashes[name]:
            return f"{name} does not match its sha256"
    return None


def checkpoint_hashes(folder: Path) -> tuple[dict[str, str], str]:
    """The {file name: sha256} of a checkpoint that :func:`checkpoint_problem` passed, and its
    manifest's name for error messages.

    Args:
        folder: the checkpoint's folder.
    """
    return (
        read_json(folder / CHECKPOINT_MANIFEST, MAX_MANIFEST_BYTES, "checkpoint manifest")["files"],
        f"{CHECKPOINT_DIR}/{folder.name}/{CHECKPOINT_MANIFEST}",
    )


def newest_checkpoint(
    directory: str | os.PathLike, algo: str, normalize: bool, report: Callable[[str], None] = lambda message: None
) -> tuple[int, Path] | None:
    """The step count and folder of the newest complete checkpoint in DIR/checkpoints (None if
    there is none).  Unfinished writes (``.tmp-*``) and incomplete or corrupt checkpoints are
    passed over, each with a line to ``report``.

    Args:
        directory: the run directory.
        algo: the algorithm's name.
        normalize: whether the run normalises.
        report: where the line of each checkpoint passed over goes.
    """
    root = Path(directory) / CHECKPOINT_DIR
    for name in sorted(os.listdir(root) if root.is_dir() else ()):
        if name.startswith(TMP_PREFIX):
            report(f"skipping {CHECKPOINT_DIR}/{name}: a checkpoint write that did not finish")
    for steps, folder in step_dirs(Path(directory)):
        problem = checkpoint_problem(folder, steps, algo, normalize)
        if problem is None:
            return steps, folder
        report(f"skipping {CHECKPOINT_DIR}/{folder.name}: incomplete or corrupt ({problem})")
    return None


def _pause_for_tests() -> None:
    pause = os.environ.get(PAUSE_IN_CHECKPOINT_ENV)
    if pause:
        time.sleep(float(pause))


def save_checkpoint(model, directory: Path, algo: str, keep: int = DEFAULT_KEEP_CHECKPOINTS) -> Path:
    """Save ``model``, its VecNormalize statistics and (off-policy) its replay buffer as the
    checkpoint DIR/checkpoints/step_<num_timesteps>/, atomically: written into a temporary
    folder with a manifest of sha256 hashes, flushed, then renamed.  Only the newest ``keep``
    checkpoints are kept (each holds its own replay buffer, tens of MB off-policy).

    Raises:
        WriteError: naming the checkpoint, if it cannot be written (a full disk): the temporary
            folder is removed, the complete checkpoints are kept.

    Args:
        model: the SB3 model.
        directory: the run directory.
        algo: the algorithm's name.
        keep: how many of the newest checkpoints to keep.
    """
    steps = int(model.num_timesteps)
    root = directory / CHECKPOINT_DIR
    final = root / f"step_{steps}"
    with publishing_folder(final) as tmp:
        files = {}
        for name, write in agent_file_writers(model, replay_buffer=algo in OFF_POLICY).items():
            write(tmp / name)
            files[name] = sha256_file(tmp / name, MAX_AGENT_FILE_BYTES)
        _pause_for_tests()
        (tmp / CHECKPOINT_MANIFEST).write_text(
            json.dumps({"algo": algo, "num_timesteps": steps, "files": files}, indent=2) + "\n"
        )
    for _, old in step_dirs(directory)[keep:]:
        shutil.rmtree(old)
    return final


def publish_final(model, directory: Path) -> dict[str, str]:
    """Write DIR/model.zip and DIR/vecnormalize.pkl, each under a temporary name renamed over the
    previous one; returns their hashes for run.json (which, written last, makes them a set).

    Args:
        model: the SB3 model.
        directory: the run directory.
    """
    files = {}
    for name, write in agent_file_writers(model, replay_buffer=False).items():
        with publishing(directory / name) as tmp:
            write(tmp)
            files[name] = sha256_file(tmp, MAX_AGENT_FILE_BYTES)
    return files


def log_progress(directory: Path, num_timesteps: int, wall_time: float) -> None:
    """Append a checkpoint's steps and training wall time (s) to DIR/checkpoints/progress.csv.

    Args:
        directory: the run directory.
        num_timesteps: the checkpoint's environment steps.
        wall_time: the run's training wall time, s.
    """
    log = directory / CHECKPOINT_DIR / "progress.csv"
    header = "" if log.exists() else "num_timesteps,wall_time_s\n"
    try:
        with log.open("a") as f:
            f.write(f"{header}{num_timesteps},{wall_time:.1f}\n")
    except OSError as err:
        raise write_error(log, err) from None


#: What the start of a run writes before its manifest: its environment's monitor file and the
#: TensorBoard folder.  A folder with nothing else, and no manifest, holds no run: its start was
#: interrupted (Ctrl-C) or failed before the run was recorded.
START_UP_FILES = ("monitor.csv", "tensorboard")


def holds_no_run(directory: Path) -> bool:
    """Whether ``directory`` is missing or holds nothing of a run: nothing but its lock file, the
    temporary files of unfinished writes and the :data:`START_UP_FILES` of an interrupted start.

    Args:
        directory: the run directory.

    Returns:
        True if a new run may start in it as in an empty folder.
    """
    return not directory.is_dir() or all(
        name == LOCK_FILE or name.startswith(TMP_PREFIX) or name in START_UP_FILES for name in os.listdir(directory)
    )


def remove_start_up_files(directory: Path) -> None:
    """Remove the :data:`START_UP_FILES` of an interrupted start from a folder that
    :func:`holds_no_run`; only under the run's lock, before a new run starts in it.

    Args:
        directory: the run directory.
    """
    if not holds_no_run(directory) or not directory.is_dir():
        return
    for name in START_UP_FILES:
        path = directory / name
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        elif os.path.lexists(path):
            path.unlink()


def check_fresh_directory(directory: Path, algo: str) -> None:
    """Refuse to start a run in a directory that holds anything but a run of ``algo`` that saved
    nothing yet (a start that failed before its first checkpoint).

    Args:
        directory: the run directory.
        algo: the algorithm's name.
    """
    # the lock file, the temporary files of a start killed in its first write and the files of a
    # start interrupted before its manifest are no run
    if holds_no_run(directory):
        return
    if not (directory / MANIFEST).is_file():
        raise TrainingError(
            f"{directory} is not empty and holds no run of `stewart-env train` (no {MANIFEST}); "
            "refusing to write into it: choose a new or empty output directory"
        )
    manifest = read_manifest(directory)
    if manifest["algo"] != algo:
        raise TrainingError(
            f"{directory} holds a {manifest['algo']} run; refusing to overwrite it with a {algo} "
            "run: choose another output directory"
        )
    if (directory / MODEL_FILE).exists() or step_dirs(directory):
        raise TrainingError(
            f"{directory} already holds a trained agent; pass --resume to continue it, "
            "or choose another output directory"
        )


def remove_unfinished_writes(directory: Path) -> None:
    """Remove the temporary files and folders of writes that did not finish (a killed run's), in
    the run directory and its checkpoints; only under the run's lock, when no one else writes.

    Args:
        directory: the run directory.
    """
    for folder in (directory, directory / CHECKPOINT_DIR):
        for name in os.listdir(folder) if folder.is_dir() else ():
            if name.startswith(TMP_PREFIX):
                path = folder / name
                shutil.rmtree(path) if path.is_dir() and not path.is_symlink() else path.unlink()
