"""``train()``: a stable-baselines3 agent trained, or resumed, in its run directory.

Training runs on the native batch of platforms through
:class:`~stewart_env.envs.StewartPlatformSB3VecEnv` (one compiled rollout call per step for all
``n_envs`` rows).  SIGINT and SIGTERM stop training at the next step, save a checkpoint and raise
:class:`~stewart_env.agents.training.errors.TrainingInterrupted`; a second signal exits at once.
One command at a time writes a run: ``train`` holds the run directory's lock
(:func:`stewart_env.files.lock_folder`), and a second one on the same ``--out`` is refused at
once.  A full disk or a failing write ends training with :class:`~stewart_env.files.WriteError`
naming the file; the complete checkpoints stay, and ``--resume`` continues from the newest.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from stewart_env.agents.training.callbacks import checkpoint_callback
from stewart_env.agents.training.env_kwargs import jsonable
from stewart_env.agents.training.environment import make_training_env, progress_bar_available, single_thread
from stewart_env.agents.training.errors import TrainingError, TrainingInterrupted
from stewart_env.agents.training.hyperparameters import (
    OFF_POLICY,
    config_path,
    parse_hyperparameters,
    read_hyperparameters,
)
from stewart_env.agents.training.rundir import (
    CHECKPOINT_DIR,
    DEFAULT_KEEP_CHECKPOINTS,
    MANIFEST,
    MODEL_FILE,
    REPLAY_BUFFER_FILE,
    START_UP_FILES,
    VECNORMALIZE_FILE,
    check_fresh_directory,
    checkpoint_hashes,
    holds_no_run,
    log_progress,
    newest_checkpoint,
    publish_final,
    read_manifest,
    remove_start_up_files,
    remove_unfinished_writes,
    run_manifest,
    save_checkpoint,
    step_dirs,
    unpickle_statistics,
    verified_bytes,
)
from stewart_env.agents.training.settings import RunPlan, TrainSettings, plant_model
from stewart_env.agents.training.signals import StopRequest, stop_on_signals
from stewart_env.dynamics import ModelSpec
from stewart_env.files import WriteError, check_not_busy, lock_folder, publish, write_error
from stewart_env.validation import integer

__all__ = ["TrainResult", "rollout_steps", "run_changes", "train"]


@dataclass
class TrainResult:
    """What a training call did: the run directory, the total env steps of the model
    (num_timesteps, over all resumes), the steps of this call, its wall time in s, the steps
    requested and the steps of one whole rollout (SB3 trains in whole rollouts, so a call runs
    ``requested`` rounded up to a multiple of ``rollout``)."""

    directory: Path
    num_timesteps: int
    steps_this_run: int
    wall_time: float
    requested: int
    rollout: int


def rollout_steps(agent, algo: str) -> int:
    """Environment steps SB3 collects between two checks of its budget: n_steps x n_envs
    on-policy, train_freq x n_envs off-policy (n_envs for a train_freq counted in episodes).

    Args:
        agent: the SB3 model.
        algo: the algorithm's name, one of :data:`ALGORITHMS`.
    """
    if algo not in OFF_POLICY:
        return int(agent.n_steps * agent.n_envs)
    freq = agent.train_freq
    return int(freq.frequency * agent.n_envs) if freq.unit.value == "step" else int(agent.n_envs)


_UNSET = object()


def _show(value: Any) -> str:
    return "(unset)" if value is _UNSET else json.dumps(value)


def run_changes(
    manifest: Mapping[str, Any],
    entry: Mapping[str, Any],
    env_kwargs: Mapping[str, Any],
    seed: int | None,
    n_envs: int | None,
) -> list[str]:
    """What differs, key by key ("key: old -> new"), between the run in ``manifest`` and a
    request to continue it with the zoo ``entry``, ``env_kwargs``, ``seed`` and ``n_envs``
    (None: the run's).  The budget ``n_timesteps`` may differ: ``--timesteps`` sets the steps
    added.

    Args:
        manifest: the run's run.json.
        entry: the zoo entry of the request.
        env_kwargs: the environment kwargs of the request.
        seed: the seed of the request (None: the run's).
        n_envs: the number of platforms of the request (None: the run's).
    """
    changes = []
    for what, old, new in (
        ("hyperparameter", manifest.get("hyperparameters", {}), jsonable(dict(entry))),
        ("environment kwarg", manifest.get("env_kwargs", {}), jsonable(dict(env_kwargs))),
    ):
        for key in sorted(set(old) | set(new)):
            before, after = old.get(key, _UNSET), new.get(key, _UNSET)
            if key != "n_timesteps" and before != after:
                changes.append(f"{what} {key}: {_show(before)} -> {_show(after)}")
    for key, value in (("seed", seed), ("n_envs", n_envs)):
        if value is not None and value != manifest.get(key):
            changes.append(f"{key}: {_show(manifest.get(key, _UNSET))} -> {_show(int(value))}")
    return changes


def train(
    algo: str,
    out: str | os.PathLike,
    *,
    model: str | ModelSpec | None = None,
    task: str | None = None,
    timesteps: int | None = None,
    seed: int | None = None,
    n_envs: int | None = None,
    checkpoint_freq: int = 50_000,
    keep_checkpoints: int = DEFAULT_KEEP_CHECKPOINTS,
    env_kwargs: Mapping[str, Any] | None = None,
    config: str | os.PathLike | None = None,
    resume: bool = False,
    progress_bar: bool = True,
    verbose: int = 0,
    report: Callable[[str], None] = TrainSettings.report,
) -> TrainResult:
    """Train (or, with ``resume``, continue training) an SB3 agent on StewartPlatform-v1.

    Args:
        algo: one of ``ALGORITHMS`` of :mod:`stewart_env.agents.training` (ppo, sac, td3, tqc, crossq).
        out: the run directory (created; see the module docstring for its contents).  A new run
            refuses a directory that holds anything else than a run of ``algo`` with nothing
            saved yet.
        model: the plant's dynamics model, a name, a :class:`~stewart_env.dynamics.ModelSpec` or
            ``"mujoco"`` (default improved); run.json records its canonical name.
        task: the task (default setpoint).
        timesteps: environment steps of this call, at least (default the config's n_timesteps):
            SB3 collects whole rollouts, so it runs ``timesteps`` rounded up to a multiple of
            :func:`rollout_steps`.  With ``resume`` they are added to the steps already done.
        seed: seeds torch, numpy and the platforms (default 0; row i gets seed + i; a resumed
            run seeds its rows with seed + num_timesteps, so it does not replay the first
            episodes).
        n_envs: platforms in the batch (default the config's n_envs).
        checkpoint_freq: environment steps between checkpoints (0: none but the final one).
        keep_checkpoints: how many of the newest checkpoints to keep.
        env_kwargs: further environment kwargs (override the config's env_kwargs; ``model`` and
            ``task`` override both).
        config: a zoo hyperparameter file (default configs/agents/<algo>.yml; resuming, the
            hyperparameters recorded in run.json).
        resume: continue from the newest complete checkpoint in ``out``.  Every setting left
            None is the run's; one given must equal the run's (the config's n_timesteps
            excepted), else TrainingError lists each difference.
        progress_bar: SB3's progress bar, when stderr is a terminal and tqdm and rich are installed.
        verbose: SB3's verbosity (0: silent).
        report: where resume messages (the checkpoint taken, those skipped) go; default stderr.

    Every check (installation, algorithm, config file and entry, hyperparameter names, output
    directory, environment kwargs, resume state and file hashes) runs before the first training
    step; failures raise :class:`TrainingError` (or ValueError from the environment) naming what
    is wrong.  SIGINT or SIGTERM during training saves a checkpoint, then raises
    :class:`TrainingInterrupted`.

    Raises:
        stewart_env.files.FolderBusy: another command writes ``out`` (its PID in the message);
            nothing was changed.
        stewart_env.files.WriteError: a write failed (a full disk), naming the file; the complete
            checkpoints are kept and ``resume`` continues from the newest.
        stewart_env.files.FileError: a file of the run is not a regular file, or is too large.
    """
    settings = TrainSettings(
        algo,
        Path(out),
        model=model,
        task=task,
        timesteps=timesteps,
        seed=seed,
        n_envs=n_envs,
        checkpoint_freq=checkpoint_freq,
        keep_checkpoints=keep_checkpoints,
        env_kwargs=env_kwargs,
        config=config,
        resume=resume,
        progress_bar=progress_bar,
        verbose=verbose,
        report=report,
    )
    with contextlib.ExitStack() as held:
        return _train(settings, held)


def _train(settings: TrainSettings, held: contextlib.ExitStack) -> TrainResult:
    """The body of :func:`train`: the run directory's lock is entered on ``held`` once every check
    that needs no file of the run has passed, and the run's state is read under it."""
    algo, directory, config, report = settings.algo, settings.out, settings.config, settings.report
    model, task, env_kwargs = settings.model, settings.task, settings.env_kwargs
    seed, n_envs = settings.seed, settings.n_envs
    steps_done, segments, checkpoint, saved = 0, [], None, {}
    check_not_busy(directory)  # before any look at the run: a run in progress is reported as such
    if settings.resume:
        if holds_no_run(directory) and any(os.path.lexists(directory / name) for name in START_UP_FILES):
            raise TrainingError(
                f"--resume: {directory} holds no run to continue: its start was interrupted before "
                "anything was saved; start it again without --resume"
            )
        read_manifest(directory)  # a directory without a run is refused before its lock is taken
        held.enter_context(lock_folder(directory, create=False))
        previous = read_manifest(directory)
        if previous["algo"] != algo:
            raise TrainingError(f"--resume: {directory} holds a {previous['algo']} run, not {algo}")
        entry = read_hyperparameters(algo, config) if config is not None else dict(previous["hyperparameters"])
        cfg_path = str(config_path(algo, config)) if config is not None else previous.get("config")
        hp = parse_hyperparameters(algo, entry)
        given = {k: v for k, v in (("model", None if model is None else str(model)), ("task", task)) if v is not None}
        changes = run_changes(previous, entry, {**previous["env_kwargs"], **(env_kwargs or {}), **given}, seed, n_envs)
        if changes:
            raise TrainingError(
                f"--resume: {directory} was trained with other settings; refusing to continue it "
                "with\n  " + "\n  ".join(changes) + "\nresume without these changes (--timesteps "
                "may differ: it sets the steps added), or start a new run in another --out"
            )
        kwargs, seed, n_envs = previous["env_kwargs"], previous["seed"], previous["n_envs"]
        # the run's model parsed once, as it is read (given, it equals the run's)
        model = plant_model(kwargs["model"]) if model is None else model
        found = newest_checkpoint(directory, algo, hp.normalize is not None, report)
        if found is None:
            older = list((directory / CHECKPOINT_DIR).glob("model_*_steps.zip"))
            raise TrainingError(
                f"--resume: no complete checkpoint in {directory / CHECKPOINT_DIR}"
                + (
                    "; its model_<steps>_steps.zip files are checkpoints of an older stewart-env, which record no "
                    "hashes: start a new run"
                    if older
                    else ""
                    if step_dirs(directory)
                    else "; the run stopped before its first checkpoint: start it again without --resume"
                )
            )
        steps_done, checkpoint = found
        segments = previous.get("segments", [])
        report(f"resuming from {CHECKPOINT_DIR}/{checkpoint.name} ({steps_done} steps)")
        hashes, what = checkpoint_hashes(checkpoint)
        saved = {name: verified_bytes(checkpoint, hashes, name, what) for name in hashes}
        remove_unfinished_writes(directory)
    else:
        cfg_path = str(config_path(algo, config))
        hp = parse_hyperparameters(algo, read_hyperparameters(algo, cfg_path))
        seed = 0 if seed is None else seed
        n_envs = hp.n_envs if n_envs is None else n_envs
        model = ModelSpec() if model is None else model  # the improved model by default
        # run.json records the model by its canonical name; the environments are given its spec
        kwargs = {**hp.env_kwargs, **(env_kwargs or {}), "model": str(model), "task": task or "setpoint"}
        jsonable(kwargs)
        check_fresh_directory(directory, algo)
        from stewart_env.envs import StewartPlatformEnv

        # a bad environment keyword fails here, before --out is made; the time limit is the
        # training batch's (StewartPlatformSB3VecEnv), not the single environment's
        if "max_episode_steps" in kwargs:
            integer("max_episode_steps", kwargs["max_episode_steps"], 1, 2**62)
        single = {key: value for key, value in kwargs.items() if key != "max_episode_steps"}
        StewartPlatformEnv(**{**single, "model": model}).close()
        held.enter_context(lock_folder(directory))
        check_fresh_directory(directory, algo)  # again, under the lock: another run may have started meanwhile
        remove_unfinished_writes(directory)
        remove_start_up_files(directory)  # of a start interrupted before its manifest
    plan = RunPlan(
        hyperparameters=hp,
        env_kwargs=kwargs,
        model=model,
        seed=seed,
        n_envs=n_envs,
        timesteps=hp.n_timesteps if settings.timesteps is None else int(settings.timesteps),
        config=cfg_path,
        monitor="monitor.csv" if not settings.resume else f"resumed_{steps_done}.monitor.csv",
        progress_bar=settings.progress_bar and progress_bar_available(),
        resume=settings.resume,
        steps_done=steps_done,
        segments=segments,
        saved=saved,
    )
    stop = StopRequest()
    try:
        agent, steps, wall, checkpoint = _learn(settings, plan, stop)
    except (OSError, WriteError) as err:  # a full disk or a failing device, in our writes or SB3's own
        cause = err if isinstance(err, WriteError) else write_error(err.filename or directory, err)
        kept = (
            "the complete checkpoints are kept (--resume continues from the newest)"
            if step_dirs(directory)
            else "no checkpoint was complete"
        )
        raise WriteError(cause.path, f"{cause.problem}; {kept}") from None
    if stop.signum is not None:
        raise TrainingInterrupted(stop.signum, checkpoint)
    return TrainResult(directory, steps, steps - steps_done, wall, plan.timesteps, rollout_steps(agent, algo))


def _learn(settings: TrainSettings, plan: RunPlan, stop: StopRequest):
    """The training of :func:`_train` once the run's state is known: (agent, steps, wall time,
    last checkpoint)."""
    algo, directory, hp, kwargs = settings.algo, settings.out, plan.hyperparameters, plan.env_kwargs
    seed, n_envs, steps_done, saved, resume = plan.seed, plan.n_envs, plan.steps_done, plan.saved, plan.resume
    cls = settings.algorithm
    with single_thread():
        statistics = unpickle_statistics(saved[VECNORMALIZE_FILE]) if resume and hp.normalize is not None else None
        agent = None
        env = make_training_env(
            n_envs,
            {**kwargs, "model": plan.model},
            seed + steps_done,
            hp.normalize,
            monitor_path=directory / plan.monitor,
            statistics=statistics,
            wrappers=hp.vec_env_wrappers,
        )
        try:
            if not resume:
                agent = cls(
                    env=env,
                    seed=seed,
                    device="cpu",
                    verbose=settings.verbose,
                    tensorboard_log=str(directory / "tensorboard"),
                    **hp.algorithm_kwargs,
                )
            else:
                agent = cls.load(
                    io.BytesIO(saved[MODEL_FILE]), env=env, device="cpu", tensorboard_log=str(directory / "tensorboard")
                )
                # A resumed run draws new exploration noise and new episodes (seed + steps done).
                agent.set_random_seed(seed + steps_done)
                if REPLAY_BUFFER_FILE in saved:
                    agent.load_replay_buffer(io.BytesIO(saved[REPLAY_BUFFER_FILE]))
                saved.clear()  # the bytes of a replay buffer: tens of MB, not kept while training
            manifest = run_manifest(
                algo=algo,
                seed=seed,
                n_envs=n_envs,
                env_kwargs=jsonable(kwargs),
                config=plan.config,
                hyperparameters=jsonable(hp.raw),
                normalize=hp.normalize is not None,
                num_timesteps=steps_done,
                segments=plan.segments,
                finished=False,
                files={},
            )
            publish(directory / MANIFEST, json.dumps(manifest, indent=2) + "\n")

            callback = checkpoint_callback(
                directory,
                algo,
                int(settings.checkpoint_freq),
                int(settings.keep_checkpoints),
                manifest["wall_time"],
                stop,
            )
            start = time.perf_counter()
            with stop_on_signals(stop):
                agent.learn(
                    total_timesteps=plan.timesteps,
                    callback=callback,
                    progress_bar=plan.progress_bar,
                    tb_log_name=algo,
                    reset_num_timesteps=not resume,
                )
                wall = time.perf_counter() - start
                steps = int(agent.num_timesteps)
                checkpoint = directory / CHECKPOINT_DIR / f"step_{steps}"
                if getattr(callback, "last", None) != steps or not checkpoint.is_dir():  # else just saved
                    checkpoint = save_checkpoint(agent, directory, algo, int(settings.keep_checkpoints))
                    log_progress(directory, steps, manifest["wall_time"] + wall)
                files = publish_final(agent, directory)
                manifest["segments"].append(
                    {"start": steps_done, "end": steps, "wall_time": wall, "interrupted": stop.signum is not None}
                )
                manifest.update(
                    num_timesteps=steps,
                    finished=stop.signum is None,
                    files=files,
                    wall_time=sum(s["wall_time"] for s in manifest["segments"]),
                )
                publish(directory / MANIFEST, json.dumps(manifest, indent=2) + "\n")
        finally:
            env.close()
            # learn() leaves its TensorBoard writer open (a thread and a file); a process that trains
            # agent after agent, as a study's workers do, would keep one per agent.  The next learn()
            # opens its own.
            logger = getattr(agent, "_logger", None)
            if logger is not None:
                logger.close()
    return agent, steps, wall, checkpoint
