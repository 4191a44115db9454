"""PlatformParams, all parameters of one platform: built from a config mapping or file with the
documented defaults (the schema is in :mod:`stewart_env.params`), and validated as a whole.

The checks need no kinematics beyond the leg vectors at the home pose; the condition of the leg
Jacobian there is checked where a platform becomes a model
(:class:`stewart_env.dynamics.Dynamics`), by the kernels' Jacobian.
"""

# Annotations are evaluated here, not postponed: the classes are shown and pickled under
# stewart_env.params, whose namespace could not resolve their names for typing.get_type_hints.

import dataclasses
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stewart_env.params.actuators import ActuatorSets, actuator_sets_from_config
from stewart_env.params.bodies import N_LEGS, Damping, Limits, RigidBody, _ValueObject, set_field, unit_rows
from stewart_env.params.checks import ConfigError, array, describe, frozen_array, mapping, number, within
from stewart_env.params.reader import parse_config, read_config_text
from stewart_env.rotations import rpy_to_matrix

__all__ = ["N_LEGS", "MIN_PLATFORM_MASS", "MIN_PLATFORM_INERTIA", "PlatformParams", "from_text"]

# A Hooke axis closer than this to its leg (|k x e| = sine of the angle between them) makes the
# U-joint frame y = normalize(k x e) ill-defined: about 0.06 deg.
_MIN_HOOKE_SINE = 1e-3
# Standard gravity: the default `gravity`, and the |g| that sizes the default force range when
# gravity is switched off.
_G0 = 9.81
_DEFAULT_MAX_ANGLE = 0.5
_DEFAULT_MAX_CONDITION = 1000.0
#: Far below any real platform; they keep accelerations (force / mass, torque / inertia) finite.
MIN_PLATFORM_MASS = 1e-6
MIN_PLATFORM_INERTIA = 1e-15

_TOP_KEYS_REQUIRED = ("base_joints", "platform_joints", "hooke_axes", "platform", "upper_leg", "lower_leg", "damping")
_TOP_KEYS_OPTIONAL = ("gravity", "limits", "home", "actuators")


