"""The study's settings as one frozen record, checked when it is made, and the checks of a
study's folder (its recorded settings, its own agents)."""

from __future__ import annotations

import json
import math
import numbers
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from stewart_env.agents.evaluation.evaluation import ORIENTATION_TOLERANCE, POSITION_TOLERANCE, slug
from stewart_env.agents.studies.mismatch.backends import check_backend
from stewart_env.agents.studies.mismatch.constants import (
    AGENTS_DIR,
    AUTO_THREADS,
    CONTROLLERS,
    DEFAULT_CONTROLLERS,
    EVAL_SEED_OFFSET,
    MAX_STEPS,
    QUICK_TIMESTEPS,
    SIMPLIFICATIONS,
    STUDY_FILE,
    TRUE_MODEL,
    MismatchError,
)
from stewart_env.agents.training import ALGORITHMS, MAX_MANIFEST_BYTES, jsonable, read_hyperparameters
from stewart_env.agents.training.settings import plant_model
from stewart_env.dynamics import ModelSpec, Switch
from stewart_env.dynamics.threads import MAX_THREADS
from stewart_env.errors import UsageError
from stewart_env.files import publish, read_json, sha256_file
from stewart_env.params import MAX_CONFIG_BYTES
from stewart_env.params.shipped import is_platform_name
from stewart_env.validation import MAX_SEED, Interval, seed

__all__ = ["MismatchSettings", "Model", "check_own_agents", "check_study", "closed_form", "design_models"]

#: A model of the study once parsed: its spec, or "mujoco" for MuJoCo's plant.
Model = ModelSpec | str


