"""Where the study's jobs run: in this process (local) or as Ray tasks, on a local Ray instance
or an existing cluster whose address is probed before Ray is asked to join it."""

from __future__ import annotations

import socket
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from stewart_env.agents.studies.mismatch.constants import (
    AUTO_THREADS,
    BACKENDS,
    CPUS_PER_JOB,
    RAY_AUTH_HINT,
    RAY_CONNECT_TIMEOUT,
    RAY_INSTALL_HINT,
    MismatchError,
)
from stewart_env.agents.studies.mismatch.jobs import on_threads
from stewart_env.agents.training import TrainingError
from stewart_env.errors import UsageError

__all__ = ["BackendError", "LocalBackend", "RayBackend", "check_backend", "make_backend", "ray_endpoint"]


class BackendError(UsageError):
    """The backend failed while the study ran (a Ray node or worker died, a job crashed): what
    finished is kept, and the same command continues the study."""


class LocalBackend:
    """Runs jobs in this process, one after another, in order; on ``threads`` physics threads
    (:func:`stewart_env.set_num_threads`) until :meth:`close` when given, on this process's own
    count otherwise.

    Args:
        threads: the physics threads of the jobs, or None to leave this process's count.
    """

    name = "local"

    def __init__(self, threads: int | None = None):
        import stewart_env as se

        self.restore = None
        if threads is not None:
            self.restore = se.get_num_threads()
            se.set_num_threads(threads)

    def run(self, fn: Callable, jobs: Sequence[tuple]) -> Iterator[tuple[int, Any]]:
        """(index, fn(*args)) of each job, in order.

        Args:
            fn: the job's function.
            jobs: the arguments of each job.
        """
        for i, args in enumerate(jobs):
            yield i, fn(*args)

    def put(self, value):
        """``value`` itself: the jobs run here.

        Args:
            value: the value the jobs share.
        """
        return value

    def close(self) -> None:
        """Gives this process back its physics threads' count, if the backend set it."""
        if self.restore is not None:
            import stewart_env as se

            se.set_num_threads(self.restore)
            self.restore = None


