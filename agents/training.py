"""Training reinforcement-learning agents on ``StewartPlatform-v0`` with stable-baselines3.

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

Every file is published atomically (:mod:`stewart_env.files`): a checkpoint is written into
``checkpoints/.tmp-step_<steps>-<random>/`` and renamed to ``step_<steps>/`` once complete; the
final files are written under temporary names and renamed.  A run killed at any moment leaves its
newest complete checkpoint, which ``--resume`` finds by its manifest and hashes.  SIGINT and
SIGTERM stop training at the next step, save a checkpoint and raise :class:`TrainingInterrupted`;
a second signal exits at once.  One command at a time writes a run: ``train`` holds the run
directory's lock (:func:`stewart_env.files.lock_folder`), and a second one on the same ``--out``
is refused at once.  A full disk or a failing write ends training with
:class:`~stewart_env.files.WriteError` naming the file; the complete checkpoints stay, and
``--resume`` continues from the newest.

Hyperparameters come from ``configs/agents/{ppo,sac,td3}.yml`` in rl-baselines3-zoo's format,
keyed by the environment id, so the same files drive ``python -m rl_zoo3.train``.  The zoo's
string-valued entries (``policy_kwargs: "dict(net_arch=[64, 64])"``) are read by a parser of
that vocabulary (:func:`zoo_eval`), never evaluated as Python.  Training runs on the native batch
of platforms through :class:`~stewart_env.envs.StewartPlatformSB3VecEnv` (one compiled rollout
call per step for all ``n_envs`` rows).

:func:`load_agent` turns a run directory back into a policy with SB3's ``predict`` that applies
the saved observation normalisation itself, so it runs on raw environment observations next to
the PD and computed-torque baselines.  SB3's model zip and the statistics are pickles, i.e. code:
their sha256 is checked against run.json before anything is unpickled, which catches truncated,
swapped or edited files, but a run directory is trusted as a whole, like any pickle.

stable-baselines3 and torch are imported inside the functions that need them, so that
``stewart-env`` commands that do not train start without loading torch.
"""

from __future__ import annotations

import argparse
import ast
import contextlib
import hashlib
import importlib.util
import inspect
import io
import json
import os
import pickle
import platform as _platform
import re
import shutil
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from stewart_env.files import (
    LOCK_FILE,
    TMP_PREFIX,
    FileError,
    WriteError,
    check_not_busy,
    lock_folder,
    publish,
    publishing,
    publishing_folder,
    read_json,
    read_regular,
    sha256_file,
    write_error,
)
from stewart_env.params import MAX_CONFIG_BYTES, config_dir
from stewart_env.progress import on_terminal
from stewart_env.registration import ENV_ID
from stewart_env.validation import integer

ALGORITHMS = ("ppo", "sac", "td3")
OFF_POLICY = ("sac", "td3")
#: Where the zoo-format hyperparameter files live: configs/agents, shipped as stewart_env.configs.
CONFIG_DIR = config_dir("agents")

#: Keys of a zoo hyperparameter entry that are not constructor arguments of the algorithm.
#: rl_zoo3 consumes them itself; ``stewart-env train`` handles the first group and refuses the
#: second with a pointer to rl_zoo3.
ZOO_KEYS_HANDLED = ("n_timesteps", "policy", "normalize", "n_envs", "env_kwargs", "noise_type", "noise_std")
ZOO_KEYS_ZOO_ONLY = ("frame_stack", "env_wrapper", "vec_env_wrapper", "callback", "monitor_kwargs")
#: Zoo keys whose string value is a Python expression to rl_zoo3; here, data in that syntax.
ZOO_EVALUATED_KEYS = ("policy_kwargs", "replay_buffer_class", "replay_buffer_kwargs")
#: Zoo keys that accept a schedule string "lin_<initial value>".
ZOO_SCHEDULE_KEYS = ("learning_rate", "clip_range", "clip_range_vf")
#: The torch.nn activation classes a config may name, as ``nn.<Name>`` or ``th.nn.<Name>``.
ACTIVATIONS = ("ReLU", "Tanh", "ELU", "LeakyReLU", "GELU", "SiLU", "SELU", "Sigmoid", "Softplus", "Mish")

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
RL_INSTALL_HINT = ('install the RL extra: first torch==2.13.0 (the CPU build, not the default CUDA one), then '
                   'pip install "stewart-env[rl]"')


#: Bound of every count (steps, platforms, checkpoints): SB3 keeps its step counters in int64.
MAX_COUNT = 2**62
#: Bound of a training seed: SB3 seeds numpy's global generator with it, which takes 32 bits.
MAX_SEED = 2**32 - 1


class TrainingError(ValueError):
    """A training or loading request that cannot be carried out; the message says why."""


class TrainingInterrupted(KeyboardInterrupt):
    """Training stopped by SIGINT or SIGTERM after saving ``checkpoint``; ``exit_code`` is the
    shell's 128 + signal number (130 for SIGINT, 143 for SIGTERM)."""

    def __init__(self, signum: int, checkpoint: Path):
        super().__init__(signal.Signals(signum).name, str(checkpoint))
        self.signum = signum
        self.checkpoint = checkpoint
        self.exit_code = 128 + signum


def check_rl_installed() -> None:
    """TrainingError with the install command unless stable-baselines3 and torch are importable.
    Looks them up without importing them, so it is cheap and runs before anything is written."""
    missing = [name for name in ("torch", "stable_baselines3") if importlib.util.find_spec(name) is None]
    if missing:
        raise TrainingError(f"{' and '.join(missing)} not installed; {RL_INSTALL_HINT}")


def progress_bar_available() -> bool:
    """SB3's progress bar needs tqdm and rich, and a terminal on stderr to draw on."""
    return all(importlib.util.find_spec(name) is not None for name in ("tqdm", "rich")) and on_terminal()


@contextlib.contextmanager
def single_thread(numba: bool = True) -> Iterator[None]:
    """One thread for torch (and, with ``numba``, the compiled kernels) inside the block, the
    previous counts restored after it: for small MLPs and batches of tens of platforms a second
    thread gains little, and on a shared machine it slows everyone else."""
    import torch

    before_torch = torch.get_num_threads()
    if numba:
        import numba as nb

        before_numba = nb.get_num_threads()
        nb.set_num_threads(1)
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(before_torch)
        if numba:
            nb.set_num_threads(before_numba)


# -- hyperparameters ------------------------------------------------------------------------------


