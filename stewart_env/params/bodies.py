"""The parts of a platform's parameters as immutable value objects: :class:`RigidBody` (one body's
inertial parameters), :class:`Damping` (the joints' viscous friction) and :class:`Limits` (the
environment's operating limits), compared, hashed and pickled by value (as is PlatformParams).

Each validates its values when built (directly, by ``from_dict`` or by ``dataclasses.replace``)
and raises :class:`~stewart_env.params.ConfigError` naming the field.
"""

# Annotations are evaluated here, not postponed: the classes are shown and pickled under
# stewart_env.params, whose namespace could not resolve their names for typing.get_type_hints.

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from stewart_env.params.checks import ConfigError, array, frozen_array, interval, mapping, number

__all__ = ["N_LEGS", "set_field", "unit_rows", "RigidBody", "Damping", "Limits"]

#: The platform's legs (six: a 6-UPS mechanism); its rows of per-leg arrays.
N_LEGS = 6


class _ValueObject:
    """Equality, hashing and pickling by value for frozen dataclasses whose fields may be numpy
    arrays (the dataclass defaults would compare arrays elementwise)."""

    def _key(self) -> tuple:
        key = []
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if isinstance(value, np.ndarray):
                # + 0.0 maps -0.0 to 0.0, so that equal arrays have equal bytes.
                value = (value.shape, (value + 0.0).tobytes())
            key.append(value)
        return tuple(key)

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return self._key() == other._key()

    def __hash__(self) -> int:
        return hash((type(self).__name__, self._key()))

    def __reduce__(self):
        # Rebuild through the constructor so that an unpickled copy is validated and read-only too.
        return type(self), tuple(getattr(self, f.name) for f in dataclasses.fields(self))


def set_field(obj: object, name: str, value: object) -> None:
    """Store a checked value in a frozen dataclass's field (from its ``__post_init__``).

    Args:
        obj: the dataclass instance.
        name: the field's name.
        value: the checked value.
    """
    object.__setattr__(obj, name, value)


def unit_rows(axes: np.ndarray, key: str) -> np.ndarray:
    """(N_LEGS, 3) unit rows from (N_LEGS, 3) rows or one shared (3,) row. Rows already unit to
    1e-12 are kept as given, so that loading a saved config reproduces it bit for bit.

    Args:
        axes: the checked float64 rows (of :func:`~stewart_env.params.checks.array`).
        key: the rows' key path in the config, which the error names, e.g. ``hooke_axes``.

    Returns:
        A new (N_LEGS, 3) array of unit rows.

    Raises:
        ConfigError: a zero row (named ``key[i]``).
    """
    axes = np.broadcast_to(axes, (N_LEGS, 3)).copy()
    for i, row in enumerate(axes):
        norm = float(np.linalg.norm(row))
        if norm < 1e-12:
            raise ConfigError(f"{key}[{i}]", "zero vector")
        if abs(norm - 1.0) > 1e-12:
            axes[i] = row / norm
    return axes


def _symmetric_eigenvalues(matrix: np.ndarray, key: str) -> np.ndarray:
    """Eigenvalues of an inertia matrix after checking its symmetry relative to its scale."""
    scale = float(np.max(np.abs(matrix)))
    asymmetry = float(np.max(np.abs(matrix - matrix.T)))
    if asymmetry > 1e-12 * scale:
        raise ConfigError(key, f"not symmetric (largest |I - I^T| entry {asymmetry:.3g})")
    return np.linalg.eigvalsh(matrix)