@dataclass(frozen=True, eq=False)
class PlatformParams(_ValueObject):
    """All parameters of one 6-UPS Stewart platform. Immutable: arrays are float64 and read-only.

    Attributes:
        name: platform name (a config's file stem).
        base_joints: (6, 3) b_i, base joint B_i in {B}, m.
        platform_joints: (6, 3) p_i, platform joint P_i in {P}, m.
        hooke_axes: (6, 3) unit k_i, fixed U-joint axes in {B} (a (3,) value is shared by all
            legs; rows are normalised).
        platform: platform + payload; com R0 in {P}, inertia about the CoM in {P} axes (positive
            definite, mass > 0).
        upper_leg: six upper legs (pistons); com r_u0 from P_i in the leg frame {D_i}, inertia
            about the CoM in {D_i} axes. A single RigidBody is shared by all legs.
        lower_leg: six lower legs (cylinders); com r_d0 from B_i in {D_i}, inertia as above.
        damping: viscous joint friction coefficients.
        gravity: (3,) m/s^2 in {B}.
        limits: the environment's operating limits.
        home_position: (3,) P's origin at the home pose, in {B}, m.
        home_rpy: (3,) roll, pitch, yaw at the home pose, rad.
        actuators: the legs' actuator parameter sets (electric, hydraulic), empty where the config
            has no ``actuators`` section.

    Besides each value's own checks, the home pose must be valid: every leg of nonzero length,
    no Hooke axis parallel to its leg, leg lengths inside limits.leg_length and the position
    inside the workspace box. The model built on the platform
    (:class:`stewart_env.dynamics.Dynamics`) also requires the Jacobian (rows
    [e_i, (R p_i) x e_i]) at the home pose to be conditioned within limits.max_condition.

    Raises:
        ConfigError: a value that fails its check, or an invalid home pose (the message names
            the config key).

    Examples:
        >>> import stewart_env as se
        >>> from stewart_env.params import Damping
        >>> params = se.load_platform("dasgupta1998")
        >>> frictionless = params.replace(damping=Damping(universal=0.0, prismatic=0.0, spherical=0.0))
        >>> frictionless.damping.prismatic, frictionless.name
        (0.0, 'dasgupta1998')
        >>> params.replace(gravity=[0.0, 0.0, float("nan")])
        Traceback (most recent call last):
        ...
        stewart_env.params.ConfigError: gravity[2]: not a finite number (nan)
    """

    name: str
    base_joints: np.ndarray
    platform_joints: np.ndarray
    hooke_axes: np.ndarray
    platform: RigidBody
    upper_leg: tuple[RigidBody, ...]
    lower_leg: tuple[RigidBody, ...]
    damping: Damping
    gravity: np.ndarray
    limits: Limits
    home_position: np.ndarray
    home_rpy: np.ndarray
    actuators: ActuatorSets = ActuatorSets()

    def __post_init__(self) -> None:
        if not isinstance(self.name, str):
            raise ConfigError("name", f"must be a string, got {describe(self.name)}")
        base = array(self.base_joints, "base_joints", (N_LEGS, 3))
        plat = array(self.platform_joints, "platform_joints", (N_LEGS, 3))
        hooke = unit_rows(array(self.hooke_axes, "hooke_axes", (N_LEGS, 3), (3,)), "hooke_axes")
        platform = _instance(self.platform, RigidBody, "platform")
        _check_platform_mass(platform.mass)
        eigenvalues = np.linalg.eigvalsh(platform.inertia)
        if eigenvalues[0] <= 1e-12 * eigenvalues[-1]:
            raise ConfigError("platform.inertia", f"not positive definite (eigenvalues {eigenvalues.tolist()})")
        if eigenvalues[0] < MIN_PLATFORM_INERTIA:
            raise ConfigError(
                "platform.inertia",
                f"smallest principal moment {eigenvalues[0]:.3g} is below {MIN_PLATFORM_INERTIA:g} kg m^2",
            )
        upper = _legs(self.upper_leg, "upper_leg")
        lower = _legs(self.lower_leg, "lower_leg")
        _instance(self.damping, Damping, "damping")
        gravity = array(self.gravity, "gravity", (3,))
        limits = _instance(self.limits, Limits, "limits")
        position = array(self.home_position, "home.position", (3,))
        rpy = array(self.home_rpy, "home.rpy", (3,))
        _instance(self.actuators, ActuatorSets, "actuators")

        lengths = _home_leg_lengths(base, plat, hooke, position, rpy)
        lo, hi = limits.leg_length
        for i, length in enumerate(lengths):
            if not lo <= length <= hi:
                raise ConfigError(
                    "limits.leg_length",
                    f"leg {i} is {length:.4f} m long at the home pose, outside [{lo}, {hi}]",
                )
        if np.any(position < limits.position_min) or np.any(position > limits.position_max):
            raise ConfigError(
                "limits.workspace",
                f"home position {position.tolist()} lies outside the box "
                f"[{limits.position_min.tolist()}, {limits.position_max.tolist()}]",
            )
        _check_home_cone_angles(base, plat, position, rpy, limits)

        set_field(self, "base_joints", frozen_array(base))
        set_field(self, "platform_joints", frozen_array(plat))
        set_field(self, "hooke_axes", frozen_array(hooke))
        set_field(self, "upper_leg", upper)
        set_field(self, "lower_leg", lower)
        set_field(self, "gravity", frozen_array(gravity))
        set_field(self, "home_position", frozen_array(position))
        set_field(self, "home_rpy", frozen_array(rpy))

    @classmethod
    def from_dict(cls, d: Mapping, name: str = "custom") -> "PlatformParams":
        """Build from a config mapping (the schema of :mod:`stewart_env.params`), filling the
        documented defaults for `gravity`, `home` and `limits`.

        Args:
            d: the config mapping.
            name: the platform's name.

        Raises:
            ConfigError: a missing or unknown key, or a value that fails its check (named).
        """
        d = mapping(d, "", _TOP_KEYS_REQUIRED, _TOP_KEYS_OPTIONAL)
        base = array(d["base_joints"], "base_joints", (N_LEGS, 3))
        plat = array(d["platform_joints"], "platform_joints", (N_LEGS, 3))
        hooke = unit_rows(array(d["hooke_axes"], "hooke_axes", (N_LEGS, 3), (3,)), "hooke_axes")
        with within("platform"):
            body = mapping(d["platform"], "", ("mass", "com", "inertia"))
        # Checked before RigidBody, which accepts a massless body and would word it ">= 0".
        _check_platform_mass(number(body["mass"], "platform.mass"))
        with within("platform"):
            platform = RigidBody.from_dict(body)
        upper = _legs_from_config(d["upper_leg"], "upper_leg")
        lower = _legs_from_config(d["lower_leg"], "lower_leg")
        with within("damping"):
            damping = Damping.from_dict(d["damping"])
        gravity = array(d.get("gravity", [0.0, 0.0, -_G0]), "gravity", (3,))

        if "home" in d:
            home = mapping(d["home"], "home", ("position",), ("rpy",))
            position = array(home["position"], "home.position", (3,))
            rpy = array(home.get("rpy", [0.0, 0.0, 0.0]), "home.rpy", (3,))
        else:
            position, rpy = np.zeros(3), np.zeros(3)
        try:
            lengths = _home_leg_lengths(base, plat, hooke, position, rpy)
        except ConfigError as err:
            if "home" in d:
                raise
            raise ConfigError(
                "",
                "missing key 'home': the default home pose (position [0, 0, 0], rpy [0, 0, 0]) "
                f"is not valid ({err}); give home: {{position: [x, y, z], rpy: [roll, pitch, yaw]}}",
            ) from None

        with within("limits"):
            limits = _limits_from_config(
                d.get("limits", {}), lengths, position, gravity, platform.mass + N_LEGS * _mean_mass(upper, lower)
            )
        with within("actuators"):
            actuators = actuator_sets_from_config(d["actuators"]) if "actuators" in d else ActuatorSets()
        return cls(
            name=name,
            base_joints=base,
            platform_joints=plat,
            hooke_axes=hooke,
            platform=platform,
            upper_leg=upper,
            lower_leg=lower,
            damping=damping,
            gravity=gravity,
            limits=limits,
            home_position=position,
            home_rpy=rpy,
            actuators=actuators,
        )

    @classmethod
    def from_yaml(cls, path: str | os.PathLike) -> "PlatformParams":
        """Load a YAML config file (a regular *.yaml or *.yml file of at most MAX_CONFIG_BYTES);
        the platform's name is the file stem.

        Args:
            path: the config file.

        Raises:
            ConfigError: the file cannot be read or holds no valid config (naming the file and key).
        """
        path = Path(path)
        return from_text(read_config_text(path), path.stem, str(path))

    def to_dict(self) -> dict:
        """The config as plain lists and floats (every key written out, defaults included);
        `PlatformParams.from_dict(p.to_dict(), p.name) == p`. Legs that share their parameters
        are written as one mapping."""

        def legs(bodies: tuple[RigidBody, ...]) -> dict | list[dict]:
            if all(body == bodies[0] for body in bodies):
                return bodies[0].to_dict()
            return [body.to_dict() for body in bodies]

        config = {
            "base_joints": self.base_joints.tolist(),
            "platform_joints": self.platform_joints.tolist(),
            "hooke_axes": self.hooke_axes.tolist(),
            "platform": self.platform.to_dict(),
            "upper_leg": legs(self.upper_leg),
            "lower_leg": legs(self.lower_leg),
            "damping": self.damping.to_dict(),
            "gravity": self.gravity.tolist(),
            "limits": self.limits.to_dict(),
            "home": {"position": self.home_position.tolist(), "rpy": self.home_rpy.tolist()},
        }
        if self.actuators:
            config["actuators"] = self.actuators.to_dict()
        return config

    def replace(self, **changes) -> "PlatformParams":
        """A copy with some fields changed (dataclass field names), validated again.

        Args:
            **changes: {field name: new value}.

        Raises:
            ConfigError: a new value that fails its check.
        """
        return dataclasses.replace(self, **changes)


