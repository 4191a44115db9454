"""Time to a precise agent: the wall time a training run takes to reach a target on held-out episodes.

:func:`time_to_agent` trains one stable-baselines3 agent per seed with a zoo config (the reader of
``stewart-env train``: ``read_hyperparameters`` of :mod:`stewart_env.agents.training`) and, every
``interval`` seconds of training wall time, pauses training and evaluates the current policy
deterministically on ``episodes`` held-out episodes with :func:`~stewart_env.agents.evaluation.evaluate`
(episode i reset with :data:`EVALUATION_SEED` + i: the same episodes at every point and for every
seed, disjoint from the training rows' seeds, which are below 2**33).  Each evaluation is a point of
the learning curve: success rate and median steady-state position error.  A seed stops at the first
point meeting the target (success >= ``target_success`` and median steady-state position error <=
``target_error_mm``) or at the first point at or past the ``budget``.

The clock is training wall time: evaluation time is excluded from it (and reported apart).  Points
are taken between rollouts (SB3 checks its callbacks there), so a point lies at or just past its
scheduled time.  A callback times every rollout (``_on_rollout_start`` to ``_on_rollout_end``:
collection) against the rest of the iteration (the update: learning), so the report gives the
environment steps per second of collection and of learning separately.

The learning-rate schedule of a ``lin_<x>`` config anneals over the config's ``n_timesteps``, as in
``stewart-env train`` with that config: a run stopped at its target has annealed only part way.

Files in ``out`` (locked while written, each published atomically, rewritten after every point,
with training paused and the writing left out of the clock, so a run stopped keeps every point
taken): ``time_to_agent.json`` (settings, every seed's points and throughputs, the summary), ``points.csv`` (one row per point), ``summary.md`` (the table
of :func:`summary_table`) and ``learning_curve.png`` (:func:`learning_curve_figure`); and each
finished seed's agent, the policy of its last point, as a run of ``stewart-env train`` in
``agents/seed_<seed>`` (``stewart-env evaluate --agent`` loads it).
"""

from __future__ import annotations

import csv
import json
import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from stewart_env.agents.evaluation.evaluation import curve_style, evaluate, new_figure
from stewart_env.agents.training import (
    ALGORITHM_NAMES,
    Hyperparameters,
    TrainedAgent,
    TrainingError,
    algorithm_class,
    config_path,
    jsonable,
    make_training_env,
    parse_hyperparameters,
    read_hyperparameters,
    run_manifest,
    save_agent,
    single_thread,
    timer_callback,
)
from stewart_env.errors import UsageError
from stewart_env.files import LOCK_FILE, TMP_PREFIX, lock_folder, publish, publishing
from stewart_env.progress import on_terminal, progress
from stewart_env.validation import MAX_SEED, real

__all__ = [
    "AGENTS_DIR",
    "EVALUATION_SEED",
    "FILES",
    "Point",
    "SeedResult",
    "TimeToAgentError",
    "TimeToAgentResult",
    "TimeToAgentSettings",
    "learning_curve_figure",
    "resolve_config",
    "summary_table",
    "time_to_agent",
    "write_files",
]

#: Seed of the first held-out evaluation episode.  Training rows are seeded seed + i with
#: seed <= MAX_SEED (2**32 - 1) and i < n_envs, so every training seed lies below this one.
EVALUATION_SEED = 2**40
#: The files written into ``out``.
FILES = {"json": "time_to_agent.json", "csv": "points.csv", "markdown": "summary.md", "png": "learning_curve.png"}
#: The folder of ``out`` that holds each seed's agent, ``agents/seed_<seed>``.
AGENTS_DIR = "agents"


class TimeToAgentError(TrainingError):
    """A time-to-agent request that cannot be carried out: the argument's name is its
    ``argument`` (``"out"``, ``"config"``, ...; see :class:`~stewart_env.errors.UsageError`) and the message
    begins with it."""