def algorithm_class(algo: str):
    """The stable-baselines3 class of ``algo`` (one of :data:`ALGORITHMS`)."""
    if algo not in ALGORITHMS:
        raise TrainingError(f"unknown algorithm {algo!r}; choose one of {', '.join(ALGORITHMS)}")
    check_rl_installed()
    import stable_baselines3

    return getattr(stable_baselines3, algo.upper())


def config_path(algo: str, config: str | os.PathLike | None = None) -> Path:
    """The hyperparameter file of ``algo``: ``config`` if given, else configs/agents/<algo>.yml."""
    path = Path(config) if config is not None else CONFIG_DIR / f"{algo}.yml"
    if not path.is_file():
        raise TrainingError(f"hyperparameter file not found: {path}")
    return path


def read_hyperparameters(algo: str, config: str | os.PathLike | None = None, env_id: str = ENV_ID) -> dict[str, Any]:
    """The raw zoo entry for ``env_id`` in the hyperparameter file of ``algo`` (a copy)."""
    path = config_path(algo, config)
    try:
        entries = yaml.safe_load(read_regular(path, MAX_CONFIG_BYTES, "config file"))
    except yaml.YAMLError as exc:
        raise TrainingError(f"{path}: not valid YAML: {exc}") from None
    if not isinstance(entries, dict) or env_id not in entries:
        found = ", ".join(map(str, entries)) if isinstance(entries, dict) else ""
        raise TrainingError(f"{path}: no entry for {env_id!r} (found: {found or 'nothing'})")
    entry = entries[env_id]
    if not isinstance(entry, dict):
        raise TrainingError(f"{path}: the entry for {env_id!r} must be a mapping of hyperparameters")
    return dict(entry)


def _describe(node: ast.AST) -> str:
    """What a refused piece of a zoo expression is, for the error message."""
    if isinstance(node, ast.Call):
        return f"the call {ast.unparse(node.func)}(...)"
    if isinstance(node, (ast.Attribute, ast.Name)):
        return f"the name {ast.unparse(node)}"
    if isinstance(node, ast.Lambda):
        return "a lambda"
    if isinstance(node, (ast.ListComp, ast.SetComp, ast.DictComp, ast.GeneratorExp)):
        return "a comprehension"
    if isinstance(node, ast.Constant):
        return f"the constant {node.value!r}"
    return f"the expression {ast.unparse(node)!r}"


def _zoo_value(node: ast.AST, key: str, text: str) -> Any:
    """The data of one node of a zoo expression; TrainingError naming ``key`` for anything else."""
    if isinstance(node, ast.Constant) and (node.value is None or type(node.value) in (bool, int, float, str)):
        return node.value
    if (isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd))
            and isinstance(node.operand, ast.Constant) and type(node.operand.value) in (int, float)):
        return -node.operand.value if isinstance(node.op, ast.USub) else node.operand.value
    if isinstance(node, (ast.List, ast.Tuple)):
        items = [_zoo_value(e, key, text) for e in node.elts]
        return items if isinstance(node, ast.List) else tuple(items)
    if isinstance(node, ast.Dict) and None not in node.keys:  # a None key is a ** unpacking
        keys = [_zoo_value(k, key, text) for k in node.keys]
        if not all(isinstance(k, (str, int, float, bool)) or k is None for k in keys):
            raise TrainingError(f"hyperparameter {key}: dict keys must be names or numbers in {text!r}")
        return dict(zip(keys, (_zoo_value(v, key, text) for v in node.values)))
    if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "dict" and not node.args
            and all(k.arg is not None for k in node.keywords)):
        return {k.arg: _zoo_value(k.value, key, text) for k in node.keywords}
    if isinstance(node, ast.Attribute):
        dotted = ast.unparse(node)
        if dotted in {f"{prefix}.{name}" for prefix in ("nn", "th.nn") for name in ACTIVATIONS}:
            import torch

            return getattr(torch.nn, node.attr)
    raise TrainingError(f"hyperparameter {key}: {_describe(node)} is not allowed in {text!r}; a config holds data "
                        "only: dict(key=value, ...), {...}, [...], (...), numbers, strings, True/False/None and "
                        f"nn.<activation> ({', '.join(ACTIVATIONS)})")


def zoo_eval(text: str, key: str) -> Any:
    """Read a zoo hyperparameter string (e.g. ``policy_kwargs: "dict(net_arch=[64, 64])"``) as
    data: the subset of Python that rl-zoo configs use (see :func:`_zoo_value`), parsed, never
    evaluated, so that a config from a stranger cannot run code."""
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as exc:
        raise TrainingError(f"hyperparameter {key}: not an expression: {text!r} ({exc.msg})") from None
    return _zoo_value(tree.body, key, text)


def _schedule(value: Any, key: str):
    """A zoo schedule ("lin_<x>": linear from x to 0 over training) or a constant, as SB3 takes it."""
    if isinstance(value, str):
        kind, _, initial = value.partition("_")
        try:
            start = float(initial)
        except ValueError:
            start = None
        if kind != "lin" or start is None:
            raise TrainingError(f"hyperparameter {key}: expected a number or 'lin_<number>', got {value!r}")
        from stable_baselines3.common.utils import LinearSchedule

        return LinearSchedule(start, 0.0, 1.0)
    return value


@dataclass
class Hyperparameters:
    """A zoo entry split the way rl_zoo3 splits it.

    algorithm_kwargs go to the algorithm's constructor (policy included); n_envs rows of the
    native batch; n_timesteps the default budget; normalize the VecNormalize keyword arguments
    (None: no normalisation); env_kwargs the entry's environment keyword arguments.
    """

    algorithm_kwargs: dict[str, Any]
    n_envs: int
    n_timesteps: int
    normalize: dict[str, Any] | None
    env_kwargs: dict[str, Any]
    raw: dict[str, Any]


def check_hyperparameter_names(algo: str, entry: Mapping[str, Any]) -> None:
    """Refuse keys that are neither zoo keys nor constructor arguments of the algorithm."""
    cls = algorithm_class(algo)
    valid = set(inspect.signature(cls.__init__).parameters) - {"self", "env"}
    zoo = set(ZOO_KEYS_HANDLED) | set(ZOO_KEYS_ZOO_ONLY)
    unknown = sorted(k for k in entry if k not in valid and k not in zoo)
    if unknown:
        raise TrainingError(f"{algo}: unknown hyperparameter(s) {', '.join(unknown)}; valid: "
                            f"{', '.join(sorted(valid | zoo))}")


