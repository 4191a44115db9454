"""Sim-to-sim model mismatch: what a controller loses when it was designed or trained on a
simplified dynamics model of the Stewart platform, as numbers with confidence intervals.

The study is a matrix.  Rows are controllers, each tied to the dynamics model it was built on:

* ``PD + gravity comp. [m]``: the task-space PD law with the holding forces of model ``m``'s
  statics (the only model term it uses);
* ``CT [m]``: the computed-torque controller with internal model ``m`` (its inverse dynamics);
* ``<ALGO> [m]``: RL agents trained on a plant simulated with model ``m``, one per training seed;
* ``<ALGO> [improved + DR]`` (optional): agents trained on the improved model with domain
  randomisation of the inertial and friction parameters (:data:`DEFAULT_RANDOMIZATION`).

The models are the training models and, per simplification, ``improved+cK``: the improved model
with one of the classical model's simplifications C1-C4 switched on.  PD and CT rows exist for
the closed-form models only; an agent can be trained on any model the environment simulates.
Columns are test plants: the environment simulated with each test model (nominal parameters).

Every cell runs the row's controller on the column's plant over the same seeded episodes (for
each training seed of a learned row) and reports a point estimate with a 95 % stratified
bootstrap interval over seeds and episodes (:mod:`stewart_env.agents.statistics`): the success
rate as a mean, every other metric as an interquartile mean (a few failed episodes dominate a
mean).  The cost of a simplification to a controller family is the paired difference, on the
exact (improved) plant, between the family's row built on the simplified model and its row built
on the exact one; it is resolved when its interval excludes zero.  Where the simplified model is
a test plant too, the double difference compares each controller with itself on the two plants
(see :class:`Difference`): the training seeds' own spread cancels in it.

Output in DIR: ``matrix.csv`` (one line per row and test plant; every metric with
``<metric>_ci_low``, ``<metric>_ci_high`` and ``<metric>_n``, the values it rests on),
``matrix.md`` (tables with intervals, the costs and their ranking), ``differences.csv``,
``forest.png`` (every cost with its interval) and ``heatmap_<metric>.png``; trained agents in
``DIR/agents/<name>/seed_<s>/`` and each finished evaluation in ``DIR/cells/`` (a second run with
the same DIR reuses both and runs only what is missing).  ``study.json`` holds the settings that
give the cells their meaning; a second run with other settings is refused.  One command at a time
works on a study: ``mismatch`` holds the lock of DIR (:func:`stewart_env.files.lock_folder`) until
it ends, and a second one on the same DIR is refused at once.  A study's agents belong to it: they
are not shared with another study through a common folder (``DIR/agents`` as a symbolic link is
refused), since a study's finished cells name the hashes of the agents they ran.  A full disk ends
the study with the file it could not write; the finished agents and cells are kept.

Work runs on a backend: ``local`` (in this process, one job after another) or ``ray`` (every
training run and every evaluation is a Ray task requesting :data:`CPUS_PER_JOB` CPUs, on a local
Ray instance or an existing cluster).  Both give the same numbers for the same seeds.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import signal
import socket
import sys
import tempfile
import time
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from stewart_env.cli.arguments import checked as _checked
from stewart_env.agents.evaluation import ORIENTATION_TOLERANCE, POSITION_TOLERANCE
from stewart_env.agents.statistics import (
    Interval,
    double_difference,
    paired_difference,
    point_estimate,
    seeds_to_resolve,
    stratified_bootstrap,
)
from stewart_env.agents.training import (
    ALGORITHMS,
    MANIFEST,
    MAX_AGENT_FILE_BYTES,
    MAX_MANIFEST_BYTES,
    MODEL_FILE,
    VECNORMALIZE_FILE,
    TrainingError,
    TrainingInterrupted,
    jsonable,
    load_agent,
    newest_checkpoint,
    parse_env_kwargs,
    read_hyperparameters,
    read_manifest,
    train,
)
from stewart_env.dynamics.model import SIMPLIFICATIONS as SIMPLIFICATION_TEXT
from stewart_env.files import (WriteError, check_not_busy, lock_folder, publish, publishing, publishing_folder,
                               read_json, read_regular, write_error)
from stewart_env.progress import progress as progress_bar

#: Environment steps per RL agent of the quick default study: a smoke-scale budget (such agents
#: still lose the platform); --timesteps 1500000 or more for agents that hold a set point.
QUICK_TIMESTEPS = 20_000
#: The classical model's simplifications, each a switch on the improved model.
SIMPLIFICATIONS = tuple(SIMPLIFICATION_TEXT)
#: Domain randomisation of the DR row: per-episode factors on the nominal parameters.  The legs'
#: inertial parameters get the widest ranges because three of the classical model's four
#: simplifications (C1-C3) concern the legs' dynamics.
DEFAULT_RANDOMIZATION: dict[str, tuple[float, float]] = {
    "platform.mass": (0.8, 1.2),
    "platform.inertia": (0.8, 1.2),
    "platform.com": (0.5, 1.5),
    "legs.mass": (0.5, 1.5),
    "legs.inertia": (0.5, 2.0),
    "legs.com": (0.5, 1.5),
    "damping": (0.0, 2.0),
}
#: Evaluation episodes use seeds EVAL_SEED_OFFSET + i, away from the training runs' seeds.
EVAL_SEED_OFFSET = 100_000
#: The largest training seed: numpy's and torch's seeding of a run take 32-bit seeds.
MAX_SEED = 2**32 - 1
#: The longest evaluation episode, in control steps (1e5 s at the default 10 ms step): a longer one
#: is a typo, not a study.
MAX_STEPS = 10**7
#: The metrics whose differences measure a simplification's cost, on the true plant: the static
#: error (where a wrong model shows most on a set point) and the transient error, each in position
#: and orientation, and the effort: the force peak and the control energy (a learned agent's peak
#: is often the actuators' limit, so only its energy shows how hard it pushes).  Settling time and
#: overshoot are left out: undefined in the episodes that never settle.
RANKING_METRICS = ("steady_state_position_error", "steady_state_orientation_error", "rms_position_error",
                   "rms_orientation_error", "peak_leg_force", "control_energy")
TRUE_MODEL = "improved"
#: A cell whose controller succeeds in fewer than this share of the episodes is marked failed: its
#: heatmap cell is hatched grey, and its differences are marked, not ranked.
FAILURE_THRESHOLD = 0.5
#: The statistic of each metric's cells: the success rate is a share (a mean); every other
#: metric an interquartile mean.
STATISTIC = {"success": "mean"}
DEFAULT_STATISTIC = "iqm"
#: CPUs each training run and each evaluation requests from Ray: training runs on one torch and
#: numba thread (training.single_thread), and an evaluation steps one batch of platforms.
CPUS_PER_JOB = 1
BACKENDS = ("local", "ray")
#: Since Ray 2.59 a cluster started with ``ray start`` checks a token when one exists in
#: ~/.ray/auth_token (any earlier local Ray instance writes it), and a driver joining it by an
#: explicit address sends the token only when told to.
RAY_AUTH_HINT = ("; if the cluster checks a token (Ray 2.59 and later do when ~/.ray/auth_token exists), set "
                 "RAY_AUTH_MODE=token and give its token in ~/.ray/auth_token or RAY_AUTH_TOKEN (see "
                 "`ray get-auth-token` on the head node), or join with --ray-address auto on the head node")
#: Seconds to wait for a Ray head node to accept a connection before refusing its address.
RAY_CONNECT_TIMEOUT = 5.0
RAY_INSTALL_HINT = 'install the distributed extra: pip install -e ".[distributed]" (ray)'
#: Settings recorded in study.json: a second run in the same directory must match them.
STUDY_FILE = "study.json"
CELLS_DIR = "cells"
AGENTS_DIR = "agents"
#: Bound of a finished cell's file read back (every metric of every episode of one evaluation).
MAX_CELL_BYTES = 256 << 20
#: The files of an agent folder that loading it needs (and that a Ray worker sends back).
AGENT_FILES = (MANIFEST, MODEL_FILE, VECNORMALIZE_FILE)


def statistic(metric: str) -> str:
    """The statistic ("mean" or "iqm") a metric's cells report."""
    return STATISTIC.get(metric, DEFAULT_STATISTIC)


@dataclass
class Row:
    """One controller of the study: its label, family ("PD", "CT" or the RL algorithm), the model
    it was designed or trained on, and for a learned row its training seeds and agent folders
    (seed -> path).  ``kind`` is "pd", "ct" or "agent"; ``info`` a note for the tables."""

    label: str
    family: str
    model: str
    kind: str = "ct"
    seeds: tuple[int, ...] = ()
    agents: dict[int, Path] = field(default_factory=dict)
    info: str = ""
    randomized: bool = False