@dataclass
class Point:
    """One evaluation of the learning curve: ``wall_time`` (s of training, evaluation excluded),
    ``steps`` (environment steps trained on), ``success`` (fraction of the held-out episodes),
    ``median_error_mm`` (median over them of the steady-state position error, mm) and
    ``evaluation_time`` (s this evaluation took)."""

    wall_time: float
    steps: int
    success: float
    median_error_mm: float
    evaluation_time: float


@dataclass
class SeedResult:
    """One seed's run: its points, whether and when it reached the target (``wall_time`` and
    ``steps`` of the first point meeting it, None if not reached), the training time and steps in
    all, and the time and steps of collection (rollouts) and of learning (updates)."""

    seed: int
    points: list[Point] = field(default_factory=list)
    reached: bool = False
    wall_time: float | None = None
    steps: int | None = None
    training_time: float = 0.0
    total_steps: int = 0
    collection_time: float = 0.0
    collection_steps: int = 0
    learning_time: float = 0.0
    learning_steps: int = 0
    evaluation_time: float = 0.0
    finished: bool = False

    @property
    def collection_rate(self) -> float:
        """Environment steps per second of collection (rollouts only)."""
        return self.collection_steps / self.collection_time if self.collection_time > 0 else math.nan

    @property
    def learning_rate(self) -> float:
        """Environment steps learnt from per second of updates (the rollouts' steps / update time)."""
        return self.learning_steps / self.learning_time if self.learning_time > 0 else math.nan

    @property
    def rate(self) -> float:
        """Environment steps per second of training (collection, learning and SB3's bookkeeping)."""
        return self.total_steps / self.training_time if self.training_time > 0 else math.nan

    def as_dict(self) -> dict[str, Any]:
        """The fields and the three rates (steps/s of collection, of learning and of training), as JSON takes them."""
        out = asdict(self)
        out.update(
            collection_steps_per_s=self.collection_rate, learning_steps_per_s=self.learning_rate, steps_per_s=self.rate
        )
        return out


@dataclass
class TimeToAgentResult:
    """Every seed's :class:`SeedResult`, the settings (``settings``) and the written ``files``."""

    settings: dict[str, Any]
    seeds: list[SeedResult]
    files: dict[str, Path] = field(default_factory=dict)

    @property
    def reached(self) -> int:
        """How many seeds reached the target."""
        return sum(s.reached for s in self.seeds)

    def done(self) -> list[SeedResult]:
        """The seeds that finished (a seed still training is written with its points so far)."""
        return [s for s in self.seeds if s.finished or s.reached]

    def median_time(self) -> float:
        """Median over the finished seeds of the wall time to target, a seed that did not reach it
        counting as infinite: inf when half of them or more did not reach it (NaN if none finished)."""
        done = self.done()
        return float(np.median([s.wall_time if s.reached else math.inf for s in done])) if done else math.nan


# -- checks ----------------------------------------------------------------------------------------


def resolve_config(algo: str, config: str | os.PathLike | None) -> Path:
    """The hyperparameter file, found as ``stewart-env train`` finds it
    (``stewart_env.agents.training.config_path``: a path, or a shipped config's name).

    Args:
        algo: the algorithm, whose shipped config is the default.
        config: a path, a shipped config's name, or None for the algorithm's shipped config.

    Raises:
        TimeToAgentError: no such file or config (its argument is ``"config"``).
    """
    try:
        return config_path(algo, config)
    except TrainingError as err:
        raise TimeToAgentError.about("config", err.problem) from None


def _number(name: str, value: Any, low: float, high: float = math.inf, low_open: bool = False) -> float:
    """``value`` checked by the package's one number check, as this module's error."""
    try:
        return real(name, value, low, high, low_open=low_open)
    except UsageError as err:
        raise TimeToAgentError.about(err.argument or name, err.problem) from None


def _seeds(seeds: Sequence[int]) -> list[int]:
    seeds = list(seeds)
    if (
        not seeds
        or any(isinstance(s, bool) or not isinstance(s, (int, np.integer)) or not 0 <= s <= MAX_SEED for s in seeds)
        or len(set(seeds)) != len(seeds)
    ):
        raise TimeToAgentError.about("seeds", f"expected distinct integers in [0, {MAX_SEED}], got {seeds!r}")
    return [int(s) for s in seeds]