@dataclass(frozen=True)
class MismatchSettings:
    """Everything a mismatch study is asked for, checked at construction: a bad value raises
    :class:`~.constants.MismatchError` naming it, before any work.

    The models (``train_models``, ``test_models``, ``agent_models``, ``cost_plant``) are given as
    names or :class:`~stewart_env.dynamics.ModelSpec`; once made, each is parsed once into its
    spec (``"mujoco"`` for MuJoCo's plant), which the study's environments and jobs are given;
    the tables, the files and the rows' labels name each by its canonical name (``str()``).

    Attributes:
        train_models: models to build controllers on (PD's statics, CT's internal model, RL plants).
        test_models: the plants every controller is evaluated on (the columns).
        task: "setpoint", "tracking" or "disturbance".
        algo: the RL algorithm ("ppo", "sac", "td3"), or None for the model-based rows only.
        timesteps: environment steps per agent.
        episodes: evaluation episodes per cell, seeds EVAL_SEED_OFFSET + i, the same for every cell.
        seeds: training seeds, one agent per seed and learned row.
        domain_randomization: add agents trained on the improved model with domain randomisation.
        simplifications: which of c1..c4 get an ``improved+cK`` row (() for none).
        env_kwargs: further environment kwargs shared by training and test plants; once made, with
            the platform and as JSON values.
        n_envs: platforms per training batch (None: the algorithm config's).
        max_steps: evaluation episode length in control steps (None: the registered 500).
        platform: a platform name or config path (a path made absolute, so that a later run from
            elsewhere finds the same file).
        backend: "local" or "ray"; ray_address: an existing Ray cluster ("auto", "HOST:PORT").
        agent_models: the models RL agents are trained on (None: every model controllers are built
            on, the improved+cK ones included); any model the environment simulates.
        config: the agents' zoo hyperparameter file (None: configs/agents/<algo>.yml), made absolute.
        position_tolerance (m), orientation_tolerance (rad): the success band of the evaluation
            (:func:`~stewart_env.agents.evaluation.evaluate`), which decides the failed cells.
        cost_plant: the test plant the simplifications' costs are measured on.
        controller_platforms: further platforms controllers are built on (e.g. an identified one),
            each ``"NAME=PLATFORM"`` or ``"PLATFORM"`` (a platform name or config path; its name in
            the rows then the shipped name or the file's stem); each adds the rows of every
            training model built and trained on it, run on the plants of ``platform``.  Once
            made, ((name, platform), ...), a config by its absolute path.
        controllers: the model-based controllers built on each model, by kind
            (:data:`~.constants.CONTROLLERS`: ``"pd"``, ``"ct"``, ``"lqr"``, ``"mpc"``; default PD
            and CT), in the rows' order; each name once.
        physics_threads: the threads of each job's physics batches (:func:`stewart_env.set_num_threads`):
            ``"auto"`` (the default), on Ray the CPUs the job was given
            (:data:`~.constants.CPUS_PER_JOB`) and in this process the package's default (one per
            core); or a count from 1 to ``MAX_THREADS`` for every job. Not recorded: the numbers are
            the same on any count.
        plant_actuator: the actuator of the test plants (``"ideal"``, ``"lag"``, ``"electric"`` or
            ``"hydraulic"``, the environment's ``actuator``), or None for the actuator of
            ``env_kwargs`` (the environment's default: ideal force sources).  Controllers are built
            on the actuator of ``env_kwargs``: the agents train on it, and PD with gravity
            compensation and computed torque, which command leg forces, take it for ideal force
            sources; so ``plant_actuator="electric"`` runs controllers built on ideal actuators on
            electric drives.  A drive (electric, hydraulic) needs a platform with its parameters
            (``motion_simulator``), the lag its ``actuator_tau`` in ``env_kwargs``.
        hyperparameters: read from ``config`` when it is given (an edited file changes the agents).
    """

    train_models: Sequence[str | ModelSpec] = ("classical", "improved")
    test_models: Sequence[str | ModelSpec] = ("classical", "improved", "improved_centroidal")
    task: str = "setpoint"
    algo: str | None = "ppo"
    timesteps: int = QUICK_TIMESTEPS
    episodes: int = 5
    seeds: Sequence[int] = (0,)
    domain_randomization: bool = False
    simplifications: Sequence[str] = SIMPLIFICATIONS
    env_kwargs: Mapping[str, Any] | None = None
    n_envs: int | None = None
    max_steps: int | None = None
    platform: str = "dasgupta1998"
    backend: str = "local"
    ray_address: str | None = None
    agent_models: Sequence[str | ModelSpec] | None = None
    config: str | os.PathLike | None = None
    position_tolerance: float = POSITION_TOLERANCE
    orientation_tolerance: float = ORIENTATION_TOLERANCE
    cost_plant: str | ModelSpec = TRUE_MODEL
    controller_platforms: Sequence[Any] = ()
    physics_threads: int | str = AUTO_THREADS
    plant_actuator: str | None = None
    controllers: Sequence[str] = DEFAULT_CONTROLLERS
    hyperparameters: Any = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        from stewart_env.tasks import TASKS

        def set_(name: str, value: Any) -> None:  # a frozen record sets its checked values once, here
            object.__setattr__(self, name, value)

        if self.algo is not None and self.algo not in ALGORITHMS:
            raise MismatchError(f"algo: unknown algorithm {self.algo!r}; choose one of {', '.join(ALGORITHMS)}")
        if self.task not in TASKS:
            raise MismatchError(f"task: unknown task {self.task!r}; choose one of {', '.join(TASKS)}")
        if self.task == "cueing":  # its cells would score a cueing agent by the distance from home
            raise MismatchError(
                "task: the study scores the position error and success of the setpoint tasks, not the cueing "
                "metrics; what a model costs a cueing agent is `stewart-env cueing-results --agent-models classical` "
                "(docs/results/cueing.md)"
            )
        unknown = [c for c in self.simplifications if c not in SIMPLIFICATIONS]
        if unknown:
            raise MismatchError(
                f"simplifications: unknown {', '.join(unknown)}; choose from {', '.join(SIMPLIFICATIONS)}"
            )
        set_("simplifications", tuple(self.simplifications))
        set_("controllers", _check_controllers(self.controllers))
        platform = _check_platform(self.platform)
        set_("platform", platform)
        set_("train_models", tuple(_check_models(self.train_models, "train models", platform)))
        set_("test_models", tuple(_check_models(self.test_models, "test models", platform)))
        set_("seeds", _check_seeds(self.seeds))
        try:
            set_("cost_plant", plant_model(self.cost_plant))
        except UsageError as err:
            raise MismatchError(f"cost plant: {err.problem}", argument="cost_plant", problem=err.problem) from None
        if self.cost_plant not in self.test_models:
            raise MismatchError(
                f"cost plant: {str(self.cost_plant)!r} is not one of the test models "
                f"({', '.join(map(str, self.test_models))}); pass --cost-plant with one of them, or add "
                f"{self.cost_plant} to --test-models"
            )
        if self.agent_models is not None:
            set_("agent_models", tuple(_check_models(self.agent_models, "agent models", platform)))
        for name in ("episodes", "timesteps", "n_envs", "max_steps"):
            if getattr(self, name) is not None:
                set_(name, _checked(COUNT, name, getattr(self, name)))
        if self.max_steps is not None and self.max_steps > MAX_STEPS:
            raise MismatchError(f"max_steps: at most {MAX_STEPS} control steps per episode, got {self.max_steps}")
        for name in ("position_tolerance", "orientation_tolerance"):
            set_(name, _checked(TOLERANCE, name, getattr(self, name)))
        set_("controller_platforms", check_controller_platforms(self.controller_platforms))
        # rows' cells and agents live in folders named by the slugs of their labels
        own = {slug(str(m)) for m in [*self.design_models, "improved + DR"]}
        for name, _ in self.controller_platforms:
            clash = [m for m in self.train_models if slug(f"{m} @ {name}") in own]
            if clash:
                raise MismatchError(
                    f"controller platform: the name {name!r} makes the rows of {clash[0]} on it "
                    "share their files with another row's; name it otherwise with NAME=PLATFORM"
                )
        env_kwargs = dict(self.env_kwargs or {})
        clash = [k for k in ("model", "task", "randomization", "platform") if k in env_kwargs]
        if clash:
            raise MismatchError(
                f"env kwargs: {', '.join(clash)} {'is' if len(clash) == 1 else 'are'} set by the "
                "study itself (--train-models/--test-models, --task, --domain-randomization, "
                "--platform)"
            )
        env_kwargs["platform"] = platform
        set_("env_kwargs", jsonable(env_kwargs))
        if self.plant_actuator is not None:
            _check_plant_actuator(self.plant_actuator, self.env_kwargs)
        check_backend(self.backend, self.ray_address)
        if self.physics_threads != AUTO_THREADS:
            set_("physics_threads", _checked(THREADS, "physics_threads", self.physics_threads))
        if self.config is not None:
            if self.algo is None:
                raise MismatchError("config: only with an RL algorithm (--algo)")
            set_("config", str(Path(self.config).resolve()))
            set_("hyperparameters", jsonable(read_hyperparameters(self.algo, self.config)))

    @property
    def design_models(self) -> list[Model]:
        """The models controllers are built on (:func:`design_models`)."""
        return design_models(self.train_models, self.simplifications)

    @property
    def models(self) -> dict[str, Model]:
        """Every model of the study by its canonical name: the spec (or ``"mujoco"``) a job is
        given for a row's or a plant's name, looked up, not parsed again."""
        every = [*self.design_models, *self.test_models, *(self.agent_models or ()), ModelSpec(TRUE_MODEL)]  # DR
        return {str(m): m for m in every}

    def evaluation(self) -> dict[str, Any]:
        """What every evaluation's numbers depend on besides its row and plant (part of each
        cell's spec)."""
        out = {
            "task": self.task,
            "env_kwargs": self.env_kwargs,
            "episodes": self.episodes,
            "eval_seed": EVAL_SEED_OFFSET,
            "max_steps": self.max_steps,
            "position_tolerance": self.position_tolerance,
            "orientation_tolerance": self.orientation_tolerance,
        }
        if self.plant_actuator is not None:  # only then: the cells of studies on one actuator stay valid
            out["plant_actuator"] = self.plant_actuator
        return out

    def recorded(self) -> dict[str, Any]:
        """The settings study.json records: those that give the finished cells and agents their
        meaning (rows, test models and seeds may be added to a study)."""
        out = {
            **self.evaluation(),
            "algo": self.algo,
            "timesteps": self.timesteps if self.algo else None,
            "n_envs": self.n_envs if self.algo else None,
        }
        if self.config is not None:  # the hyperparameters themselves: an edited file changes the agents
            out["config"] = {"path": self.config, "hyperparameters": self.hyperparameters}
        if self.controller_platforms:  # recorded only when given: studies without them resume as before
            # a config's content too: an identification written again to the same file changes the rows
            out["controller_platforms"] = [
                {"name": name, "platform": platform, "sha256": _file_hash(platform)}
                for name, platform in self.controller_platforms
            ]
        return out