@dataclass(frozen=True, eq=False)
class RigidBody(_ValueObject):
    """Inertial parameters of one rigid body.

    Attributes:
        mass: kg, >= 0 (0 describes a massless body, whose inertia must then be zero).
        com: (3,) centre of mass, m, in the body's reference frame (see PlatformParams).
        inertia: (3, 3) inertia about the CoM in the body's reference axes, kg m^2: symmetric and
            positive semidefinite. A (3,) value is taken as the diagonal.

    Positive definiteness, needed for the platform, is checked by PlatformParams; a leg part may
    be a point mass or a slender rod (a zero moment about its axis).

    Raises:
        ConfigError: a value that fails its check (the message names the config key).
    """

    mass: float
    com: np.ndarray
    inertia: np.ndarray

    def __post_init__(self) -> None:
        mass = number(self.mass, "mass")
        if mass < 0:
            raise ConfigError("mass", f"must be >= 0, got {mass}")
        com = array(self.com, "com", (3,))
        inertia = array(self.inertia, "inertia", (3, 3), (3,))
        if inertia.shape == (3,):
            inertia = np.diag(inertia)
        eigenvalues = _symmetric_eigenvalues(inertia, "inertia")
        if eigenvalues[0] < -1e-12 * float(np.max(np.abs(eigenvalues))):
            raise ConfigError("inertia", f"not positive semidefinite (eigenvalues {eigenvalues.tolist()})")
        if mass == 0 and np.any(inertia != 0):
            raise ConfigError("inertia", "must be zero for a massless body (mass 0)")
        set_field(self, "mass", mass)
        set_field(self, "com", frozen_array(com))
        # Averaging with the transpose removes rounding-level asymmetry; it is exact for a
        # symmetric matrix, so loading is idempotent.
        set_field(self, "inertia", frozen_array(0.5 * (inertia + inertia.T)))

    @classmethod
    def from_dict(cls, d: Mapping) -> "RigidBody":
        """From a config mapping {mass, com, inertia}.

        Args:
            d: the mapping: mass (kg), com ((3,), m, in the body's frame) and inertia ((3, 3),
                kg m^2, about the CoM).

        Raises:
            ConfigError: a missing or unknown key, or a value that fails its check.
        """
        d = mapping(d, "", ("mass", "com", "inertia"))
        return cls(mass=d["mass"], com=d["com"], inertia=d["inertia"])

    def to_dict(self) -> dict:
        """The config mapping {mass, com, inertia} of :meth:`from_dict`, as plain lists and floats."""
        return {"mass": self.mass, "com": self.com.tolist(), "inertia": self.inertia.tolist()}


@dataclass(frozen=True, eq=False)
class Damping(_ValueObject):
    """Viscous joint friction coefficients (the paper's model).

    Attributes:
        universal: Cu >= 0, N m s/rad: U-joint torque -Cu omega_l on the leg.
        prismatic: Cp >= 0, N s/m: force -Cp dL/dt on the upper leg along e_i.
        spherical: Cs >= 0, N m s/rad: torque -Cs (omega_l - omega) on the leg, the opposite on
            the platform.

    Raises:
        ConfigError: a value that fails its check (the message names the config key).
    """

    universal: float
    prismatic: float
    spherical: float

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self):
            value = number(getattr(self, field.name), field.name)
            if value < 0:
                raise ConfigError(field.name, f"must be >= 0, got {value}")
            set_field(self, field.name, value)

    @classmethod
    def from_dict(cls, d: Mapping) -> "Damping":
        """From a config mapping {universal, prismatic, spherical}.

        Args:
            d: the mapping of the three coefficients (see the class docstring for their units).

        Raises:
            ConfigError: a missing or unknown key, or a value that fails its check.
        """
        d = mapping(d, "", ("universal", "prismatic", "spherical"))
        return cls(**d)

    def to_dict(self) -> dict:
        """The config mapping {universal, prismatic, spherical} of :meth:`from_dict`."""
        return {"universal": self.universal, "prismatic": self.prismatic, "spherical": self.spherical}


#: The default mounting axis of every joint of a joint cone limit: the z axis of its body's frame
#: ({B} for the universal joints, {P} for the spherical joints).
_Z_AXES = np.tile([0.0, 0.0, 1.0], (N_LEGS, 1))