#: The two measures of a simplification's cost: the cost itself, between the rows built on the
#: simplified and on the exact model, both on the cost plant; and the double difference, each row's
#: change from the simplified model's plant to the cost plant, the one row's minus the other's.
COST, DOUBLE_DIFFERENCE = "cost", "double difference"


@dataclass
class Difference:
    """The cost of one simplification to one controller family on one metric.  ``measure``
    :data:`COST`: ``interval`` of (row built on the simplified model) - (row built on the exact
    model), both on ``plant``.  :data:`DOUBLE_DIFFERENCE`: of [that row on ``plant`` - on the
    simplified model's plant] - [the exact row on ``plant`` - on the simplified model's plant]; on
    the exact plant, the sum of the two ways of building on the wrong model (the simplified row on
    the exact plant, the exact row on the simplified plant), each compared with the row built on
    that plant's model.  ``failed`` if a row succeeds in fewer than :data:`FAILURE_THRESHOLD` of
    the episodes on a plant the measure uses."""

    family: str
    simplification: str
    label: str
    reference: str
    metric: str
    interval: Interval
    failed: bool
    plant: str = TRUE_MODEL
    measure: str = COST
    #: two-sided p of Welch's t test between the two rows' per-seed values (for a double
    #: difference, their per-seed changes between the plants); None with fewer than two seeds
    seed_p: float | None = None

    @property
    def resolved(self) -> bool:
        return self.interval.resolved


@dataclass
class MismatchResult:
    """The study's numbers: ``summary[row label][test model][metric]`` an :class:`Interval`;
    ``rows`` in table order; ``test_models`` the columns; ``differences`` the simplifications'
    costs; ``per_seed[row label][metric]`` a learned row's point estimate per training seed on the
    plant the costs are measured on; ``files`` what was written."""

    rows: list[Row]
    test_models: list[str]
    summary: dict[str, dict[str, dict[str, Interval]]]
    episodes: int
    differences: list[Difference] = field(default_factory=list)
    per_seed: dict[str, dict[str, list[float]]] = field(default_factory=dict)
    files: dict[str, Path] = field(default_factory=dict)

    def matrix(self, metric: str) -> np.ndarray:
        """(rows, test models) array of one metric's point estimates."""
        return np.array([[self.summary[r.label][m][metric].estimate for m in self.test_models] for r in self.rows])


# -- checks ---------------------------------------------------------------------------------------


def _check_models(names: Sequence[str], what: str, platform: str) -> list[str]:
    """The model names, each checked by building the environment on it (one source of truth for
    what the environment simulates)."""
    from stewart_env.envs import StewartPlatformEnv

    out = []
    for name in names:
        try:
            StewartPlatformEnv(model=name, platform=platform).close()
        except (ValueError, KeyError, ImportError) as exc:
            raise TrainingError(f"{what}: {name!r} is not a model the environment simulates ({exc})") from None
        out.append(name)
    if not out:
        raise TrainingError(f"{what}: give at least one model")
    return out


def closed_form(model: str, platform: str) -> bool:
    """Whether ``model`` is a closed-form dynamics model (one PD and CT rows can be built on)."""
    import stewart_env as se

    try:
        se.make_dynamics(model, se.load_platform(platform))
    except (ValueError, KeyError):
        return False
    return True


def _check_seeds(seeds: Sequence[int]) -> tuple[int, ...]:
    seeds = tuple(seeds)
    bad = [s for s in seeds if isinstance(s, bool) or not isinstance(s, (int, np.integer)) or not 0 <= s <= MAX_SEED]
    if not seeds or bad:
        raise TrainingError(f"seeds: expected one or more integers in [0, {MAX_SEED}], got {list(seeds)!r}")
    if len(set(seeds)) != len(seeds):
        raise TrainingError(f"seeds: each seed once, got {list(seeds)!r}")
    return tuple(int(s) for s in seeds)


def _check_platform(platform: str) -> str:
    from stewart_env.cli.arguments import platform_name

    try:
        platform_name(platform)
    except argparse.ArgumentTypeError as err:
        raise TrainingError(f"platform: {err}") from None
    # a config file by its absolute path, so that a later run from elsewhere finds the same one
    return platform if Path(platform).suffix == "" and not Path(platform).exists() else str(Path(platform).resolve())


def _changes(old: Mapping[str, Any], new: Mapping[str, Any]) -> list[str]:
    return [f"{k}: {old.get(k)!r} -> {new.get(k)!r}" for k in sorted(set(old) | set(new)) if old.get(k) != new.get(k)]


def _check_study(out: Path, settings: dict[str, Any]) -> None:
    """Refuse a directory holding a study of other settings; record the settings otherwise."""
    path = out / STUDY_FILE
    if os.path.lexists(path):
        changes = _changes(read_json(path, MAX_MANIFEST_BYTES, "study file"), settings)
        if changes:
            raise TrainingError(f"{out} holds a study with other settings; its finished cells and agents would "
                                "mean something else:\n  " + "\n  ".join(changes) + "\nrun with the study's "
                                "settings (rows, test models and seeds may be added), or use another --out")
    else:
        publish(path, json.dumps(settings, indent=1, sort_keys=True))


def _check_own_agents(out: Path) -> None:
    """Refuse agents shared with another study: DIR/agents as a symbolic link (or one below it)."""
    agents = out / AGENTS_DIR
    for path in [agents, *agents.glob("*"), *agents.glob("*/*")]:
        if path.is_symlink():
            raise TrainingError(f"{path} is a symbolic link: a study's agents are not shared with another study "
                                f"(its cells record the hashes of the agents they ran); give each study its own "
                                f"--out, or copy the agents into {agents}")


# -- backends -------------------------------------------------------------------------------------


class LocalBackend:
    """Runs jobs in this process, one after another, in order."""

    name = "local"

    def run(self, fn: Callable, jobs: Sequence[tuple]) -> Iterator[tuple[int, Any]]:
        for i, args in enumerate(jobs):
            yield i, fn(*args)

    def put(self, value):
        return value

    def close(self) -> None:
        pass


class BackendError(TrainingError):
    """The backend failed while the study ran (a Ray node or worker died, a job crashed): what
    finished is kept, and the same command continues the study."""


class RayBackend:
    """Runs every job as a Ray task requesting :data:`CPUS_PER_JOB` CPUs, on the cluster at
    ``address`` ("auto", "HOST:PORT") or, without one, on a local Ray instance started here (or
    the one this process already joined)."""

    name = "ray"

    def __init__(self, address: str | None = None):
        import ray

        self.ray = ray
        self.started = False
        if not ray.is_initialized():
            endpoint = None if address is None else _ray_endpoint(address)
            if endpoint is not None:  # Ray itself retries an address that does not answer for ever
                try:
                    socket.create_connection(endpoint, timeout=RAY_CONNECT_TIMEOUT).close()
                except OSError as exc:
                    raise TrainingError(f"--ray-address {address}: nothing answers there "
                                        f"({exc.strerror or exc}); is the cluster's head node started?") from None
            kwargs = {"address": address} if address else {"include_dashboard": False}
            try:
                ray.init(logging_level="ERROR", log_to_driver=False, **kwargs)
            except (ConnectionError, ValueError, RuntimeError, ray.exceptions.RayError) as exc:
                raise TrainingError(f"--ray-address {address}: cannot join the Ray cluster ({exc}){RAY_AUTH_HINT}") \
                    from None
            self.started = True

    def put(self, value):
        return self.ray.put(value)

    def run(self, fn: Callable, jobs: Sequence[tuple]) -> Iterator[tuple[int, Any]]:
        ray = self.ray
        remote = ray.remote(num_cpus=CPUS_PER_JOB, max_retries=0)(fn)
        pending = {remote.remote(*args): i for i, args in enumerate(jobs)}
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
        if self.started:
            self.ray.shutdown()


def _ray_endpoint(address: str) -> tuple[str, int] | None:
    """(host, port) of a Ray address "HOST:PORT" or "ray://HOST:PORT"; None for "auto"."""
    if address == "auto":
        return None
    host, sep, port = address.split("://", 1)[-1].rpartition(":")
    if not (sep and host and port.isdigit() and 1 <= int(port) <= 65535):
        raise TrainingError(f"--ray-address: expected auto, HOST:PORT or ray://HOST:PORT, got {address!r}")
    return host, int(port)


def check_backend(name: str, address: str | None = None) -> None:
    """Refuse an unknown backend, an address without Ray or of no Ray form, and the Ray backend
    without ray installed."""
    if name not in BACKENDS:
        raise TrainingError(f"backend: expected one of {', '.join(BACKENDS)}, got {name!r}")
    if name == "local" and address is not None:
        raise TrainingError("--ray-address: only with --backend ray")
    if address is not None:
        _ray_endpoint(address)
    if name == "ray":
        try:
            import ray  # noqa: F401
        except ImportError:
            raise TrainingError(f"--backend ray needs ray: {RAY_INSTALL_HINT}") from None