def parse_hyperparameters(algo: str, entry: Mapping[str, Any]) -> Hyperparameters:
    """Turn a zoo entry into SB3 arguments, as rl_zoo3's ExperimentManager does."""
    check_hyperparameter_names(algo, entry)
    zoo_only = [k for k in ZOO_KEYS_ZOO_ONLY if k in entry]
    if zoo_only:
        raise TrainingError(f"{algo}: hyperparameter(s) {', '.join(zoo_only)} are handled by rl_zoo3 only; "
                            "train with `python -m rl_zoo3.train` or remove them")
    kwargs = {k: v for k, v in entry.items() if k not in ZOO_KEYS_HANDLED}
    kwargs["policy"] = entry.get("policy", "MlpPolicy")
    for key in ZOO_EVALUATED_KEYS:
        if isinstance(kwargs.get(key), str):
            kwargs[key] = zoo_eval(kwargs[key], key)
    for key in ZOO_SCHEDULE_KEYS:
        if key in kwargs:
            kwargs[key] = _schedule(kwargs[key], key)
    if isinstance(kwargs.get("train_freq"), list):
        kwargs["train_freq"] = tuple(kwargs["train_freq"])
    if entry.get("noise_type") is not None:
        from stable_baselines3.common.noise import NormalActionNoise, OrnsteinUhlenbeckActionNoise

        noise = {"normal": NormalActionNoise, "ornstein-uhlenbeck": OrnsteinUhlenbeckActionNoise}
        kind = str(entry["noise_type"]).strip()
        if kind not in noise:
            raise TrainingError(f"{algo}: noise_type must be one of {', '.join(noise)}, got {kind!r}")
        std = float(entry.get("noise_std", 0.1))
        kwargs["action_noise"] = noise[kind](mean=np.zeros(6), sigma=std * np.ones(6))

    normalize = entry.get("normalize", False)
    if isinstance(normalize, str):
        normalize = zoo_eval(normalize, "normalize")
    if normalize is True:
        normalize = {}
    elif normalize is False:
        normalize = None
    elif not isinstance(normalize, dict):
        raise TrainingError(f"{algo}: normalize must be true, false or a dict (or its string), got {normalize!r}")
    if normalize is not None and "gamma" in entry:
        normalize = {**normalize, "gamma": entry["gamma"]}  # as the zoo: discount the reward as the agent does

    n_envs = entry.get("n_envs", 1)
    _check_count(f"{algo}: n_envs", n_envs, 1)
    if "n_timesteps" not in entry:
        raise TrainingError(f"{algo}: the entry has no n_timesteps")
    env_kwargs = entry.get("env_kwargs") or {}
    if not isinstance(env_kwargs, dict):
        raise TrainingError(f"{algo}: env_kwargs must be a mapping, got {env_kwargs!r}")
    return Hyperparameters(kwargs, n_envs, int(float(entry["n_timesteps"])), normalize, dict(env_kwargs), dict(entry))


# -- environment kwargs from the command line -------------------------------------------------------


def parse_env_kwargs(items: Sequence[str] | None) -> dict[str, Any]:
    """``--env-kwargs`` values: one JSON object, or ``key=value`` tokens whose values are JSON
    (numbers, true/false, lists, objects) or else plain strings."""
    out: dict[str, Any] = {}
    for item in items or ():
        text = item.strip()
        if text.startswith("{"):
            try:
                value = json.loads(text)
            except json.JSONDecodeError as exc:
                raise TrainingError(f"--env-kwargs: not a JSON object: {text!r} ({exc})") from None
            out.update(value)
            continue
        key, sep, raw = text.partition("=")
        if not sep or not key:
            raise TrainingError(f"--env-kwargs: expected key=value or a JSON object, got {item!r}")
        try:
            out[key] = json.loads(raw)
        except json.JSONDecodeError:
            out[key] = raw
    return out


