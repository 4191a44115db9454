"""The environments' configuration: small frozen records, each validated once at construction.

The keyword arguments of :class:`~stewart_env.envs.StewartPlatformEnv` (and of the vector
environment) are grouped by what they configure: :class:`PhysicsConfig` (model, plant, platform,
time steps, domain randomisation), :class:`TaskConfig`, :class:`ActuatorConfig`,
:class:`ConstraintConfig`, :class:`ObservationConfig` and :class:`RenderConfig`.  A record checks its fields with the shared
validators of :mod:`stewart_env.validation` (errors name the argument) and keeps them in checked
form (floats, a loaded :class:`~stewart_env.params.PlatformParams`, a
:class:`~stewart_env.randomization.Randomization`).  Every field carries its description (field
metadata ``"doc"``); the environment card's Arguments table is checked against
:func:`arguments_table`, and the environments' signatures are made from them
(:mod:`stewart_env.envs.keywords`), so the records are the one source of the arguments, their
defaults and their ranges.
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from stewart_env.dynamics import Dynamics, ModelSpec, make_dynamics
from stewart_env.envs.action_delay import MAX_DELAY_STEPS
from stewart_env.errors import UsageError
from stewart_env.params import PlatformParams, load_platform
from stewart_env.randomization import Randomization
from stewart_env.registration import CURRENT_VERSION
from stewart_env.tasks.constraints import CONSTRAINT_NAMES, DEFAULT_TERMINATE_ON
from stewart_env.validation import ArgumentError, check_keywords, choice, flag, integer, real

if TYPE_CHECKING:
    from stewart_env.tasks import Task

__all__ = [
    "ACTION_MODES",
    "ACTUATORS",
    "PLANTS",
    "POSE_LAWS",
    "RECORDS",
    "ActuatorConfig",
    "ConstraintConfig",
    "EnvConfig",
    "ObservationConfig",
    "PhysicsConfig",
    "RenderConfig",
    "TaskConfig",
    "arguments_table",
    "defaults",
    "model_argument",
    "model_spec",
]

#: At most this many RK4 substeps per control step (control_dt / physics_dt).
MAX_SUBSTEPS = 10**6
OBSERVATION_MODES = ("pose", "sensors")
#: The plant that integrates the closed-form model ``model`` with RK4 (stewart_env.integrate).
CLOSED_FORM = "closed_form"
#: The plant that is MuJoCo simulating the same mechanism (stewart_env.mujoco.MujocoPlant); also
#: accepted as ``model="mujoco"``, another spelling of ``plant="mujoco"`` (:func:`model_argument`).
MUJOCO = "mujoco"
#: What can simulate the platform (the ``plant`` argument).
PLANTS = (CLOSED_FORM, MUJOCO)
RENDER_MODES = ("rgb_array", "human")
# Relative tolerance on control_dt / physics_dt being a whole number (rounding of decimal inputs).
_DT_TOLERANCE = 1e-9


def _argument(default: Any, doc: str) -> Any:
    """A record field that is an environment argument: its default and its card description."""
    return field(default=default, metadata={"doc": doc})


def _derived() -> Any:
    """A record field computed from the arguments (not an argument itself)."""
    return field(init=False, repr=False, compare=False)


class _Record:
    """Frozen-dataclass helpers: ``_set`` stores a checked value in ``__post_init__``."""

    def _set(self, name: str, value: Any) -> None:
        object.__setattr__(self, name, value)


def _platform(value: Any) -> PlatformParams:
    if isinstance(value, PlatformParams):
        return value
    if isinstance(value, str) or hasattr(value, "__fspath__"):
        return load_platform(value)
    raise ArgumentError.about("platform", f"expected a config name, a YAML path or a PlatformParams, got {value!r}")


def model_spec(model: Any) -> ModelSpec | None:
    """The ``model`` argument parsed once: a closed-form model's :class:`~stewart_env.dynamics.ModelSpec`,
    or None for ``"mujoco"`` (any case), another spelling of ``plant="mujoco"``.

    Args:
        model: a model name, a ModelSpec or ``"mujoco"``.

    Returns:
        The spec, or None for MuJoCo.

    Raises:
        UsageError: an unknown model or switch; ``err.argument`` is ``"model"`` and the message
            names the MuJoCo spelling too.
    """
    if isinstance(model, str) and model.strip().lower() == MUJOCO:
        return None
    return ModelSpec.parse(model, "model", hint=f"; or {MUJOCO!r} (MuJoCo simulating the same mechanism)")


def model_argument(model: Any) -> str:
    """The canonical value of the ``model`` argument: a closed-form model's canonical name (e.g.
    ``"improved+c1"``, :class:`~stewart_env.dynamics.ModelSpec`), or ``"mujoco"`` (any case), another
    spelling of ``plant="mujoco"``.

    Args:
        model: a model name, a ModelSpec or ``"mujoco"``.

    Returns:
        The canonical name.

    Raises:
        UsageError: an unknown model or switch (see :func:`model_spec`).
    """
    spec = model_spec(model)
    return MUJOCO if spec is None else spec.name


@dataclass(frozen=True)
class PhysicsConfig(_Record):
    """The simulated mechanism, what simulates it, and its time steps.  Derived: ``dynamics`` (the
    nominal closed-form model ``model``: what the closed-form plant integrates, and what the leg
    sensors and the actuators' holding forces use on either plant) and ``substeps`` (RK4 substeps
    per control step; ``physics_dt`` becomes control_dt / substeps, so that n control steps are
    exactly n control_dt).  ``model="mujoco"`` is stored as ``model="improved", plant="mujoco"``."""

    model: str = _argument(
        "improved",
        'dynamics model: `"improved"`, `"improved_centroidal"`, `"classical"`, '
        'optionally with switches such as `"+c1"`; `"mujoco"` is another '
        'spelling of `plant="mujoco"` (with the `"improved"` model)',
    )
    plant: str = _argument(
        CLOSED_FORM,
        'what simulates the platform: `"closed_form"` (`model` integrated with '
        'RK4) or `"mujoco"` (MuJoCo simulating the same mechanism, needs the '
        "`mujoco` extra)",
    )
    platform: str | os.PathLike | PlatformParams = _argument(
        "dasgupta1998",
        "a shipped config name, a YAML path, or a `PlatformParams`; a string with no `/` and no "
        "`.yaml`/`.yml` suffix is always a shipped config's name, whatever the working directory "
        "holds",
    )
    control_dt: float = _argument(0.01, "s per environment step, 1e-6 to 10")
    physics_dt: float = _argument(
        0.001, "s per RK4 substep; `control_dt` must be a whole multiple of it, at most 10^6 substeps"
    )
    randomization: dict[str, tuple[float, float]] | None = _argument(
        None,
        'domain randomisation spec, e.g. `{"platform.mass": (0.8, 1.2), "legs.mass": (0.9, 1.1), '
        '"inertia": (0.9, 1.1), "com": (0.9, 1.1), "damping": (0.5, 2.0)}`',
    )
    dynamics: Dynamics = _derived()
    substeps: int = _derived()

    def __post_init__(self) -> None:
        self._set("platform", _platform(self.platform))
        spec = model_spec(self.model)
        plant = choice("plant", self.plant.strip().lower() if isinstance(self.plant, str) else self.plant, PLANTS)
        if spec is None:  # the other spelling: MuJoCo simulating, the improved model for the rest
            spec, plant = ModelSpec("improved"), MUJOCO
        self._set("model", spec.name)
        self._set("plant", plant)
        self._set("dynamics", make_dynamics(spec, self.platform))
        control_dt = real("control_dt", self.control_dt, 1e-6, 10.0)
        physics_dt = real("physics_dt", self.physics_dt, 0.0, control_dt, low_open=True)
        substeps = round(control_dt / physics_dt)
        if substeps > MAX_SUBSTEPS:
            problem = (
                f"control_dt / physics_dt is {control_dt / physics_dt:.6g}, more than {MAX_SUBSTEPS} RK4 "
                "substeps per step"
            )
            raise UsageError(f"physics_dt ({physics_dt}): {problem}", argument="physics_dt", problem=problem)
        if abs(substeps * physics_dt - control_dt) > _DT_TOLERANCE * control_dt:
            problem = (
                f"must be a whole multiple of physics_dt ({physics_dt}): the ratio is {control_dt / physics_dt:.6g}"
            )
            raise UsageError(f"control_dt ({control_dt}) {problem}", argument="control_dt", problem=problem)
        self._set("control_dt", control_dt)
        self._set("physics_dt", control_dt / substeps)
        self._set("substeps", substeps)
        spec = self.randomization
        if not isinstance(spec, Randomization):
            spec = Randomization(spec) if spec else None
        self._set("randomization", spec or None)


@dataclass(frozen=True)
class TaskConfig(_Record):
    """What the platform should do; the task checks its own options (see :mod:`stewart_env.tasks`)."""

    task: str | type[Task] = _argument(
        "setpoint", '`"setpoint"`, `"tracking"`, `"disturbance"`, `"hold"`, `"cueing"` (or a `Task` subclass)'
    )
    task_options: dict[str, Any] | None = _argument(
        None,
        "dict of the task's options, its reward weights included (see Starting State, Rewards and `stewart_env.tasks`)",
    )
    version: int = _argument(
        CURRENT_VERSION,
        f"the environment's version, 0 to {CURRENT_VERSION}, set by the id "
        "`StewartPlatform-v<version>`: its tasks' defaults (see Version History)",
    )

    def __post_init__(self) -> None:
        from stewart_env.tasks import TASKS

        if isinstance(self.task, str) and self.task not in TASKS:  # a Task subclass is checked by the task registry
            raise UsageError.about("task", f"unknown task {self.task!r}; choose one of {', '.join(TASKS)}")
        options = self.task_options
        if options is not None and not isinstance(options, dict):
            raise ArgumentError.about("task_options", f"expected a dict of options, got {options!r}")
        self._set("task_options", dict(options or {}))
        self._set("version", integer("version", self.version, 0, CURRENT_VERSION))


#: What the action commands (the ``action_mode`` argument): leg forces, leg lengths, a platform pose.
ACTION_MODES = ("force", "leg_length", "pose")
#: The inner loops of the pose mode (the ``pose_law`` argument), in the compiled step's order.
POSE_LAWS = ("ik", "pd_gravity", "computed_torque")
#: The actuator models (the ``actuator`` argument), in the compiled step's order.
ACTUATORS = ("ideal", "lag", "electric", "hydraulic")
#: The drives whose parameters come from the platform's ``actuators:`` section.
DRIVES = ("electric", "hydraulic")


@dataclass(frozen=True)
class ActuatorConfig(_Record):
    """The legs' actuators and what the action commands.  ``actuator`` is kept resolved: None
    becomes ``"lag"`` when ``actuator_tau > 0``, else ``"ideal"``.  Derived: ``physics_rate``,
    whether the actuation runs at the physics rate in the compiled step (a mode other than force,
    or a drive with states of its own) rather than as forces held over the control step."""

    actuator_tau: float = _argument(
        0.0, "s, first-order actuator lag time constant, 0 to 100; 0 applies the commanded forces directly"
    )
    action_mode: str = _argument(
        "force",
        '`"force"` (six leg-force set points over `limits.leg_force`, N), `"leg_length"` (six leg-length set '
        "points over the stroke `limits.leg_length`, m, each tracked by a leg servo at the physics rate) or "
        '`"pose"` (a pose set point over the workspace box `limits.position_min`..`position_max`, m, and '
        "`home_rpy` +- `max_angle`, rad, tracked at the physics rate by `pose_law`); see Action Space",
    )
    pose_law: str = _argument(
        "ik",
        'the pose mode\'s inner loop: `"ik"` (inverse kinematics into the leg servos), `"pd_gravity"` '
        '(task-space PD with gravity compensation) or `"computed_torque"`, on the nominal model',
    )
    actuator: str | None = _argument(
        None,
        '`"ideal"` (a force source), `"lag"` (first-order lag of `actuator_tau`), `"electric"` (motor and '
        'ball screw) or `"hydraulic"` (valve-controlled cylinder), the last two from the platform\'s '
        '`actuators:` section; None: `"lag"` when `actuator_tau` > 0, else `"ideal"`',
    )
    observe_actuators: bool = _argument(
        False,
        "append the states a drive reports to the observation: motor currents (electric, over the current "
        "limit) or chamber pressures A and B (hydraulic, over the supply-return span)",
    )
    physics_rate: bool = _derived()

    def __post_init__(self) -> None:
        tau = real("actuator_tau", self.actuator_tau, 0.0, 100.0)
        self._set("actuator_tau", tau)
        self._set("action_mode", choice("action_mode", self.action_mode, ACTION_MODES))
        self._set("pose_law", choice("pose_law", self.pose_law, POSE_LAWS))
        actuator = self.actuator
        if actuator is None:
            actuator = "lag" if tau > 0 else "ideal"
        actuator = choice("actuator", actuator, ACTUATORS)
        if actuator == "lag" and tau == 0:
            raise UsageError.about("actuator_tau", 'must be > 0 for actuator="lag"')
        self._set("actuator", actuator)
        observe = flag("observe_actuators", self.observe_actuators)
        if observe and actuator not in DRIVES:
            raise UsageError.about(
                "observe_actuators", f"the {actuator!r} actuator reports no state; choose actuator= one of {DRIVES}"
            )
        self._set("observe_actuators", observe)
        self._set("physics_rate", self.action_mode != "force" or actuator in DRIVES)

    def lag(self, control_dt: float) -> float:
        """The fraction of the command error closed per control step of ``control_dt`` (0: none).

        Args:
            control_dt: the control step, s.
        """
        tau = self.actuator_tau
        # the lag held over the control step is the force mode's; at the physics rate the
        # compiled actuation steps its own lag
        if self.actuator != "lag" or self.physics_rate:
            return 0.0
        return 1.0 - math.exp(-control_dt / tau)


@dataclass(frozen=True)
class ConstraintConfig(_Record):
    """Which of the platform's limits end an episode, and the action's delay.  ``terminate_on`` is
    kept as a tuple in the order of the constraints (``stewart_env.tasks.constraints``); the batch
    checks it against the platform's constraints (those whose limit the platform has)."""

    terminate_on: tuple[str, ...] = _argument(
        DEFAULT_TERMINATE_ON,
        "the constraints that end an episode, a tuple of the platform's: "
        f"{', '.join(f'`{name!r}`' for name in CONSTRAINT_NAMES)} (see Constraint Costs); "
        "`()` for none",
    )
    action_delay: int = _argument(
        0, f"control steps between the action and the actuators, 0 to {MAX_DELAY_STEPS} (see Constraint Costs)"
    )

    def __post_init__(self) -> None:
        names = self.terminate_on
        if isinstance(names, str) or not isinstance(names, (tuple, list, set, frozenset)):
            raise UsageError.about("terminate_on", f"expected a tuple of constraint names, got {type(names).__name__}")
        for name in names:
            if name not in CONSTRAINT_NAMES:
                shown = repr(name)[:40] if isinstance(name, str) else type(name).__name__
                raise UsageError.about(
                    "terminate_on", f"unknown constraint {shown}; choose from {', '.join(CONSTRAINT_NAMES)}"
                )
        self._set("terminate_on", tuple(name for name in CONSTRAINT_NAMES if name in names))
        self._set("action_delay", integer("action_delay", self.action_delay, 0, MAX_DELAY_STEPS))