def make_backend(name: str, address: str | None = None):
    """The backend called ``name`` ("local" or "ray"); ``address`` only with "ray"."""
    check_backend(name, address)
    return LocalBackend() if name == "local" else RayBackend(address)


# -- jobs (top-level functions: Ray workers import them by name) ----------------------------------


def _train_job(row: dict[str, Any], timesteps: int) -> dict[str, bytes]:
    """Train one agent in a temporary folder of the worker and return its files' bytes (the
    worker's file system need not be the driver's)."""
    with tempfile.TemporaryDirectory(prefix="stewart-env-agent-") as tmp:
        folder = Path(tmp) / "agent"
        train(**row, out=folder, timesteps=timesteps)
        return _agent_files(folder)


def _agent_files(folder: Path) -> dict[str, bytes]:
    """The bytes of an agent's files in ``folder``, by name (what travels to and from workers)."""
    return {name: read_regular(folder / name, MAX_AGENT_FILE_BYTES) for name in AGENT_FILES
            if os.path.lexists(folder / name)}


def _load_agent(agent):
    """An agent from its folder (a path) or from its files' bytes (a dict), written to a
    temporary folder first."""
    if not isinstance(agent, dict):
        return load_agent(agent)
    with tempfile.TemporaryDirectory(prefix="stewart-env-agent-") as tmp:
        for name, data in agent.items():
            (Path(tmp) / name).write_bytes(data)
        return load_agent(tmp)


def make_policy(kind: str, model: str, agent=None):
    """A policy (or a factory env -> policy) for :func:`~.evaluation.evaluate`: the PD law with
    model ``model``'s holding forces, CT with internal model ``model``, or the trained ``agent``
    (a folder, or its files' bytes)."""
    if kind == "agent":
        return _load_agent(agent)
    if kind == "ct":
        from stewart_env.agents.computed_torque import ComputedTorquePolicy

        return lambda env: ComputedTorquePolicy(env, model)
    if kind == "pd":
        from stewart_env.agents.pd import PDPolicy

        return lambda env: PDPolicy(env, gravity_compensation=True, gravity_model=model)
    raise ValueError(f"kind: expected 'pd', 'ct' or 'agent', got {kind!r}")


def _evaluate_job(spec: dict[str, Any], agent=None) -> dict[str, Any]:
    """One evaluation: the controller of ``spec`` on its plant; every metric per episode, and the
    episodes' terminations."""
    from stewart_env.agents.evaluation import METRICS, evaluate

    policy = make_policy(spec["kind"], spec["design_model"], agent)
    result = evaluate(policy, {**spec["env_kwargs"], "model": spec["plant"], "task": spec["task"]},
                      episodes=spec["episodes"], seed=spec["eval_seed"], label=spec["controller"],
                      max_steps=spec["max_steps"], position_tolerance=spec["position_tolerance"],
                      orientation_tolerance=spec["orientation_tolerance"], progress=False)
    return {"metrics": {key: [ep.metrics[key] for ep in result.episodes] for key, *_ in METRICS},
            "terminations": [ep.termination for ep in result.episodes]}


# -- building the rows ------------------------------------------------------------------------------


def design_models(train_models: Sequence[str], simplifications: Sequence[str]) -> list[str]:
    """The models controllers are built on: the training models, then improved+cK per simplification."""
    return list(train_models) + [f"improved+{c}" for c in simplifications if f"improved+{c}" not in train_models]


def build_rows(out: Path, models: Sequence[str], algo: str | None, seeds: Sequence[int], domain_randomization: bool,
               platform: str, agent_models: Sequence[str] | None = None) -> list[Row]:
    """The study's controllers; learned rows (on ``agent_models``, default all ``models``) name
    their agent folders (trained or not yet)."""
    from stewart_env.agents.evaluation import slug

    analytic = [m for m in models if closed_form(m, platform)]
    rows = [Row(f"PD + gravity comp. [{m}]", "PD", m, "pd",
                info="task-space PD, gravity compensation from this model's statics") for m in analytic]
    rows += [Row(f"CT [{m}]", "CT", m, "ct", info="computed torque, this model's inverse dynamics") for m in analytic]
    if algo is None:
        return rows
    agent_models = models if agent_models is None else agent_models
    trainings = [(m, False) for m in agent_models] + ([("improved", True)] if domain_randomization else [])
    for m, randomized in trainings:
        name = f"{m} + DR" if randomized else m
        agents = {s: out / "agents" / slug(name) / f"seed_{s}" for s in seeds}
        rows.append(Row(f"{algo.upper()} [{name}]", algo.upper(), m, "agent", tuple(seeds), agents,
                        randomized=randomized))
    return rows


def _training_row(algo: str, row: Row, seed: int, env_kwargs: Mapping[str, Any], task: str,
                  n_envs: int | None, config: str | None = None) -> dict[str, Any]:
    """The keywords of :func:`~.training.train` for one agent of a learned row."""
    rest = dict(env_kwargs)
    if row.randomized:
        rest["randomization"] = {k: list(v) for k, v in DEFAULT_RANDOMIZATION.items()}
    return dict(algo=algo, model=row.model, task=task, seed=seed, n_envs=n_envs, checkpoint_freq=0,
                env_kwargs=rest, config=config)


def _finished_agent(directory: Path, algo: str, seed: int, env_kwargs: Mapping[str, Any]) -> bool:
    """Whether ``directory`` holds this agent, trained; refuses one trained differently."""
    if not (directory / MODEL_FILE).exists():
        return False
    manifest = read_manifest(directory)
    found = (manifest["algo"], manifest["seed"], manifest["env_kwargs"])
    if found != (algo, seed, env_kwargs):
        raise TrainingError(
            f"{directory} holds an agent trained differently (algorithm, seed, env kwargs: {found}) from "
            f"this study's row ({(algo, seed, env_kwargs)}); use another --out")
    # a run stopped by a signal saves its model too, unfinished: it is continued, not reused
    return bool(manifest.get("finished"))


def _train_locally(directory: Path, training: dict[str, Any], timesteps: int, progress: bool) -> None:
    """Train one agent into ``directory``, continuing it from its newest checkpoint if a stopped
    study left one (given the row's settings, train() refuses a run trained otherwise)."""
    resumable = None
    if (directory / MANIFEST).exists():
        resumable = newest_checkpoint(directory, training["algo"], bool(read_manifest(directory).get("normalize")))
    if resumable:
        steps, _ = resumable
        train(**training, out=directory, timesteps=max(timesteps - steps, 1), resume=True, progress_bar=progress)
    else:
        train(**training, out=directory, timesteps=timesteps, progress_bar=progress)


def _publish_agent(directory: Path, files: Mapping[str, bytes]) -> None:
    """Write an agent's files, sent back by a worker, as ``directory`` in one rename (replacing an
    unfinished local run of this agent)."""
    with publishing_folder(directory) as tmp:
        for name, data in files.items():
            (tmp / name).write_bytes(data)


# -- the study --------------------------------------------------------------------------------------


def _cell_path(out: Path, row: Row, plant: str, seed: int | None) -> Path:
    from stewart_env.agents.evaluation import slug

    return out / CELLS_DIR / slug(row.label) / slug(plant) / ("model_based.json" if seed is None else f"seed_{seed}.json")


def _cell_spec(row: Row, plant: str, seed: int | None, common: Mapping[str, Any]) -> dict[str, Any]:
    """What an evaluation's numbers depend on; a finished cell is reused only if all of it is equal."""
    spec = {"controller": row.label, "kind": row.kind, "design_model": row.model, "plant": plant, **common}
    if seed is not None:
        spec["agent_seed"] = seed
        spec["agent_sha256"] = read_manifest(row.agents[seed])["files"][MODEL_FILE]
    return spec