def from_text(text: str, name: str, source: str) -> PlatformParams:
    """The platform of a config file's `text`, named `name`; every error names `source`.

    Args:
        text: the config file's text (YAML).
        name: the platform's name.
        source: where the text comes from (a path), for the errors.

    Raises:
        ConfigError: text that is no valid config.
    """
    config = parse_config(text, source)
    try:
        return PlatformParams.from_dict(config, name=name)
    except ConfigError as err:
        raise ConfigError(err.key, err.problem, source) from None


# ----------------------------------------------------------------------------------------------
# The home pose, as far as validation needs it.


def _home_leg_lengths(
    base: np.ndarray, plat: np.ndarray, hooke: np.ndarray, position: np.ndarray, rpy: np.ndarray
) -> np.ndarray:
    """Leg lengths L_i (6,) at a pose, m, after checking that every leg has a direction and that
    no fixed Hooke axis is parallel to its leg (where the U-joint frame is undefined)."""
    q = plat @ rpy_to_matrix(rpy).T
    legs = position + q - base
    lengths = np.linalg.norm(legs, axis=1)
    scale = 1.0 + float(np.max(np.abs(np.concatenate([base, plat]))))
    for i, length in enumerate(lengths):
        if length <= 1e-9 * scale:
            raise ConfigError("home.position", f"leg {i} has zero length at the home pose")
    e = legs / lengths[:, None]
    for i in range(N_LEGS):
        sine = float(np.linalg.norm(np.cross(hooke[i], e[i])))
        if sine < _MIN_HOOKE_SINE:
            angle = np.degrees(np.arcsin(min(sine, 1.0)))
            raise ConfigError(f"hooke_axes[{i}]", f"parallel to leg {i} at the home pose (angle {angle:.1f} deg)")
    return lengths


