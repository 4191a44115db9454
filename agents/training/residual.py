"""Residual cueing: PPO trained to correct the tuned classical washout, not to replace it.

The agent's action, low-passed (a first-order filter of time constant ``smoothing``, s), is added
to the washout's pose command, ``clip(washout + scale * filtered, -1, 1)``, and the agent observes
the environment's observation followed by the washout's command and the filtered residual (6
numbers each, in [-1, 1]): the filter keeps the residual from adding a step-to-step jitter to the
pose, which the person on the platform would feel as false specific-force cues.  An untrained agent, whose residual is near 0, cues as the washout does and
stays inside the platform's limits, so that training starts from the washout's cueing instead of
from a platform that explores its whole workspace box and ends at the limits.  The washout runs
outside the environment, in the agents layer: :class:`ResidualWashoutVecEnv` wraps the training
batch, :class:`ResidualWashoutPolicy` runs a trained agent on any cueing environment in pose mode,
and :func:`train_residual` trains one agent with a zoo-format config whose entry holds the key
:data:`RESIDUAL_KEY` (``configs/agents/ppo_cueing_residual.yml``).

An agent's folder holds ``model.zip`` (SB3's), ``vecnormalize.pkl`` (the observation statistics)
and ``residual.json`` (its settings, the files' sha256, checked before they are unpickled, and the
training's CPU and wall time).
"""

from __future__ import annotations

import collections
import io
import json
import os
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from stewart_env.agents.controllers.washout import WashoutParams, WashoutPolicy, load_washout_params
from stewart_env.agents.training.environment import single_thread
from stewart_env.agents.training.errors import TrainingError
from stewart_env.agents.training.rundir import sha256_hex
from stewart_env.files import publish

__all__ = [
    "RESIDUAL_KEY",
    "ResidualFilter",
    "ResidualSettings",
    "ResidualWashoutPolicy",
    "ResidualWashoutVecEnv",
    "load_residual",
    "residual_settings",
    "train_residual",
]

#: The config entry's key of the residual's settings: ``{washout: <config>, scale: <s>, smoothing: <tau>}``.
RESIDUAL_KEY = "residual_washout"
#: The files of a trained agent.
MODEL_FILE, STATISTICS_FILE, MANIFEST = "model.zip", "vecnormalize.pkl", "residual.json"


class ResidualSettings:
    """The residual's settings: the washout it corrects and the residual's scale.

    Attributes:
        washout: the washout's parameters.
        washout_config: where they were read (a shipped name or a path).
        scale: the factor of the agent's action, in (0, 2]: a residual of 1 moves the pose command
            by ``scale`` of the pose action's half-range.
        smoothing: the residual's low-pass time constant, s, 0 to 10 (0: none).
    """

    def __init__(self, washout: str = "washout", scale: float = 0.2, smoothing: float = 0.0):
        for name, value, low, high in (("scale", scale, 0.0, 2.0), ("smoothing", smoothing, 0.0, 10.0)):
            bad = isinstance(value, bool) or not isinstance(value, (int, float))
            if bad or not (low < float(value) <= high if name == "scale" else low <= float(value) <= high):
                interval = "(0, 2]" if name == "scale" else "[0, 10] s"
                raise TrainingError(f"{RESIDUAL_KEY}: {name} must be a number in {interval}, got {value!r}")
        self.washout_config = str(washout)
        self.washout: WashoutParams = load_washout_params(self.washout_config)
        self.scale = float(scale)
        self.smoothing = float(smoothing)

    def as_dict(self) -> dict[str, Any]:
        """The settings as the config and ``residual.json`` write them."""
        return {"washout": self.washout_config, "scale": self.scale, "smoothing": self.smoothing}


