"""Training reinforcement-learning agents on ``StewartPlatform-v0`` with stable-baselines3.

One run lives in one directory ``DIR``:

====================================  ==========================================================
``DIR/run.json``                      the run manifest: algorithm, dynamics model, task, seed,
                                      steps, environment kwargs, hyperparameters, versions
``DIR/model.zip``                     the trained model (SB3 ``save``)
``DIR/vecnormalize.pkl``              the VecNormalize statistics the model was trained with
``DIR/checkpoints/``                  ``model_<steps>_steps.zip`` and ``vecnormalize_<steps>_steps.pkl``
                                      every ``checkpoint_freq`` steps, the replay buffer of the
                                      latest checkpoint (off-policy algorithms) and
                                      ``progress.csv`` (steps and wall time of each checkpoint)
``DIR/tensorboard/``                  TensorBoard logs (``tensorboard --logdir DIR/tensorboard``)
``DIR/monitor.csv``                   per-episode return, length, wall time and termination reason
                                      (``resumed_<steps>.monitor.csv`` for a resumed part)
====================================  ==========================================================

Hyperparameters come from ``configs/agents/{ppo,sac,td3}.yml`` in rl-baselines3-zoo's format,
keyed by the environment id, so the same files drive ``python -m rl_zoo3.train``.  Training runs
on the native batch of platforms through :class:`~stewart_env.envs.StewartPlatformSB3VecEnv`
(one compiled rollout call per step for all ``n_envs`` rows).

:func:`load_agent` turns a run directory back into a policy with SB3's ``predict`` that applies
the saved observation normalisation itself, so it runs on raw environment observations next to
the PD and computed-torque baselines.

stable-baselines3 and torch are imported inside the functions that need them, so that
``stewart-env`` commands that do not train start without loading torch.
"""

from __future__ import annotations

import argparse
import importlib.resources
import inspect
import json
import os
import pickle
import platform as _platform
import re
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

ENV_ID = "StewartPlatform-v0"
ALGORITHMS = ("ppo", "sac", "td3")
OFF_POLICY = ("sac", "td3")
#: Where the zoo-format hyperparameter files live: configs/agents, shipped as stewart_env.configs.
CONFIG_DIR = Path(str(importlib.resources.files("stewart_env.configs") / "agents"))

#: Keys of a zoo hyperparameter entry that are not constructor arguments of the algorithm.
#: rl_zoo3 consumes them itself; ``stewart-env train`` handles the first group and refuses the
#: second with a pointer to rl_zoo3.
ZOO_KEYS_HANDLED = ("n_timesteps", "policy", "normalize", "n_envs", "env_kwargs", "noise_type", "noise_std")
ZOO_KEYS_ZOO_ONLY = ("frame_stack", "env_wrapper", "vec_env_wrapper", "callback", "monitor_kwargs")
#: Zoo keys whose string value is Python code the zoo evaluates.
ZOO_EVALUATED_KEYS = ("policy_kwargs", "replay_buffer_class", "replay_buffer_kwargs")
#: Zoo keys that accept a schedule string "lin_<initial value>".
ZOO_SCHEDULE_KEYS = ("learning_rate", "clip_range", "clip_range_vf")

MANIFEST = "run.json"
MODEL_FILE = "model.zip"
VECNORMALIZE_FILE = "vecnormalize.pkl"
CHECKPOINT_DIR = "checkpoints"
_CHECKPOINT_RE = re.compile(r"^model_(\d+)_steps\.zip$")


class TrainingError(ValueError):
    """A training or loading request that cannot be carried out; the message says why."""


# -- hyperparameters ------------------------------------------------------------------------------


def algorithm_class(algo: str):
    """The stable-baselines3 class of ``algo`` (one of :data:`ALGORITHMS`)."""
    if algo not in ALGORITHMS:
        raise TrainingError(f"unknown algorithm {algo!r}; choose one of {', '.join(ALGORITHMS)}")
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
        with open(path) as f:
            entries = yaml.safe_load(f)
    except yaml.YAMLError as exc:
        raise TrainingError(f"{path}: not valid YAML: {exc}") from None
    if not isinstance(entries, dict) or env_id not in entries:
        found = ", ".join(map(str, entries)) if isinstance(entries, dict) else ""
        raise TrainingError(f"{path}: no entry for {env_id!r} (found: {found or 'nothing'})")
    entry = entries[env_id]
    if not isinstance(entry, dict):
        raise TrainingError(f"{path}: the entry for {env_id!r} must be a mapping of hyperparameters")
    return dict(entry)