@dataclass(frozen=True, eq=False)
class Limits(_ValueObject):
    """Operating limits used by the environment (the dynamics ignores them).

    Attributes:
        leg_length: actuator stroke (min, max), m, 0 < min < max.
        leg_force: actuator force range (min, max), N, min < max; positive extends the leg.
        position_min: (3,) lower corner of the workspace box for P's origin, in {B}, m.
        position_max: (3,) upper corner, elementwise > position_min.
        max_angle: rad, in (0, pi]: bound on the deviation of each of roll, pitch, yaw from the
            home rpy.
        max_condition: bound on the condition number of the 6x6 leg Jacobian, > 1.
        max_leg_velocity: bound on each leg's rate |dL_i/dt|, m/s, > 0; inf (the default) for
            none.
        max_leg_acceleration: bound on each leg's acceleration |d2L_i/dt2| over a control step,
            m/s^2, > 0; inf for none.
        max_force_rate: bound on each leg force's rate |dF_i/dt| over a control step, N/s, > 0;
            inf for none.
        max_universal_angle: bound on each universal joint's cone angle, the angle between the
            leg axis e_i and the joint's mounting axis, rad, in (0, pi]; inf for none.
        universal_axes: (6, 3) unit mounting axes of the universal joints in {B} (a (3,) value
            is shared by all joints; rows are normalised); the base's z axis by default.
        max_spherical_angle: bound on each spherical joint's cone angle, between e_i and the
            joint's mounting axis R c_i, rad, in (0, pi]; inf for none.
        spherical_axes: (6, 3) unit mounting axes c_i of the spherical joints in {P}, as
            universal_axes; the platform's z axis by default.

    A mounting axis is the leg's direction, from the base joint towards the platform joint, at
    which the joint sits at the centre of its cone (docs/physics.md, "Limits and constraint
    costs"). Error messages use the config's key names (``workspace.position_min``,
    ``universal_joint.max_angle``).

    Raises:
        ConfigError: a value that fails its check (the message names the config key).
    """

    leg_length: tuple[float, float]
    leg_force: tuple[float, float]
    position_min: np.ndarray
    position_max: np.ndarray
    max_angle: float
    max_condition: float
    max_leg_velocity: float = math.inf
    max_leg_acceleration: float = math.inf
    max_force_rate: float = math.inf
    max_universal_angle: float = math.inf
    universal_axes: np.ndarray | None = None
    max_spherical_angle: float = math.inf
    spherical_axes: np.ndarray | None = None

    def __post_init__(self) -> None:
        leg_length = interval(self.leg_length, "leg_length")
        if leg_length[0] <= 0:
            raise ConfigError("leg_length", f"minimum must be > 0, got {leg_length[0]}")
        leg_force = interval(self.leg_force, "leg_force")
        position_min = array(self.position_min, "workspace.position_min", (3,))
        position_max = array(self.position_max, "workspace.position_max", (3,))
        if not np.all(position_min < position_max):
            raise ConfigError(
                "workspace",
                f"position_min {position_min.tolist()} must be below position_max "
                f"{position_max.tolist()} on every axis",
            )
        max_angle = number(self.max_angle, "workspace.max_angle")
        if not 0 < max_angle <= np.pi:
            raise ConfigError("workspace.max_angle", f"must be in (0, pi], got {max_angle}")
        max_condition = number(self.max_condition, "max_condition")
        if not max_condition > 1:
            raise ConfigError("max_condition", f"must be > 1, got {max_condition}")
        set_field(self, "leg_length", leg_length)
        set_field(self, "leg_force", leg_force)
        set_field(self, "position_min", frozen_array(position_min))
        set_field(self, "position_max", frozen_array(position_max))
        set_field(self, "max_angle", max_angle)
        set_field(self, "max_condition", max_condition)
        for name, key in (
            ("max_leg_velocity", "leg_velocity"),
            ("max_leg_acceleration", "leg_acceleration"),
            ("max_force_rate", "force_rate"),
        ):
            set_field(self, name, _optional_bound(getattr(self, name), key))
        for joint in ("universal", "spherical"):
            key = f"{joint}_joint"
            bound = _optional_bound(getattr(self, f"max_{joint}_angle"), f"{key}.max_angle")
            if np.pi < bound < math.inf:
                raise ConfigError(f"{key}.max_angle", f"must be in (0, pi] rad, got {bound}")
            axes = getattr(self, f"{joint}_axes")
            axes = _Z_AXES if axes is None else unit_rows(array(axes, f"{key}.axes", (N_LEGS, 3), (3,)), f"{key}.axes")
            set_field(self, f"max_{joint}_angle", bound)
            set_field(self, f"{joint}_axes", frozen_array(axes))

    def to_dict(self) -> dict:
        """The config mapping of the limits, as a platform config's ``limits`` holds them (a
        bound that is absent, inf, is left out, and so are default mounting axes)."""
        d = {
            "leg_length": list(self.leg_length),
            "leg_force": list(self.leg_force),
            "workspace": {
                "position_min": self.position_min.tolist(),
                "position_max": self.position_max.tolist(),
                "max_angle": self.max_angle,
            },
            "max_condition": self.max_condition,
        }
        for name, key in (
            ("max_leg_velocity", "leg_velocity"),
            ("max_leg_acceleration", "leg_acceleration"),
            ("max_force_rate", "force_rate"),
        ):
            if getattr(self, name) != math.inf:
                d[key] = getattr(self, name)
        for joint in ("universal", "spherical"):
            joint_limit = {}
            if getattr(self, f"max_{joint}_angle") != math.inf:
                joint_limit["max_angle"] = getattr(self, f"max_{joint}_angle")
            axes = getattr(self, f"{joint}_axes")
            if not np.array_equal(axes, _Z_AXES):
                joint_limit["axes"] = axes.tolist()
            if joint_limit:
                d[f"{joint}_joint"] = joint_limit
        return d


def _optional_bound(value: object, key: str) -> float:
    """A bound that may be absent: inf as given (no limit), else a number > 0 (``key`` names it)."""
    if isinstance(value, (float, np.floating)) and value == math.inf:
        return math.inf
    bound = number(value, key)
    if not bound > 0:
        raise ConfigError(key, f"must be > 0, got {bound}")
    return bound
