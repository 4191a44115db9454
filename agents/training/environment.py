"""The training environment and the threads it runs on: the native batch of platforms behind
stable-baselines3's VecMonitor and VecNormalize, one torch thread, SB3's progress bar when it can
be drawn; and SB3's ``SubprocVecEnv`` with its workers' physics threads sized to the cores, so
that W worker processes on C cores each run ``max(1, C // W)`` threads instead of C each."""

from __future__ import annotations

import contextlib
import importlib.util
import os
from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import Any

from stewart_env.agents.training.hyperparameters import MAX_COUNT
from stewart_env.dynamics.threads import MAX_THREADS
from stewart_env.errors import UsageError
from stewart_env.progress import on_terminal
from stewart_env.validation import integer

__all__ = [
    "SizedEnvFactory",
    "available_cores",
    "make_subprocess_env",
    "make_training_env",
    "progress_bar_available",
    "single_thread",
    "worker_threads",
]


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
    wrappers: Sequence[tuple[Callable[..., Any], Mapping[str, Any]]] = (),
):
    """The training VecEnv: ``n_envs`` platforms in one native batch, VecMonitor (episode
    statistics, ``monitor_path`` CSV), the config's ``wrappers`` (where rl_zoo3 puts its
    ``vec_env_wrapper``: the monitor records the environment's reward) and, if ``normalize`` is
    not None, VecNormalize with those kwargs, or the saved VecNormalize ``statistics`` put on this
    batch (resuming).  Rows are seeded seed, seed + 1, ...; ValueError from the environment for
    bad kwargs.

    Args:
        n_envs: the number of platforms in the batch.
        env_kwargs: the environment kwargs.
        seed: the seed of the first row.
        normalize: VecNormalize's kwargs, or None for no normalisation.
        monitor_path: the CSV file of VecMonitor (None: none).
        statistics: saved VecNormalize statistics to put on the batch (resuming), or None.
        wrappers: each wrapper's class and keyword arguments
            (:attr:`~stewart_env.agents.training.Hyperparameters.vec_env_wrappers`), in order.
    """
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from stewart_env.envs import StewartPlatformSB3VecEnv

    env = StewartPlatformSB3VecEnv(num_envs=n_envs, **env_kwargs)
    env.seed(seed)
    env = VecMonitor(env, filename=None if monitor_path is None else str(monitor_path), info_keywords=("termination",))
    for wrapper, options in wrappers:
        env = wrapper(env, **options)
    if normalize is None:
        return env
    if statistics is not None:
        statistics.set_venv(env)  # what VecNormalize.load does after unpickling
        return statistics
    return VecNormalize(env, **normalize)


def available_cores() -> int:
    """The cores this process may run on: its CPU affinity (``taskset``, a container's CPU set)
    where the system tells it, else the machine's count; what the physics threads default to."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # no affinity on this system (macOS, Windows)
        return os.cpu_count() or 1


def worker_threads(workers: int, cores: int | None = None) -> int:
    """The physics threads of each of ``workers`` processes running side by side on ``cores``
    cores: ``max(1, cores // workers)``, so that together they do not ask for more than the cores.

    Args:
        workers: the processes side by side, at least 1.
        cores: the cores they share (default ``available_cores()``).

    Returns:
        The thread count for each worker's :func:`stewart_env.set_num_threads`.

    Raises:
        ValueError: ``workers`` or ``cores`` not a positive integer (the message names it).
    """
    workers = integer("workers", workers, 1, MAX_COUNT)
    cores = available_cores() if cores is None else integer("cores", cores, 1, MAX_COUNT)
    return max(1, cores // workers)


class SizedEnvFactory:
    """An environment factory for a worker process that first sets the process's physics threads
    (:func:`stewart_env.set_num_threads`), then makes the environment; picklable when ``make`` is
    (SB3's ``SubprocVecEnv`` sends it to its worker with cloudpickle).

    Args:
        make: the factory of the environment, called with no arguments in the worker.
        threads: the physics threads of the worker.
    """

    def __init__(self, make: Callable[[], Any], threads: int):
        self.make = make
        self.threads = integer("threads", threads, 1, MAX_THREADS)

    def __call__(self):
        """Set the worker's physics threads and make its environment.

        Returns:
            What ``make`` returns.
        """
        import stewart_env

        stewart_env.set_num_threads(self.threads)
        return self.make()


def make_subprocess_env(
    env_fns: Sequence[Callable[[], Any]], start_method: str | None = None, cores: int | None = None
):
    """SB3's ``SubprocVecEnv`` of ``env_fns``, one worker process each, every worker's physics
    threads set to :func:`worker_threads` of their number on ``cores``: without it each worker
    would start a thread per core.

    Args:
        env_fns: the environments' factories (e.g. ``lambda: gymnasium.make("StewartPlatform-v1")``).
        start_method: the multiprocessing start method (SB3's default: forkserver where there is one).
        cores: the cores the workers share (default ``available_cores()``).

    Returns:
        The ``SubprocVecEnv``.

    Raises:
        ValueError: no factory, or ``cores`` not a positive integer.
    """
    from stable_baselines3.common.vec_env import SubprocVecEnv

    if not env_fns:
        raise UsageError.about("env_fns", "expected at least one environment factory, got none")
    threads = worker_threads(len(env_fns), cores)
    return SubprocVecEnv([SizedEnvFactory(fn, threads) for fn in env_fns], start_method=start_method)
