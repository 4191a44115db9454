"""The training environment and the threads it runs on: the native batch of platforms behind
stable-baselines3's VecMonitor and VecNormalize, one torch thread, SB3's progress bar when it can
be drawn."""

from __future__ import annotations

import contextlib
import importlib.util
import os
from collections.abc import Iterator, Mapping
from typing import Any

from stewart_env.progress import on_terminal

__all__ = ["make_training_env", "progress_bar_available", "single_thread"]


def progress_bar_available() -> bool:
    """SB3's progress bar needs tqdm and rich, and a terminal on stderr to draw on."""
    return all(importlib.util.find_spec(name) is not None for name in ("tqdm", "rich")) and on_terminal()


@contextlib.contextmanager
def single_thread() -> Iterator[None]:
    """One torch thread inside the block, the previous count restored after it: for small MLPs and
    batches of tens of platforms a second thread gains little, and on a shared machine it slows
    everyone else."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(before)


def make_training_env(
    n_envs: int,
    env_kwargs: Mapping[str, Any],
    seed: int,
    normalize: dict[str, Any] | None,
    monitor_path: str | os.PathLike | None = None,
    statistics=None,
):
    """The training VecEnv: ``n_envs`` platforms in one native batch, VecMonitor (episode
    statistics, ``monitor_path`` CSV) and, if ``normalize`` is not None, VecNormalize with those
    kwargs, or the saved VecNormalize ``statistics`` put on this batch (resuming).  Rows are
    seeded seed, seed + 1, ...; ValueError from the environment for bad kwargs.

    Args:
        n_envs: the number of platforms in the batch.
        env_kwargs: the environment kwargs.
        seed: the seed of the first row.
        normalize: VecNormalize's kwargs, or None for no normalisation.
        monitor_path: the CSV file of VecMonitor (None: none).
        statistics: saved VecNormalize statistics to put on the batch (resuming), or None.
    """
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from stewart_env.envs import StewartPlatformSB3VecEnv

    env = StewartPlatformSB3VecEnv(num_envs=n_envs, **env_kwargs)
    env.seed(seed)
    env = VecMonitor(env, filename=None if monitor_path is None else str(monitor_path), info_keywords=("termination",))
    if normalize is None:
        return env
    if statistics is not None:
        statistics.set_venv(env)  # what VecNormalize.load does after unpickling
        return statistics
    return VecNormalize(env, **normalize)
