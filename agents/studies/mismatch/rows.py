"""The study's controllers (its rows) and their agents: which rows a study has, the training of
each agent, whether a folder already holds it, and publishing one a worker sent back."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from stewart_env.agents.studies.mismatch.constants import (
    AGENTS_DIR,
    DEFAULT_CONTROLLERS,
    DEFAULT_RANDOMIZATION,
    TRUE_MODEL,
    MismatchError,
)
from stewart_env.agents.studies.mismatch.results import Row
from stewart_env.agents.studies.mismatch.settings import Model, closed_form
from stewart_env.agents.training import (
    ALGORITHM_NAMES,
    MANIFEST,
    MODEL_FILE,
    newest_checkpoint,
    parse_hyperparameters,
    read_hyperparameters,
    read_manifest,
    train,
)
from stewart_env.files import publishing_folder

__all__ = ["build_rows", "config_env_kwargs", "finished_agent", "publish_agent", "train_agent", "training_keywords"]


def build_rows(
    out: Path,
    models: Sequence[Model],
    algo: str | None,
    seeds: Sequence[int],
    domain_randomization: bool,
    platform: str,
    agent_models: Sequence[Model] | None = None,
    controller_platforms: Sequence[tuple[str, str]] = (),
    platform_models: Sequence[Model] = (),
    controllers: Sequence[str] = DEFAULT_CONTROLLERS,
) -> list[Row]:
    """The study's controllers: the model-based ``controllers`` on each model; learned rows (on ``agent_models``, default all ``models``) name
    their agent folders (trained or not yet).  Each of ``controller_platforms`` (name, platform)
    adds the rows of ``platform_models`` (those of ``agent_models`` for the learned rows) built on
    it, labelled ``[model @ name]``.  The models are specs (:attr:`MismatchSettings.models
    <.settings.MismatchSettings.models>`), a row's ``model`` the canonical name.

    Args:
        out: the study's folder, which holds the agents.
        models: the models controllers are built on.
        algo: the RL algorithm, or None for the model-based rows only.
        seeds: the training seeds, one agent per seed and learned row.
        domain_randomization: add agents trained on the improved model with domain randomisation.
        platform: the study's platform (a name or config path).
        agent_models: the models RL agents are trained on (None: all ``models``).
        controller_platforms: further (name, platform) pairs controllers are built on.
        platform_models: the models whose rows each controller platform adds.
        controllers: the model-based controllers' kinds (:data:`~.constants.CONTROLLERS`), in
            the rows' order.
    """
    rows = _rows(out, models, algo, seeds, domain_randomization, platform, agent_models, None, controllers)
    for name, other in controller_platforms:
        learned = [m for m in platform_models if agent_models is None or m in agent_models]
        rows += _rows(out, platform_models, algo, seeds, False, other, learned, name, controllers)
    return rows


def _rows(
    out: Path,
    models: Sequence[Model],
    algo: str | None,
    seeds: Sequence[int],
    domain_randomization: bool,
    platform: str,
    agent_models: Sequence[Model] | None,
    platform_name: str | None = None,
    controllers: Sequence[str] = DEFAULT_CONTROLLERS,
) -> list[Row]:
    """The rows of ``models`` built on ``platform``; ``platform_name`` None for the study's own."""
    from stewart_env.agents.evaluation.evaluation import slug

    def on(m: Model) -> str:
        return str(m) if platform_name is None else f"{m} @ {platform_name}"

    built = {} if platform_name is None else {"platform": platform, "platform_name": platform_name}
    where = "" if platform_name is None else f", on platform {platform_name}"
    analytic = [m for m in models if closed_form(m)]
    rows = [
        Row(
            f"{_MODEL_BASED[kind][0]} [{on(m)}]",
            kind.upper(),
            str(m),
            kind,
            info=_MODEL_BASED[kind][1] + where,
            **built,
        )
        for kind in controllers
        for m in analytic
    ]
    if algo is None:
        return rows
    agent_models = models if agent_models is None else agent_models
    trainings = [(m, False) for m in agent_models] + ([(TRUE_MODEL, True)] if domain_randomization else [])
    for m, randomized in trainings:
        name = f"{m} + DR" if randomized else on(m)
        agents = {s: out / AGENTS_DIR / slug(name) / f"seed_{s}" for s in seeds}
        rows.append(
            Row(
                f"{ALGORITHM_NAMES[algo]} [{name}]",
                ALGORITHM_NAMES[algo],
                str(m),
                "agent",
                tuple(seeds),
                agents,
                randomized=randomized,
                **built,
            )
        )
    return rows