def jsonable(value: Any) -> Any:
    """``value`` with tuples and numpy values made JSON-friendly (for run.json)."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise TrainingError(f"environment kwarg value {value!r} cannot be written to {MANIFEST}; "
                        "pass names, numbers, lists and dicts")


# -- the environment ------------------------------------------------------------------------------


def make_training_env(n_envs: int, env_kwargs: Mapping[str, Any], seed: int, normalize: dict[str, Any] | None,
                      monitor_path: str | os.PathLike | None = None, statistics=None):
    """The training VecEnv: ``n_envs`` platforms in one native batch, VecMonitor (episode
    statistics, ``monitor_path`` CSV) and, if ``normalize`` is not None, VecNormalize with those
    kwargs, or the saved VecNormalize ``statistics`` put on this batch (resuming).  Rows are
    seeded seed, seed + 1, ...; ValueError from the environment for bad kwargs."""
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from stewart_env.envs import StewartPlatformSB3VecEnv

    env = StewartPlatformSB3VecEnv(num_envs=n_envs, **env_kwargs)
    env.seed(seed)
    env = VecMonitor(env, filename=None if monitor_path is None else str(monitor_path),
                     info_keywords=("termination",))
    if normalize is None:
        return env
    if statistics is not None:
        statistics.set_venv(env)  # what VecNormalize.load does after unpickling
        return statistics
    return VecNormalize(env, **normalize)


# -- files: atomic writes and hashes --------------------------------------------------------------


def _agent_file_writers(model, replay_buffer: bool) -> dict[str, Callable[[Path], None]]:
    """{file name: a function writing it to a path} for ``model``, its VecNormalize statistics
    and (``replay_buffer``) its replay buffer."""
    writers = {MODEL_FILE: model.save}
    vn = model.get_vec_normalize_env()
    if vn is not None:
        writers[VECNORMALIZE_FILE] = lambda path: vn.save(str(path))
    if replay_buffer and getattr(model, "replay_buffer", None) is not None:
        writers[REPLAY_BUFFER_FILE] = model.save_replay_buffer
    return writers


def _verified_bytes(folder: Path, hashes: Mapping[str, str], name: str, what: str) -> bytes:
    """The bytes of ``folder/name`` if their sha256 is ``hashes[name]``; TrainingError otherwise.
    Reading once and unpickling these bytes leaves no gap between the check and the load."""
    path = folder / name
    if name not in hashes:
        raise TrainingError(f"{path}: not listed in {what}; refusing to load an unrecorded file")
    if not os.path.lexists(path):
        raise TrainingError(f"{path}: missing ({what} lists it)")
    data = read_regular(path, MAX_AGENT_FILE_BYTES)
    if hashlib.sha256(data).hexdigest() != hashes[name]:
        raise TrainingError(f"{path}: its sha256 does not match {what}: the file was changed, truncated or "
                            "replaced after it was written; refusing to unpickle it")
    return data


def _unpickle_statistics(data: bytes):
    normalizer = pickle.loads(data)  # SB3's VecNormalize.save format; the bytes' hash was checked
    from stable_baselines3.common.vec_env import VecNormalize

    if not isinstance(normalizer, VecNormalize):
        raise TrainingError(f"{VECNORMALIZE_FILE} does not hold VecNormalize statistics")
    return normalizer


# -- the run directory ----------------------------------------------------------------------------


def read_manifest(directory: str | os.PathLike) -> dict[str, Any]:
    """DIR/run.json as a dict; TrainingError if missing or unreadable."""
    path = Path(directory) / MANIFEST
    if not os.path.lexists(path):
        raise TrainingError(f"{directory}: no {MANIFEST}; not a directory written by `stewart-env train`")
    manifest = read_json(path, MAX_MANIFEST_BYTES, "run manifest")
    if not isinstance(manifest, dict) or manifest.get("algo") not in ALGORITHMS:
        raise TrainingError(f"{path}: not a run manifest of `stewart-env train` (no known algorithm)")
    for key, kind in (("env_kwargs", dict), ("hyperparameters", dict), ("seed", int), ("n_envs", int)):
        if not isinstance(manifest.get(key), kind):
            raise TrainingError(f"{path}: not a run manifest of `stewart-env train` ({key} missing or not a "
                                f"{kind.__name__})")
    return manifest


def _versions() -> dict[str, str]:
    import gymnasium
    import stable_baselines3
    import torch

    import stewart_env

    return {"stewart_env": stewart_env.__version__, "stable_baselines3": stable_baselines3.__version__,
            "torch": torch.__version__, "gymnasium": gymnasium.__version__, "numpy": np.__version__,
            "python": _platform.python_version()}


def _step_dirs(directory: Path) -> list[tuple[int, Path]]:
    """The published checkpoint directories, newest first."""
    root = directory / CHECKPOINT_DIR
    found = [(int(m.group(1)), root / name) for name in (os.listdir(root) if root.is_dir() else ())
             if (m := _STEP_DIR_RE.match(name))]
    return sorted(found, reverse=True)


def _required_files(algo: str, normalize: bool) -> list[str]:
    return [MODEL_FILE] + [VECNORMALIZE_FILE] * normalize + [REPLAY_BUFFER_FILE] * (algo in OFF_POLICY)


def checkpoint_problem(folder: Path, steps: int, algo: str, normalize: bool) -> str | None:
    """Why the checkpoint in ``folder`` cannot be resumed from (None if it is complete: manifest
    present, its step count and algorithm, every file the run needs, every hash matching)."""
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


def _checkpoint_hashes(folder: Path) -> tuple[dict[str, str], str]:
    """The {file name: sha256} of a checkpoint that :func:`checkpoint_problem` passed, and its
    manifest's name for error messages."""
    return (read_json(folder / CHECKPOINT_MANIFEST, MAX_MANIFEST_BYTES, "checkpoint manifest")["files"],
            f"{CHECKPOINT_DIR}/{folder.name}/{CHECKPOINT_MANIFEST}")


def newest_checkpoint(directory: str | os.PathLike, algo: str, normalize: bool,
                      report: Callable[[str], None] = lambda message: None) -> tuple[int, Path] | None:
    """The step count and folder of the newest complete checkpoint in DIR/checkpoints (None if
    there is none).  Unfinished writes (``.tmp-*``) and incomplete or corrupt checkpoints are
    passed over, each with a line to ``report``."""
    root = Path(directory) / CHECKPOINT_DIR
    for name in sorted(os.listdir(root) if root.is_dir() else ()):
        if name.startswith(TMP_PREFIX):
            report(f"skipping {CHECKPOINT_DIR}/{name}: a checkpoint write that did not finish")
    for steps, folder in _step_dirs(Path(directory)):
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
    """
    steps = int(model.num_timesteps)
    root = directory / CHECKPOINT_DIR
    final = root / f"step_{steps}"
    with publishing_folder(final) as tmp:
        files = {}
        for name, write in _agent_file_writers(model, replay_buffer=algo in OFF_POLICY).items():
            write(tmp / name)
            files[name] = sha256_file(tmp / name, MAX_AGENT_FILE_BYTES)
        _pause_for_tests()
        (tmp / CHECKPOINT_MANIFEST).write_text(json.dumps({"algo": algo, "num_timesteps": steps, "files": files},
                                                          indent=2) + "\n")
    for _, old in _step_dirs(directory)[keep:]:
        shutil.rmtree(old)
    return final


def _publish_final(model, directory: Path) -> dict[str, str]:
    """Write DIR/model.zip and DIR/vecnormalize.pkl, each under a temporary name renamed over the
    previous one; returns their hashes for run.json (which, written last, makes them a set)."""
    files = {}
    for name, write in _agent_file_writers(model, replay_buffer=False).items():
        with publishing(directory / name) as tmp:
            write(tmp)
            files[name] = sha256_file(tmp, MAX_AGENT_FILE_BYTES)
    return files


def log_progress(directory: Path, num_timesteps: int, wall_time: float) -> None:
    """Append a checkpoint's steps and training wall time (s) to DIR/checkpoints/progress.csv."""
    log = directory / CHECKPOINT_DIR / "progress.csv"
    header = "" if log.exists() else "num_timesteps,wall_time_s\n"
    try:
        with log.open("a") as f:
            f.write(f"{header}{num_timesteps},{wall_time:.1f}\n")
    except OSError as err:
        raise write_error(log, err) from None


# -- signals --------------------------------------------------------------------------------------


class _StopRequest:
    """The first SIGINT/SIGTERM received while training, or None."""

    signum: int | None = None