def _check_out(out: Path) -> None:
    """Refuse an output folder that holds anything else than a lock or unfinished writes: another
    measurement's files are never overwritten."""
    if out.exists() and not out.is_dir():
        raise TimeToAgentError.about("out", f"{str(out)!r} is not a directory")
    if out.is_dir() and [n for n in os.listdir(out) if n != LOCK_FILE and not n.startswith(TMP_PREFIX)]:
        raise TimeToAgentError.about("out", f"{str(out)!r} is not empty; choose a new or empty output directory")


@dataclass(frozen=True)
class TimeToAgentSettings:
    """What a time-to-agent measurement is asked for, checked at construction (a bad value raises
    :class:`TimeToAgentError` naming it, before anything is written) and completed from the
    algorithm's config: built once by :func:`time_to_agent`, read by every seed's run.

    Attributes:
        algo: one of ``ALGORITHMS`` of :mod:`stewart_env.agents.training`.
        config: the zoo hyperparameter file, a path or a shipped config's name (None: the
            algorithm's); once made, the file's path.
        task: the task.
        model: the plant's dynamics model.
        seeds: the training seeds, distinct; once made, a tuple of ints.
        target_success: the fraction of held-out episodes that must succeed, in [0, 1].
        target_error_mm: the bound of the median steady-state position error, mm (>= 0).
        budget: training wall time per seed, s (> 0).
        interval: training wall time between points, s (> 0).
        episodes: held-out episodes per point.
        n_envs: platforms in the training batch (None: the config's); once made, an int.
        env_kwargs: further environment keywords; once made, the environment's keywords: the
            config's, these, the model and the task.
        hyperparameters: the config's entry, split (made from ``config``).
    """

    algo: str
    config: str | os.PathLike | None = None
    task: str = "setpoint"
    model: str = "improved"
    seeds: Sequence[int] = (0,)
    target_success: float = 0.98
    target_error_mm: float = 0.5
    budget: float = 300.0
    interval: float = 30.0
    episodes: int = 50
    n_envs: int | None = None
    env_kwargs: Mapping[str, Any] | None = None
    hyperparameters: Hyperparameters = field(init=False, repr=False)

    def __post_init__(self):
        algorithm_class(self.algo)
        made = {
            "target_success": _number("target_success", self.target_success, 0.0, 1.0),
            "target_error_mm": _number("target_error_mm", self.target_error_mm, 0.0),
            "budget": _number("budget", self.budget, 0.0, low_open=True),
            "interval": _number("interval", self.interval, 0.0, low_open=True),
        }
        episodes, n_envs = self.episodes, self.n_envs
        if isinstance(episodes, bool) or not isinstance(episodes, (int, np.integer)) or not 1 <= episodes <= 2**31 - 1:
            raise TimeToAgentError.about("episodes", f"expected an integer in [1, {2**31 - 1}], got {episodes!r}")
        if n_envs is not None and (isinstance(n_envs, bool) or not isinstance(n_envs, (int, np.integer)) or n_envs < 1):
            raise TimeToAgentError.about("n_envs", f"expected a positive integer, got {n_envs!r}")
        made["seeds"] = tuple(_seeds(self.seeds))
        made["config"] = resolve_config(self.algo, self.config)
        hp = parse_hyperparameters(self.algo, read_hyperparameters(self.algo, made["config"]))
        kwargs = {**hp.env_kwargs, **(self.env_kwargs or {}), "model": self.model, "task": self.task}
        jsonable(kwargs)
        from stewart_env.envs import StewartPlatformEnv

        StewartPlatformEnv(**kwargs).close()  # a bad environment keyword fails here, before anything is written
        made.update(
            episodes=int(episodes),
            n_envs=int(hp.n_envs if n_envs is None else n_envs),
            env_kwargs=kwargs,
            hyperparameters=hp,
        )
        for name, value in made.items():
            object.__setattr__(self, name, value)

    @property
    def algorithm(self) -> type:
        """The SB3 (or sb3-contrib) class of ``algo``."""
        return algorithm_class(self.algo)

    def as_dict(self) -> dict[str, Any]:
        """The settings as the measurement's JSON file records them.

        Returns:
            The JSON-fit settings, with the first held-out episode's seed and the hyperparameters.
        """
        return {
            "algo": self.algo,
            "config": str(self.config),
            "task": self.task,
            "model": self.model,
            "env_kwargs": jsonable(self.env_kwargs),
            "n_envs": self.n_envs,
            "seeds": list(self.seeds),
            "target_success": self.target_success,
            "target_error_mm": self.target_error_mm,
            "budget_s": self.budget,
            "interval_s": self.interval,
            "episodes": self.episodes,
            "evaluation_seed": EVALUATION_SEED,
            "hyperparameters": jsonable(self.hyperparameters.raw),
        }