class ResidualFilter:
    """The residuals' first-order low-pass, one per row: ``y += a (u - y)`` with ``a = dt / (tau + dt)``
    (backward Euler), started at 0 on a new episode.

    Args:
        tau: the time constant, s (0: ``y = u``).
        dt: the control step, s.
    """

    def __init__(self, tau: float, dt: float):
        self.gain = dt / (tau + dt)
        self.state = np.zeros((0, 6))

    def reset(self, rows=None) -> None:
        """Start over (the rows ``rows``, a boolean mask, or all).

        Args:
            rows: the rows to restart; None: every row.
        """
        mask = None if rows is None else np.asarray(rows, dtype=bool).reshape(-1)
        if mask is None or len(mask) != len(self.state):  # all, or a batch not stepped yet
            self.state = np.zeros((0, 6))
        else:
            self.state[mask] = 0.0

    def step(self, residual) -> np.ndarray:
        """The filtered residuals (N, 6) after ``residual`` (N, 6), clipped to [-1, 1] first.

        Args:
            residual: the agent's actions.

        Returns:
            The filter's output.
        """
        residual = np.clip(np.asarray(residual, dtype=float), -1.0, 1.0)  # as SB3 clips a Box action
        if self.state.shape != residual.shape:  # a new batch
            self.state = np.zeros_like(residual)
        self.state = self.state + self.gain * (residual - self.state)
        return self.state.copy()


def residual_settings(entry: Mapping[str, Any]) -> tuple[ResidualSettings, dict[str, Any]]:
    """Split a zoo entry into the residual's settings and the entry SB3's parser reads.

    Args:
        entry: the config's entry (``read_hyperparameters``).

    Returns:
        (the settings, the entry without :data:`RESIDUAL_KEY`).

    Raises:
        TrainingError: the entry has no :data:`RESIDUAL_KEY` mapping, or a bad value in it.
    """
    value = entry.get(RESIDUAL_KEY)
    if not isinstance(value, Mapping):
        raise TrainingError(f"{RESIDUAL_KEY}: the config needs a mapping {RESIDUAL_KEY}: {{washout, scale}}")
    unknown = sorted(set(value) - {"washout", "scale", "smoothing"})
    if unknown:
        raise TrainingError(f"{RESIDUAL_KEY}: unknown key(s) {', '.join(unknown)}; valid: washout, scale, smoothing")
    rest = {k: v for k, v in entry.items() if k != RESIDUAL_KEY}
    return ResidualSettings(**value), rest


def combine(washout_action: np.ndarray, residual: np.ndarray, scale: float) -> np.ndarray:
    """The pose command: the washout's plus ``scale`` times the residual, clipped to [-1, 1].

    Args:
        washout_action: (N, 6) the washout's pose actions.
        residual: (N, 6) the (filtered) residuals, in [-1, 1].
        scale: the residual's factor.

    Returns:
        (N, 6) float32 actions.
    """
    return np.clip(washout_action + scale * residual, -1.0, 1.0).astype(np.float32)


def _augmented_space(space):
    from gymnasium import spaces

    low = np.concatenate([space.low, -np.ones(12, dtype=space.dtype)])
    high = np.concatenate([space.high, np.ones(12, dtype=space.dtype)])
    return spaces.Box(low=low, high=high, dtype=space.dtype)


def _vec_env_wrapper():
    from stable_baselines3.common.vec_env import VecEnvWrapper

    return VecEnvWrapper


