"""The study from its settings to its files: train the missing agents, evaluate the missing
cells on a backend, storing each result as it arrives, then the summary, the costs and the
report."""

from __future__ import annotations

import json
import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from stewart_env import files
from stewart_env.agents.evaluation.evaluation import ORIENTATION_TOLERANCE, POSITION_TOLERANCE
from stewart_env.agents.studies.mismatch.backends import LocalBackend, RayBackend, make_backend
from stewart_env.agents.studies.mismatch.cells import (
    cell_intervals,
    cell_path,
    cell_spec,
    cell_wall_time,
    metric_values,
    read_cell,
    stored_cells,
)
from stewart_env.agents.studies.mismatch.constants import (
    AUTO_THREADS,
    DEFAULT_CONTROLLERS,
    QUICK_TIMESTEPS,
    RANKING_METRICS,
    SIMPLIFICATIONS,
    TRUE_MODEL,
    statistic,
)
from stewart_env.agents.studies.mismatch.costs import per_seed_estimates, simplification_costs
from stewart_env.agents.studies.mismatch.jobs import agent_files, evaluate_job, train_job
from stewart_env.agents.studies.mismatch.results import MismatchResult, Row
from stewart_env.agents.studies.mismatch.rows import (
    build_rows,
    config_env_kwargs,
    finished_agent,
    publish_agent,
    train_agent,
    training_keywords,
)
from stewart_env.agents.studies.mismatch.settings import MismatchSettings, changes, check_own_agents, check_study
from stewart_env.agents.studies.mismatch.tables import write_tables
from stewart_env.agents.studies.mismatch.timing import JobTimes
from stewart_env.agents.training import jsonable, read_manifest
from stewart_env.dynamics import ModelSpec
from stewart_env.files import check_not_busy, lock_folder, write_error
from stewart_env.progress import progress as progress_bar

__all__ = ["run_mismatch", "run_study", "summarize", "write_outputs"]


def run_mismatch(
    out: str | Path,
    train_models: Sequence[str | ModelSpec] = ("classical", "improved"),
    test_models: Sequence[str | ModelSpec] = ("classical", "improved", "improved_centroidal"),
    task: str = "setpoint",
    algo: str | None = "ppo",
    timesteps: int = QUICK_TIMESTEPS,
    episodes: int = 5,
    seeds: Sequence[int] = (0,),
    domain_randomization: bool = False,
    simplifications: Sequence[str] = SIMPLIFICATIONS,
    env_kwargs: dict[str, Any] | None = None,
    n_envs: int | None = None,
    max_steps: int | None = None,
    platform: str = "dasgupta1998",
    backend: str = "local",
    ray_address: str | None = None,
    agent_models: Sequence[str | ModelSpec] | None = None,
    config: str | os.PathLike | None = None,
    position_tolerance: float = POSITION_TOLERANCE,
    orientation_tolerance: float = ORIENTATION_TOLERANCE,
    cost_plant: str | ModelSpec = TRUE_MODEL,
    controller_platforms: Sequence[Any] = (),
    physics_threads: int | str = AUTO_THREADS,
    plant_actuator: str | None = None,
    progress: bool = True,
    controllers: Sequence[str] = DEFAULT_CONTROLLERS,
) -> MismatchResult:
    """Run the mismatch study and write it to ``out`` (see :mod:`stewart_env.agents.studies.mismatch`).

    The arguments but ``out`` and ``progress`` are those of
    :class:`~stewart_env.agents.studies.mismatch.settings.MismatchSettings`, which checks them all before
    any work starts; :func:`run_study` runs a study from such a record.

    Args:
        out: the study's folder (created; an earlier run of the same settings is continued).
        train_models: models to build controllers on (PD's statics, CT's internal model, RL plants).
        test_models: the plants every controller is evaluated on (the columns).
        task: "setpoint", "tracking" or "disturbance".
        algo: the RL algorithm ("ppo", "sac", "td3"), or None for the model-based rows only.
        timesteps: environment steps per agent.
        episodes: evaluation episodes per cell, the same seeds for every cell.
        seeds: training seeds, one agent per seed and learned row.
        domain_randomization: add agents trained on the improved model with domain randomisation.
        simplifications: which of c1..c4 get an ``improved+cK`` row (() for none).
        env_kwargs: further environment kwargs shared by training and test plants.
        n_envs: platforms per training batch (None: the algorithm config's).
        max_steps: evaluation episode length in control steps (None: the registered 500).
        platform: a platform name or config path.
        backend: "local" or "ray".
        ray_address: an existing Ray cluster ("auto", "HOST:PORT"), with ``backend="ray"`` only.
        agent_models: the models RL agents are trained on (None: every model controllers are built on).
        config: the agents' zoo hyperparameter file (None: configs/agents/<algo>.yml).
        position_tolerance: the position band of a success in the evaluation, m.
        orientation_tolerance: the orientation band of a success in the evaluation, rad.
        cost_plant: the test plant the simplifications' costs are measured on.
        controller_platforms: further platforms controllers are built on, each ``"NAME=PLATFORM"`` or
            ``"PLATFORM"``.
        physics_threads: each job's physics threads, ``"auto"`` (the CPUs a Ray job was given; this
            process's count locally) or a count.
        plant_actuator: the test plants' actuator (None: that of ``env_kwargs``, on which the
            controllers are built).
        progress: show a progress bar.
        controllers: the model-based controllers built on each model: ``"pd"``, ``"ct"``,
            ``"lqr"``, ``"mpc"`` (default PD and CT).

    Raises:
        MismatchError: a bad argument, named (a :class:`~stewart_env.errors.UsageError`), or a
            folder holding a study of other settings.
        FolderBusy: another study runs on ``out``.
        WriteError: a failed write (a full disk), naming the file; the finished agents and cells
            are kept.
    """
    check_not_busy(out)  # a study in progress is reported at once, not by what it left so far
    settings = MismatchSettings(
        train_models=train_models,
        test_models=test_models,
        task=task,
        algo=algo,
        timesteps=timesteps,
        episodes=episodes,
        seeds=seeds,
        domain_randomization=domain_randomization,
        simplifications=simplifications,
        env_kwargs=env_kwargs,
        n_envs=n_envs,
        max_steps=max_steps,
        platform=platform,
        backend=backend,
        ray_address=ray_address,
        agent_models=agent_models,
        config=config,
        position_tolerance=position_tolerance,
        orientation_tolerance=orientation_tolerance,
        cost_plant=cost_plant,
        controller_platforms=controller_platforms,
        physics_threads=physics_threads,
        plant_actuator=plant_actuator,
        controllers=controllers,
    )
    return run_study(out, settings, progress=progress)