@contextlib.contextmanager
def _stop_on_signals(stop: _StopRequest) -> Iterator[None]:
    """Inside the block, SIGINT and SIGTERM set ``stop.signum`` (training then stops at the next
    step and saves a checkpoint); a second signal exits at once with 128 + its number.  Only the
    main thread can own signal handlers: elsewhere the block changes nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        name = signal.Signals(signum).name
        if stop.signum is not None:
            os.write(2, f"stewart-env train: second signal ({name}); exiting now without saving\n".encode())
            os._exit(128 + signum)
        stop.signum = signum
        os.write(2, f"stewart-env train: {name} received; saving a checkpoint (send it again to exit at once)\n"
                 .encode())

    previous = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


def _checkpoint_callback(directory: Path, algo: str, freq: int, keep: int, wall_offset: float, stop: _StopRequest):
    """An SB3 callback that stops training once ``stop`` holds a signal, and otherwise calls
    :func:`save_checkpoint` at the first rollout end ``freq`` environment steps after the last
    checkpoint (0: never), logging each checkpoint's step count and training wall time (s,
    ``wall_offset`` plus the time since this call started) to DIR/checkpoints/progress.csv, so
    that a point of the learning curve can be matched to its budget."""
    from stable_baselines3.common.callbacks import BaseCallback

    class Checkpoints(BaseCallback):
        def _on_training_start(self) -> None:
            self.last = self.model.num_timesteps
            self.start = time.perf_counter() - wall_offset

        def _on_step(self) -> bool:
            return stop.signum is None

        def _on_rollout_end(self) -> None:
            # at the end of a rollout, not in _on_step: off-policy, SB3 stores a step's transition
            # after the step's callback, so a checkpoint taken there would miss it
            steps = self.model.num_timesteps
            if freq and steps - self.last >= freq and stop.signum is None:
                self.last = steps
                save_checkpoint(self.model, directory, algo, keep)
                log_progress(directory, steps, time.perf_counter() - self.start)

    return Checkpoints()


# -- training -------------------------------------------------------------------------------------


@dataclass
class TrainResult:
    """What a training call did: the run directory, the total env steps of the model
    (num_timesteps, over all resumes), the steps of this call, its wall time in s, the steps
    requested and the steps of one whole rollout (SB3 trains in whole rollouts, so a call runs
    ``requested`` rounded up to a multiple of ``rollout``)."""

    directory: Path
    num_timesteps: int
    steps_this_run: int
    wall_time: float
    requested: int
    rollout: int


def rollout_steps(agent, algo: str) -> int:
    """Environment steps SB3 collects between two checks of its budget: n_steps x n_envs
    on-policy, train_freq x n_envs off-policy (n_envs for a train_freq counted in episodes)."""
    if algo not in OFF_POLICY:
        return int(agent.n_steps * agent.n_envs)
    freq = agent.train_freq
    return int(freq.frequency * agent.n_envs) if freq.unit.value == "step" else int(agent.n_envs)


def _check_count(name: str, value: Any, minimum: int, maximum: int = MAX_COUNT) -> None:
    """A count of steps, platforms or checkpoints, through the package's one integer check."""
    try:
        integer(name, value, minimum, maximum)
    except ValueError as err:
        raise TrainingError(str(err)) from None


_UNSET = object()


def _show(value: Any) -> str:
    return "(unset)" if value is _UNSET else json.dumps(value)


def run_changes(manifest: Mapping[str, Any], entry: Mapping[str, Any], env_kwargs: Mapping[str, Any],
                seed: int | None, n_envs: int | None) -> list[str]:
    """What differs, key by key ("key: old -> new"), between the run in ``manifest`` and a
    request to continue it with the zoo ``entry``, ``env_kwargs``, ``seed`` and ``n_envs``
    (None: the run's).  The budget ``n_timesteps`` may differ: ``--timesteps`` sets the steps
    added."""
    changes = []
    for what, old, new in (("hyperparameter", manifest.get("hyperparameters", {}), jsonable(dict(entry))),
                           ("environment kwarg", manifest.get("env_kwargs", {}), jsonable(dict(env_kwargs)))):
        for key in sorted(set(old) | set(new)):
            before, after = old.get(key, _UNSET), new.get(key, _UNSET)
            if key != "n_timesteps" and before != after:
                changes.append(f"{what} {key}: {_show(before)} -> {_show(after)}")
    for key, value in (("seed", seed), ("n_envs", n_envs)):
        if value is not None and value != manifest.get(key):
            changes.append(f"{key}: {_show(manifest.get(key, _UNSET))} -> {_show(int(value))}")
    return changes


def _check_fresh_directory(directory: Path, algo: str) -> None:
    """Refuse to start a run in a directory that holds anything but a run of ``algo`` that saved
    nothing yet (a start that failed before its first checkpoint)."""
    # the lock file, and the temporary files of a start killed in its first write, are no run
    if not directory.is_dir() or not [name for name in os.listdir(directory)
                                      if name != LOCK_FILE and not name.startswith(TMP_PREFIX)]:
        return
    if not (directory / MANIFEST).is_file():
        raise TrainingError(f"{directory} is not empty and holds no run of `stewart-env train` (no {MANIFEST}); "
                            "refusing to write into it: choose a new or empty output directory")
    manifest = read_manifest(directory)
    if manifest["algo"] != algo:
        raise TrainingError(f"{directory} holds a {manifest['algo']} run; refusing to overwrite it with a {algo} "
                            "run: choose another output directory")
    if (directory / MODEL_FILE).exists() or _step_dirs(directory):
        raise TrainingError(f"{directory} already holds a trained agent; pass --resume to continue it, "
                            "or choose another output directory")


def _stderr_report(message: str) -> None:
    print(f"stewart-env train: {message}", file=sys.stderr)