class ResidualWashoutVecEnv(_vec_env_wrapper()):
    """The training batch of a residual agent: SB3's VecEnv whose action is the residual and whose
    observation ends with the washout's pose command and the filtered residual.

    Args:
        venv: a :class:`~stewart_env.envs.StewartPlatformSB3VecEnv` on ``task="cueing"`` in pose mode.
        settings: the residual's settings.

    Raises:
        UsageError: an environment the washout cannot drive (not the cueing task, not pose mode).
    """

    def __init__(self, venv, settings: ResidualSettings):
        super().__init__(venv, observation_space=_augmented_space(venv.observation_space))
        self.settings = settings
        self.washout = WashoutPolicy(venv.venv, settings.washout)
        self._base = np.zeros((venv.num_envs, 6), dtype=np.float32)
        self.filter = ResidualFilter(settings.smoothing, venv.venv.unwrapped.dt)
        self._filtered = np.zeros((venv.num_envs, 6))
        self._reasons = tuple(venv.venv.unwrapped.termination_reasons)
        #: how the training's episodes ended, by reason ("time_limit": truncated), all and the last 500
        self.endings: collections.Counter = collections.Counter()
        self.recent_endings: collections.deque = collections.deque(maxlen=500)

    def reset(self) -> np.ndarray:
        """Every row starts over, the washout's filters too.

        Returns:
            The augmented observations (N, obs_dim + 12).
        """
        obs = self.venv.reset()
        self.washout.reset()
        self.filter.reset()
        self._filtered = np.zeros((self.num_envs, 6))
        self._base, _ = self.washout.predict(obs)
        return self._augment(obs)

    def _augment(self, obs) -> np.ndarray:
        return np.concatenate([obs, self._base, self._filtered], axis=1).astype(obs.dtype)

    def step_async(self, actions: np.ndarray) -> None:
        """Hold the pose commands of the residual ``actions`` (N, 6).

        Args:
            actions: the agent's residuals.
        """
        self._filtered = self.filter.step(actions)
        self.venv.step_async(combine(self._base, self._filtered, self.settings.scale))

    def step_wait(self):
        """Step the batch; the washout's filters start over on the rows that ended.

        Returns:
            (augmented observations, rewards, dones, infos), as SB3's VecEnv.
        """
        obs, rewards, dones, infos = self.venv.step_wait()
        # an ended row's terminal observation ends with the command and residual of its last step,
        # not those the washout would give after it: only a truncation bootstraps from it (the
        # motions end by termination), and the washout's state then starts the row's next episode
        for i in np.flatnonzero(dones):
            reason = "time_limit" if infos[i].get("TimeLimit.truncated") else self._reasons[infos[i]["termination"]]
            self.endings[reason] += 1
            self.recent_endings.append(reason)
            terminal = infos[i].get("terminal_observation")
            if terminal is not None:
                extra = np.concatenate([self._base[i], self._filtered[i]])
                infos[i]["terminal_observation"] = np.concatenate([terminal, extra]).astype(terminal.dtype)
        self._base, _ = self.washout.predict(obs, episode_start=dones)
        if dones.any():
            self.filter.reset(dones)
            self._filtered[dones] = 0.0
        return self._augment(obs), rewards, dones, infos


class ResidualWashoutPolicy:
    """A trained residual agent on a cueing environment, with SB3's ``predict`` on raw observations.

    Args:
        env: the cueing environment (single or vector), ``action_mode="pose"``.
        model: the trained SB3 model.
        normalizer: its VecNormalize statistics (frozen), or None.
        settings: the residual's settings.
    """

    def __init__(self, env, model, normalizer, settings: ResidualSettings):
        self.washout = WashoutPolicy(env, settings.washout)
        self.filter = ResidualFilter(settings.smoothing, env.unwrapped.dt)
        self._filtered: np.ndarray | None = None
        self.model = model
        self.normalizer = normalizer
        self.settings = settings

    def reset(self) -> None:
        """Start the washout's and the residual's filters over (a new batch of episodes)."""
        self.washout.reset()
        self.filter.reset()
        self._filtered = None

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        """SB3's interface: (action (6,) or (N, 6), None).

        Args:
            observation: one raw observation (obs_dim,) or a batch (N, obs_dim).
            state: unused.
            episode_start: SB3's episode starts (N,): those rows' washout filters start over.
            deterministic: the agent's mean residual rather than a sample.

        Returns:
            (action, None).
        """
        obs = np.atleast_2d(np.asarray(observation, dtype=np.float32))
        base, _ = self.washout.predict(obs, episode_start=episode_start)
        if self._filtered is None or len(self._filtered) != len(obs):  # a new batch
            self.filter.reset()
            self._filtered = np.zeros((len(obs), 6))
        if episode_start is not None:
            starts = np.asarray(episode_start, dtype=bool).reshape(-1)
            if starts.any():
                self.filter.reset(starts)
                self._filtered[starts] = 0.0
        augmented = np.concatenate([obs, base, self._filtered], axis=1).astype(np.float32)
        if self.normalizer is not None:
            augmented = self.normalizer.normalize_obs(augmented).astype(np.float32)
        with single_thread():
            residual, _ = self.model.predict(augmented, deterministic=deterministic)
        self._filtered = self.filter.step(residual)
        action = combine(base, self._filtered, self.settings.scale)
        return (action[0] if np.ndim(observation) == 1 else action), None


