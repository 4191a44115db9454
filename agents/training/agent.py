"""A trained agent loaded back from its run directory: :func:`load_agent` and :class:`TrainedAgent`.

:func:`load_agent` turns a run directory back into a policy with SB3's ``predict`` that applies
the saved observation normalisation itself, so it runs on raw environment observations next to
the PD and computed-torque baselines.  SB3's model zip and the statistics are pickles, i.e. code:
their sha256 is checked against run.json before anything is unpickled, which catches truncated,
swapped or edited files, but a run directory is trusted as a whole, like any pickle.
"""

from __future__ import annotations

import io
import os
from pathlib import Path
from typing import Any

import numpy as np

from stewart_env.agents.training.environment import single_thread
from stewart_env.agents.training.errors import TrainingError
from stewart_env.agents.training.hyperparameters import ALGORITHM_NAMES, algorithm_class
from stewart_env.agents.training.rundir import (
    CHECKPOINT_DIR,
    MANIFEST,
    MODEL_FILE,
    VECNORMALIZE_FILE,
    checkpoint_hashes,
    checkpoint_problem,
    read_manifest,
    step_dirs,
    unpickle_statistics,
    verified_bytes,
)
from stewart_env.registration import ENV_ID

__all__ = ["TrainedAgent", "load_agent"]


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
        return (
            f"TrainedAgent({self.algo} on {self.env_kwargs.get('model')!r}, {self.num_timesteps} steps, "
            f"{self.directory})"
        )

    @property
    def name(self) -> str:
        """A short label for tables: ``<algorithm> (<training model>)``, e.g. ``PPO (improved)``."""
        return f"{ALGORITHM_NAMES[self.algo]} ({self.env_kwargs.get('model')})"

    def normalize(self, observation) -> np.ndarray:
        """Raw observations -> the normalised observations the network was trained on (float32).

        Args:
            observation: raw observations (obs_dim,) or (N, obs_dim).
        """
        obs = np.asarray(observation, dtype=np.float32)
        if self._normalizer is None:
            return obs
        return self._normalizer.normalize_obs(obs).astype(np.float32)

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        """SB3's interface on raw observations: (action (6,) or (N,6) in [-1, 1], None).  The
        network runs on one torch thread; the caller's thread count is restored after.

        Args:
            observation: one raw observation (obs_dim,) or a batch (N, obs_dim).
            state: SB3's recurrent state, passed to the model.
            episode_start: SB3's episode starts, passed to the model.
            deterministic: the mean action rather than a sample.
        """
        with single_thread():
            return self.model.predict(
                self.normalize(observation), state=state, episode_start=episode_start, deterministic=deterministic
            )

    def make_env(self, **overrides: Any):
        """``gymnasium.make("StewartPlatform-v1")`` with the training kwargs and ``overrides``.

        Args:
            **overrides: environment kwargs that replace the training ones.
        """
        import gymnasium

        import stewart_env  # noqa: F401  (registers the environment)

        return gymnasium.make(ENV_ID, **{**self.env_kwargs, **overrides})


def load_agent(directory: str | os.PathLike, checkpoint: int | None = None) -> TrainedAgent:
    """The agent trained in ``directory`` by ``stewart-env train`` (its final model, or the
    checkpoint at ``checkpoint`` steps) as a :class:`TrainedAgent`.

    The model zip and the statistics are pickles: their sha256 is checked against run.json (or
    the checkpoint's manifest) before they are unpickled, and a file that does not match is
    refused with TrainingError.  This detects changed and damaged files, not a forged directory:
    load only run directories you trust.

    Args:
        directory: the run directory of ``stewart-env train``.
        checkpoint: the step count of a kept checkpoint (default the final model).
    """
    path = Path(directory)
    manifest = read_manifest(path)
    cls = algorithm_class(manifest["algo"])
    if checkpoint is None:
        folder, what = path, MANIFEST
        if not (path / MODEL_FILE).exists():
            raise TrainingError(f"{path}: no model at {MODEL_FILE}; the run has not finished (try --resume)")
        hashes = manifest.get("files")
        if not isinstance(hashes, dict) or not hashes:
            raise TrainingError(
                f"{path}: {MANIFEST} records no sha256 of {MODEL_FILE} (written by an older "
                "stewart-env, or not by `stewart-env train`); refusing to unpickle unverified files"
            )
    else:
        folder = path / CHECKPOINT_DIR / f"step_{checkpoint}"
        problem = (
            checkpoint_problem(folder, checkpoint, manifest["algo"], bool(manifest.get("normalize")))
            if folder.is_dir()
            else "no such checkpoint"
        )
        if problem is not None:
            found = ", ".join(str(steps) for steps, _ in step_dirs(path)) or "none"
            raise TrainingError(
                f"{path}: cannot load the checkpoint at {checkpoint} steps: {problem} (checkpoints: {found})"
            )
        hashes, what = checkpoint_hashes(folder)
    model_bytes = verified_bytes(folder, hashes, MODEL_FILE, what)
    statistics = verified_bytes(folder, hashes, VECNORMALIZE_FILE, what) if manifest.get("normalize", False) else None
    with single_thread():
        model = cls.load(io.BytesIO(model_bytes), device="cpu")
    normalizer = None
    if statistics is not None:
        normalizer = unpickle_statistics(statistics)
        normalizer.training = False
    return TrainedAgent(path, manifest, model, normalizer)
