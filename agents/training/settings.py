"""What a training run is asked for and what it resolves to, each one frozen record built once:
:class:`TrainSettings`, the request of :func:`~stewart_env.agents.training.train`, checked at
construction, and :class:`RunPlan`, the run it trains once the config (or, resuming, the run's
manifest and checkpoint) has been read."""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from stewart_env import validation
from stewart_env.agents.training.errors import TrainingError
from stewart_env.agents.training.hyperparameters import Hyperparameters, algorithm_class, check_count
from stewart_env.agents.training.rundir import DEFAULT_KEEP_CHECKPOINTS
from stewart_env.dynamics import ModelSpec
from stewart_env.errors import UsageError

__all__ = ["RunPlan", "TrainSettings", "plant_model"]


def plant_model(model: Any) -> ModelSpec | str:
    """The environment's ``model`` argument parsed once, for the keywords of every environment
    made from it: a dynamics model's :class:`~stewart_env.dynamics.ModelSpec`, or ``"mujoco"``
    (:func:`stewart_env.envs.config.model_spec`); its canonical name is ``str()`` of it.

    Args:
        model: a model name, a ModelSpec or ``"mujoco"`` (any case).

    Returns:
        The spec, or ``"mujoco"``.

    Raises:
        UsageError: an unknown model or switch (``err.argument`` is ``"model"``).
    """
    from stewart_env.envs.config import MUJOCO, model_spec

    spec = model_spec(model)
    return MUJOCO if spec is None else spec


def _stderr_report(message: str) -> None:
    print(f"stewart-env train: {message}", file=sys.stderr)


@dataclass(frozen=True)
class TrainSettings:
    """The request of :func:`~stewart_env.agents.training.train`, checked at construction: the
    algorithm, the counts and the seed (a bad one raises
    :class:`~stewart_env.agents.training.TrainingError` naming it); the config, the environment's
    keywords and the run directory are checked where they are read.

    Attributes:
        algo: one of ``ALGORITHMS`` (ppo, sac, td3, tqc, crossq).
        out: the run directory.
        model: the plant's dynamics model (None: improved, or the run's); once made, its
            :class:`~stewart_env.dynamics.ModelSpec` or ``"mujoco"`` (``plant_model``).
        task: the task (None: setpoint, or the run's).
        timesteps: environment steps of this call, at least (None: the config's n_timesteps).
        seed: the first row's seed (None: 0, or the run's).
        n_envs: platforms in the batch (None: the config's, or the run's).
        checkpoint_freq: environment steps between checkpoints (0: none but the final one).
        keep_checkpoints: how many of the newest checkpoints to keep.
        env_kwargs: further environment keywords.
        config: a zoo hyperparameter file or a shipped config's name (None: the algorithm's).
        resume: continue from the newest complete checkpoint in ``out``.
        progress_bar: SB3's progress bar, where it can be drawn.
        verbose: SB3's verbosity.
        report: where resume messages go.
    """

    algo: str
    out: Path
    model: str | ModelSpec | None = None
    task: str | None = None
    timesteps: int | None = None
    seed: int | None = None
    n_envs: int | None = None
    checkpoint_freq: int = 50_000
    keep_checkpoints: int = DEFAULT_KEEP_CHECKPOINTS
    env_kwargs: Mapping[str, Any] | None = None
    config: str | os.PathLike | None = None
    resume: bool = False
    progress_bar: bool = True
    verbose: int = 0
    report: Callable[[str], None] = _stderr_report

    def __post_init__(self):
        algorithm_class(self.algo)  # an unknown algorithm, or a missing extra, is refused first
        for name in ("timesteps", "n_envs"):
            if getattr(self, name) is not None:
                check_count(name, getattr(self, name), 1)
        if self.seed is not None:
            try:
                validation.seed("seed", self.seed)
            except UsageError as err:
                raise TrainingError(str(err), argument=err.argument, problem=err.problem) from None
        if self.model is not None:  # parsed once: the run's environments take the spec
            try:
                object.__setattr__(self, "model", plant_model(self.model))
            except UsageError as err:
                raise TrainingError(str(err), argument=err.argument, problem=err.problem) from None
        check_count("checkpoint_freq", self.checkpoint_freq, 0)
        check_count("keep_checkpoints", self.keep_checkpoints, 1)
        object.__setattr__(self, "out", Path(self.out))

    @property
    def algorithm(self) -> type:
        """The SB3 (or sb3-contrib) class of ``algo``."""
        return algorithm_class(self.algo)


@dataclass(frozen=True)
class RunPlan:
    """The run a training call trains, resolved from its :class:`TrainSettings` and the config
    (a new run) or the run's manifest and newest checkpoint (resuming).

    Attributes:
        hyperparameters: the zoo entry, split.
        env_kwargs: the environment's keywords as run.json records them, model (by its
            canonical name) and task included.
        model: the plant's model, parsed once: what the run's environments are given as ``model``.
        seed: the first row's seed.
        n_envs: platforms in the batch.
        timesteps: environment steps of this call, at least.
        config: the hyperparameter file recorded in the manifest (None: unknown, an older run).
        monitor: the monitor CSV's file name in the run directory.
        progress_bar: whether SB3 draws its progress bar.
        resume: whether the run continues from a checkpoint.
        steps_done: the environment steps of the run so far (0: a new run).
        segments: the run's earlier training segments (the manifest's ``segments``).
        saved: the checkpoint's files by name (resuming; emptied once loaded, since a replay
            buffer is tens of MB).
    """

    hyperparameters: Hyperparameters
    env_kwargs: Mapping[str, Any]
    model: ModelSpec | str
    seed: int
    n_envs: int
    timesteps: int
    config: str | None
    monitor: str
    progress_bar: bool
    resume: bool = False
    steps_done: int = 0
    segments: list = field(default_factory=list)
    saved: dict[str, bytes] = field(default_factory=dict)