@dataclass(frozen=True)
class ObservationConfig(_Record):
    """What the agent observes and how.  ``observation_noise`` is kept as a number or a dict of
    checked numbers; its term names are checked against the observation layout by the batch."""

    observation_mode: str = _argument("pose", '`"pose"` (pose and twist) or `"sensors"` (leg lengths and rates)')
    normalize_observation: bool = _argument(
        True, "scale the observation by the platform's limits (see Observation Space)"
    )
    observation_noise: float | dict[str, float] = _argument(
        0.0, "Gaussian noise std in observation units, 0 to 100: a number, or a dict term name -> std"
    )
    observation_delay: int = _argument(0, "control steps between measurement and observation, 0 to 1000")
    error_integral: bool = _argument(False, "observe the time integral of the pose error (see Observation Space)")
    error_integral_limit: float = _argument(
        0.1, "s, anti-windup bound T of the error integral: +-T h (position), +-T A (orientation); 1e-6 to 1e6"
    )
    error_integral_band: float | None = _argument(
        None, "integrate an error component only within this fraction (0 to 1e6) of its scale (h, A); None: always"
    )

    def __post_init__(self) -> None:
        self._set("observation_mode", choice("observation_mode", self.observation_mode, OBSERVATION_MODES))
        self._set("normalize_observation", flag("normalize_observation", self.normalize_observation))
        noise = self.observation_noise
        if isinstance(noise, dict):
            noise = {name: real(f"observation_noise[{name!r}]", s, 0.0, 100.0) for name, s in noise.items()}
        else:
            noise = real("observation_noise", noise, 0.0, 100.0)
        self._set("observation_noise", noise)
        self._set("observation_delay", integer("observation_delay", self.observation_delay, 0, 1000))
        self._set("error_integral", flag("error_integral", self.error_integral))
        self._set("error_integral_limit", real("error_integral_limit", self.error_integral_limit, 1e-6, 1e6))
        band = self.error_integral_band
        self._set(
            "error_integral_band", None if band is None else real("error_integral_band", band, 0.0, 1e6, low_open=True)
        )