# -- one seed --------------------------------------------------------------------------------------


def _run_seed(
    settings: TimeToAgentSettings,
    seed: int,
    bar,
    publish_point: Callable[[SeedResult], None],
    agent_dir: Path,
) -> SeedResult:
    """Train one seed until the target or the budget; the points and throughputs of the run.
    ``publish_point`` gets the seed's result so far after every point (training paused).  The
    policy of the last point, the one that met the target if one did, is saved into ``agent_dir``
    as a run of ``stewart-env train`` (``evaluate --agent`` loads it)."""
    algo, hp, env_kwargs, n_envs = settings.algo, settings.hyperparameters, settings.env_kwargs, settings.n_envs
    budget, interval, episodes = settings.budget, settings.interval, settings.episodes
    result = SeedResult(seed)
    paused = {"evaluation": 0.0, "writing": 0.0}

    def clock() -> float:  # training wall time: evaluation and the writing of points excluded
        return time.perf_counter() - start - paused["evaluation"] - paused["writing"]

    def take_times() -> None:
        result.evaluation_time = paused["evaluation"]
        result.collection_time, result.collection_steps = timer.collection_time, timer.collection_steps
        result.learning_time, result.learning_steps = timer.learning_time, timer.learning_steps

    next_point = interval
    env = make_training_env(n_envs, env_kwargs, seed, hp.normalize, wrappers=hp.vec_env_wrappers)
    try:
        agent = settings.algorithm(env=env, seed=seed, device="cpu", verbose=0, **hp.algorithm_kwargs)
        policy = TrainedAgent(Path("."), {"algo": algo, "env_kwargs": env_kwargs}, agent, agent.get_vec_normalize_env())

        def on_point(force: bool = False) -> bool:
            nonlocal next_point
            now = clock()
            bar.update(max(0.0, min(now, budget) - bar.n))
            if not force and now < next_point and now < budget:
                return False
            begin = time.perf_counter()
            episodes_run = evaluate(policy, env_kwargs, episodes, EVALUATION_SEED, progress=False).episodes
            spent = time.perf_counter() - begin
            paused["evaluation"] += spent
            success = float(np.mean([ep.metrics["success"] for ep in episodes_run]))
            error = 1e3 * float(np.median([ep.metrics["steady_state_position_error"] for ep in episodes_run]))
            point = Point(now, int(agent.num_timesteps), success, error, spent)
            result.points.append(point)
            bar.set_postfix_str(f"success {success:.0%}, error {error:.3g} mm")
            while next_point <= now:
                next_point += interval
            reached = success >= settings.target_success and error <= settings.target_error_mm
            if reached:
                result.reached, result.wall_time, result.steps = True, now, point.steps
            begin = time.perf_counter()
            take_times()
            result.training_time, result.total_steps = now, point.steps
            last = force or reached or now >= budget
            if last:  # the policy as evaluated: after this point SB3 steps the batch (and its statistics) once more
                segment = {"start": 0, "end": point.steps, "wall_time": now, "interrupted": False}
                save_agent(
                    agent,
                    agent_dir,
                    run_manifest(
                        algo=algo,
                        seed=seed,
                        n_envs=n_envs,
                        env_kwargs=jsonable(env_kwargs),
                        config=str(settings.config),
                        hyperparameters=jsonable(hp.raw),
                        normalize=hp.normalize is not None,
                        num_timesteps=point.steps,
                        segments=[segment],
                        finished=True,
                        files={},
                    ),
                )
            publish_point(result)
            paused["writing"] += time.perf_counter() - begin
            return last

        timer = timer_callback(clock, on_point)
        start = time.perf_counter()
        # the schedule's horizon: the config's budget (see the module docstring); training ends
        # through the callback long before, or at it if the config's budget is smaller
        agent.learn(total_timesteps=hp.n_timesteps, callback=timer, progress_bar=False)
        timer.finish()
        if not timer.stop:  # SB3 ended at the config's n_timesteps first: a last point on the final policy
            on_point(force=True)
        result.training_time = clock()
        result.total_steps = int(agent.num_timesteps)
    finally:
        env.close()
    take_times()
    result.finished = True
    return result