def run_study(
    out: str | Path, settings: MismatchSettings, progress: bool = True, figures: bool = True
) -> MismatchResult:
    """Run the study of ``settings`` in ``out``, reusing what an earlier run of it finished, and
    write its report (:func:`write_outputs`; the figures only if ``figures``).

    Args:
        out: the study's folder (created; an earlier run of the same settings is continued).
        settings: the study's settings.
        progress: show a progress bar.
        figures: also draw the figures.
    """
    out = Path(out)
    with lock_folder(out):  # one command at a time on a study, until this one ends
        check_own_agents(out)
        check_study(out, settings)
        runner = make_backend(settings.backend, settings.ray_address, settings.physics_threads)
        start = time.perf_counter()
        rows = build_rows(
            out,
            settings.design_models,
            settings.algo,
            settings.seeds,
            settings.domain_randomization,
            settings.platform,
            settings.agent_models,
            settings.controller_platforms,
            settings.train_models,
            settings.controllers,
        )
        try:
            run_jobs(runner, out, rows, settings, progress)
        finally:
            runner.close()
        result = summarize(out, rows, settings)
        result.files = write_outputs(result, out, settings, time.perf_counter() - start, figures=figures)
        return result


def run_jobs(
    runner: LocalBackend | RayBackend, out: Path, rows: list[Row], settings: MismatchSettings, progress: bool
) -> None:
    """Train the missing agents, then evaluate the missing cells, on ``runner``; each result is
    stored as soon as it arrives, so a stopped study keeps what finished.

    Args:
        runner: the backend the jobs run on.
        out: the study's folder.
        rows: the study's controllers (:func:`~.rows.build_rows`).
        settings: the study's settings.
        progress: show a progress bar.
    """
    algo, task, config, env_kwargs = settings.algo, settings.task, settings.config, settings.env_kwargs
    common = settings.evaluation()
    models = settings.models  # the jobs are given the models' specs, looked up by name
    trainings = []
    for row in rows:
        for seed, directory in row.agents.items():
            training = training_keywords(algo, row, seed, env_kwargs, task, settings.n_envs, config, models)
            expected = {**config_env_kwargs(algo, config), **training["env_kwargs"], "model": row.model, "task": task}
            if not finished_agent(directory, algo, seed, jsonable(expected)):
                trainings.append((directory, training))
    plants = [str(m) for m in settings.test_models]
    cells = [(row, plant, seed) for row in rows for plant in plants for seed in (row.seeds or (None,))]
    bar = progress_bar(total=len(trainings) + len(cells), desc="mismatch study", unit="job", disable=not progress)
    with bar:
        if isinstance(runner, LocalBackend):
            for directory, training in trainings:
                train_agent(directory, training, settings.timesteps, progress)
                bar.update()
        else:
            jobs = [(training, settings.timesteps) for _, training in trainings]
            for i, agent in runner.run(train_job, jobs):
                publish_agent(trainings[i][0], agent)
                bar.update()

        todo = []
        # agents run on the environment of their config (e.g. an error-integral observation), nominal
        agent_common = {**common, "env_kwargs": {**config_env_kwargs(algo, config), **env_kwargs}} if algo else common
        for row, plant, seed in cells:
            path = cell_path(out, row, plant, seed)
            spec = cell_spec(row, plant, seed, agent_common if row.kind == "agent" else common)
            if os.path.lexists(path):
                stored = read_cell(path)
                if stored["spec"] == spec:
                    bar.update()
                    continue
                print(
                    f"stewart-env mismatch: recomputing {row.label} on {plant}"
                    f"{'' if seed is None else f' (seed {seed})'}: its settings changed: "
                    + "; ".join(changes(stored["spec"], spec)),
                    file=sys.stderr,
                )
            todo.append((path, spec, row, seed))
        agents = {}  # each agent read (and sent to the workers) once
        jobs = []
        for _path, spec, row, seed in todo:
            agent = None
            if seed is not None:
                key = row.agents[seed]
                if key not in agents:
                    agents[key] = runner.put(key if isinstance(runner, LocalBackend) else agent_files(key))
                agent = agents[key]
            jobs.append((spec, models[row.model], models[spec["plant"]], agent))
        for i, numbers in runner.run(evaluate_job, jobs):
            path, spec = todo[i][0], todo[i][1]
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
            except OSError as err:
                raise write_error(path.parent, err) from None
            # files.publish looked up at the call, so that a fault test can make the disk fill here
            files.publish(path, json.dumps({"spec": spec, **numbers}))
            bar.update()