#: A count of episodes, timesteps, environments or steps, and a tolerance (the same constraints
#: as the command line's --episodes ... and --position-tolerance ...).
COUNT = Interval(numbers.Integral, 1, math.inf, expected="a positive integer")
TOLERANCE = Interval(numbers.Real, 0.0, math.inf, low_open=True, expected="a finite positive number")
#: A job's physics threads other than "auto" (:func:`stewart_env.set_num_threads`'s range).
THREADS = Interval(numbers.Integral, 1, MAX_THREADS, expected=f"'auto' or an integer from 1 to {MAX_THREADS}")


def _check_plant_actuator(actuator: Any, env_kwargs: Mapping[str, Any]) -> None:
    """Refuse a test plants' actuator the environment does not simulate with the study's
    ``env_kwargs`` (an unknown name, a drive the platform has no parameters for, a lag without
    its time constant), by building the environment on it: a MismatchError naming
    ``plant_actuator``."""
    from stewart_env.envs import StewartPlatformEnv

    try:
        StewartPlatformEnv(**{**env_kwargs, "actuator": actuator}).close()
    except (ValueError, KeyError, TypeError) as err:
        problem = err.problem if isinstance(err, UsageError) else str(err)
        raise MismatchError(f"plant actuator: {problem}", argument="plant_actuator", problem=problem) from None