def train(algo: str, out: str | os.PathLike, *, model: str | None = None, task: str | None = None,
          timesteps: int | None = None, seed: int | None = None, n_envs: int | None = None,
          checkpoint_freq: int = 50_000, keep_checkpoints: int = DEFAULT_KEEP_CHECKPOINTS,
          env_kwargs: Mapping[str, Any] | None = None, config: str | os.PathLike | None = None,
          resume: bool = False, progress_bar: bool = True, verbose: int = 0,
          report: Callable[[str], None] = _stderr_report) -> TrainResult:
    """Train (or, with ``resume``, continue training) an SB3 agent on StewartPlatform-v0.

    Args:
        algo: "ppo", "sac" or "td3".
        out: the run directory (created; see the module docstring for its contents).  A new run
            refuses a directory that holds anything else than a run of ``algo`` with nothing
            saved yet.
        model, task: the plant's dynamics model and the task (default improved, setpoint).
        timesteps: environment steps of this call, at least (default the config's n_timesteps):
            SB3 collects whole rollouts, so it runs ``timesteps`` rounded up to a multiple of
            :func:`rollout_steps`.  With ``resume`` they are added to the steps already done.
        seed: seeds torch, numpy and the platforms (default 0; row i gets seed + i; a resumed
            run seeds its rows with seed + num_timesteps, so it does not replay the first
            episodes).
        n_envs: platforms in the batch (default the config's n_envs).
        checkpoint_freq: environment steps between checkpoints (0: none but the final one).
        keep_checkpoints: how many of the newest checkpoints to keep.
        env_kwargs: further environment kwargs (override the config's env_kwargs; ``model`` and
            ``task`` override both).
        config: a zoo hyperparameter file (default configs/agents/<algo>.yml; resuming, the
            hyperparameters recorded in run.json).
        resume: continue from the newest complete checkpoint in ``out``.  Every setting left
            None is the run's; one given must equal the run's (the config's n_timesteps
            excepted), else TrainingError lists each difference.
        progress_bar: SB3's progress bar, when stderr is a terminal and tqdm and rich are installed.
        report: where resume messages (the checkpoint taken, those skipped) go; default stderr.

    Every check (installation, algorithm, config file and entry, hyperparameter names, output
    directory, environment kwargs, resume state and file hashes) runs before the first training
    step; failures raise :class:`TrainingError` (or ValueError from the environment) naming what
    is wrong.  SIGINT or SIGTERM during training saves a checkpoint, then raises
    :class:`TrainingInterrupted`.

    Raises:
        stewart_env.files.FolderBusy: another command writes ``out`` (its PID in the message);
            nothing was changed.
        stewart_env.files.WriteError: a write failed (a full disk), naming the file; the complete
            checkpoints are kept and ``resume`` continues from the newest.
        stewart_env.files.FileError: a file of the run is not a regular file, or is too large.
    """
    cls = algorithm_class(algo)
    for name, value, minimum, maximum in (("timesteps", timesteps, 1, MAX_COUNT), ("seed", seed, 0, MAX_SEED),
                                          ("n_envs", n_envs, 1, MAX_COUNT)):
        if value is not None:
            _check_count(name, value, minimum, maximum)
    _check_count("checkpoint_freq", checkpoint_freq, 0)
    _check_count("keep_checkpoints", keep_checkpoints, 1)
    directory = Path(out)
    with contextlib.ExitStack() as held:
        return _train(cls, algo, directory, held, model=model, task=task, timesteps=timesteps, seed=seed,
                      n_envs=n_envs, checkpoint_freq=checkpoint_freq, keep_checkpoints=keep_checkpoints,
                      env_kwargs=env_kwargs, config=config, resume=resume, progress_bar=progress_bar,
                      verbose=verbose, report=report)


def _remove_unfinished_writes(directory: Path) -> None:
    """Remove the temporary files and folders of writes that did not finish (a killed run's), in
    the run directory and its checkpoints; only under the run's lock, when no one else writes."""
    for folder in (directory, directory / CHECKPOINT_DIR):
        for name in os.listdir(folder) if folder.is_dir() else ():
            if name.startswith(TMP_PREFIX):
                path = folder / name
                shutil.rmtree(path) if path.is_dir() and not path.is_symlink() else path.unlink()


def _train(cls, algo: str, directory: Path, held: contextlib.ExitStack, *, model, task, timesteps, seed, n_envs,
           checkpoint_freq, keep_checkpoints, env_kwargs, config, resume, progress_bar, verbose,
           report) -> TrainResult:
    """The body of :func:`train`: the run directory's lock is entered on ``held`` once every check
    that needs no file of the run has passed, and the run's state is read under it."""
    steps_done, segments, checkpoint = 0, [], None
    check_not_busy(directory)  # before any look at the run: a run in progress is reported as such
    if resume:
        read_manifest(directory)  # a directory without a run is refused before its lock is taken
        held.enter_context(lock_folder(directory, create=False))
        previous = read_manifest(directory)
        if previous["algo"] != algo:
            raise TrainingError(f"--resume: {directory} holds a {previous['algo']} run, not {algo}")
        entry = read_hyperparameters(algo, config) if config is not None else dict(previous["hyperparameters"])
        cfg_path = str(config_path(algo, config)) if config is not None else previous.get("config")
        hp = parse_hyperparameters(algo, entry)
        given = {k: v for k, v in (("model", model), ("task", task)) if v is not None}
        changes = run_changes(previous, entry, {**previous["env_kwargs"], **(env_kwargs or {}), **given}, seed, n_envs)
        if changes:
            raise TrainingError(f"--resume: {directory} was trained with other settings; refusing to continue it "
                                "with\n  " + "\n  ".join(changes) + "\nresume without these changes (--timesteps "
                                "may differ: it sets the steps added), or start a new run in another --out")
        kwargs, seed, n_envs = previous["env_kwargs"], previous["seed"], previous["n_envs"]
        found = newest_checkpoint(directory, algo, hp.normalize is not None, report)
        if found is None:
            older = list((directory / CHECKPOINT_DIR).glob("model_*_steps.zip"))
            raise TrainingError(f"--resume: no complete checkpoint in {directory / CHECKPOINT_DIR}" + (
                "; its model_<steps>_steps.zip files are checkpoints of an older stewart-env, which record no "
                "hashes: start a new run" if older else ""))
        steps_done, checkpoint = found
        segments = previous.get("segments", [])
        report(f"resuming from {CHECKPOINT_DIR}/{checkpoint.name} ({steps_done} steps)")
        hashes, what = _checkpoint_hashes(checkpoint)
        saved = {name: _verified_bytes(checkpoint, hashes, name, what) for name in hashes}
        _remove_unfinished_writes(directory)
    else:
        cfg_path = str(config_path(algo, config))
        hp = parse_hyperparameters(algo, read_hyperparameters(algo, cfg_path))
        seed = 0 if seed is None else seed
        n_envs = hp.n_envs if n_envs is None else n_envs
        kwargs = {**hp.env_kwargs, **(env_kwargs or {}), "model": model or "improved", "task": task or "setpoint"}
        jsonable(kwargs)
        _check_fresh_directory(directory, algo)
        from stewart_env.envs import StewartPlatformEnv

        StewartPlatformEnv(**kwargs).close()  # a bad environment keyword fails here, before --out is made
        held.enter_context(lock_folder(directory))
        _check_fresh_directory(directory, algo)  # again, under the lock: another run may have started meanwhile
        _remove_unfinished_writes(directory)
    timesteps = hp.n_timesteps if timesteps is None else int(timesteps)
    progress_bar = progress_bar and progress_bar_available()

    stop = _StopRequest()
    monitor = "monitor.csv" if not resume else f"resumed_{steps_done}.monitor.csv"
    try:
        agent, steps, wall, checkpoint = _learn(cls, algo, directory, hp, kwargs, seed, n_envs, steps_done, segments,
                                                saved if resume else {}, cfg_path, timesteps, monitor, stop,
                                                checkpoint_freq, keep_checkpoints, progress_bar, verbose)
    except (OSError, WriteError) as err:  # a full disk or a failing device, in our writes or SB3's own
        cause = err if isinstance(err, WriteError) else write_error(err.filename or directory, err)
        kept = ("the complete checkpoints are kept (--resume continues from the newest)" if _step_dirs(directory)
                else "no checkpoint was complete")
        raise WriteError(cause.path, f"{cause.problem}; {kept}") from None
    if stop.signum is not None:
        raise TrainingInterrupted(stop.signum, checkpoint)
    return TrainResult(directory, steps, steps - steps_done, wall, timesteps, rollout_steps(agent, algo))