def summarize(out: Path, rows: list[Row], settings: MismatchSettings) -> MismatchResult:
    """The study's numbers from its stored cells: every cell's intervals, the simplifications'
    costs and the learned rows' estimates per seed, on the cost plant.

    Args:
        out: the study's folder.
        rows: the study's controllers (:func:`~.rows.build_rows`).
        settings: the study's settings.
    """
    # every cell read once: the summary, the costs, the per-seed values and the timing draw on it
    plants, cost_plant = [str(m) for m in settings.test_models], str(settings.cost_plant)
    cells = {(r.label, m): stored_cells(out, r, m) for r in rows for m in plants}
    stored = {key: [cell["metrics"] for cell in found] for key, found in cells.items()}

    def values(row: Row, plant: str, metric: str):
        return metric_values(stored[row.label, plant], metric)

    summary = {r.label: {m: cell_intervals(stored[r.label, m]) for m in plants} for r in rows}
    for r in rows:
        if r.kind == "agent":
            steps = sorted({read_manifest(d)["num_timesteps"] for d in r.agents.values()})
            r.info = f"{', '.join(map(str, steps))} steps, seeds {', '.join(map(str, r.seeds))}"
    cell_times = [cell_wall_time(cell) for found in cells.values() for cell in found]
    timing = JobTimes(
        training=[float(read_manifest(d)["wall_time"]) for r in rows if r.kind == "agent" for d in r.agents.values()],
        evaluation=[t for t in cell_times if t is not None],
        untimed_cells=sum(t is None for t in cell_times),
    )
    result = MismatchResult(rows, plants, summary, settings.episodes, timing=timing)
    result.differences = simplification_costs(result, values, plant=cost_plant)
    result.per_seed = {
        r.label: {key: per_seed_estimates(values(r, cost_plant, key), statistic(key)) for key in RANKING_METRICS}
        for r in rows
        if r.kind == "agent"
    }
    return result


def write_outputs(
    result: MismatchResult, out: Path, settings: MismatchSettings, wall_time: float = 0.0, figures: bool = True
) -> dict[str, Path]:
    """The report into ``out``: matrix.csv, differences.csv and matrix.md
    (:func:`~.tables.write_tables`), then, if ``figures``, forest.png and one heatmap PNG per
    metric (:func:`~.figures.write_figures`); returns {name: path}.

    Args:
        result: the study's numbers (:func:`summarize`).
        out: the study's folder.
        settings: the study's settings.
        wall_time: the study's wall time, s, which the report gives.
        figures: also draw the figures.
    """
    written = write_tables(result, out, settings, wall_time)
    if figures:
        from stewart_env.agents.studies.mismatch.figures import write_figures

        written.update(write_figures(result, out))
    return written