def run_mismatch(out: str | Path, train_models: Sequence[str] = ("classical", "improved"),
                 test_models: Sequence[str] = ("classical", "improved", "improved_centroidal"),
                 task: str = "setpoint", algo: str | None = "ppo", timesteps: int = QUICK_TIMESTEPS,
                 episodes: int = 5, seeds: Sequence[int] = (0,), domain_randomization: bool = False,
                 simplifications: Sequence[str] = SIMPLIFICATIONS, env_kwargs: Mapping[str, Any] | None = None,
                 n_envs: int | None = None, max_steps: int | None = None, platform: str = "dasgupta1998",
                 backend: str = "local", ray_address: str | None = None, agent_models: Sequence[str] | None = None,
                 config: str | os.PathLike | None = None, position_tolerance: float = POSITION_TOLERANCE,
                 orientation_tolerance: float = ORIENTATION_TOLERANCE, cost_plant: str = TRUE_MODEL,
                 progress: bool = True) -> MismatchResult:
    """Run the mismatch study and write it to ``out`` (see the module docstring).

    train_models: models to build controllers on (PD's statics, CT's internal model, RL plants).
    test_models: the plants every controller is evaluated on (the columns).
    task: "setpoint", "tracking" or "disturbance"; platform: a platform name or config path.
    algo: the RL algorithm ("ppo", "sac", "td3"), or None for the model-based rows only.
    timesteps: environment steps per agent; seeds: one agent per seed and learned row.
    episodes: evaluation episodes per cell, seeds EVAL_SEED_OFFSET + i, the same for every cell.
    simplifications: which of c1..c4 get an ``improved+cK`` row ([] for none).
    env_kwargs: further environment kwargs shared by training and test plants.
    n_envs: platforms per training batch (default the algorithm config's).
    max_steps: evaluation episode length in control steps (default the registered 500).
    backend: "local" or "ray"; ray_address: an existing Ray cluster ("auto", "HOST:PORT").
    position_tolerance (m), orientation_tolerance (rad): the success band of the evaluation
        (:func:`~.evaluation.evaluate`), which decides the failed cells; widen it on tasks whose
        errors never settle inside the set-point band (disturbance rejection).
    cost_plant: the test plant the simplifications' costs are measured on (default the exact
        improved model; "mujoco" asks what each model costs on MuJoCo's simulation).
    config: the agents' zoo hyperparameter file (default configs/agents/<algo>.yml).
    agent_models: the models RL agents are trained on (default: every model controllers are built
        on, the improved+cK ones included); any model the environment simulates.

    Every argument is checked before any work starts; errors raise TrainingError naming it.  A
    second study on ``out`` while one runs raises :class:`~stewart_env.files.FolderBusy`, a failed
    write (a full disk) :class:`~stewart_env.files.WriteError` naming the file, the finished agents
    and cells kept.
    """
    from stewart_env.agents.evaluation import METRICS
    from stewart_env.tasks import TASKS

    check_not_busy(out)  # a study in progress is reported at once, not by what it left so far
    if algo is not None and algo not in ALGORITHMS:
        raise TrainingError(f"algo: unknown algorithm {algo!r}; choose one of {', '.join(ALGORITHMS)}")
    if task not in TASKS:
        raise TrainingError(f"task: unknown task {task!r}; choose one of {', '.join(TASKS)}")
    unknown = [c for c in simplifications if c not in SIMPLIFICATIONS]
    if unknown:
        raise TrainingError(f"simplifications: unknown {', '.join(unknown)}; choose from {', '.join(SIMPLIFICATIONS)}")
    platform = _check_platform(platform)
    train_models = _check_models(train_models, "train models", platform)
    test_models = _check_models(test_models, "test models", platform)
    seeds = _check_seeds(seeds)
    if cost_plant not in test_models:
        raise TrainingError(f"cost plant: {cost_plant!r} is not one of the test models ({', '.join(test_models)}); "
                            f"pass --cost-plant with one of them, or add {cost_plant} to --test-models")
    if agent_models is not None:
        agent_models = _check_models(agent_models, "agent models", platform)
    for name, value in (("episodes", episodes), ("timesteps", timesteps), ("n_envs", n_envs), ("max_steps", max_steps)):
        if value is not None and (isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1):
            raise TrainingError(f"{name}: expected a positive integer, got {value!r}")
    if max_steps is not None and max_steps > MAX_STEPS:
        raise TrainingError(f"max_steps: at most {MAX_STEPS} control steps per episode, got {max_steps}")
    for name, value in (("position_tolerance", position_tolerance), ("orientation_tolerance", orientation_tolerance)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < math.inf:
            raise TrainingError(f"{name}: expected a finite positive number, got {value!r}")
    env_kwargs = dict(env_kwargs or {})
    clash = [k for k in ("model", "task", "randomization", "platform") if k in env_kwargs]
    if clash:
        raise TrainingError(f"env kwargs: {', '.join(clash)} {'is' if len(clash) == 1 else 'are'} set by the study itself "
                            "(--train-models/--test-models, --task, --domain-randomization, --platform)")
    env_kwargs["platform"] = platform
    env_kwargs = jsonable(env_kwargs)
    check_backend(backend, ray_address)
    if config is not None:
        if algo is None:
            raise TrainingError("config: only with an RL algorithm (--algo)")
        config = str(Path(config).resolve())
        hyperparameters = jsonable(read_hyperparameters(algo, config))
    out = Path(out)
    with lock_folder(out):  # one command at a time on a study, until this one ends
        _check_own_agents(out)
        common = {"task": task, "env_kwargs": env_kwargs, "episodes": int(episodes), "eval_seed": EVAL_SEED_OFFSET,
                  "max_steps": max_steps, "position_tolerance": float(position_tolerance),
                  "orientation_tolerance": float(orientation_tolerance)}
        settings = {**common, "algo": algo, "timesteps": int(timesteps) if algo else None,
                    "n_envs": n_envs if algo else None}
        if config is not None:  # the hyperparameters themselves: an edited file changes the agents
            settings["config"] = {"path": config, "hyperparameters": hyperparameters}
        _check_study(out, settings)
        runner = make_backend(backend, ray_address)

        start = time.perf_counter()
        rows = build_rows(out, design_models(train_models, simplifications), algo, seeds, domain_randomization,
                          platform, agent_models)
        try:
            _run_jobs(runner, out, rows, algo, timesteps, common, test_models, n_envs, progress, config)
        finally:
            runner.close()
        # every cell read once: the summary, the costs and the per-seed values all draw on it
        stored = {(r.label, m): _stored_metrics(out, r, m) for r in rows for m in test_models}

        def values(row: Row, plant: str, metric: str) -> np.ndarray:
            return _metric_values(stored[row.label, plant], metric)

        summary = {r.label: {m: _cell_intervals(stored[r.label, m]) for m in test_models} for r in rows}
        for r in rows:
            if r.kind == "agent":
                steps = sorted({read_manifest(d)["num_timesteps"] for d in r.agents.values()})
                r.info = f"{', '.join(map(str, steps))} steps, seeds {', '.join(map(str, r.seeds))}"
        result = MismatchResult(rows, list(test_models), summary, int(episodes))
        result.differences = simplification_costs(result, values, plant=cost_plant)
        result.per_seed = {r.label: {key: per_seed_estimates(values(r, cost_plant, key), statistic(key))
                                     for key in RANKING_METRICS} for r in rows if r.kind == "agent"}
        header = {"task": task, "platform": platform, "episodes": episodes, "eval_seed": EVAL_SEED_OFFSET, "algo": algo,
                  "seeds": list(seeds), "backend": backend, "wall_time": time.perf_counter() - start,
                  "position_tolerance": position_tolerance, "orientation_tolerance": orientation_tolerance,
                  "cost_plant": cost_plant}
        result.files = write_outputs(result, out, METRICS, header)
        return result


def _run_jobs(runner, out: Path, rows: list[Row], algo: str | None, timesteps: int, common: Mapping[str, Any],
              test_models: Sequence[str], n_envs: int | None, progress: bool, config: str | None = None) -> None:
    """Train the missing agents, then evaluate the missing cells, on ``runner``; each result is
    stored as soon as it arrives, so a stopped study keeps what finished."""
    env_kwargs, task = common["env_kwargs"], common["task"]
    trainings = []
    for row in rows:
        for seed, directory in row.agents.items():
            training = _training_row(algo, row, seed, env_kwargs, task, n_envs, config)
            expected = {**_config_env_kwargs(algo, config), **training["env_kwargs"], "model": row.model, "task": task}
            if not _finished_agent(directory, algo, seed, jsonable(expected)):
                trainings.append((directory, training))
    cells = [(row, plant, seed) for row in rows for plant in test_models for seed in (row.seeds or (None,))]
    bar = progress_bar(total=len(trainings) + len(cells), desc="mismatch study", unit="job", disable=not progress)
    with bar:
        if isinstance(runner, LocalBackend):
            for directory, training in trainings:
                _train_locally(directory, training, timesteps, progress)
                bar.update()
        else:
            jobs = [(training, timesteps) for _, training in trainings]
            for i, files in runner.run(_train_job, jobs):
                _publish_agent(trainings[i][0], files)
                bar.update()

        todo = []
        # agents run on the environment of their config (e.g. an error-integral observation), nominal
        agent_common = {**common, "env_kwargs": {**_config_env_kwargs(algo, config), **env_kwargs}} if algo else common
        for row, plant, seed in cells:
            path = _cell_path(out, row, plant, seed)
            spec = _cell_spec(row, plant, seed, agent_common if row.kind == "agent" else common)
            if os.path.lexists(path):
                stored = _read_cell(path)
                if stored["spec"] == spec:
                    bar.update()
                    continue
                print(f"stewart-env mismatch: recomputing {row.label} on {plant}"
                      f"{'' if seed is None else f' (seed {seed})'}: its settings changed: "
                      + "; ".join(_changes(stored["spec"], spec)), file=sys.stderr)
            todo.append((path, spec, row, seed))
        agents = {}  # each agent read (and sent to the workers) once
        jobs = []
        for path, spec, row, seed in todo:
            agent = None
            if seed is not None:
                key = row.agents[seed]
                if key not in agents:
                    agents[key] = runner.put(key if isinstance(runner, LocalBackend) else _agent_files(key))
                agent = agents[key]
            jobs.append((spec, agent))
        for i, numbers in runner.run(_evaluate_job, jobs):
            path, spec = todo[i][0], todo[i][1]
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
            except OSError as err:
                raise write_error(path.parent, err) from None
            publish(path, json.dumps({"spec": spec, **numbers}))
            bar.update()


def _config_env_kwargs(algo: str, config: str | None = None) -> dict[str, Any]:
    """The env kwargs the algorithm's config adds to every run (run.json records them)."""
    from stewart_env.agents.training import parse_hyperparameters, read_hyperparameters

    return dict(parse_hyperparameters(algo, read_hyperparameters(algo, config)).env_kwargs)


def _stored_metrics(out: Path, row: Row, plant: str) -> list[dict[str, list[float]]]:
    """A stored cell's metrics per episode, one dict per seed (one for a model-based row)."""
    paths = [_cell_path(out, row, plant, seed) for seed in (row.seeds or (None,))]
    return [_read_cell(p)["metrics"] for p in paths]


def _read_cell(path: Path) -> dict[str, Any]:
    """A finished cell's file: its spec and its metrics per episode."""
    cell = read_json(path, MAX_CELL_BYTES, "cell file")
    if not (isinstance(cell, dict) and isinstance(cell.get("spec"), dict) and isinstance(cell.get("metrics"), dict)):
        raise TrainingError(f"{path}: not a cell of a mismatch study (no spec and metrics); remove it to compute "
                            "the cell again")
    return cell


def _metric_values(stored: list[dict[str, list[float]]], metric: str) -> np.ndarray:
    """One metric's values, (seeds, episodes), of a cell's :func:`_stored_metrics`."""
    return np.array([s[metric] for s in stored], dtype=float)


def cell_values(out: Path, row: Row, plant: str, metric: str) -> np.ndarray:
    """A stored cell's values of one metric, (seeds, episodes)."""
    return _metric_values(_stored_metrics(out, row, plant), metric)


def _cell_intervals(stored: list[dict[str, list[float]]]) -> dict[str, Interval]:
    """Every metric's interval of a cell's :func:`_stored_metrics`."""
    from stewart_env.agents.evaluation import METRICS

    return {key: stratified_bootstrap(_metric_values(stored, key), statistic(key)) for key, *_ in METRICS}


# -- the cost of each simplification ----------------------------------------------------------------


def _compared_rows(result: MismatchResult, family: str) -> list[tuple[str, Row]]:
    """(name, row) of the ``family``'s rows built on a simplified model, or with domain
    randomisation: the whole classical model, C1..C4, DR."""
    by_model = {r.model: r for r in result.rows if r.family == family and not r.randomized}
    out = [("classical model", by_model["classical"])] if "classical" in by_model else []
    out += [(c.upper(), by_model[f"improved+{c}"]) for c in SIMPLIFICATIONS if f"improved+{c}" in by_model]
    out += [("domain randomisation", r) for r in result.rows if r.family == family and r.randomized]
    return out


def simplification_costs(result: MismatchResult, values: Callable[[Row, str, str], np.ndarray],
                         plant: str = TRUE_MODEL) -> list[Difference]:
    """Per controller family with a row built on the exact model: for each simplification and each
    of :data:`RANKING_METRICS`, the paired difference on ``plant`` of the row built on the
    simplified model minus the exact-model row, with its interval; and where the simplified model
    is a test plant too, the double difference (see :class:`Difference`).  ``values(row, plant,
    metric)`` gives a cell's values (seeds, episodes), e.g. :func:`cell_values` of a study's
    directory."""
    if plant not in result.test_models:
        return []
    differences = []
    for family in dict.fromkeys(r.family for r in result.rows):
        exact = next((r for r in result.rows if r.family == family and r.model == TRUE_MODEL and not r.randomized),
                     None)
        if exact is None:
            continue
        for name, row in _compared_rows(result, family):
            home = row.model if row.model in result.test_models and row.model != plant and not row.randomized else None
            for metric in RANKING_METRICS:
                mine, theirs = values(row, plant, metric), values(exact, plant, metric)
                differences.append(Difference(
                    family, name, row.label, exact.label, metric,
                    paired_difference(mine, theirs, statistic(metric)), _failed(result, (row, exact), (plant,)),
                    plant, seed_p=_seed_test(mine, theirs, statistic(metric))))
                if home is not None:
                    mine_home, theirs_home = values(row, home, metric), values(exact, home, metric)
                    differences.append(Difference(
                        family, name, row.label, exact.label, metric,
                        double_difference(mine, mine_home, theirs, theirs_home, statistic(metric)),
                        _failed(result, (row, exact), (plant, home)), plant, DOUBLE_DIFFERENCE,
                        _seed_test(mine - mine_home, theirs - theirs_home, statistic(metric))))
    return differences


def per_seed_estimates(values: np.ndarray, statistic_name: str) -> list[float]:
    """A cell's point estimate for each training seed alone: ``values`` (seeds, episodes)."""
    return [point_estimate(v, statistic_name) for v in values]


def _seed_test(values: np.ndarray, reference: np.ndarray, statistic_name: str) -> float | None:
    """Two-sided p of Welch's t test between two cells' per-seed point estimates: a check of a
    difference that does not lean on the bootstrap, which with few seeds is too narrow; None with
    fewer than two seeds a cell or no spread to test."""
    from scipy.stats import ttest_ind

    if min(len(values), len(reference)) < 2:
        return None
    mine, theirs = per_seed_estimates(values, statistic_name), per_seed_estimates(reference, statistic_name)
    # seeds that agree to rounding (a deterministic part of the controller): scipy warns, the p stands
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        p = float(ttest_ind(mine, theirs, equal_var=False).pvalue)
    return p if np.isfinite(p) else None


def _failed(result: MismatchResult, rows: Sequence[Row], plants: Sequence[str]) -> bool:
    """Whether any of ``rows`` succeeds in fewer than :data:`FAILURE_THRESHOLD` of its episodes on
    any of ``plants``."""
    return min(result.summary[r.label][p]["success"].estimate for r in rows for p in plants) < FAILURE_THRESHOLD


# -- outputs ---------------------------------------------------------------------------------------


def _fmt(value: float, factor: float, spec: str) -> str:
    return "-" if not np.isfinite(value) else format(value * factor, spec)


def format_interval(interval: Interval, factor: float, spec: str) -> str:
    """``estimate [low, high]`` in display units; '-' where undefined."""
    if not np.isfinite(interval.estimate):
        return "-"
    return (f"{_fmt(interval.estimate, factor, spec)} [{_fmt(interval.low, factor, spec)}, "
            f"{_fmt(interval.high, factor, spec)}]")


#: What a planning figure (:func:`seeds_needed`) is sized for, as the text that follows it.
PLANNING_BASES = {"estimate": "at its own estimate",
                  "double difference": "at half the double difference, {effect}",
                  "double difference bound": "at the most it can be, half the double difference's larger bound, "
                                             "{effect}; so at least that many"}


def seeds_needed(cost: Difference, differences: Sequence[Difference]) -> tuple[int | None, str, float]:
    """About how many training seeds per row would resolve an unresolved cost
    (:func:`~.statistics.seeds_to_resolve`), what the figure is sized for (a key of
    :data:`PLANNING_BASES`) and the size.  Where the study has the double difference of the same
    family, simplification and metric, it sizes the figure: it is the sum of the costs of the two
    directions, measured without the seeds' spread, so half of it is a far better guess of the
    cost than the cost's own estimate, which at few seeds is mostly their spread; where it is not
    resolved, half its larger bound bounds the cost, and the figure is a lower bound."""
    double = next((d for d in differences if d.measure == DOUBLE_DIFFERENCE and
                   (d.family, d.simplification, d.metric) == (cost.family, cost.simplification, cost.metric)), None)
    if double is None or not np.isfinite(double.interval.estimate):
        effect, basis = cost.interval.estimate, "estimate"
    elif double.resolved:
        effect, basis = 0.5 * double.interval.estimate, "double difference"
    else:
        effect, basis = 0.5 * max(abs(double.interval.low), abs(double.interval.high)), "double difference bound"
    return seeds_to_resolve(cost.interval, effect), basis, abs(effect)


def _unresolved_text(cost: Difference, differences: Sequence[Difference], factor: float) -> str:
    """An unresolved cost's name, with the seeds per row that would resolve it where it rests on
    several (:func:`seeds_needed`); ``factor`` converts SI to the table's units."""
    seeds, basis, effect = seeds_needed(cost, differences)
    if seeds is None:
        return cost.simplification
    size = PLANNING_BASES[basis].format(effect=_fmt(effect, factor, ".3g"))
    return f"{cost.simplification} (about {seeds} seeds a row would resolve it, {size})"


def _difference_table(differences: Sequence[Difference], meta) -> list[str]:
    """A markdown table of one family's differences: rows simplifications, columns
    :data:`RANKING_METRICS`, entries difference [interval], resolved in bold, failed marked."""
    lines = ["| simplification | " + " | ".join(meta[k][1] for k in RANKING_METRICS) + " |",
             "|---|" + "---|" * len(RANKING_METRICS)]
    for name in dict.fromkeys(d.simplification for d in differences):
        cells = []
        for key in RANKING_METRICS:
            d = next(x for x in differences if x.simplification == name and x.metric == key)
            text = format_interval(d.interval, meta[key][2], meta[key][3])
            cells.append(f"*failed* {text}" if d.failed else f"**{text}**" if d.resolved else text)
        label = f"{name}: {SIMPLIFICATION_TEXT[name.lower()]}" if name.lower() in SIMPLIFICATION_TEXT else name
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return lines + [""]


def _cost_lines(result: MismatchResult, metrics) -> list[str]:
    """The markdown sections of the simplifications' costs: per family a table (rows:
    simplifications, columns: metrics, entries: difference [interval], resolved in bold, failed
    marked), then per metric the ranking of the resolved costs that are not failed; then the
    double differences, per family a table."""
    costs = [d for d in result.differences if d.measure == COST]
    if not costs:
        return []
    meta = {m[0]: m for m in metrics}
    plant = costs[0].plant
    lines = [f"## The cost of each simplification on the {plant} plant", "",
             f"Each entry: (controller built on the simplified model) - (the same controller built on the "
             f"{TRUE_MODEL} model), both on the {plant} plant, paired by episode, with its 95 % interval "
             "(stratified bootstrap over seeds and episodes). **Bold**: resolved (the interval excludes zero). "
             f"*failed*: one of the two rows succeeds in fewer than {FAILURE_THRESHOLD:.0%} of the episodes, so "
             "the difference measures the failure and is not ranked.", ""]
    for family in dict.fromkeys(d.family for d in costs):
        mine = [d for d in costs if d.family == family]
        lines += [f"### {family}", "", *_difference_table(mine, meta)]
        for key in RANKING_METRICS:
            ranked = sorted((d for d in mine if d.metric == key and d.resolved and not d.failed),
                            key=lambda d: -abs(d.interval.estimate))
            unresolved = [_unresolved_text(d, result.differences, meta[key][2]) for d in mine
                          if d.metric == key and not d.resolved and not d.failed]
            failed = [d.simplification for d in mine if d.metric == key and d.failed]
            text = ", ".join(f"{d.simplification} ({_fmt(d.interval.estimate, meta[key][2], '+.3g')})"
                             for d in ranked) or "none resolved"
            rest = (f"; not resolved: {', '.join(unresolved)}" if unresolved else "") + (
                f"; failed, not ranked: {', '.join(failed)}" if failed else "")
            lines.append(f"- {meta[key][1]}, resolved costs, largest first: {text}{rest}.")
        lines.append("")
    doubles = [d for d in result.differences if d.measure == DOUBLE_DIFFERENCE]
    if doubles:
        lines += [f"## Double differences on the {plant} plant", "",
                  f"Each entry: [controller built on the simplified model, on the {plant} plant - on the simplified "
                  f"model's plant] - [the same for the controller built on the {TRUE_MODEL} model], with its 95 % "
                  "interval. Each controller is compared with itself, seed by seed and episode by episode, so a "
                  "training seed's own bias cancels, and so does the difference between the two plants. On the "
                  "exact plant it is the sum of the two costs of building on the wrong model: the simplified "
                  "controller on the exact plant, and the exact controller on the simplified plant, each against "
                  "the controller built on its plant's model. Zero where the simplification costs nothing either "
                  "way; not ranked.", ""]
        for family in dict.fromkeys(d.family for d in doubles):
            lines += [f"### {family}", "", *_difference_table([d for d in doubles if d.family == family], meta)]
    return lines


def _per_seed_lines(result: MismatchResult, metrics, plant: str) -> list[str]:
    """The markdown table of the learned rows' estimates per training seed on ``plant``."""
    if not result.per_seed:
        return []
    from scipy.stats import norm, t

    meta = {m[0]: m for m in metrics}
    seeds = max(len(r.seeds) for r in result.rows if r.label in result.per_seed)
    # the percentile bootstrap of a mean of n values has the spread of sqrt((n - 1) / n) standard
    # errors and normal quantiles; a t interval has t quantiles on n - 1 degrees of freedom
    wider = t.ppf(0.975, seeds - 1) * math.sqrt(seeds / (seeds - 1)) / norm.ppf(0.975) if seeds > 1 else math.nan
    lines = [f"## Per training seed on the {plant} plant", "",
             "Each learned row's point estimate for each of its training seeds alone (the cells' statistic). "
             "With few seeds the bootstrap intervals above cannot reach beyond the seeds at hand, so they are "
             "narrower than 95 % intervals should be"
             + (f" (with {seeds} seeds a t interval on a mean of these values would be {wider:.2g} times as wide)"
                if seeds > 1 else "") + "; these values let any other test be applied.", "",
             "| controller | seed | " + " | ".join(meta[k][1] for k in RANKING_METRICS) + " |",
             "|---|---|" + "---|" * len(RANKING_METRICS)]
    for r in result.rows:
        if r.label in result.per_seed:
            for i, seed in enumerate(r.seeds):
                lines.append(f"| {r.label} | {seed} | " + " | ".join(
                    _fmt(result.per_seed[r.label][k][i], meta[k][2], meta[k][3]) for k in RANKING_METRICS) + " |")
    tested = [d for d in result.differences if d.seed_p is not None]
    if tested:
        lines += ["", "Welch's two-sided t test on these per-seed values, each row against the row built on the "
                  f"{TRUE_MODEL} model (for a double difference: on each agent's change between the two plants), "
                  "p per metric ('-': nothing to test):", "",
                  "| simplification | " + " | ".join(meta[k][1] for k in RANKING_METRICS) + " |",
                  "|---|" + "---|" * len(RANKING_METRICS)]
        p_values: dict[tuple[str, str, str], dict[str, float]] = {}
        for d in tested:
            p_values.setdefault((d.family, d.simplification, d.measure), {})[d.metric] = d.seed_p
        for (family, name, measure), p in p_values.items():
            label = f"{family}: {name}" + (", double diff." if measure == DOUBLE_DIFFERENCE else "")
            lines.append(f"| {label} | " + " | ".join("-" if p.get(k) is None else f"{p[k]:.2g}"
                                                      for k in RANKING_METRICS) + " |")
    return lines + [""]


def write_outputs(result: MismatchResult, out: Path, metrics, header: Mapping[str, Any]) -> dict[str, Path]:
    """matrix.csv, matrix.md, differences.csv, forest.png and one heatmap PNG per metric into
    ``out``; returns {name: path}."""
    files = {"csv": out / "matrix.csv", "markdown": out / "matrix.md", "differences": out / "differences.csv"}
    with publishing(files["csv"]) as tmp, tmp.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["controller", "family", "design_model", "test_model", "seeds", "episodes"]
                        + [f"{m[0]}{suffix}" for m in metrics for suffix in ("", "_ci_low", "_ci_high", "_n")])
        for r in result.rows:
            for m in result.test_models:
                s = result.summary[r.label][m]
                first = s[metrics[0][0]]
                values = []
                for key, *_ in metrics:
                    interval = s[key]
                    n = "" if interval.n is None else interval.n
                    values += [f"{interval.estimate:.9g}", f"{interval.low:.9g}", f"{interval.high:.9g}", n]
                writer.writerow([r.label, r.family, r.model, m, first.seeds, first.episodes] + values)
    with publishing(files["differences"]) as tmp, tmp.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["family", "simplification", "measure", "controller", "reference", "plant", "metric",
                         "statistic", "difference", "ci_low", "ci_high", "resolved", "failed", "seeds_to_resolve",
                         "seeds_sized_for", "seed_welch_p"])
        for d in result.differences:
            seeds, basis, _ = seeds_needed(d, result.differences) if d.measure == COST else (None, "", 0.0)
            writer.writerow([d.family, d.simplification, d.measure, d.label, d.reference, d.plant, d.metric,
                             statistic(d.metric), f"{d.interval.estimate:.9g}", f"{d.interval.low:.9g}",
                             f"{d.interval.high:.9g}", int(d.resolved), int(d.failed),
                             *(("", "") if seeds is None else (seeds, basis)),
                             "" if d.seed_p is None else f"{d.seed_p:.3g}"])

    seeds = header.get("seeds", [])
    lines = [f"# Model mismatch on the {header['task']} task, platform {header.get('platform', 'dasgupta1998')}", "",
             f"Rows: controllers and the dynamics model they were designed or trained on; columns: the plant "
             f"they run on. Each cell: the point estimate and its 95 % interval, a stratified bootstrap over "
             f"the training seeds ({', '.join(map(str, seeds))}; one for the model-based rows) and the "
             f"{result.episodes} episode{'s' if result.episodes != 1 else ''} (evaluation seeds {header['eval_seed']}..{header['eval_seed'] + result.episodes - 1}, "
             "the same for every cell). Success: the mean; every other metric: the interquartile mean, over the "
             "episodes where it is defined ('-' where none). An episode succeeds if it runs to its time limit and "
             f"ends within {1e3 * header.get('position_tolerance', POSITION_TOLERANCE):g} mm and "
             f"{1e3 * header.get('orientation_tolerance', ORIENTATION_TOLERANCE):g} mrad over its final window; a "
             f"cell succeeding in fewer than {FAILURE_THRESHOLD:.0%} of its episodes is marked failed.", ""]
    notes = [f"- {r.label}: {r.info}" for r in result.rows if r.info]
    if notes:
        lines += ["Controllers:", "", *dict.fromkeys(notes), ""]
    for key, title, factor, spec in metrics:
        lines += [f"## {title}", "", "| controller | " + " | ".join(result.test_models) + " |",
                  "|---|" + "---|" * len(result.test_models)]
        for r in result.rows:
            cells = [format_interval(result.summary[r.label][m][key], factor, spec) for m in result.test_models]
            lines.append(f"| {r.label} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += _cost_lines(result, metrics) + _per_seed_lines(result, metrics, header.get("cost_plant", TRUE_MODEL))
    lines.append(f"Backend: {header.get('backend', 'local')}. Wall time of this run: {header['wall_time']:.0f} s.")
    publish(files["markdown"], "\n".join(lines) + "\n")

    if result.differences:
        files["forest"] = out / "forest.png"
        with publishing(files["forest"]) as tmp:
            forest_figure(result, metrics).savefig(tmp, dpi=110)
    for key, title, factor, spec in metrics:
        path = out / f"heatmap_{key}.png"
        heatmap(result, key, title, factor, spec, path)
        files[f"heatmap {key}"] = path
    return files


def forest_figure(result: MismatchResult, metrics):
    """Every simplification's cost with its 95 % interval, one panel per metric of
    :data:`RANKING_METRICS`, one line per (family, simplification), and one per double difference
    where the study has them (labelled "double diff."): filled where resolved,
    hollow where the interval includes zero, grey crosses where a row failed.  The x axis is
    symmetric-log: costs to computed torque (micrometres) and to learned agents (millimetres)
    share it."""
    from matplotlib.ticker import FixedLocator, NullLocator

    from stewart_env.agents.evaluation import new_figure

    meta = {m[0]: m for m in metrics}
    entries = list(dict.fromkeys((d.family, d.simplification, d.measure) for d in result.differences))
    columns = 2
    fig = new_figure(figsize=(13.0, 1.4 + 0.3 * len(entries) * math.ceil(len(RANKING_METRICS) / columns)),
                     layout="constrained")
    axes = fig.subplots(math.ceil(len(RANKING_METRICS) / columns), columns, sharey=True, squeeze=False).ravel()
    y = {e: len(entries) - 1 - i for i, e in enumerate(entries)}
    for ax, key in zip(axes, RANKING_METRICS):
        factor = meta[key][2]
        mine = [d for d in result.differences if d.metric == key]
        magnitudes = [abs(v) * factor for d in mine for v in (d.interval.estimate, d.interval.low, d.interval.high)
                      if np.isfinite(v) and v != 0]
        ax.axvline(0.0, color="0.3", lw=0.8)
        for d in mine:
            i = y[d.family, d.simplification, d.measure]
            e, lo, hi = (v * factor for v in (d.interval.estimate, d.interval.low, d.interval.high))
            if not np.isfinite(e):
                continue
            colour = "0.6" if d.failed else ("C3" if d.resolved else "C0")
            ax.plot([lo, hi], [i, i], color=colour, lw=2.0, solid_capstyle="butt")
            ax.plot([e], [i], marker="x" if d.failed else "o", ms=7, color=colour,
                    mfc=colour if d.resolved and not d.failed else "white", mew=1.5)
        if magnitudes:
            low, high = (math.floor(math.log10(v)) for v in (min(magnitudes), max(magnitudes)))
            # at most about four labelled decades a side (more overlap); the linear part around zero
            # as wide as one labelled step, so that its three labels do not overlap either
            step = max(1, math.ceil((high - low + 1) / 4))
            ax.set_xscale("symlog", linthresh=10.0 ** low, linscale=step)
            # zero and every step-th decade down from the largest, none at the linear part's edges
            decades = [10.0 ** k for k in range(high + 1, low, -step)]
            ax.xaxis.set_major_locator(FixedLocator(sorted([0.0] + decades + [-d for d in decades])))
            ax.xaxis.set_minor_locator(NullLocator())
        ax.set_title(meta[key][1], fontsize=10)
        ax.set_xlabel("difference to the exact-model row")
        ax.grid(alpha=0.3, axis="x")
        for i in range(1, len(entries)):
            if entries[i][0] != entries[i - 1][0]:
                ax.axhline(y[entries[i]] + 0.5, color="0.75", lw=0.8)
    for ax in axes[::columns]:
        ax.set_yticks([y[e] for e in entries],
                      [f"{f}: {s}" + (" (double diff.)" if m == DOUBLE_DIFFERENCE else "") for f, s, m in entries])
        ax.set_ylim(-0.7, len(entries) - 0.3)
    fig.suptitle(f"The cost of each simplification on the {result.differences[0].plant} plant, 95 % intervals\n"
                 "(red filled: resolved; "
                 f"blue hollow: includes zero; grey x: a row failed, success < {FAILURE_THRESHOLD:.0%})", fontsize=11)
    return fig


def heatmap(result: MismatchResult, key: str, title: str, factor: float, spec: str, path: Path) -> None:
    """Write :func:`heatmap_figure` of one metric to ``path`` (PNG)."""
    with publishing(path) as tmp:
        heatmap_figure(result, key, title, factor, spec).savefig(tmp, dpi=110)


def heatmap_figure(result: MismatchResult, key: str, title: str, factor: float, spec: str):
    """One metric's point estimates as a rows x test-plants heatmap with the values written in the
    cells; a log colour scale when the values span more than two decades (model errors do).
    Failed cells (success below :data:`FAILURE_THRESHOLD`) are hatched grey and say so, outside
    the colour scale, so that a controller that loses the platform is never coloured as the best."""
    from matplotlib import colormaps
    from matplotlib.colors import LogNorm, Normalize
    from matplotlib.patches import Rectangle
    from matplotlib.ticker import PercentFormatter

    from stewart_env.agents.evaluation import new_figure

    values = result.matrix(key) * factor
    failed = result.matrix("success") < FAILURE_THRESHOLD
    finite = values[np.isfinite(values) & ~failed]
    positive = finite[finite > 0]
    if key == "success":  # a share of the episodes: one fixed scale for every study
        norm = Normalize(0.0, 1.0)
    elif positive.size and positive.size == finite.size and positive.max() > 100 * positive.min():
        norm = LogNorm(positive.min(), positive.max())
    else:
        norm = Normalize(*(finite.min(), finite.max()) if finite.size else (0, 1))
    cmap = colormaps["viridis" if key == "success" else "viridis_r"].with_extremes(bad="white")
    n_rows, n_cols = values.shape
    # at least as wide as the two-line title of a study with few plants
    fig = new_figure(figsize=(max(2.0 + 1.6 * n_cols, 7.0), 1.6 + 0.42 * n_rows), layout="constrained")
    ax = fig.subplots()
    image = ax.imshow(np.ma.masked_where(~np.isfinite(values) | failed, values), cmap=cmap, norm=norm, aspect="auto")
    for i, j in zip(*np.nonzero(failed)):
        ax.add_patch(Rectangle((j - 0.5, i - 0.5), 1.0, 1.0, facecolor="0.82", edgecolor="0.55", hatch="///",
                               lw=0.0))
    for i in range(n_rows):
        for j in range(n_cols):
            v = values[i, j]
            text = "-" if not np.isfinite(v) else format(v, spec)
            if failed[i, j]:
                ax.text(j, i, f"failed ({text})", ha="center", va="center", fontsize=8, color="black",
                        bbox=dict(boxstyle="round,pad=0.15", facecolor="0.82", edgecolor="none"))
                continue
            # viridis is dark at its low end, viridis_r at its high end
            dark = np.isfinite(v) and (norm(v) < 0.5 if key == "success" else norm(v) > 0.5)
            ax.text(j, i, text, ha="center", va="center", fontsize=8, color="white" if dark else "black")
    for i in range(1, n_rows):  # a white rule between controller families
        if result.rows[i].family != result.rows[i - 1].family:
            ax.axhline(i - 0.5, color="white", lw=2.5)
    ax.set_xticks(range(n_cols), result.test_models)
    ax.set_yticks(range(n_rows), [r.label for r in result.rows])
    ax.set_xlabel("test plant (dynamics model simulated)")
    ax.set_ylabel("controller [design / training model]")
    note = f"\nhatched: failed (success < {FAILURE_THRESHOLD:.0%}), value in brackets" if failed.any() else ""
    ax.set_title(title + note, fontsize=11 if not note else 10)
    fig.colorbar(image, ax=ax, shrink=0.9, format=PercentFormatter(1.0) if key == "success" else None)
    return fig


# -- command line ---------------------------------------------------------------------------------


def _names(text: str) -> list[str]:
    return [t.strip() for t in text.split(",") if t.strip()]


def seed_list(text: str) -> list[int]:
    """argparse type of --seeds: comma-separated integers >= 0, each once."""
    try:
        seeds = [int(t) for t in _names(text)]
    except ValueError:
        seeds = []
    if not seeds or min(seeds) < 0 or max(seeds) > MAX_SEED or len(set(seeds)) != len(seeds):
        raise argparse.ArgumentTypeError(f"expected comma-separated distinct integers in [0, {MAX_SEED}], e.g. 0,1,2, "
                                         f"got {text!r}")
    return seeds


episode_steps = _checked(int, lambda steps: 1 <= steps <= MAX_STEPS, f"an integer in [1, {MAX_STEPS}]",
                         "argparse type of --max-steps: an integer in [1, MAX_STEPS].")


def add_cli(subparsers) -> argparse.ArgumentParser:
    """Add ``mismatch`` to an argparse subparsers object; its ``func`` returns an exit code."""
    from stewart_env.cli.arguments import TASKS, existing_file, platform_name, positive_float, positive_int

    p = subparsers.add_parser(
        "mismatch", help="model-mismatch study: controllers built on one model, run on another",
        description="Train (or load) RL agents per training model and seed, build PD and computed-torque "
                    "controllers on the same models and on the improved model with each of C1..C4 switched on, "
                    "evaluate every controller on every test plant, and write DIR/matrix.md, DIR/matrix.csv "
                    "(95 %% intervals), DIR/differences.csv, DIR/forest.png and DIR/heatmap_<metric>.png.")
    p.add_argument("--train-models", default="classical,improved",
                   help="comma-separated models to train agents on / build PD and CT on "
                        "(default: classical,improved)")
    p.add_argument("--test-models", default="classical,improved,improved_centroidal",
                   help="comma-separated plant models (default: classical,improved,improved_centroidal)")
    p.add_argument("--task", default="setpoint", choices=TASKS, help="task (default: setpoint)")
    p.add_argument("--platform", default="dasgupta1998", type=platform_name,
                   help="platform name or config file (default: dasgupta1998)")
    p.add_argument("--out", required=True, help="study directory")
    p.add_argument("--algo", default="ppo", choices=(*ALGORITHMS, "none"),
                   help="RL algorithm, or 'none' for the model-based rows only (default: ppo)")
    p.add_argument("--timesteps", type=positive_int, default=QUICK_TIMESTEPS,
                   help=f"environment steps per agent (default: {QUICK_TIMESTEPS}, a quick smoke-scale study)")
    p.add_argument("--n-envs", type=positive_int, default=None,
                   help="platforms per training batch (default: the config's)")
    p.add_argument("--episodes", type=positive_int, default=5, help="evaluation episodes per cell (default: 5)")
    p.add_argument("--max-steps", type=episode_steps, default=None,
                   help="evaluation episode length in control steps (default: the registered 500)")
    p.add_argument("--position-tolerance", type=positive_float, default=POSITION_TOLERANCE,
                   help=f"success band, m (default: {POSITION_TOLERANCE}); a cell succeeding in fewer than "
                        f"{100 * FAILURE_THRESHOLD:g}%% of its episodes is marked failed")
    p.add_argument("--orientation-tolerance", type=positive_float, default=ORIENTATION_TOLERANCE,
                   help=f"success band, rad (default: {ORIENTATION_TOLERANCE})")
    p.add_argument("--cost-plant", default=TRUE_MODEL,
                   help=f"the test plant the simplifications' costs are measured on (default: {TRUE_MODEL})")
    p.add_argument("--seeds", type=seed_list, default=[0],
                   help="training seeds, comma-separated: one agent per seed and learned row (default: 0)")
    p.add_argument("--agent-models", default=None,
                   help="comma-separated models to train agents on (default: every model of the study, "
                        "improved+cK included)")
    p.add_argument("--config", type=existing_file, default=None,
                   help="the agents' hyperparameters, a zoo config file (default: configs/agents/<algo>.yml)")
    p.add_argument("--domain-randomization", action="store_true",
                   help="add agents trained on the improved model with domain randomisation")
    p.add_argument("--simplifications", default=",".join(SIMPLIFICATIONS),
                   help="which of c1..c4 get an improved+cK row, comma-separated, or 'none' (default: all)")
    p.add_argument("--env-kwargs", nargs="*", default=None, metavar="KW",
                   help="further environment kwargs for training and testing: JSON or key=value")
    p.add_argument("--backend", default="local", choices=BACKENDS,
                   help="local: in this process (default); ray: every training run and evaluation a Ray task")
    p.add_argument("--ray-address", default=None,
                   help="with --backend ray: an existing cluster, 'auto' or HOST:PORT (default: a local Ray instance)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(func=_cli_mismatch)
    return p


def _cli_mismatch(args: argparse.Namespace) -> int:
    simplifications = [] if args.simplifications.strip().lower() == "none" else _names(args.simplifications)
    try:
        result = run_mismatch(args.out, _names(args.train_models), _names(args.test_models), task=args.task,
                              algo=None if args.algo == "none" else args.algo, timesteps=args.timesteps,
                              episodes=args.episodes, seeds=args.seeds, domain_randomization=args.domain_randomization,
                              simplifications=simplifications, env_kwargs=parse_env_kwargs(args.env_kwargs),
                              n_envs=args.n_envs, max_steps=args.max_steps, platform=args.platform,
                              backend=args.backend, ray_address=args.ray_address,
                              agent_models=None if args.agent_models is None else _names(args.agent_models),
                              config=args.config, position_tolerance=args.position_tolerance,
                              orientation_tolerance=args.orientation_tolerance, cost_plant=args.cost_plant,
                              progress=not args.no_progress)
    except BackendError as exc:
        print(f"stewart-env mismatch: error: {exc}; finished agents and cells are kept in {args.out} (run the same "
              "command again to continue)", file=sys.stderr)
        return 1
    except WriteError as exc:
        print(f"stewart-env mismatch: error: {exc}; finished agents and cells are kept in {args.out} (run the same "
              "command again to continue)", file=sys.stderr)
        return 1
    except (TrainingError, ValueError) as exc:
        print(f"stewart-env mismatch: error: {exc}", file=sys.stderr)
        return 2
    except TrainingInterrupted as stop:
        print(f"stewart-env mismatch: stopped by {signal.Signals(stop.signum).name}; checkpoint saved in "
              f"{stop.checkpoint}; finished agents and cells are kept in {args.out} (run the same command again "
              "to continue)", file=sys.stderr)
        return stop.exit_code
    except KeyboardInterrupt:
        print(f"stewart-env mismatch: interrupted; finished agents and cells are kept in {args.out} (run the same "
              "command again to continue)", file=sys.stderr)
        return 130
    print(f"{len(result.rows)} controllers x {len(result.test_models)} plants -> {result.files['markdown']}")
    return 0