def zoo_eval(text: str, key: str) -> Any:
    """Evaluate a zoo hyperparameter string (e.g. ``policy_kwargs: "dict(net_arch=[64, 64])"``)
    as rl_zoo3 does, with ``nn``/``th`` (torch) and ``np`` in scope."""
    import torch

    scope = {"__builtins__": {}, "dict": dict, "list": list, "tuple": tuple, "nn": torch.nn, "th": torch, "np": np}
    try:
        return eval(text, scope)  # the zoo's own format: a Python expression in the config file
    except Exception as exc:
        raise TrainingError(f"hyperparameter {key}: cannot evaluate {text!r}: {exc}") from None


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
    if isinstance(n_envs, bool) or not isinstance(n_envs, int) or n_envs < 1:
        raise TrainingError(f"{algo}: n_envs must be a positive integer, got {n_envs!r}")
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
                      monitor_path: str | os.PathLike | None = None,
                      vecnormalize_path: str | os.PathLike | None = None):
    """The training VecEnv: ``n_envs`` platforms in one native batch, VecMonitor (episode
    statistics, ``monitor_path`` CSV) and, if ``normalize`` is not None, VecNormalize with those
    kwargs, or with the statistics saved at ``vecnormalize_path`` (resuming).  Rows are seeded
    seed, seed + 1, ...; ValueError from the environment for bad kwargs."""
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from stewart_env.envs import StewartPlatformSB3VecEnv

    env = StewartPlatformSB3VecEnv(num_envs=n_envs, **env_kwargs)
    env.seed(seed)
    env = VecMonitor(env, filename=None if monitor_path is None else str(monitor_path),
                     info_keywords=("termination",))
    if normalize is None:
        return env
    if vecnormalize_path is not None:
        return VecNormalize.load(str(vecnormalize_path), env)
    return VecNormalize(env, **normalize)


# -- the run directory ----------------------------------------------------------------------------


def check_writable(directory: str | os.PathLike) -> Path:
    """Create ``directory`` if needed and prove it writable; TrainingError naming it otherwise."""
    path = Path(directory)
    try:
        path.mkdir(parents=True, exist_ok=True)
        probe = path / ".write-test"
        probe.write_text("")
        probe.unlink()
    except OSError as exc:
        raise TrainingError(f"output directory {str(path)!r} is not writable: {exc.strerror or exc}") from None
    return path


def latest_checkpoint(directory: str | os.PathLike) -> int | None:
    """The step count of the latest checkpoint in DIR/checkpoints, or None if there is none."""
    ckpt = Path(directory) / CHECKPOINT_DIR
    steps = [int(m.group(1)) for name in (os.listdir(ckpt) if ckpt.is_dir() else ())
             if (m := _CHECKPOINT_RE.match(name))]
    return max(steps, default=None)


def _checkpoint_files(directory: Path, steps: int) -> dict[str, Path]:
    ckpt = directory / CHECKPOINT_DIR
    return {"model": ckpt / f"model_{steps}_steps.zip", "vecnormalize": ckpt / f"vecnormalize_{steps}_steps.pkl",
            "replay_buffer": ckpt / f"replay_buffer_{steps}_steps.pkl"}


def read_manifest(directory: str | os.PathLike) -> dict[str, Any]:
    """DIR/run.json as a dict; TrainingError if missing or unreadable."""
    path = Path(directory) / MANIFEST
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise TrainingError(f"{directory}: no {MANIFEST}; not a directory written by `stewart-env train`") from None
    except json.JSONDecodeError as exc:
        raise TrainingError(f"{path}: not valid JSON ({exc})") from None


def _versions() -> dict[str, str]:
    import gymnasium
    import stable_baselines3
    import torch

    import stewart_env

    return {"stewart_env": stewart_env.__version__, "stable_baselines3": stable_baselines3.__version__,
            "torch": torch.__version__, "gymnasium": gymnasium.__version__, "numpy": np.__version__,
            "python": _platform.python_version()}


def _write_manifest(directory: Path, manifest: dict[str, Any]) -> None:
    tmp = directory / (MANIFEST + ".tmp")
    tmp.write_text(json.dumps(manifest, indent=2) + "\n")
    os.replace(tmp, directory / MANIFEST)  # atomic: an interrupted write never leaves half a manifest