def _check_home_cone_angles(
    base: np.ndarray, plat: np.ndarray, position: np.ndarray, rpy: np.ndarray, limits: Limits
) -> None:
    """Every joint's cone angle at the home pose within its bound (docs/physics.md, "Limits and
    constraint costs": the angle between the leg axis e_i and the joint's mounting axis)."""
    rotation = rpy_to_matrix(rpy)
    legs = position + plat @ rotation.T - base
    e = legs / np.linalg.norm(legs, axis=1)[:, None]
    for joint, axes in (("universal", limits.universal_axes), ("spherical", limits.spherical_axes @ rotation.T)):
        bound = getattr(limits, f"max_{joint}_angle")
        angles = np.arctan2(np.linalg.norm(np.cross(axes, e), axis=1), np.sum(axes * e, axis=1))
        for i, angle in enumerate(angles):
            if angle > bound:
                raise ConfigError(
                    f"limits.{joint}_joint.max_angle",
                    f"leg {i} is {np.degrees(angle):.1f} deg from its mounting axis at the home pose, "
                    f"above {np.degrees(bound):.1f} deg",
                )


# ----------------------------------------------------------------------------------------------
# Fields of PlatformParams.


def _check_platform_mass(mass: float) -> None:
    if not mass >= MIN_PLATFORM_MASS:
        raise ConfigError("platform.mass", f"must be >= {MIN_PLATFORM_MASS:g} kg, got {mass}")


def _legs(value: object, key: str) -> tuple[RigidBody, ...]:
    """Six leg parts from one shared RigidBody or a sequence of six."""
    if isinstance(value, RigidBody):
        return (value,) * N_LEGS
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, Sequence) or len(value) != N_LEGS:
        raise ConfigError(key, f"expected a RigidBody or a sequence of six, got {describe(value)}")
    for i, body in enumerate(value):
        if not isinstance(body, RigidBody):
            raise ConfigError(f"{key}[{i}]", f"expected a RigidBody, got {describe(body)}")
    return tuple(value)