def _check_controllers(controllers: Any) -> tuple[str, ...]:
    """The model-based controllers' kinds as a tuple: known, each once."""
    items = (controllers,) if isinstance(controllers, str) else tuple(controllers)
    unknown = [c for c in items if c not in CONTROLLERS]
    if unknown:
        raise MismatchError(
            f"controllers: unknown {', '.join(map(repr, unknown))}; choose from {', '.join(CONTROLLERS)}",
            argument="controllers",
            problem=f"unknown {', '.join(map(repr, unknown))}",
        )
    twice = sorted({c for c in items if items.count(c) > 1})
    if twice:
        raise MismatchError(
            f"controllers: {', '.join(twice)} given twice", argument="controllers", problem="a controller given twice"
        )
    return items


def _checked(constraint: Interval, name: str, value: Any) -> Any:
    """``value`` checked by ``constraint``; a MismatchError naming ``name`` (as data too) otherwise."""
    try:
        return constraint.check(name, value)
    except UsageError as err:
        raise MismatchError(str(err), argument=err.argument, problem=err.problem) from None


def design_models(train_models: Sequence[Model], simplifications: Sequence[str]) -> list[Model]:
    """The models controllers are built on: the training models, then improved+cK per simplification.

    Args:
        train_models: the training models, each a :class:`~stewart_env.dynamics.ModelSpec` (or ``"mujoco"``).
        simplifications: the simplifications c1..c4 that get a row.

    Returns:
        The models' specs (``"mujoco"`` as given), the training models first.
    """
    simplified = [ModelSpec(TRUE_MODEL, Switch[c.upper()]) for c in simplifications]
    return list(train_models) + [m for m in simplified if m not in train_models]


def _check_models(names: Sequence[str | ModelSpec], what: str, platform: str) -> list[Model]:
    """The models' specs (:func:`~stewart_env.agents.training.settings.plant_model`: each name
    parsed once), each checked by building the environment on it (one source of truth for what
    the environment simulates, e.g. whether MuJoCo is installed)."""
    from stewart_env.envs import StewartPlatformEnv

    out = []
    for name in names:
        try:
            model = plant_model(name)
            StewartPlatformEnv(model=model, platform=platform).close()
        except (ValueError, KeyError, ImportError) as exc:
            shown = str(name) if isinstance(name, ModelSpec) else name
            raise MismatchError(f"{what}: {shown!r} is not a model the environment simulates ({exc})") from None
        out.append(model)
    if not out:
        raise MismatchError(f"{what}: give at least one model")
    return out


def closed_form(model: str) -> bool:
    """Whether ``model`` is a closed-form dynamics model (one PD and CT rows can be built on), not
    MuJoCo's plant nor an unknown name.

    Args:
        model: a model name, a ModelSpec or ``"mujoco"``.

    Returns:
        Whether it names a :class:`~stewart_env.ModelSpec`.
    """
    from stewart_env.envs.config import model_spec

    try:
        return model_spec(model) is not None
    except UsageError:
        return False


def _check_seeds(seeds: Sequence[int]) -> tuple[int, ...]:
    seeds = tuple(seeds)
    try:
        checked = tuple(seed("seeds", s) for s in seeds)
    except ValueError:
        checked = ()
    if not checked:
        raise MismatchError(f"seeds: expected one or more integers in [0, {MAX_SEED}], got {list(seeds)!r}")
    if len(set(checked)) != len(checked):
        raise MismatchError(f"seeds: each seed once, got {list(seeds)!r}")
    return checked