class _Still:
    """Zero leg forces: the policy of the warm-up episode."""

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        return np.zeros((len(observation), 6), dtype=np.float32), None


def _warm_up(env_kwargs: Mapping[str, Any]) -> None:
    """Two steps of one episode before any clock starts: the kernels' first compilation (tens of
    seconds on a cold cache) is a cost of the installation, not of training."""
    evaluate(_Still(), env_kwargs, episodes=1, seed=EVALUATION_SEED, max_steps=2, progress=False)


# -- the measurement -------------------------------------------------------------------------------


def time_to_agent(
    algo: str,
    out: str | os.PathLike,
    *,
    config: str | os.PathLike | None = None,
    task: str = "setpoint",
    model: str = "improved",
    seeds: Sequence[int] = (0,),
    target_success: float = 0.98,
    target_error_mm: float = 0.5,
    budget: float = 300.0,
    interval: float = 30.0,
    episodes: int = 50,
    n_envs: int | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    progress_bar: bool = True,
    report: Callable[[SeedResult], None] | None = None,
) -> TimeToAgentResult:
    """Measure the training wall time to a precise agent, seed by seed (module docstring).

    Args:
        algo: one of ``ALGORITHMS`` of :mod:`stewart_env.agents.training` (ppo, sac, td3, tqc, crossq).
        out: the output folder (new or empty).
        config: a zoo hyperparameter file, or the name of a shipped one (configs/agents/<name>.yml);
            default configs/agents/<algo>.yml.
        task: the task (``"setpoint"``, ``"tracking"``, ...).
        model: the plant's dynamics model.
        seeds: one training run per seed.
        target_success: fraction of held-out episodes that succeed, in [0, 1].
        target_error_mm: bound of the median steady-state position error, mm (>= 0).
        budget: training wall time per seed, s (> 0).
        interval: training wall time between points, s (> 0).
        episodes: held-out episodes per point.
        n_envs: platforms in the training batch (default the config's n_envs).
        env_kwargs: further environment keywords (over the config's env_kwargs).
        progress_bar: a bar per seed, on terminals only.
        report: called with every finished seed's result.

    Every argument is checked before training starts; a bad one raises :class:`TimeToAgentError`
    (a ValueError) naming it.  ``out`` is locked while the measurement runs
    (:class:`~stewart_env.files.FolderBusy` if another command holds it); a failing write raises
    :class:`~stewart_env.files.WriteError`.
    """
    settings = TimeToAgentSettings(
        algo,
        config=config,
        task=task,
        model=model,
        seeds=seeds,
        target_success=target_success,
        target_error_mm=target_error_mm,
        budget=budget,
        interval=interval,
        episodes=episodes,
        n_envs=n_envs,
        env_kwargs=env_kwargs,
    )
    out = Path(out)
    _check_out(out)
    recorded = settings.as_dict()
    result = TimeToAgentResult(recorded, [])
    with lock_folder(out) as folder:
        _check_out(folder)  # again, under the lock
        with single_thread():
            _warm_up(settings.env_kwargs)
            for seed in settings.seeds:
                with progress(
                    total=settings.budget,
                    desc=f"{algo} seed {seed}",
                    unit="s",
                    disable=not (progress_bar and on_terminal()),
                    leave=False,
                ) as bar:
                    done = _run_seed(
                        settings,
                        seed,
                        bar,
                        publish_point=lambda partial: write_files(
                            TimeToAgentResult(recorded, [*result.seeds, partial]), folder
                        ),
                        agent_dir=folder / AGENTS_DIR / f"seed_{seed}",
                    )
                result.seeds.append(done)
                result.files = write_files(result, folder)
                if report is not None:
                    report(done)
    return result