def _legs_from_config(value: object, key: str) -> tuple[RigidBody, ...]:
    """Six leg parts from one shared config mapping or a list of six."""
    if isinstance(value, Mapping):
        with within(key):
            return (RigidBody.from_dict(value),) * N_LEGS
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence):
        raise ConfigError(key, f"expected one mapping or a list of six, got {describe(value)}")
    if len(value) != N_LEGS:
        raise ConfigError(key, f"expected one mapping or a list of six, got a list of {len(value)}")
    bodies = []
    for i, item in enumerate(value):
        with within(f"{key}[{i}]"):
            bodies.append(RigidBody.from_dict(item))
    return tuple(bodies)


def _instance(value: object, cls: type, key: str) -> object:
    if not isinstance(value, cls):
        raise ConfigError(key, f"expected a {cls.__name__}, got {describe(value)}")
    return value


def _mean_mass(upper: tuple[RigidBody, ...], lower: tuple[RigidBody, ...]) -> float:
    """Mean mass of one leg (upper + lower part), kg."""
    return float(np.mean([u.mass + d.mass for u, d in zip(upper, lower)]))


def _limits_from_config(
    value: object, lengths: np.ndarray, position: np.ndarray, gravity: np.ndarray, total_mass: float
) -> Limits:
    """Limits from the config's `limits` mapping, each missing entry replaced by its default
    (the schema of stewart_env.params), computed from the home leg lengths, home position and the weight;
    a missing bound of the leg velocity, acceleration, force rate or a joint cone is no bound (inf)."""
    limits = mapping(
        value,
        "",
        (),
        (
            "leg_length",
            "leg_force",
            "workspace",
            "max_condition",
            "leg_velocity",
            "leg_acceleration",
            "force_rate",
            "universal_joint",
            "spherical_joint",
        ),
    )
    workspace = mapping(limits.get("workspace", {}), "workspace", (), ("position_min", "position_max", "max_angle"))
    joints = {
        joint: mapping(limits.get(f"{joint}_joint", {}), f"{joint}_joint", (), ("max_angle", "axes"))
        for joint in ("universal", "spherical")
    }
    g = float(np.linalg.norm(gravity)) or _G0
    leg_weight = total_mass * g / N_LEGS
    half_box = 0.5 * float(np.mean(lengths))
    return Limits(
        leg_length=limits.get("leg_length", (0.8 * float(lengths.min()), 1.2 * float(lengths.max()))),
        leg_force=limits.get("leg_force", (-10.0 * leg_weight, 10.0 * leg_weight)),
        position_min=workspace.get("position_min", position - half_box),
        position_max=workspace.get("position_max", position + half_box),
        max_angle=workspace.get("max_angle", _DEFAULT_MAX_ANGLE),
        max_condition=limits.get("max_condition", _DEFAULT_MAX_CONDITION),
        max_leg_velocity=_bound_from_config(limits, "leg_velocity"),
        max_leg_acceleration=_bound_from_config(limits, "leg_acceleration"),
        max_force_rate=_bound_from_config(limits, "force_rate"),
        max_universal_angle=_bound_from_config(joints["universal"], "max_angle", "universal_joint.max_angle"),
        universal_axes=joints["universal"].get("axes"),
        max_spherical_angle=_bound_from_config(joints["spherical"], "max_angle", "spherical_joint.max_angle"),
        spherical_axes=joints["spherical"].get("axes"),
    )


def _bound_from_config(section: Mapping, key: str, name: str | None = None) -> object:
    """The config's bound `key` of `section` as given (Limits checks it), inf when absent: no
    limit. A bound written as inf is refused (every number of a config is finite): leaving the key
    out says "no limit". `name` is the key path the error names (default `key`)."""
    if key not in section:
        return math.inf
    value = section[key]
    if isinstance(value, (float, np.floating)) and math.isinf(value):
        raise ConfigError(name or key, f"not a finite number ({value}); leave the key out for no limit")
    return value