class RayBackend:
    """Runs every job as a Ray task requesting :data:`~.constants.CPUS_PER_JOB` CPUs, on the
    cluster at ``address`` ("auto", "HOST:PORT") or, without one, on a local Ray instance started
    here (or the one this process already joined).  A task sets its worker's physics threads to
    those CPUs (:func:`~.jobs.on_threads`): the workers side by side on a node share its cores
    instead of each taking all of them; or to ``threads`` when given.

    Args:
        address: the cluster's address, or None for a local Ray instance.
        threads: each task's physics threads, or None for the CPUs it requests.
    """

    name = "ray"

    def __init__(self, address: str | None = None, threads: int | None = None):
        import ray

        self.ray = ray
        self.threads = CPUS_PER_JOB if threads is None else threads
        self.started = False
        if not ray.is_initialized():
            endpoint = None if address is None else ray_endpoint(address)
            if endpoint is not None:  # Ray itself retries an address that does not answer for ever
                try:
                    socket.create_connection(endpoint, timeout=RAY_CONNECT_TIMEOUT).close()
                except OSError as exc:
                    raise MismatchError(
                        f"--ray-address {address}: nothing answers there "
                        f"({exc.strerror or exc}); is the cluster's head node started?"
                    ) from None
            kwargs = {"address": address} if address else {"include_dashboard": False}
            try:
                ray.init(logging_level="ERROR", log_to_driver=False, **kwargs)
            except (ConnectionError, ValueError, RuntimeError, ray.exceptions.RayError) as exc:
                raise MismatchError(
                    f"--ray-address {address}: cannot join the Ray cluster ({exc}){RAY_AUTH_HINT}"
                ) from None
            self.started = True

    def put(self, value):
        """``value`` in Ray's object store: sent to the workers once, however many jobs use it.

        Args:
            value: the value the jobs share.
        """
        return self.ray.put(value)

    def run(self, fn: Callable, jobs: Sequence[tuple]) -> Iterator[tuple[int, Any]]:
        """(index, fn(*args)) of each job as it finishes; the unfinished ones are cancelled when the
        caller stops (Ctrl-C, an error).

        Args:
            fn: the job's function.
            jobs: the arguments of each job.
        """
        ray = self.ray
        # each task under its job's name (train_job, evaluate_job), as Ray's state API and dashboard list it
        remote = ray.remote(num_cpus=CPUS_PER_JOB, max_retries=0)(on_threads).options(name=fn.__name__)
        pending = {remote.remote(self.threads, fn, *args): i for i, args in enumerate(jobs)}
        try:
            while pending:
                done, _ = ray.wait(list(pending), num_returns=1)
                for ref in done:
                    yield pending.pop(ref), self._result(ref)
        finally:  # stopped (Ctrl-C, an error): the unfinished tasks are of no use
            for ref in pending:
                try:
                    ray.cancel(ref, force=True)
                except ray.exceptions.RayError:  # the cluster is gone already
                    break

    def _result(self, ref):
        """A finished task's value; a job's own error as it would be raised here, and a failure
        of the cluster (a node, raylet or worker died) as a :class:`BackendError`."""
        errors = self.ray.exceptions
        try:
            return self.ray.get(ref)
        except errors.RayTaskError as exc:
            if isinstance(exc.cause, (TrainingError, ValueError)):
                raise exc.cause from None
            raise BackendError(f"a job failed on the Ray cluster: {type(exc.cause).__name__}: {exc.cause}") from None
        except errors.RayError as exc:
            reason = (str(exc).strip().splitlines() or [""])[0].rstrip(".")
            raise BackendError(f"the Ray cluster failed: {type(exc).__name__}: {reason}") from None

    def close(self) -> None:
        """Shuts down the Ray instance this backend started; a cluster it joined keeps running."""
        if self.started:
            self.ray.shutdown()


def ray_endpoint(address: str) -> tuple[str, int] | None:
    """(host, port) of a Ray address "HOST:PORT" or "ray://HOST:PORT"; None for "auto".

    Args:
        address: the Ray address (``--ray-address``).
    """
    if address == "auto":
        return None
    host, sep, port = address.split("://", 1)[-1].rpartition(":")
    if not (sep and host and port.isdigit() and 1 <= int(port) <= 65535):
        raise MismatchError(f"--ray-address: expected auto, HOST:PORT or ray://HOST:PORT, got {address!r}")
    return host, int(port)


def check_backend(name: str, address: str | None = None) -> None:
    """Refuse an unknown backend, an address without Ray or of no Ray form, and the Ray backend
    without ray installed.

    Args:
        name: the backend's name (``--backend``).
        address: the Ray address (``--ray-address``), or None.
    """
    if name not in BACKENDS:
        raise MismatchError(f"backend: expected one of {', '.join(BACKENDS)}, got {name!r}")
    if name == "local" and address is not None:
        raise MismatchError("--ray-address: only with --backend ray")
    if address is not None:
        ray_endpoint(address)
    if name == "ray":
        try:
            import ray  # noqa: F401
        except ImportError:
            raise MismatchError(f"--backend ray needs ray: {RAY_INSTALL_HINT}") from None


def make_backend(name: str, address: str | None = None, threads: int | str | None = None) -> LocalBackend | RayBackend:
    """The backend called ``name`` ("local" or "ray"); ``address`` only with "ray".

    Args:
        name: the backend's name (``--backend``).
        address: the Ray address (``--ray-address``), or None.
        threads: the jobs' physics threads (``--physics-threads``): a count, or ``"auto"`` (or None)
            for the backend's own (:class:`LocalBackend`, :class:`RayBackend`).

    Returns:
        The backend.
    """
    check_backend(name, address)
    threads = None if threads == AUTO_THREADS else threads
    return LocalBackend(threads) if name == "local" else RayBackend(address, threads)