# -- reports ---------------------------------------------------------------------------------------


def _median_range(values: Sequence[float], spec: str) -> str:
    values = [v for v in values if v is not None and math.isfinite(v)]
    if not values:
        return "-"
    low, mid, high = min(values), float(np.median(values)), max(values)
    return format(mid, spec) if len(values) == 1 else f"{mid:{spec}} ({low:{spec}}-{high:{spec}})"


def summary_table(result: TimeToAgentResult) -> str:
    """A markdown table: per seed, then the median (range) over seeds, of the wall time and steps to
    target, the last point's success and error, and the steps/s of collection, learning and all.

    Args:
        result: the measurement.
    """
    s = result.settings
    head = [
        "seed",
        "time to target (s)",
        "steps at target",
        "success",
        "median ss error (mm)",
        "collection steps/s",
        "learning steps/s",
        "training steps/s",
        "evaluation (s)",
    ]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]

    def last(r: SeedResult) -> Point | None:
        return r.points[-1] if r.points else None

    for r in result.seeds:
        p = last(r)
        lines.append(
            "| "
            + " | ".join(
                [
                    str(r.seed),
                    f"{r.wall_time:.0f}"
                    if r.reached
                    else (f"not reached (> {s['budget_s']:g})" if r.finished else "running"),
                    f"{r.steps}" if r.reached else "-",
                    "-" if p is None else f"{p.success:.0%}",
                    "-" if p is None else f"{p.median_error_mm:.3g}",
                    f"{r.collection_rate:.0f}",
                    f"{r.learning_rate:.0f}",
                    f"{r.rate:.0f}",
                    f"{r.evaluation_time:.0f}",
                ]
            )
            + " |"
        )
    if len(result.done()) > 1:
        median = result.median_time()
        reached = [r for r in result.seeds if r.reached]
        time_cell = f"{median:.0f}" if math.isfinite(median) else f"not reached (> {s['budget_s']:g})"
        if reached:
            times = [r.wall_time for r in reached]
            time_cell += f" (reached {len(reached)}/{len(result.done())}: {min(times):.0f}-{max(times):.0f})"
        else:
            time_cell += f" (reached 0/{len(result.done())})"
        points = [last(r) for r in result.seeds if r.points]
        lines.append(
            "| "
            + " | ".join(
                [
                    "median (range)",
                    time_cell,
                    _median_range([r.steps for r in reached], ".0f"),
                    _median_range([p.success * 100 for p in points], ".0f") + " %" if points else "-",
                    _median_range([p.median_error_mm for p in points], ".3g"),
                    _median_range([r.collection_rate for r in result.seeds], ".0f"),
                    _median_range([r.learning_rate for r in result.seeds], ".0f"),
                    _median_range([r.rate for r in result.seeds], ".0f"),
                    _median_range([r.evaluation_time for r in result.seeds], ".0f"),
                ]
            )
            + " |"
        )
    return "\n".join(lines)