#: Each model-based controller's label and note in the tables, by kind (its family: the kind upper-cased).
_MODEL_BASED = {
    "pd": ("PD + gravity comp.", "task-space PD, gravity compensation from this model's statics"),
    "ct": ("CT", "computed torque, this model's inverse dynamics"),
    "lqr": ("LQR", "LQR around home from this model's control step Jacobians, its inverse dynamics as feed-forward"),
    "mpc": ("MPC", "linearised MPC on this model, the leg force limits as constraints"),
}


def training_keywords(
    algo: str,
    row: Row,
    seed: int,
    env_kwargs: Mapping[str, Any],
    task: str,
    n_envs: int | None,
    config: str | None = None,
    models: Mapping[str, Model] | None = None,
) -> dict[str, Any]:
    """The keywords of :func:`~stewart_env.agents.training.train` for one agent of a learned row.

    Args:
        algo: the RL algorithm.
        row: the learned row.
        seed: the agent's training seed.
        env_kwargs: the study's further environment kwargs.
        task: the task.
        n_envs: platforms per training batch (None: the config's).
        config: the zoo hyperparameter file (None: the algorithm's shipped one).
        models: the study's models by canonical name (:attr:`~.settings.MismatchSettings.models`),
            so that the training is given the row's model parsed (None: by its name).

    Returns:
        The keywords.
    """
    rest = dict(env_kwargs)
    if row.platform is not None:  # trained on the platform the row is built on, e.g. an identified one
        rest["platform"] = row.platform
    if row.randomized:
        rest["randomization"] = {k: list(v) for k, v in DEFAULT_RANDOMIZATION.items()}
    return dict(
        algo=algo,
        model=row.model if models is None else models[row.model],
        task=task,
        seed=seed,
        n_envs=n_envs,
        checkpoint_freq=0,
        env_kwargs=rest,
        config=config,
    )


def config_env_kwargs(algo: str, config: str | None = None) -> dict[str, Any]:
    """The env kwargs the algorithm's config adds to every run (run.json records them).

    Args:
        algo: the RL algorithm.
        config: the zoo hyperparameter file (None: the algorithm's shipped one).
    """
    return dict(parse_hyperparameters(algo, read_hyperparameters(algo, config)).env_kwargs)


def finished_agent(directory: Path, algo: str, seed: int, env_kwargs: Mapping[str, Any]) -> bool:
    """Whether ``directory`` holds this agent, trained to the end; refuses one trained
    differently (another algorithm, seed or environment) with a :class:`~.constants.MismatchError`.

    Args:
        directory: the agent's folder.
        algo: the RL algorithm.
        seed: the agent's training seed.
        env_kwargs: the environment kwargs it must have been trained with (run.json's form).
    """
    if not (directory / MODEL_FILE).exists():
        return False
    manifest = read_manifest(directory)
    found = (manifest["algo"], manifest["seed"], manifest["env_kwargs"])
    if found != (algo, seed, env_kwargs):
        raise MismatchError(
            f"{directory} holds an agent trained differently (algorithm, seed, env kwargs: {found}) from "
            f"this study's row ({(algo, seed, env_kwargs)}); use another --out"
        )
    # a run stopped by a signal saves its model too, unfinished: it is continued, not reused
    return bool(manifest.get("finished"))


def train_agent(directory: Path, training: Mapping[str, Any], timesteps: int, progress: bool = False) -> None:
    """Train one agent into ``directory`` (``training``: :func:`training_keywords`), continuing it
    from its newest checkpoint if a stopped study left one (given the row's settings,
    :func:`~stewart_env.agents.training.train` refuses a run trained otherwise).

    Args:
        directory: the agent's folder.
        training: the keywords of :func:`training_keywords`.
        timesteps: the environment steps to train for.
        progress: show SB3's progress bar.
    """
    resumable = None
    if (directory / MANIFEST).exists():
        resumable = newest_checkpoint(directory, training["algo"], bool(read_manifest(directory).get("normalize")))
    if resumable:
        steps, _ = resumable
        train(**training, out=directory, timesteps=max(timesteps - steps, 1), resume=True, progress_bar=progress)
    else:
        train(**training, out=directory, timesteps=timesteps, progress_bar=progress)


def publish_agent(directory: Path, files: Mapping[str, bytes]) -> None:
    """Write an agent's files, sent back by a worker, as ``directory`` in one rename (replacing an
    unfinished local run of this agent).

    Args:
        directory: the agent's folder.
        files: the agent's files' bytes, by name.
    """
    with publishing_folder(directory) as tmp:
        for name, data in files.items():
            (tmp / name).write_bytes(data)