def _checkpoint_callback(directory: Path, freq: int, save_replay_buffer: bool, wall_offset: float):
    """An SB3 callback calling :func:`save_checkpoint` every ``freq`` environment steps (0: never)
    and logging each checkpoint's step count and training wall time (s, ``wall_offset`` plus the
    time since this call started) to DIR/checkpoints/progress.csv, so that a point of the
    learning curve can be matched to its budget."""
    from stable_baselines3.common.callbacks import BaseCallback

    class Checkpoints(BaseCallback):
        def _on_training_start(self) -> None:
            self.last = self.num_timesteps
            self.start = time.perf_counter() - wall_offset

        def _on_step(self) -> bool:
            if freq and self.num_timesteps - self.last >= freq:
                self.last = self.num_timesteps
                save_checkpoint(self.model, directory, save_replay_buffer)
                log_progress(directory, self.num_timesteps, time.perf_counter() - self.start)
            return True

    return Checkpoints()


def log_progress(directory: Path, num_timesteps: int, wall_time: float) -> None:
    """Append a checkpoint's steps and training wall time (s) to DIR/checkpoints/progress.csv."""
    log = directory / CHECKPOINT_DIR / "progress.csv"
    header = "" if log.exists() else "num_timesteps,wall_time_s\n"
    with log.open("a") as f:
        f.write(f"{header}{num_timesteps},{wall_time:.1f}\n")


def _single_thread() -> None:
    """One thread for torch and for the compiled kernels: for small MLPs and batches of tens of
    platforms a second thread gains little, and on a shared machine it slows everyone else."""
    import numba
    import torch

    torch.set_num_threads(1)
    numba.set_num_threads(1)


def save_checkpoint(model, directory: Path, save_replay_buffer: bool) -> Path:
    """Save ``model``, its VecNormalize statistics and (``save_replay_buffer``) its replay buffer
    as the checkpoint of its step count in DIR/checkpoints.  Only the latest replay buffer is
    kept: it is tens of MB, while the models are small and all kept, for picking a point of the
    learning curve."""
    files = _checkpoint_files(directory, model.num_timesteps)
    files["model"].parent.mkdir(parents=True, exist_ok=True)
    model.save(files["model"])
    vn = model.get_vec_normalize_env()
    if vn is not None:
        vn.save(files["vecnormalize"])
    if save_replay_buffer and getattr(model, "replay_buffer", None) is not None:
        model.save_replay_buffer(files["replay_buffer"])
        for old in files["replay_buffer"].parent.glob("replay_buffer_*_steps.pkl"):
            if old != files["replay_buffer"]:
                old.unlink()
    return files["model"]


# -- training -------------------------------------------------------------------------------------


@dataclass
class TrainResult:
    """What a training call did: the run directory, the total env steps of the model
    (num_timesteps, over all resumes), the steps of this call and its wall time in s."""

    directory: Path
    num_timesteps: int
    steps_this_run: int
    wall_time: float