def _learn(cls, algo, directory, hp, kwargs, seed, n_envs, steps_done, segments, saved, cfg_path, timesteps, monitor,
           stop, checkpoint_freq, keep_checkpoints, progress_bar, verbose):
    """The training of :func:`_train` once the run's state is known: (agent, steps, wall time,
    last checkpoint)."""
    resume = bool(saved)
    with single_thread():
        statistics = _unpickle_statistics(saved[VECNORMALIZE_FILE]) if resume and hp.normalize is not None else None
        env = make_training_env(n_envs, kwargs, seed + steps_done, hp.normalize, monitor_path=directory / monitor,
                                statistics=statistics)
        try:
            if not resume:
                agent = cls(env=env, seed=seed, device="cpu", verbose=verbose,
                            tensorboard_log=str(directory / "tensorboard"), **hp.algorithm_kwargs)
            else:
                agent = cls.load(io.BytesIO(saved[MODEL_FILE]), env=env, device="cpu",
                                 tensorboard_log=str(directory / "tensorboard"))
                # A resumed run draws new exploration noise and new episodes (seed + steps done).
                agent.set_random_seed(seed + steps_done)
                if REPLAY_BUFFER_FILE in saved:
                    agent.load_replay_buffer(io.BytesIO(saved[REPLAY_BUFFER_FILE]))
                saved.clear()  # the bytes of a replay buffer: tens of MB, not kept while training
            manifest = {
                "env_id": ENV_ID, "algo": algo, "model": kwargs["model"], "task": kwargs["task"], "seed": seed,
                "n_envs": int(n_envs), "env_kwargs": jsonable(kwargs), "config": cfg_path,
                "hyperparameters": jsonable(hp.raw), "normalize": hp.normalize is not None,
                "versions": _versions(), "num_timesteps": steps_done,
                "wall_time": sum(s["wall_time"] for s in segments), "segments": segments, "finished": False,
                "files": {},
            }
            publish(directory / MANIFEST, json.dumps(manifest, indent=2) + "\n")

            callback = _checkpoint_callback(directory, algo, int(checkpoint_freq), int(keep_checkpoints),
                                            manifest["wall_time"], stop)
            start = time.perf_counter()
            with _stop_on_signals(stop):
                agent.learn(total_timesteps=timesteps, callback=callback, progress_bar=progress_bar,
                            tb_log_name=algo, reset_num_timesteps=not resume)
                wall = time.perf_counter() - start
                steps = int(agent.num_timesteps)
                checkpoint = directory / CHECKPOINT_DIR / f"step_{steps}"
                if getattr(callback, "last", None) != steps or not checkpoint.is_dir():  # else just saved
                    checkpoint = save_checkpoint(agent, directory, algo, int(keep_checkpoints))
                    log_progress(directory, steps, manifest["wall_time"] + wall)
                files = _publish_final(agent, directory)
                manifest["segments"].append({"start": steps_done, "end": steps, "wall_time": wall,
                                             "interrupted": stop.signum is not None})
                manifest.update(num_timesteps=steps, finished=stop.signum is None, files=files,
                                wall_time=sum(s["wall_time"] for s in manifest["segments"]))
                publish(directory / MANIFEST, json.dumps(manifest, indent=2) + "\n")
        finally:
            env.close()
    return agent, steps, wall, checkpoint


# -- loading a trained agent ----------------------------------------------------------------------


class TrainedAgent:
    """A trained SB3 model with its observation normalisation, behind SB3's ``predict``.

    ``predict(obs)`` takes raw environment observations, (obs_dim,) or (N, obs_dim), normalises
    them with the saved VecNormalize statistics (as during training, frozen) and returns the
    model's action(s) and None (no recurrent state).  Attributes: ``algo``, ``env_kwargs`` (the
    environment the agent was trained on, as a dict for gymnasium.make), ``manifest``
    (run.json), ``model`` (the SB3 model), ``num_timesteps``.
    """

    def __init__(self, directory: Path, manifest: dict[str, Any], model, normalizer):
        self.directory = directory
        self.manifest = manifest
        self.algo = manifest["algo"]
        self.env_kwargs = dict(manifest["env_kwargs"])
        self.model = model
        self.num_timesteps = int(model.num_timesteps)
        self._normalizer = normalizer

    def __repr__(self) -> str:
        return (f"TrainedAgent({self.algo} on {self.env_kwargs.get('model')!r}, {self.num_timesteps} steps, "
                f"{self.directory})")

    @property
    def name(self) -> str:
        """A short label for tables: ``<ALGO> (<training model>)``."""
        return f"{self.algo.upper()} ({self.env_kwargs.get('model')})"

    def normalize(self, observation) -> np.ndarray:
        """Raw observations -> the normalised observations the network was trained on (float32)."""
        obs = np.asarray(observation, dtype=np.float32)
        if self._normalizer is None:
            return obs
        return self._normalizer.normalize_obs(obs).astype(np.float32)

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        """SB3's interface on raw observations: (action (6,) or (N,6) in [-1, 1], None).  The
        network runs on one torch thread; the caller's thread count is restored after."""
        with single_thread(numba=False):
            return self.model.predict(self.normalize(observation), state=state, episode_start=episode_start,
                                      deterministic=deterministic)

    def make_env(self, **overrides: Any):
        """``gymnasium.make("StewartPlatform-v0")`` with the training kwargs and ``overrides``."""
        import gymnasium

        import stewart_env  # noqa: F401  (registers the environment)

        return gymnasium.make(ENV_ID, **{**self.env_kwargs, **overrides})