def _check_platform(platform: str) -> str:
    """The platform, a config file by its absolute path; one that does not load is refused."""
    from stewart_env.params import load_platform

    try:
        load_platform(platform)
    except (ValueError, OSError, KeyError, TypeError) as err:
        raise MismatchError(f"platform: {err}", argument="platform", problem=str(err)) from None
    # a config file by its absolute path, so that a later run from elsewhere finds the same one
    return platform if is_platform_name(platform) else str(Path(platform).resolve())


#: What may name a controller platform in the rows' labels.
_PLATFORM_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+-]*")


def _refuse_platform(problem: str) -> MismatchError:
    """The error of one controller platform: ``controller platform: <problem>``, its argument
    ``controller_platforms``."""
    return MismatchError(f"controller platform: {problem}", argument="controller_platforms", problem=problem)


def check_controller_platforms(items: Sequence[Any]) -> tuple[tuple[str, str], ...]:
    """((name, platform), ...) of the controller platforms: each loads, each name once.

    Args:
        items: the controller platforms, each ``"NAME=PLATFORM"`` or ``"PLATFORM"`` (or a (name, platform)
            pair).
    """
    if isinstance(items, (str, bytes)):
        raise MismatchError(
            f"controller platforms: expected a list of platforms, got {items!r}",
            argument="controller_platforms",
            problem=f"expected a list of platforms, got {items!r}",
        )
    out: list[tuple[str, str]] = []
    for item in items:
        if isinstance(item, (tuple, list)) and len(item) == 2:
            name, platform = item
        elif isinstance(item, (str, os.PathLike)):
            text = os.fspath(item)
            head, sep, tail = text.partition("=")
            name, platform = (head, tail) if sep and _PLATFORM_NAME.fullmatch(head) else (None, text)
        else:
            raise _refuse_platform(f"expected NAME=PLATFORM or PLATFORM, got {item!r}")
        try:
            checked = _check_platform(str(platform))
        except MismatchError as err:
            raise _refuse_platform(err.problem) from None
        name = Path(checked).stem if name is None else name
        if not isinstance(name, str) or not _PLATFORM_NAME.fullmatch(name):
            raise _refuse_platform(
                f"{name!r} cannot name a platform in the rows; give NAME=PLATFORM with NAME letters, digits and _.+-"
            )
        if slug(name) in (slug(n) for n, _ in out):  # the rows' files are named by the slug
            raise _refuse_platform(f"two platforms named {name!r}; name them apart with NAME=PLATFORM")
        out.append((name, checked))
    return tuple(out)


def _file_hash(platform: str) -> str | None:
    """The SHA-256 of a platform config file, None for a shipped platform's name."""
    path = Path(platform)
    return sha256_file(path, MAX_CONFIG_BYTES) if path.is_absolute() and path.is_file() else None


def changes(old: Mapping[str, Any], new: Mapping[str, Any]) -> list[str]:
    """``key: old -> new`` of every key whose value differs.

    Args:
        old: the recorded settings.
        new: the requested settings.
    """
    return [f"{k}: {old.get(k)!r} -> {new.get(k)!r}" for k in sorted(set(old) | set(new)) if old.get(k) != new.get(k)]


def check_study(out: Path, settings: MismatchSettings) -> None:
    """Refuse a directory holding a study of other settings; record the settings otherwise.

    Args:
        out: the study's folder.
        settings: the requested settings.
    """
    path = out / STUDY_FILE
    recorded = settings.recorded()
    if os.path.lexists(path):
        found = changes(read_json(path, MAX_MANIFEST_BYTES, "study file"), recorded)
        if found:
            raise MismatchError(
                f"{out} holds a study with other settings; its finished cells and agents would "
                "mean something else:\n  " + "\n  ".join(found) + "\nrun with the study's "
                "settings (rows, test models and seeds may be added), or use another --out"
            )
    else:
        publish(path, json.dumps(recorded, indent=1, sort_keys=True))


def check_own_agents(out: Path) -> None:
    """Refuse agents shared with another study: DIR/agents as a symbolic link (or one below it).

    Args:
        out: the study's folder.
    """
    agents = out / AGENTS_DIR
    for path in [agents, *agents.glob("*"), *agents.glob("*/*")]:
        if path.is_symlink():
            raise MismatchError(
                f"{path} is a symbolic link: a study's agents are not shared with another study "
                f"(its cells record the hashes of the agents they ran); give each study its own "
                f"--out, or copy the agents into {agents}"
            )