def train(algo: str, out: str | os.PathLike, *, model: str = "improved", task: str = "setpoint",
          timesteps: int | None = None, seed: int = 0, n_envs: int | None = None,
          checkpoint_freq: int = 50_000, env_kwargs: Mapping[str, Any] | None = None,
          config: str | os.PathLike | None = None, resume: bool = False, progress_bar: bool = True,
          verbose: int = 0) -> TrainResult:
    """Train (or, with ``resume``, continue training) an SB3 agent on StewartPlatform-v0.

    Args:
        algo: "ppo", "sac" or "td3".
        out: the run directory (created; see the module docstring for its contents).
        model, task: the plant's dynamics model and the task (environment kwargs).
        timesteps: environment steps of this call (default the config's n_timesteps).  With
            ``resume`` they are added to the steps already done: num_timesteps continues.
        seed: seeds torch, numpy and the platforms (row i gets seed + i; a resumed run seeds
            its rows with seed + num_timesteps, so it does not replay the first episodes).
        n_envs: platforms in the batch (default the config's n_envs).
        checkpoint_freq: environment steps between checkpoints (0: none but the final one).
        env_kwargs: further environment kwargs (override the config's env_kwargs; ``model`` and
            ``task`` override both).
        config: a zoo hyperparameter file (default configs/agents/<algo>.yml).
        resume: continue from the latest checkpoint in ``out`` (its model, VecNormalize
            statistics and, off-policy, replay buffer).

    Every check (algorithm, config file and entry, hyperparameter names, output directory,
    environment kwargs, resume state) runs before the first training step; failures raise
    :class:`TrainingError` (or ValueError from the environment) naming what is wrong.
    """
    cls = algorithm_class(algo)
    cfg_path = config_path(algo, config)
    hp = parse_hyperparameters(algo, read_hyperparameters(algo, cfg_path))
    if timesteps is None:
        timesteps = hp.n_timesteps
    if isinstance(timesteps, bool) or not isinstance(timesteps, (int, np.integer)) or timesteps < 1:
        raise TrainingError(f"timesteps must be a positive integer, got {timesteps!r}")
    n_envs = hp.n_envs if n_envs is None else n_envs
    if isinstance(n_envs, bool) or not isinstance(n_envs, (int, np.integer)) or n_envs < 1:
        raise TrainingError(f"n_envs must be a positive integer, got {n_envs!r}")
    if isinstance(checkpoint_freq, bool) or not isinstance(checkpoint_freq, (int, np.integer)) or checkpoint_freq < 0:
        raise TrainingError(f"checkpoint_freq must be an integer >= 0, got {checkpoint_freq!r}")
    kwargs = {**hp.env_kwargs, **(env_kwargs or {}), "model": model, "task": task}
    jsonable(kwargs)
    directory = check_writable(out)

    steps_done, segments = 0, []
    if resume:
        manifest = read_manifest(directory)
        if manifest["algo"] != algo:
            raise TrainingError(f"--resume: {directory} holds a {manifest['algo']} run, not {algo}")
        latest = latest_checkpoint(directory)
        if latest is None:
            raise TrainingError(f"--resume: no checkpoint in {directory / CHECKPOINT_DIR}")
        steps_done, segments = latest, manifest.get("segments", [])
        # The run's environment, seed and batch, whatever the command line says: the saved
        # statistics and replay buffer belong to them.
        kwargs, seed, n_envs = manifest["env_kwargs"], manifest["seed"], manifest["n_envs"]
    elif (directory / MODEL_FILE).exists() or latest_checkpoint(directory) is not None:
        raise TrainingError(f"{directory} already holds a trained agent; pass --resume to continue it, "
                            "or choose another output directory")

    _single_thread()
    files = _checkpoint_files(directory, steps_done)
    monitor = "monitor.csv" if not resume else f"resumed_{steps_done}.monitor.csv"
    env = make_training_env(n_envs, kwargs, seed + steps_done, hp.normalize, monitor_path=directory / monitor,
                            vecnormalize_path=files["vecnormalize"] if resume else None)
    try:
        if not resume:
            agent = cls(env=env, seed=seed, device="cpu", verbose=verbose,
                        tensorboard_log=str(directory / "tensorboard"), **hp.algorithm_kwargs)
        else:
            agent = cls.load(files["model"], env=env, device="cpu", tensorboard_log=str(directory / "tensorboard"))
            # A resumed run draws new exploration noise and new episodes (seed + steps done).
            agent.set_random_seed(seed + steps_done)
            if algo in OFF_POLICY and files["replay_buffer"].exists():
                agent.load_replay_buffer(files["replay_buffer"])
        manifest = {
            "env_id": ENV_ID, "algo": algo, "model": kwargs["model"], "task": kwargs["task"], "seed": seed,
            "n_envs": n_envs, "env_kwargs": jsonable(kwargs), "config": str(cfg_path),
            "hyperparameters": jsonable(hp.raw), "normalize": hp.normalize is not None,
            "versions": _versions(), "num_timesteps": steps_done,
            "wall_time": sum(s["wall_time"] for s in segments), "segments": segments, "finished": False,
        }
        _write_manifest(directory, manifest)

        callback = _checkpoint_callback(directory, int(checkpoint_freq), algo in OFF_POLICY, manifest["wall_time"])
        start = time.perf_counter()
        interrupted = False
        try:
            agent.learn(total_timesteps=int(timesteps), callback=callback, progress_bar=progress_bar,
                        tb_log_name=algo, reset_num_timesteps=not resume)
        except KeyboardInterrupt:
            interrupted = True  # keep what was learnt: the checkpoint below lets --resume continue
        wall = time.perf_counter() - start
        if getattr(callback, "last", None) != agent.num_timesteps:  # else the callback just saved it
            save_checkpoint(agent, directory, algo in OFF_POLICY)
            log_progress(directory, agent.num_timesteps, manifest["wall_time"] + wall)
        agent.save(directory / MODEL_FILE)
        if agent.get_vec_normalize_env() is not None:
            agent.get_vec_normalize_env().save(str(directory / VECNORMALIZE_FILE))
        manifest["segments"].append({"start": steps_done, "end": int(agent.num_timesteps), "wall_time": wall,
                                     "interrupted": interrupted})
        manifest.update(num_timesteps=int(agent.num_timesteps), finished=not interrupted,
                        wall_time=sum(s["wall_time"] for s in manifest["segments"]))
        _write_manifest(directory, manifest)
    finally:
        env.close()
    if interrupted:
        raise KeyboardInterrupt
    return TrainResult(directory, int(agent.num_timesteps), int(agent.num_timesteps) - steps_done, wall)


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
        """SB3's interface on raw observations: (action (6,) or (N,6) in [-1, 1], None)."""
        return self.model.predict(self.normalize(observation), state=state, episode_start=episode_start,
                                  deterministic=deterministic)

    def make_env(self, **overrides: Any):
        """``gymnasium.make("StewartPlatform-v0")`` with the training kwargs and ``overrides``."""
        import gymnasium

        import stewart_env  # noqa: F401  (registers the environment)

        return gymnasium.make(ENV_ID, **{**self.env_kwargs, **overrides})