def load_agent(directory: str | os.PathLike, checkpoint: int | None = None) -> TrainedAgent:
    """The agent trained in ``directory`` by ``stewart-env train`` (its final model, or the
    checkpoint at ``checkpoint`` steps) as a :class:`TrainedAgent`.

    The model zip and the statistics are pickles: their sha256 is checked against run.json (or
    the checkpoint's manifest) before they are unpickled, and a file that does not match is
    refused with TrainingError.  This detects changed and damaged files, not a forged directory:
    load only run directories you trust."""
    path = Path(directory)
    manifest = read_manifest(path)
    cls = algorithm_class(manifest["algo"])
    if checkpoint is None:
        folder, what = path, MANIFEST
        if not (path / MODEL_FILE).exists():
            raise TrainingError(f"{path}: no model at {MODEL_FILE}; the run has not finished (try --resume)")
        hashes = manifest.get("files")
        if not isinstance(hashes, dict) or not hashes:
            raise TrainingError(f"{path}: {MANIFEST} records no sha256 of {MODEL_FILE} (written by an older "
                                "stewart-env, or not by `stewart-env train`); refusing to unpickle unverified files")
    else:
        folder = path / CHECKPOINT_DIR / f"step_{checkpoint}"
        problem = (checkpoint_problem(folder, checkpoint, manifest["algo"], bool(manifest.get("normalize")))
                   if folder.is_dir() else "no such checkpoint")
        if problem is not None:
            found = ", ".join(str(steps) for steps, _ in _step_dirs(path)) or "none"
            raise TrainingError(f"{path}: cannot load the checkpoint at {checkpoint} steps: {problem} "
                                f"(checkpoints: {found})")
        hashes, what = _checkpoint_hashes(folder)
    model_bytes = _verified_bytes(folder, hashes, MODEL_FILE, what)
    statistics = (_verified_bytes(folder, hashes, VECNORMALIZE_FILE, what)
                  if manifest.get("normalize", False) else None)
    with single_thread():
        model = cls.load(io.BytesIO(model_bytes), device="cpu")
    normalizer = None
    if statistics is not None:
        normalizer = _unpickle_statistics(statistics)
        normalizer.training = False
    return TrainedAgent(path, manifest, model, normalizer)


# -- command line ---------------------------------------------------------------------------------


def _env_kwargs_token(text: str) -> str:
    """argparse type of one --env-kwargs token: checked here, so that a bad one is an argparse error."""
    try:
        parse_env_kwargs([text])
    except TrainingError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("--env-kwargs: ")) from None
    return text


def add_cli(subparsers) -> argparse.ArgumentParser:
    """Add ``train`` to an argparse subparsers object; its ``func`` returns an exit code."""
    from stewart_env.agents.arguments import TASKS, existing_file, nonnegative_int, plant_model_name, positive_int

    p = subparsers.add_parser(
        "train", help="train an RL agent (stable-baselines3) on StewartPlatform-v0",
        description="Train a stable-baselines3 agent with the hyperparameters of configs/agents/<algo>.yml "
                    "(rl-baselines3-zoo format). Writes DIR/model.zip, DIR/vecnormalize.pkl, DIR/run.json, "
                    "checkpoints and TensorBoard logs. SIGINT (Ctrl-C) or SIGTERM saves a checkpoint and exits "
                    "with 130 or 143; a second signal exits at once.")
    p.add_argument("--algo", required=True, choices=ALGORITHMS, help=f"algorithm: {', '.join(ALGORITHMS)}")
    p.add_argument("--model", type=plant_model_name, default=None,
                   help="plant: a dynamics model, or mujoco for MuJoCo's simulation of the same mechanism "
                        "(needs the mujoco extra) (default: improved; with --resume, the run's)")
    p.add_argument("--task", choices=TASKS, default=None,
                   help="task (default: setpoint; with --resume, the run's)")
    p.add_argument("--timesteps", type=positive_int, default=None,
                   help="environment steps of this call, at least: SB3 rounds up to whole rollouts of n_steps x "
                        "n_envs (default: the config's n_timesteps; with --resume, steps added to those done)")
    p.add_argument("--seed", type=nonnegative_int, default=None,
                   help="random seed (default: 0; with --resume, the run's)")
    p.add_argument("--out", required=True, help="run directory (new or empty, unless --resume)")
    p.add_argument("--resume", action="store_true",
                   help="continue the run in --out from its newest complete checkpoint; a setting that differs from "
                        "the run's is refused, except --timesteps")
    p.add_argument("--n-envs", type=positive_int, default=None,
                   help="platforms in the training batch (default: the config's; with --resume, the run's)")
    p.add_argument("--checkpoint-freq", type=nonnegative_int, default=50_000,
                   help="environment steps between checkpoints, 0 for none but the final (default: 50000)")
    p.add_argument("--keep-checkpoints", type=positive_int, default=DEFAULT_KEEP_CHECKPOINTS, metavar="K",
                   help=f"keep the newest K checkpoints (default: {DEFAULT_KEEP_CHECKPOINTS})")
    p.add_argument("--config", type=existing_file, default=None,
                   help="hyperparameter file (default: configs/agents/<algo>.yml; with --resume, the run's)")
    p.add_argument("--env-kwargs", nargs="*", type=_env_kwargs_token, default=None, metavar="KW",
                   help="environment kwargs: a JSON object or key=value pairs (values parsed as JSON)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar (there is none unless stderr is a "
                   "terminal)")
    p.set_defaults(func=_cli_train)
    return p


def _cli_train(args: argparse.Namespace) -> int:
    try:
        result = train(args.algo, args.out, model=args.model, task=args.task, timesteps=args.timesteps,
                       seed=args.seed, n_envs=args.n_envs, checkpoint_freq=args.checkpoint_freq,
                       keep_checkpoints=args.keep_checkpoints, env_kwargs=parse_env_kwargs(args.env_kwargs),
                       config=args.config, resume=args.resume, progress_bar=not args.no_progress)
    except TrainingInterrupted as stop:
        print(f"stewart-env train: stopped by {signal.Signals(stop.signum).name}; checkpoint saved in "
              f"{stop.checkpoint} (continue with --resume)", file=sys.stderr)
        return stop.exit_code
    except KeyboardInterrupt:
        print("stewart-env train: interrupted before training started; nothing saved", file=sys.stderr)
        return 130
    except (TrainingError, ValueError) as exc:
        print(f"stewart-env train: error: {exc}", file=sys.stderr)
        return 2
    print(f"trained {args.algo}: requested {result.requested} steps, ran {result.steps_this_run} (whole rollouts "
          f"of {result.rollout}); {result.num_timesteps} in total, in {result.wall_time:.0f} s -> {result.directory}")
    return 0
