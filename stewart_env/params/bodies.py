"""The parts of a platform's parameters as immutable value objects: :class:`RigidBody` (one body's
inertial parameters), :class:`Damping` (the joints' viscous friction) and :class:`Limits` (the
environment's operating limits), compared, hashed and pickled by value (as is PlatformParams).

Each validates its values when built (directly, by ``from_dict`` or by ``dataclasses.replace``)
and raises :class:`~stewart_env.params.ConfigError` naming the field.
"""

# Annotations are evaluated here, not postponed: the classes are shown and pickled under
# stewart_env.params, whose namespace could not resolve their names for typing.get_type_hints.

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from stewart_env.params.checks import ConfigError, array, frozen_array, interval, mapping, number

__all__ = ["set_field", "RigidBody", "Damping", "Limits"]


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

    Error messages use the config's key names (``workspace.position_min``).

    Raises:
        ConfigError: a value that fails its check (the message names the config key).
    """

    leg_length: tuple[float, float]
    leg_force: tuple[float, float]
    position_min: np.ndarray
    position_max: np.ndarray
    max_angle: float
    max_condition: float

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

    def to_dict(self) -> dict:
        """The config mapping of the limits, as a platform config's ``limits`` holds them."""
        return {
            "leg_length": list(self.leg_length),
            "leg_force": list(self.leg_force),
            "workspace": {
                "position_min": self.position_min.tolist(),
                "position_max": self.position_max.tolist(),
                "max_angle": self.max_angle,
            },
            "max_condition": self.max_condition,
        }
