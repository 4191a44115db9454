"""What actuation costs a controller: each action mode's controllers on each actuator level.

The study (``stewart-env actuation``) runs, on the ``motion_simulator`` platform (the shipped one
with electric and hydraulic parameter sets), per task (set point, tracking), per action mode and
per actuator level (ideal force sources, a first-order lag of :data:`LAG_TAU`, electric drives,
hydraulic cylinders), the controllers of that mode (:data:`CONTROLLERS`):

* ``force`` mode: PD with gravity compensation (``pd-gc``, :class:`~.controllers.pd.PDPolicy`)
  and computed torque (``ct``, :class:`~.controllers.computed_torque.ComputedTorquePolicy`) on
  the improved model, each commanding leg forces, which the drives then track;
* ``pose`` mode: the target pose commanded to the mode's inner loop, inverse kinematics into the
  leg servos (``ik``), PD with gravity compensation (``pd-gc``) or computed torque (``ct``) at the
  physics rate (the environment's ``pose_law``);
* ``leg_length`` mode: the target's inverse kinematics commanded to the leg servos (``ik``); PD
  and computed torque are task-space laws, which this mode has no place for;
* in every mode, PPO (``ppo``) with the mode's shipped config (:data:`PPO_CONFIGS`), one agent
  per training seed, for the cells asked (:attr:`ActuationSettings.ppo_cells`), trained by the
  study into its folder or read from a folder of trained agents.

Each cell is one evaluation (:func:`~stewart_env.agents.evaluation.evaluate`) of
:attr:`ActuationSettings.episodes` seeded episodes, the same episodes in every cell; a PPO cell
has one such evaluation per training seed.  Its numbers (:data:`STUDY_METRICS`): success, RMS
position and orientation error, peak leg force, the cost rate (the episode's mean constraint
cost per control step) and the limit hits (the steps after which a constraint was violated, all
constraints summed), each with a 95 % stratified bootstrap interval over seeds and episodes
(:func:`~stewart_env.agents.evaluation.statistics.stratified_bootstrap`).

A finished cell is a file with what its numbers depend on (its spec), published whole when it
finishes, as the mismatch study's cells (:mod:`~stewart_env.agents.studies.mismatch.cells`): a
second run into the same folder reuses every cell whose spec is unchanged and an interrupted run
keeps the cells it finished.  The study writes ``actuation.md`` (a Markdown table), ``actuation.csv``
and ``results.json``.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from stewart_env.agents.evaluation.evaluation import METRICS, evaluate, slug
from stewart_env.agents.evaluation.statistics import stratified_bootstrap
from stewart_env.agents.studies.mismatch.cells import metric_values, read_cell
from stewart_env.agents.studies.mismatch.rows import config_env_kwargs, finished_agent, train_agent
from stewart_env.agents.studies.mismatch.settings import changes
from stewart_env.agents.training import MODEL_FILE, jsonable, load_agent, read_manifest
from stewart_env.agents.training.hyperparameters import config_path
from stewart_env.envs.config import ACTION_MODES, ACTUATORS
from stewart_env.errors import UsageError
from stewart_env.files import lock_folder, publish, write_error
from stewart_env.progress import progress as progress_bar

__all__ = [
    "CONTROLLERS",
    "LAG_TAU",
    "PPO_CONFIGS",
    "STUDY_METRICS",
    "ActuationError",
    "ActuationSettings",
    "PoseCommand",
    "LegLengthCommand",
    "run_actuation",
]

#: The platform of the study: the shipped one with electric and hydraulic parameter sets.
PLATFORM = "motion_simulator"
#: The lag actuator's time constant, s: a force loop of a few tens of milliseconds.
LAG_TAU = 0.02
#: The tasks of the study.
TASKS = ("setpoint", "tracking")
#: Each action mode's controllers: the model-based ones, then PPO.
CONTROLLERS = {"force": ("pd-gc", "ct", "ppo"), "leg_length": ("ik", "ppo"), "pose": ("ik", "pd-gc", "ct", "ppo")}
#: The shipped PPO config of each mode (configs/agents/<name>.yml).
PPO_CONFIGS = {"force": "ppo", "leg_length": "ppo_leg_length", "pose": "ppo_pose"}
#: The pose mode's inner loop (the environment's ``pose_law``) of each of its model-based controllers.
POSE_LAWS = {"ik": "ik", "pd-gc": "pd_gravity", "ct": "computed_torque"}
#: The seed of the first evaluation episode (episode k is seeded EVAL_SEED + k), apart from the
#: training seeds.
EVAL_SEED = 10_000
#: Bound of a cell file read back.
MAX_CELL_BYTES = 16 << 20
CELLS_DIR = "cells"
AGENTS_DIR = "agents"
STUDY_FILE = "study.json"
#: The study's numbers per episode: (key, column title, factor from SI to the shown unit, format).
STUDY_METRICS = (
    ("success", "success", 1.0, ".0%"),
    ("rms_position_error", "RMS pos. err. (mm)", 1e3, ".3g"),
    ("rms_orientation_error", "RMS ori. err. (mrad)", 1e3, ".3g"),
    ("peak_leg_force", "peak leg force (kN)", 1e-3, ".3g"),
    ("cost_rate", "cost rate", 1.0, ".3g"),
    ("limit_hits", "limit hits / episode", 1.0, ".3g"),
)


class ActuationError(UsageError):
    """A study request that cannot be carried out; the message names the argument or path."""


@dataclass(frozen=True)
class ActuationSettings:
    """The study's request, checked when made: a bad value raises :class:`ActuationError` naming it.

    Attributes:
        tasks: the tasks, of :data:`TASKS`.
        modes: the action modes, of the environment's ``ACTION_MODES``.
        actuators: the actuator levels, of the environment's ``ACTUATORS``.
        episodes: evaluation episodes per cell (and per PPO seed), seeds EVAL_SEED + k.
        ppo_cells: the (mode, actuator, task) cells PPO runs in, each ``"MODE:ACTUATOR:TASK"``
            or a triple, or ``"all"`` for every cell of the study; () for the model-based
            controllers only.
        seeds: PPO's training seeds, one agent each per PPO cell.
        timesteps: environment steps per agent (None: the mode's config's n_timesteps).
        agents: a folder of trained agents, laid out as the study's own (``MODE-ACTUATOR-TASK/seed_S``),
            read only: a missing agent leaves its cell out (None: the study's ``agents`` folder,
            where it trains the missing ones).
        max_steps: evaluation episode length in control steps (None: the registered 500).
        ppo_trained_on: the actuator every PPO agent is trained on, whatever actuator its cell
            runs (None: each cell's own): ``"ideal"`` runs the agents trained on ideal force
            sources on every actuator of the cells, what the drives cost one agent.
    """

    tasks: Sequence[str] = TASKS
    modes: Sequence[str] = ACTION_MODES
    actuators: Sequence[str] = ACTUATORS
    episodes: int = 5
    ppo_cells: Sequence[Any] = ()
    seeds: Sequence[int] = (0, 1, 2)
    timesteps: int | None = None
    agents: str | os.PathLike | None = None
    max_steps: int | None = None
    ppo_trained_on: str | None = None

    def __post_init__(self) -> None:
        def set_(name: str, value: Any) -> None:  # a frozen record sets its checked values once, here
            object.__setattr__(self, name, value)

        for name, choices in (("tasks", TASKS), ("modes", ACTION_MODES), ("actuators", ACTUATORS)):
            given = tuple(getattr(self, name))
            unknown = [v for v in given if v not in choices]
            if unknown or not given:
                problem = f"expected one or more of {', '.join(choices)}, got {list(given)!r}"
                raise ActuationError(f"{name}: {problem}", argument=name, problem=problem)
            set_(name, tuple(dict.fromkeys(given)))
        cells = list(self.ppo_cells)
        if "all" in cells:  # every (mode, actuator, task) of the study
            cells = [c for c in cells if c != "all"] + [
                (m, a, t) for m in self.modes for a in self.actuators for t in self.tasks
            ]
        set_("ppo_cells", tuple(dict.fromkeys(_ppo_cell(c) for c in cells)))
        if self.ppo_trained_on is not None and self.ppo_trained_on not in ACTUATORS:
            problem = f"expected one of {', '.join(ACTUATORS)} or None, got {self.ppo_trained_on!r}"
            raise ActuationError(f"ppo_trained_on: {problem}", argument="ppo_trained_on", problem=problem)
        for name in ("episodes", "timesteps", "max_steps"):
            value = getattr(self, name)
            if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < 1):
                problem = f"expected a positive integer, got {value!r}"
                raise ActuationError(f"{name}: {problem}", argument=name, problem=problem)
        seeds = tuple(self.seeds)
        if not seeds or any(isinstance(s, bool) or not isinstance(s, int) or s < 0 for s in seeds):
            problem = f"expected one or more non-negative integers, got {list(seeds)!r}"
            raise ActuationError(f"seeds: {problem}", argument="seeds", problem=problem)
        if len(set(seeds)) != len(seeds):
            raise ActuationError(f"seeds: each seed once, got {list(seeds)!r}", argument="seeds", problem="repeated")
        set_("seeds", seeds)
        if self.agents is not None:
            folder = Path(self.agents)
            if not folder.is_dir():
                problem = f"{folder} is not a folder of trained agents"
                raise ActuationError(f"agents: {problem}", argument="agents", problem=problem)
            set_("agents", str(folder.resolve()))

    def training_actuator(self, actuator: str) -> str:
        """The actuator the PPO agents of a cell are trained on.

        Args:
            actuator: the cell's actuator, the one its agents run on.
        """
        return actuator if self.ppo_trained_on is None else self.ppo_trained_on

    def cells(self) -> list[tuple[str, str, str, str]]:
        """Every (task, mode, controller, actuator) cell of the study, in the tables' order."""
        out = []
        for task in self.tasks:
            for mode in self.modes:
                for controller in CONTROLLERS[mode]:
                    for actuator in self.actuators:
                        if controller != "ppo" or (mode, actuator, task) in self.ppo_cells:
                            out.append((task, mode, controller, actuator))
        return out


def _ppo_cell(cell: Any) -> tuple[str, str, str]:
    """A PPO cell as (mode, actuator, task), from ``"MODE:ACTUATOR:TASK"`` or a triple."""
    parts = cell.split(":") if isinstance(cell, str) else list(cell)
    ok = len(parts) == 3 and parts[0] in ACTION_MODES and parts[1] in ACTUATORS and parts[2] in TASKS
    if not ok:
        problem = (
            f"expected MODE:ACTUATOR:TASK with MODE one of {', '.join(ACTION_MODES)}, ACTUATOR one of "
            f"{', '.join(ACTUATORS)} and TASK one of {', '.join(TASKS)}, got {cell!r}"
        )
        raise ActuationError(f"ppo_cells: {problem}", argument="ppo_cells", problem=problem)
    return (parts[0], parts[1], parts[2])


# -- the controllers -------------------------------------------------------------------------------


class _TargetCommand:
    """A policy that commands the target the observation carries (the mode's inner loop tracks it).

    Args:
        env: the environment (single), whose actuation maps a command to an action.
    """

    def __init__(self, env):
        from stewart_env.agents.controllers.pd import EnvPolicy

        self._decoder = EnvPolicy(env, None)
        self._actuation = env.unwrapped._core.actuation
        self._platform = env.unwrapped.platform

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        """SB3's interface: (action (6,) or (N, 6), None) for one observation or a batch.

        Args:
            observation: one observation (obs_dim,) or a batch (N, obs_dim).
            state: SB3's recurrent state; unused.
            episode_start: SB3's episode starts; unused.
            deterministic: SB3's flag; unused (the policy is deterministic).
        """
        obs = np.asarray(observation)
        _, reference = self._decoder.decode(obs)
        action = np.clip(self.command(reference.position, reference.rotation), -1.0, 1.0).astype(np.float32)
        return (action[0] if obs.ndim == 1 else action), None


class PoseCommand(_TargetCommand):
    """The pose mode's action that commands the target pose (see :class:`_TargetCommand`)."""

    def command(self, position: np.ndarray, rotation: np.ndarray) -> np.ndarray:
        """The actions (N, 6) that command the poses ``position`` (N, 3), ``rotation`` (N, 3, 3).

        Args:
            position: the targets' positions, m.
            rotation: the targets' rotations.

        Returns:
            The actions, unclipped.
        """
        return np.stack([self._actuation.pose_command(p, r) for p, r in zip(position, rotation)])


class LegLengthCommand(_TargetCommand):
    """The leg_length mode's action that commands the target's leg lengths, by inverse kinematics
    on the nominal platform (see :class:`_TargetCommand`)."""

    def command(self, position: np.ndarray, rotation: np.ndarray) -> np.ndarray:
        """The actions (N, 6) that command the leg lengths of the poses ``position`` (N, 3), ``rotation`` (N, 3, 3).

        Args:
            position: the targets' positions, m.
            rotation: the targets' rotations.

        Returns:
            The actions, unclipped.
        """
        from stewart_env.kinematics import inverse_kinematics

        lengths, _ = inverse_kinematics(self._platform, position, rotation)
        mid, half = self._actuation.length_map
        return (lengths - mid) / half


def env_kwargs_of(mode: str, controller: str, actuator: str, task: str) -> dict[str, Any]:
    """The environment's keywords of a cell (a PPO cell's without its config's).

    Args:
        mode: the action mode.
        controller: the controller (of :data:`CONTROLLERS`).
        actuator: the actuator level.
        task: the task.
    """
    out: dict[str, Any] = {"platform": PLATFORM, "task": task, "action_mode": mode, "actuator": actuator}
    if actuator == "lag":
        out["actuator_tau"] = LAG_TAU
    if mode == "pose" and controller != "ppo":
        out["pose_law"] = POSE_LAWS[controller]
    return out


def make_policy(mode: str, controller: str, agent: Path | None = None):
    """A policy or a factory env -> policy for :func:`~stewart_env.agents.evaluation.evaluate`.

    Args:
        mode: the action mode.
        controller: the controller (of :data:`CONTROLLERS`).
        agent: a PPO agent's folder (``controller="ppo"`` only).
    """
    if controller == "ppo":
        return load_agent(agent)
    if mode == "pose":
        return PoseCommand
    if mode == "leg_length":
        return LegLengthCommand
    if controller == "ct":
        from stewart_env.agents.controllers.computed_torque import ComputedTorquePolicy

        return lambda env: ComputedTorquePolicy(env, "improved")
    from stewart_env.agents.controllers.pd import PDPolicy

    return lambda env: PDPolicy(env, gravity_compensation=True)


# -- the agents and the cells on disk ---------------------------------------------------------------


def agent_folder(agents: Path, mode: str, actuator: str, task: str, seed: int) -> Path:
    """The folder of the PPO agent of one cell and seed.

    Args:
        agents: the folder of agents.
        mode: the action mode.
        actuator: the actuator level.
        task: the task.
        seed: the training seed.
    """
    return agents / f"{mode}-{actuator}-{task}" / f"seed_{seed}"


def training_env_kwargs(mode: str, actuator: str, task: str) -> dict[str, Any]:
    """The environment kwargs a PPO agent of a cell is trained and evaluated with (its config's
    first, then the cell's), as run.json records them.

    Args:
        mode: the action mode.
        actuator: the actuator level.
        task: the task.
    """
    config = str(config_path("ppo", PPO_CONFIGS[mode]))
    kwargs = env_kwargs_of(mode, "ppo", actuator, task)
    return {**config_env_kwargs("ppo", config), **kwargs, "model": "improved"}


def cell_path(out: Path, cell: tuple[str, str, str, str], seed: int | None) -> Path:
    """The file of a cell (one per training seed of a PPO cell).

    Args:
        out: the study's folder.
        cell: (task, mode, controller, actuator).
        seed: the PPO agent's training seed; None for a model-based controller.
    """
    return out / CELLS_DIR / Path(*map(slug, cell)) / ("model_based.json" if seed is None else f"seed_{seed}.json")


def cell_spec(settings: ActuationSettings, cell, agent: Path | None, seed: int | None) -> dict[str, Any]:
    """What a cell's numbers depend on; a finished cell is reused only if all of it is equal.

    Args:
        settings: the study's settings.
        cell: (task, mode, controller, actuator).
        agent: the PPO agent's folder (None for a model-based controller).
        seed: its training seed.
    """
    task, mode, controller, actuator = cell
    spec = {
        "task": task,
        "mode": mode,
        "controller": controller,
        "actuator": actuator,
        "env_kwargs": env_kwargs_of(mode, controller, actuator, task),
        "episodes": settings.episodes,
        "eval_seed": EVAL_SEED,
        "max_steps": settings.max_steps,
    }
    if agent is not None:
        spec["env_kwargs"] = jsonable(training_env_kwargs(mode, actuator, task))
        if settings.ppo_trained_on is not None:  # (a study's own agents keep the spec they had)
            spec["agent_trained_on"] = settings.ppo_trained_on
        spec["agent_seed"] = seed
        spec["agent_sha256"] = read_manifest(agent)["files"][MODEL_FILE]
    return spec


def evaluate_cell(spec: Mapping[str, Any], agent: Path | None) -> dict[str, Any]:
    """One cell's evaluation: its numbers per episode (:data:`STUDY_METRICS`), the terminations
    and the wall time (s).

    Args:
        spec: the cell's spec (:func:`cell_spec`).
        agent: the PPO agent's folder (None for a model-based controller).
    """
    start = time.perf_counter()
    kwargs = dict(spec["env_kwargs"])
    policy = make_policy(spec["mode"], spec["controller"], agent)
    label = f"{spec['controller']} ({spec['mode']}, {spec['actuator']})"
    result = evaluate(
        policy, kwargs, episodes=spec["episodes"], seed=spec["eval_seed"], label=label,
        max_steps=spec["max_steps"], progress=False,
    )  # fmt: skip
    numbers: dict[str, list[float]] = {m.key: [ep.metrics[m.key] for ep in result.episodes] for m in METRICS}
    numbers["cost_rate"] = [float(np.mean(ep.cost)) if ep.cost is not None else math.nan for ep in result.episodes]
    numbers["limit_hits"] = [float(sum(ep.limit_hits.values())) for ep in result.episodes]
    return {
        "metrics": numbers,
        "terminations": [ep.termination for ep in result.episodes],
        "wall_time": time.perf_counter() - start,
    }


# -- the study --------------------------------------------------------------------------------------


@dataclass
class CellResult:
    """One cell's intervals by metric (point estimate, low, high), its seeds and its episodes."""

    cell: tuple[str, str, str, str]
    intervals: dict[str, tuple[float, float, float]]
    seeds: int
    episodes: int
    terminations: dict[str, int]


def run_actuation(
    out: str | os.PathLike, settings: ActuationSettings | None = None, progress: bool = True
) -> dict[str, Any]:
    """Run the study of ``settings`` in ``out`` (see the module docstring), reusing the cells an
    earlier run finished, and write its tables.

    Args:
        out: the study's folder (created).
        settings: the study's settings (default: :class:`ActuationSettings`'s defaults).
        progress: show a progress bar.

    Returns:
        ``{"cells": [CellResult, ...], "missing": [(cell, seed), ...], "files": {name: path}}``;
        ``missing``: the PPO cells' seeds without an agent in ``settings.agents``.

    Raises:
        ActuationError: a bad setting, named; a damaged cell file.
        FolderBusy: another study runs on ``out``.
        WriteError: a failed write, naming the file; the finished cells are kept.
    """
    settings = settings or ActuationSettings()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    with lock_folder(out):  # one command at a time on a study
        _check_observations_match(settings)
        agents = Path(settings.agents) if settings.agents is not None else out / AGENTS_DIR
        missing = _train_agents(agents, settings, own=settings.agents is None, progress=progress)
        cells = settings.cells()
        jobs = []
        for cell in cells:
            task, mode, controller, actuator = cell
            seeds = settings.seeds if controller == "ppo" else (None,)
            for seed in seeds:
                trained_on = settings.training_actuator(actuator)
                agent = None if seed is None else agent_folder(agents, mode, trained_on, task, seed)
                if seed is not None and (cell, seed) in missing:
                    continue
                jobs.append((cell, seed, agent))
        bar = progress_bar(total=len(jobs), desc="actuation study", unit="cell", disable=not progress)
        with bar:
            for cell, seed, agent in jobs:
                _run_cell(out, settings, cell, seed, agent)
                bar.update()
        results = [_summarize(out, cell, settings, missing) for cell in cells]
        results = [r for r in results if r is not None]
        files = _write_outputs(out, results, settings, missing, time.perf_counter() - start)
    return {"cells": results, "missing": sorted(missing), "files": files}


def _check_observations_match(settings: ActuationSettings) -> None:
    """With ``ppo_trained_on``, every PPO cell's observation must be the one its agents were
    trained on: an actuator whose drive state the observation carries (the lag's forces) has more.

    Raises:
        ActuationError: a cell whose observation differs, naming ``ppo_trained_on`` and the actuator.
    """
    if settings.ppo_trained_on is None:
        return
    import gymnasium as gym

    def shape(mode: str, actuator: str, task: str) -> tuple[int, ...]:
        env = gym.make("StewartPlatform-v1", **training_env_kwargs(mode, actuator, task))
        try:
            return env.observation_space.shape
        finally:
            env.close()

    for mode, actuator, task in settings.ppo_cells:
        if mode not in settings.modes or actuator not in settings.actuators or task not in settings.tasks:
            continue
        trained, runs = shape(mode, settings.ppo_trained_on, task), shape(mode, actuator, task)
        if trained != runs:
            problem = (
                f"an agent trained on the {settings.ppo_trained_on} actuator observes {trained[0]} numbers, the "
                f"{actuator} actuator's observation has {runs[0]} ({mode}, {task}): drop that cell or train its "
                "agents on its own actuator (no ppo_trained_on)"
            )
            raise ActuationError(f"ppo_trained_on: {problem}", argument="ppo_trained_on", problem=problem)


def _train_agents(agents: Path, settings: ActuationSettings, own: bool, progress: bool) -> set:
    """Train the study's missing agents (``own``: the study's folder), or list those a given
    folder lacks; the set of (cell, seed) without an agent."""
    missing = set()
    for mode, actuator, task in settings.ppo_cells:
        if mode not in settings.modes or actuator not in settings.actuators or task not in settings.tasks:
            continue
        cell = (task, mode, "ppo", actuator)
        trained_on = settings.training_actuator(actuator)
        expected = jsonable(training_env_kwargs(mode, trained_on, task))
        for seed in settings.seeds:
            folder = agent_folder(agents, mode, trained_on, task, seed)
            if finished_agent(folder, "ppo", seed, expected):
                continue
            if not own:
                missing.add((cell, seed))
                continue
            rest = {k: v for k, v in training_env_kwargs(mode, trained_on, task).items() if k not in ("model", "task")}
            training = dict(
                algo="ppo", model="improved", task=task, seed=seed, n_envs=None, checkpoint_freq=0,
                env_kwargs=rest, config=str(config_path("ppo", PPO_CONFIGS[mode])),
            )  # fmt: skip
            timesteps = settings.timesteps
            if timesteps is None:
                from stewart_env.agents.training import read_hyperparameters

                timesteps = int(float(read_hyperparameters("ppo", training["config"])["n_timesteps"]))
            folder.parent.mkdir(parents=True, exist_ok=True)
            train_agent(folder, training, timesteps, progress)
    return missing


def _run_cell(out: Path, settings: ActuationSettings, cell, seed: int | None, agent: Path | None) -> None:
    """Evaluate one cell unless a finished one of the same spec is on disk; publish it whole."""
    path = cell_path(out, cell, seed)
    spec = cell_spec(settings, cell, agent, seed)
    if os.path.lexists(path):
        stored = read_cell(path)
        if stored["spec"] == spec:
            return
        print(
            f"stewart-env actuation: recomputing {'/'.join(cell)}: its settings changed: "
            + "; ".join(changes(stored["spec"], spec)),
            file=sys.stderr,
        )
    numbers = evaluate_cell(spec, agent)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise write_error(path.parent, err) from None
    publish(path, json.dumps({"spec": spec, **numbers}))


def _summarize(out: Path, cell, settings: ActuationSettings, missing: set) -> CellResult | None:
    """A cell's intervals from its stored files (None for a PPO cell without any agent)."""
    seeds = settings.seeds if cell[2] == "ppo" else (None,)
    seeds = [s for s in seeds if (cell, s) not in missing]
    if not seeds:
        return None
    stored = [read_cell(cell_path(out, cell, s)) for s in seeds]
    metrics = [c["metrics"] for c in stored]
    intervals = {}
    for key, *_ in STUDY_METRICS:
        values = metric_values(metrics, key)
        if not np.isfinite(values).any():
            intervals[key] = (math.nan, math.nan, math.nan)
            continue
        interval = stratified_bootstrap(values, "mean")
        intervals[key] = (interval.estimate, interval.low, interval.high)
    terminations: dict[str, int] = {}
    for c in stored:
        for reason in c["terminations"]:
            if reason is not None:
                terminations[reason] = terminations.get(reason, 0) + 1
    return CellResult(cell, intervals, len(seeds), settings.episodes, terminations)


# -- the tables ---------------------------------------------------------------------------------------


def _shown(value: float, factor: float, spec: str) -> str:
    return "n/a" if not math.isfinite(value) else format(value * factor, spec)


def interval_text(interval: tuple[float, float, float], factor: float, spec: str) -> str:
    """``estimate [low, high]`` in the shown unit.

    Args:
        interval: (estimate, low, high), SI.
        factor: from SI to the shown unit.
        spec: the format of each number.
    """
    estimate, low, high = interval
    if not math.isfinite(estimate):
        return "n/a"
    if low == high:
        return _shown(estimate, factor, spec)
    return f"{_shown(estimate, factor, spec)} [{_shown(low, factor, spec)}, {_shown(high, factor, spec)}]"


def markdown_table(results: Sequence[CellResult]) -> str:
    """The study's table: a row per cell, each number its mean and 95 % interval.

    Args:
        results: the cells' results.
    """
    head = ["task", "mode", "controller", "actuator", *[title for _, title, *_ in STUDY_METRICS], "seeds x episodes"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in results:
        numbers = [interval_text(r.intervals[key], factor, spec) for key, _, factor, spec in STUDY_METRICS]
        lines.append("| " + " | ".join([*r.cell, *numbers, f"{r.seeds} x {r.episodes}"]) + " |")
    return "\n".join(lines) + "\n"


def _write_outputs(
    out: Path, results: Sequence[CellResult], settings: ActuationSettings, missing: set, wall_time: float
) -> dict[str, Path]:
    """actuation.md, actuation.csv and results.json of the study's cells."""
    import csv
    import io

    note = ""
    if missing:
        note = "\nPPO seeds without an agent in the agents folder (left out): " + ", ".join(
            f"{'/'.join(cell)} seed {seed}" for cell, seed in sorted(missing)
        ) + "\n"  # fmt: skip
    md = (
        "# What actuation costs\n\n"
        f"Platform {PLATFORM}; the lag actuator's time constant {LAG_TAU} s; {settings.episodes} evaluation "
        "episodes a cell (and a PPO seed); each number the mean with its 95 % stratified bootstrap interval "
        "over seeds and episodes."
        + (
            ""
            if settings.ppo_trained_on is None
            else f" Every PPO agent was trained on the {settings.ppo_trained_on} actuator and runs on its row's."
        )
        + "\n\n"
        + markdown_table(results)
        + note
    )
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(
        ["task", "mode", "controller", "actuator", "seeds", "episodes"]
        + [f"{key}{suffix}" for key, *_ in STUDY_METRICS for suffix in ("", "_low", "_high")]
    )
    for r in results:
        writer.writerow([*r.cell, r.seeds, r.episodes, *[v for key, *_ in STUDY_METRICS for v in r.intervals[key]]])
    record = {
        "platform": PLATFORM,
        "lag_tau": LAG_TAU,
        "episodes": settings.episodes,
        "eval_seed": EVAL_SEED,
        "ppo_seeds": list(settings.seeds),
        "ppo_trained_on": settings.ppo_trained_on,
        "wall_time": wall_time,
        "cells": [
            {
                "task": r.cell[0],
                "mode": r.cell[1],
                "controller": r.cell[2],
                "actuator": r.cell[3],
                "seeds": r.seeds,
                "episodes": r.episodes,
                "terminations": r.terminations,
                **{
                    key: dict(zip(("estimate", "low", "high"), (None if not math.isfinite(v) else v for v in iv)))
                    for key, iv in r.intervals.items()
                },
            }
            for r in results
        ],
        "missing": [{"cell": list(cell), "seed": seed} for cell, seed in sorted(missing)],
    }
    files = {"markdown": out / "actuation.md", "csv": out / "actuation.csv", "json": out / "results.json"}
    publish(files["markdown"], md)
    publish(files["csv"], buffer.getvalue())
    publish(files["json"], json.dumps(record, indent=1))
    return files