@dataclass(frozen=True)
class RenderConfig(_Record):
    """How frames are drawn."""

    render_mode: str | None = _argument(None, '`"rgb_array"` or `"human"`')
    width: int = _argument(480, "rendered frame width, px, 1 to 4096")
    height: int = _argument(480, "rendered frame height, px, 1 to 4096")

    def __post_init__(self) -> None:
        if self.render_mode is not None and self.render_mode not in RENDER_MODES:
            raise UsageError.about(
                "render_mode", f"expected one of {list(RENDER_MODES)} or None, got {self.render_mode!r}"
            )
        self._set("width", integer("width", self.width, 1, 4096))
        self._set("height", integer("height", self.height, 1, 4096))


#: The records of the environment's arguments, in the order of its signature and of the card's table.
RECORDS: tuple[type, ...] = (
    PhysicsConfig,
    TaskConfig,
    ActuatorConfig,
    ConstraintConfig,
    ObservationConfig,
    RenderConfig,
)


def _arguments(record: type) -> list[dataclasses.Field]:
    return [f for f in dataclasses.fields(record) if f.init]


@dataclass(frozen=True)
class EnvConfig:
    """Every argument of an environment, validated, by record.

    Attributes:
        physics: the :class:`~stewart_env.envs.config.PhysicsConfig`.
        task: the :class:`~stewart_env.envs.config.TaskConfig`.
        actuator: the :class:`~stewart_env.envs.config.ActuatorConfig`.
        constraints: the :class:`~stewart_env.envs.config.ConstraintConfig`.
        observation: the :class:`~stewart_env.envs.config.ObservationConfig`.
        render: the :class:`~stewart_env.envs.config.RenderConfig`.
    """

    physics: PhysicsConfig
    task: TaskConfig
    actuator: ActuatorConfig
    constraints: ConstraintConfig
    observation: ObservationConfig
    render: RenderConfig

    @classmethod
    def of(cls, **arguments: Any) -> EnvConfig:
        """The configuration of the given environment arguments, the others at their defaults.

        Args:
            **arguments: environment arguments by name; each record validates its own.

        Returns:
            The :class:`EnvConfig`.

        Raises:
            ValueError: an unknown name (an ArgumentError) or a value out of its range; the message
                names the argument.

        Examples:
            >>> from stewart_env.envs import EnvConfig
            >>> config = EnvConfig.of(task="tracking", control_dt=0.02)
            >>> config.task.task, config.physics.control_dt
            ('tracking', 0.02)
        """
        check_keywords("EnvConfig.of", arguments, (f.name for record in RECORDS for f in _arguments(record)))
        records = [
            record(**{f.name: arguments[f.name] for f in _arguments(record) if f.name in arguments})
            for record in RECORDS
        ]
        return cls(*records)


def arguments_table() -> str:
    """The card's Arguments table (markdown rows, header included) from the records' fields."""
    rows = ["| argument | default | description |", "|---|---|---|"]
    for record in RECORDS:
        for f in _arguments(record):
            default = f'"{f.default}"' if isinstance(f.default, str) else repr(f.default)
            rows.append(f"| `{f.name}` | `{default}` | {f.metadata['doc']} |")
    return "\n".join(rows)


def defaults() -> dict[str, Any]:
    """Every environment argument and its default, in the card's order."""
    return {f.name: f.default for record in RECORDS for f in _arguments(record)}