def learning_curve_figure(result: TimeToAgentResult):
    """Success (%) and median steady-state position error (mm, log scale) against training wall
    time, one line per seed, the target dashed, each seed's reaching point circled.

    Args:
        result: the measurement.
    """
    s = result.settings
    fig = new_figure(figsize=(9, 6.5), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True)
    for j, r in enumerate(result.seeds):
        t = [p.wall_time for p in r.points]
        style = {k: v for k, v in curve_style(j).items() if k not in ("markevery",)}
        style.update(marker=style.get("marker", "o"), ms=4)
        top.plot(t, [100 * p.success for p in r.points], label=f"seed {r.seed}", **style)
        bottom.plot(t, [max(p.median_error_mm, 1e-6) for p in r.points], label=f"seed {r.seed}", **style)
        if r.reached:
            p = r.points[-1]
            top.plot([p.wall_time], [100 * p.success], "o", ms=12, mfc="none", mec="k", zorder=20)
            bottom.plot([p.wall_time], [max(p.median_error_mm, 1e-6)], "o", ms=12, mfc="none", mec="k", zorder=20)
    top.axhline(100 * s["target_success"], color="k", ls="--", lw=1, label="target")
    if s["target_error_mm"] > 0:
        bottom.axhline(s["target_error_mm"], color="k", ls="--", lw=1, label="target")
    bottom.axvline(s["budget_s"], color="0.5", ls=":", lw=1)
    top.set_ylabel("success (%)")
    top.set_ylim(-3, 103)
    bottom.set_ylabel("median steady-state\nposition error (mm)")
    bottom.set_yscale("log")
    bottom.set_xlabel("training wall time (s, evaluation excluded; dotted: budget)")
    for ax in (top, bottom):
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8, loc="best")
    fig.suptitle(
        f"{ALGORITHM_NAMES[s['algo']]} ({Path(s['config']).name}) on the {s['task']} task, {s['model']} model: "
        f"{s['episodes']} held-out episodes a point (circled: target reached)",
        fontsize=10,
    )
    return fig


def write_files(result: TimeToAgentResult, out: Path) -> dict[str, Path]:
    """Write the four files of ``result`` into ``out`` (held locked by the caller), each atomically.

    Args:
        result: the measurement.
        out: the output folder.

    Returns:
        The paths of the files written, by name.
    """
    paths = {key: out / name for key, name in FILES.items()}
    median = result.median_time()
    summary = {
        "reached": result.reached,
        "seeds": len(result.done()),
        "running": len(result.seeds) - len(result.done()),
        "median_time_to_target_s": median if math.isfinite(median) else None,
    }
    publish(
        paths["json"],
        json.dumps(
            _finite({"settings": result.settings, "summary": summary, "seeds": [r.as_dict() for r in result.seeds]}),
            indent=2,
        )
        + "\n",
    )
    with publishing(paths["csv"]) as tmp, tmp.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(
            [
                "seed",
                "wall_time_s",
                "steps",
                "success",
                "median_steady_state_error_mm",
                "evaluation_time_s",
                "target_met",
            ]
        )
        s = result.settings
        for r in result.seeds:
            for p in r.points:
                met = p.success >= s["target_success"] and p.median_error_mm <= s["target_error_mm"]
                writer.writerow(
                    [
                        r.seed,
                        f"{p.wall_time:.3f}",
                        p.steps,
                        f"{p.success:.6g}",
                        f"{p.median_error_mm:.9g}",
                        f"{p.evaluation_time:.3f}",
                        int(met),
                    ]
                )
    s = result.settings
    publish(
        paths["markdown"],
        f"# Time to a precise agent: {ALGORITHM_NAMES[s['algo']]} on the {s['task']} task\n\n"
        f"Target: success >= {s['target_success']:.0%} and median steady-state position error <= "
        f"{s['target_error_mm']:g} mm on {s['episodes']} held-out episodes; budget {s['budget_s']:g} s of "
        f"training wall time a seed, a point every {s['interval_s']:g} s (evaluation time excluded). "
        f"Config: `{s['config']}`, {s['n_envs']} platforms a batch.\n\n" + summary_table(result) + "\n",
    )
    with publishing(paths["png"]) as tmp:
        learning_curve_figure(result).savefig(tmp, dpi=110, format="png")
    return paths


def _finite(value: Any) -> Any:
    """``value`` with NaN and infinities as None (JSON has none of them)."""
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