def load_agent(directory: str | os.PathLike, checkpoint: int | None = None) -> TrainedAgent:
    """The agent trained in ``directory`` by ``stewart-env train`` (its final model, or the
    checkpoint at ``checkpoint`` steps) as a :class:`TrainedAgent`."""
    path = Path(directory)
    manifest = read_manifest(path)
    cls = algorithm_class(manifest["algo"])
    if checkpoint is None:
        model_file, vn_file = path / MODEL_FILE, path / VECNORMALIZE_FILE
    else:
        files = _checkpoint_files(path, checkpoint)
        model_file, vn_file = files["model"], files["vecnormalize"]
    if not model_file.exists():
        raise TrainingError(f"{path}: no model at {model_file.name}"
                            + ("; the run has not finished (try --resume)" if checkpoint is None else ""))
    _single_thread()
    model = cls.load(model_file, device="cpu")
    normalizer = None
    if manifest.get("normalize", False):
        if not vn_file.exists():
            raise TrainingError(f"{path}: the model was trained with VecNormalize but {vn_file.name} is missing")
        with open(vn_file, "rb") as f:
            normalizer = pickle.load(f)  # SB3's VecNormalize.save format; normalize_obs needs no env
        normalizer.training = False
    return TrainedAgent(path, manifest, model, normalizer)


# -- command line ---------------------------------------------------------------------------------


def add_cli(subparsers) -> argparse.ArgumentParser:
    """Add ``train`` to an argparse subparsers object; its ``func`` returns an exit code."""
    p = subparsers.add_parser(
        "train", help="train an RL agent (stable-baselines3) on StewartPlatform-v0",
        description="Train a stable-baselines3 agent with the hyperparameters of configs/agents/<algo>.yml "
                    "(rl-baselines3-zoo format). Writes DIR/model.zip, DIR/vecnormalize.pkl, DIR/run.json, "
                    "checkpoints and TensorBoard logs.")
    p.add_argument("--algo", required=True, help=f"algorithm: {', '.join(ALGORITHMS)}")
    p.add_argument("--model", default="improved", help="plant dynamics model (default: improved)")
    p.add_argument("--task", default="setpoint", help="task: setpoint, tracking or disturbance (default: setpoint)")
    p.add_argument("--timesteps", type=int, default=None,
                   help="environment steps of this call (default: the config's n_timesteps; with --resume, "
                        "steps added to those already done)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.add_argument("--out", required=True, help="run directory")
    p.add_argument("--resume", action="store_true", help="continue the run in --out from its latest checkpoint")
    p.add_argument("--n-envs", type=int, default=None, help="platforms in the training batch (default: the config's)")
    p.add_argument("--checkpoint-freq", type=int, default=50_000,
                   help="environment steps between checkpoints, 0 for none but the final (default: 50000)")
    p.add_argument("--config", default=None, help="hyperparameter file (default: configs/agents/<algo>.yml)")
    p.add_argument("--env-kwargs", nargs="*", default=None, metavar="KW",
                   help="environment kwargs: a JSON object or key=value pairs (values parsed as JSON)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_cli_train)
    return p


def _cli_train(args: argparse.Namespace) -> int:
    try:
        result = train(args.algo, args.out, model=args.model, task=args.task, timesteps=args.timesteps,
                       seed=args.seed, n_envs=args.n_envs, checkpoint_freq=args.checkpoint_freq,
                       env_kwargs=parse_env_kwargs(args.env_kwargs), config=args.config, resume=args.resume,
                       progress_bar=not args.no_progress)
    except (TrainingError, ValueError) as exc:
        print(f"stewart-env train: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"stewart-env train: interrupted; checkpoint saved in {Path(args.out) / CHECKPOINT_DIR} "
              "(continue with --resume)", file=sys.stderr)
        return 130
    print(f"trained {args.algo} for {result.steps_this_run} steps ({result.num_timesteps} in total) "
          f"in {result.wall_time:.0f} s -> {result.directory}")
    return 0