def train_residual(
    out: str | os.PathLike,
    config: str | os.PathLike,
    seed: int = 0,
    timesteps: int | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    n_envs: int | None = None,
    progress_bar: bool = False,
) -> dict[str, Any]:
    """Train one residual PPO agent on ``task="cueing"`` into ``out``.

    Args:
        out: the agent's folder (created; its files replaced).
        config: a PPO zoo config with :data:`RESIDUAL_KEY` (a shipped name or a path).
        seed: seeds torch, numpy and the platforms (row i gets seed + i).
        timesteps: environment steps (default the config's n_timesteps).
        env_kwargs: environment keywords over the config's.
        n_envs: platforms in the batch (default the config's n_envs).
        progress_bar: SB3's progress bar.

    Returns:
        The manifest written to ``out/residual.json``.

    Raises:
        TrainingError: a bad config.
    """
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from stewart_env.agents.training.hyperparameters import (
        algorithm_class,
        parse_hyperparameters,
        read_hyperparameters,
    )
    from stewart_env.envs import StewartPlatformSB3VecEnv

    entry = read_hyperparameters("ppo", config)
    settings, rest = residual_settings(entry)
    hp = parse_hyperparameters("ppo", rest)
    kwargs = {**hp.env_kwargs, **(env_kwargs or {}), "task": "cueing"}
    steps = hp.n_timesteps if timesteps is None else int(timesteps)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with single_thread():
        raw = StewartPlatformSB3VecEnv(num_envs=hp.n_envs if n_envs is None else int(n_envs), **kwargs)
        raw.seed(seed)
        residual = ResidualWashoutVecEnv(raw, settings)
        env = VecMonitor(residual, info_keywords=("termination",))
        if hp.normalize is not None:
            env = VecNormalize(env, **hp.normalize)
        try:
            agent = algorithm_class("ppo")(env=env, seed=seed, device="cpu", verbose=0, **hp.algorithm_kwargs)
            cpu, wall = time.process_time(), time.perf_counter()
            agent.learn(total_timesteps=steps, progress_bar=progress_bar)
            cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
            model = io.BytesIO()
            agent.save(model)
            files = {MODEL_FILE: model.getvalue()}
            if hp.normalize is not None:
                import pickle

                files[STATISTICS_FILE] = pickle.dumps(env)
            endings = {
                "all": dict(residual.endings),
                "last_500": dict(collections.Counter(residual.recent_endings)),
            }
        finally:
            env.close()
    for name, data in files.items():
        publish(out / name, data)
    manifest = {
        "algo": "ppo",
        "config": str(config),
        "seed": seed,
        "num_timesteps": int(agent.num_timesteps),
        "env_kwargs": kwargs,
        "residual": settings.as_dict(),
        "cpu_seconds": cpu,
        "wall_seconds": wall,
        "episode_endings": endings,
        "files": {name: sha256_hex(data) for name, data in files.items()},
    }
    publish(out / MANIFEST, json.dumps(manifest, indent=2) + "\n")
    return manifest


def load_residual(directory: str | os.PathLike, env) -> ResidualWashoutPolicy:
    """The residual agent trained in ``directory`` by :func:`train_residual`, on ``env``.

    Args:
        directory: the agent's folder.
        env: the cueing environment it will drive (pose mode).

    Returns:
        The policy.

    Raises:
        TrainingError: no finished agent there, or a file whose sha256 is not the manifest's.
    """
    path = Path(directory)
    try:
        manifest = json.loads((path / MANIFEST).read_text())
    except (OSError, ValueError) as err:
        raise TrainingError(f"{path}: no residual agent ({MANIFEST}: {err})") from None
    from stewart_env.agents.training.hyperparameters import algorithm_class
    from stewart_env.agents.training.rundir import verified_bytes

    hashes = manifest["files"]
    data = {name: verified_bytes(path, hashes, name, MANIFEST) for name in hashes}

    with single_thread():
        model = algorithm_class("ppo").load(io.BytesIO(data[MODEL_FILE]), device="cpu")
    normalizer = None
    if STATISTICS_FILE in data:
        from stewart_env.agents.training.rundir import unpickle_statistics

        normalizer = unpickle_statistics(data[STATISTICS_FILE])  # its sha256 checked above
        normalizer.training = False
    return ResidualWashoutPolicy(env, model, normalizer, ResidualSettings(**manifest["residual"]))
