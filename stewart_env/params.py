"""Platform parameters of the 6-UPS Stewart platform: the config schema, loading and validation.

A platform is described by one config (a YAML file or a plain dict) with these keys:

    base_joints: [[x, y, z], ...]        # six rows: b_i in {B}, m
    platform_joints: [[x, y, z], ...]    # six rows: p_i in {P}, m
    hooke_axes: [[kx, ky, kz], ...]      # six rows or one shared row: fixed U-joint axes k_i in {B}
    platform:  {mass: .., com: [..], inertia: ..}   # com in {P}; inertia about the CoM, {P} axes
    upper_leg: {mass: .., com: [..], inertia: ..}   # one mapping for all legs, or a list of six
    lower_leg: {mass: .., com: [..], inertia: ..}   # same
    damping:   {universal: Cu, prismatic: Cp, spherical: Cs}
    gravity: [0, 0, -9.81]               # optional, m/s^2 in {B}
    limits:                              # optional; each entry optional (defaults below)
      leg_length: [min, max]             # actuator stroke, m
      leg_force: [min, max]              # actuator force range, N
      workspace: {position_min: [..], position_max: [..], max_angle: rad}
      max_condition: 1000.0              # bound on the leg Jacobian's condition number
    home: {position: [x, y, z], rpy: [roll, pitch, yaw]}   # optional (see below)

`inertia` is a 3x3 nested list or a 3-list, the shorthand for a diagonal matrix. The leg CoMs are
given in the leg frame {D_i} = [e_i, y_i, z_i]: the upper leg's from the platform joint P_i
(CoM = P_i + T_i r_u0), the lower leg's from the base joint B_i (CoM = B_i + T_i r_d0).
Orientations use R = Rz(yaw) Ry(pitch) Rx(roll).

Defaults when `home` or `limits` (or any entry of `limits`) is missing, so that a platform can be
built from the physical keys alone:

- home: position [0, 0, 0], rpy [0, 0, 0], accepted only if that pose is valid (every leg of
  nonzero length, no Hooke axis parallel to its leg); otherwise loading fails and asks for `home`.
  A `home` given without `rpy` takes rpy [0, 0, 0].
- limits.leg_length: (0.8 min_i L_i, 1.2 max_i L_i) with L_i the leg lengths at the home pose.
- limits.leg_force: (-10 W, 10 W), W = (m_p + 6 (m_u + m_d)) |g| / 6 the weight share of one leg
  (|g| = 9.81 when gravity is zero, so that the range is never empty).
- limits.workspace.position_min / position_max: the home position -/+ 0.5 mean_i L_i on each axis.
- limits.workspace.max_angle: 0.5 rad.  limits.max_condition: 1000.

Every number must be a real number (not a boolean), finite as a float64 and at most 1e12 in
magnitude, so that nothing overflows in the dynamics; the platform's mass must be at least 1e-6 kg
and its principal moments of inertia at least 1e-15 kg m^2.

Every invalid input raises `ConfigError` (a `ValueError`) whose message starts with the key path
of the offending value, e.g. ``upper_leg[2].inertia: not symmetric`` or
``base_joints[3][1]: not a finite number (inf)``. Leg indices in messages count from 0, like the
rows of the arrays. Messages quote at most a short excerpt of a value, never a whole file.

Files: `load_platform` and `PlatformParams.from_yaml` read only regular files named *.yaml or
*.yml of at most 1 MB (`MAX_CONFIG_BYTES`), with YAML's safe loader, nesting at most 32 levels
deep and at most 5000 values once aliases are expanded; a key given twice in one mapping is an
error (a merge, <<: *anchor, may still be overridden).
"""

from __future__ import annotations

import dataclasses
import importlib.resources
import math
import os
import re
import reprlib
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np
import yaml

from stewart_env.errors import UsageError
from stewart_env.files import FileError, read_regular
from stewart_env.rotations import rpy_to_matrix

__all__ = [
    "ConfigError",
    "RigidBody",
    "Damping",
    "Limits",
    "PlatformParams",
    "load_platform",
    "available_platforms",
]

N_LEGS = 6
# A Hooke axis closer than this to its leg (|k x e| = sine of the angle between them) makes the
# U-joint frame y = normalize(k x e) ill-defined: about 0.06 deg.
_MIN_HOOKE_SINE = 1e-3
# Standard gravity: the default `gravity`, and the |g| that sizes the default force range when
# gravity is switched off.
_G0 = 9.81
_DEFAULT_MAX_ANGLE = 0.5
_DEFAULT_MAX_CONDITION = 1000.0
# No physical value of a Stewart platform in SI units comes near 1e12; products of a few such
# values in the dynamics stay far from float64's 1.8e308.
_MAX_MAGNITUDE = 1e12
# Far below any real platform; they keep accelerations (force / mass, torque / inertia) finite.
_MIN_PLATFORM_MASS = 1e-6
_MIN_PLATFORM_INERTIA = 1e-15

#: Largest platform config file accepted, bytes. The shipped configs are about 4 KB.
MAX_CONFIG_BYTES = 1 << 20
_CONFIG_SUFFIXES = (".yaml", ".yml")
# A config has about 200 values nested 4 deep; far larger documents are refused before they are
# built (a few KB of nested YAML aliases can expand to billions of values).
_MAX_YAML_DEPTH = 32
_MAX_YAML_VALUES = 5_000
# Longest integer literal read; Python's int() takes quadratic time in the literal's length.
_MAX_INT_LITERAL = 1000
# Longest excerpt of a value quoted in an error message, characters.
_EXCERPT = 60


class ConfigError(UsageError):
    """An invalid platform parameter or config file (also raised for an invalid domain
    randomisation spec).

    Attributes:
        key: path of the offending value in the config, e.g. ``"platform.inertia"`` or
            ``"hooke_axes[3]"``; empty for problems of the config or file as a whole.
        problem: what is wrong with it.
        source: the file the config came from, if any.
    """

    def __init__(self, key: str, problem: str, source: str | None = None):
        super().__init__(key, problem, source)
        self.key = key
        self.problem = problem
        self.source = source

    def __str__(self) -> str:
        text = f"{self.key}: {self.problem}" if self.key else self.problem
        return f"{self.source}: {text}" if self.source else text

    def within(self, prefix: str) -> ConfigError:
        """The same error, its key moved under `prefix` (``"inertia"`` -> ``"platform.inertia"``)."""
        if not self.key:
            key = prefix
        elif self.key.startswith("["):
            key = prefix + self.key
        else:
            key = f"{prefix}.{self.key}"
        return ConfigError(key, self.problem, self.source)


@contextmanager
def _within(prefix: str) -> Iterator[None]:
    """Re-raise a ConfigError from the block with its key path under `prefix`."""
    try:
        yield
    except ConfigError as err:
        raise err.within(prefix) from None


# ----------------------------------------------------------------------------------------------
# Coercion of raw values (numbers, nested lists, numpy arrays) into checked float64 values.


# PyYAML (YAML 1.1) reads exponent floats without a dot, such as 1e-4, as text.
_TEXT_HINT = " (text; in YAML write floats with a dot, e.g. 1.0e-4)"


def _excerpt(text: str, limit: int = _EXCERPT) -> str:
    return text if len(text) <= limit else text[:limit - 3] + "..."


class _ShortRepr(reprlib.Repr):
    """repr() that stays short however large or deeply nested the value is (a YAML file can
    expand to a huge structure): a few items per level, a few levels."""

    def __init__(self) -> None:
        super().__init__()
        self.maxlevel = 3
        self.maxlist = self.maxtuple = self.maxdict = self.maxset = self.maxfrozenset = 4
        self.maxstring = self.maxlong = self.maxother = _EXCERPT

    def repr_int(self, x: int, level: int) -> str:
        try:
            return super().repr_int(x, level)
        except ValueError:  # str() refuses integers of more than sys.get_int_max_str_digits()
            return f"an integer of about {int(x.bit_length() * math.log10(2))} digits"


_short_repr = _ShortRepr()


def _short(value: object) -> str:
    """A short excerpt of `value`'s repr for an error message."""
    try:
        return _excerpt(_short_repr.repr(value))
    except Exception:  # a foreign object whose repr fails: name its type instead
        return f"a {type(value).__name__}"


def _describe(value: object) -> str:
    """`_short(value)`, with a hint when it is a number that YAML read as text."""
    return _short(value) + (_TEXT_HINT if isinstance(value, str) and _is_float_text(value) else "")


def _is_float_text(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _number(value: object, key: str) -> float:
    """A finite float of magnitude at most _MAX_MAGNITUDE. Booleans and strings are refused:
    they are always a mistake here."""
    numeric = isinstance(value, (int, float, np.integer, np.floating))
    if isinstance(value, (bool, np.bool_)) or not numeric:
        raise ConfigError(key, f"must be a number, got {_describe(value)}")
    try:
        number = float(value)
    except OverflowError:  # an int beyond float64's range
        number = math.inf
    if not math.isfinite(number):
        raise ConfigError(key, f"not a finite number ({_describe(value if isinstance(value, int) else number)})")
    if abs(number) > _MAX_MAGNITUDE:
        raise ConfigError(key, f"magnitude above {_MAX_MAGNITUDE:g}, got {number:g}")
    return number


def _frozen_array(values: np.ndarray) -> np.ndarray:
    """A float64 copy whose memory belongs to an immutable bytes object, so that nobody can turn
    its WRITEABLE flag back on."""
    data = np.ascontiguousarray(values, dtype=np.float64)
    return np.frombuffer(data.tobytes(), dtype=np.float64).reshape(data.shape)


def _is_sequence(value: object) -> bool:
    return isinstance(value, (Sequence, np.ndarray)) and not isinstance(value, (str, bytes))


def _array(value: object, key: str, *shapes: tuple[int, ...]) -> np.ndarray:
    """A float64 array of one of `shapes` (not yet frozen), every entry checked by `_number` and
    named by its index path, e.g. ``base_joints[3][1]``."""
    expected = " or ".join(str(s) for s in shapes)
    if isinstance(value, np.ndarray) and value.dtype.kind in "iuf":
        if value.shape not in shapes:
            raise ConfigError(key, f"expected shape {expected}, got {value.shape}")
        with np.errstate(over="ignore"):  # an overflowing float128 becomes inf, refused below
            arr = value.astype(np.float64)
        bad = np.argwhere(~(np.abs(arr) <= _MAX_MAGNITUDE))
        if bad.size:
            index = tuple(int(i) for i in bad[0])
            _number(value[index], key + "".join(f"[{i}]" for i in index))
        return arr
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]
    if not _is_sequence(value):
        raise ConfigError(key, f"expected numbers of shape {expected}, got {_describe(value)}")
    depth = max(len(s) for s in shapes)
    longest = max(max(s) for s in shapes)

    def numbers(item: object, where: str, level: int) -> float | list:
        # Lengths are checked before walking, so a huge or deep list costs nothing.
        if isinstance(item, np.ndarray) and item.ndim == 0:
            item = item[()]
        if not _is_sequence(item) or level == depth:
            return _number(item, where)
        if len(item) > longest:
            raise ConfigError(where, f"expected shape {expected}, got a sequence of {len(item)} items")
        return [numbers(x, f"{where}[{i}]", level + 1) for i, x in enumerate(item)]

    nested = numbers(value, key, 0)
    try:
        arr = np.array(nested, dtype=np.float64)
    except ValueError:
        raise ConfigError(key, f"expected numbers of shape {expected}, got rows of unequal lengths") from None
    if arr.shape not in shapes:
        raise ConfigError(key, f"expected shape {expected}, got {arr.shape}")
    return arr


def _interval(value: object, key: str) -> tuple[float, float]:
    """(min, max) with min < max."""
    lo, hi = _array(value, key, (2,))
    if not lo < hi:
        raise ConfigError(key, f"expected (min, max) with min < max, got ({lo}, {hi})")
    return float(lo), float(hi)


def _mapping(value: object, key: str, required: Sequence[str], optional: Sequence[str] = ()) -> Mapping:
    """Check that `value` is a mapping with all `required` keys and nothing unknown."""
    if not isinstance(value, Mapping):
        # The whole document is never quoted: it may be any file, e.g. one of secrets.
        got = _describe(value) if key else _kind(value)
        raise ConfigError(key, f"expected a mapping, got {got}")
    # Unknown keys first: a misspelt required key is then reported as the typo it is.
    known = (*required, *optional)
    unknown = [k for k in value if k not in known]
    if unknown:
        raise ConfigError(
            key,
            f"unknown key {_key_names(unknown)} (expected " + ", ".join(repr(k) for k in known) + ")",
        )
    missing = [k for k in required if k not in value]
    if missing:
        raise ConfigError(key, "missing key " + ", ".join(repr(k) for k in missing))
    return value


_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_.]{0,39}")  # dotted too: randomisation keys ("legs.mass")


def _key_names(keys: Sequence) -> str:
    """Unknown keys for an error message, the first three of them: quoted if they look like
    misspelt names, else only described, for a file that is no config at all may be all keys (a
    line of /etc/shadow is a YAML key)."""
    names = [repr(k) if isinstance(k, str) and _NAME.fullmatch(k) else f"({_kind(k)})" for k in keys[:3]]
    return ", ".join(names) + (f" and {len(keys) - 3} more" if len(keys) > 3 else "")


def _kind(value: object) -> str:
    """What `value` is, without quoting it."""
    if value is None:
        return "None"
    if isinstance(value, str):
        return f"text of {len(value)} characters"
    if _is_sequence(value):
        return f"a {type(value).__name__} of {len(value)} items"
    name = type(value).__name__
    return f"{'an' if name[0] in 'aeiou' else 'a'} {name}"


def _symmetric_eigenvalues(matrix: np.ndarray, key: str) -> np.ndarray:
    """Eigenvalues of an inertia matrix after checking its symmetry relative to its scale."""
    scale = float(np.max(np.abs(matrix)))
    asymmetry = float(np.max(np.abs(matrix - matrix.T)))
    if asymmetry > 1e-12 * scale:
        raise ConfigError(key, f"not symmetric (largest |I - I^T| entry {asymmetry:.3g})")
    return np.linalg.eigvalsh(matrix)


# ----------------------------------------------------------------------------------------------
# Value objects.


class _ValueObject:
    """Equality, hashing and pickling by value for the frozen dataclasses below, whose fields may
    be numpy arrays (the dataclass defaults would compare arrays elementwise)."""

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


def _set(obj: object, name: str, value: object) -> None:
    object.__setattr__(obj, name, value)


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
    """

    mass: float
    com: np.ndarray
    inertia: np.ndarray

    def __post_init__(self) -> None:
        mass = _number(self.mass, "mass")
        if mass < 0:
            raise ConfigError("mass", f"must be >= 0, got {mass}")
        com = _array(self.com, "com", (3,))
        inertia = _array(self.inertia, "inertia", (3, 3), (3,))
        if inertia.shape == (3,):
            inertia = np.diag(inertia)
        eigenvalues = _symmetric_eigenvalues(inertia, "inertia")
        if eigenvalues[0] < -1e-12 * float(np.max(np.abs(eigenvalues))):
            raise ConfigError("inertia",
                              f"not positive semidefinite (eigenvalues {eigenvalues.tolist()})")
        if mass == 0 and np.any(inertia != 0):
            raise ConfigError("inertia", "must be zero for a massless body (mass 0)")
        _set(self, "mass", mass)
        _set(self, "com", _frozen_array(com))
        # Averaging with the transpose removes rounding-level asymmetry; it is exact for a
        # symmetric matrix, so loading is idempotent.
        _set(self, "inertia", _frozen_array(0.5 * (inertia + inertia.T)))

    @classmethod
    def from_dict(cls, d: Mapping) -> RigidBody:
        """From a config mapping {mass, com, inertia}."""
        d = _mapping(d, "", ("mass", "com", "inertia"))
        return cls(mass=d["mass"], com=d["com"], inertia=d["inertia"])

    def to_dict(self) -> dict:
        return {"mass": self.mass, "com": self.com.tolist(), "inertia": self.inertia.tolist()}


@dataclass(frozen=True, eq=False)
class Damping(_ValueObject):
    """Viscous joint friction coefficients (the paper's model).

    Attributes:
        universal: Cu >= 0, N m s/rad: U-joint torque -Cu omega_l on the leg.
        prismatic: Cp >= 0, N s/m: force -Cp dL/dt on the upper leg along e_i.
        spherical: Cs >= 0, N m s/rad: torque -Cs (omega_l - omega) on the leg, the opposite on
            the platform.
    """

    universal: float
    prismatic: float
    spherical: float

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self):
            value = _number(getattr(self, field.name), field.name)
            if value < 0:
                raise ConfigError(field.name, f"must be >= 0, got {value}")
            _set(self, field.name, value)

    @classmethod
    def from_dict(cls, d: Mapping) -> Damping:
        d = _mapping(d, "", ("universal", "prismatic", "spherical"))
        return cls(**d)

    def to_dict(self) -> dict:
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
    """

    leg_length: tuple[float, float]
    leg_force: tuple[float, float]
    position_min: np.ndarray
    position_max: np.ndarray
    max_angle: float
    max_condition: float

    def __post_init__(self) -> None:
        leg_length = _interval(self.leg_length, "leg_length")
        if leg_length[0] <= 0:
            raise ConfigError("leg_length", f"minimum must be > 0, got {leg_length[0]}")
        leg_force = _interval(self.leg_force, "leg_force")
        position_min = _array(self.position_min, "workspace.position_min", (3,))
        position_max = _array(self.position_max, "workspace.position_max", (3,))
        if not np.all(position_min < position_max):
            raise ConfigError(
                "workspace",
                f"position_min {position_min.tolist()} must be below position_max "
                f"{position_max.tolist()} on every axis",
            )
        max_angle = _number(self.max_angle, "workspace.max_angle")
        if not 0 < max_angle <= np.pi:
            raise ConfigError("workspace.max_angle", f"must be in (0, pi], got {max_angle}")
        max_condition = _number(self.max_condition, "max_condition")
        if not max_condition > 1:
            raise ConfigError("max_condition", f"must be > 1, got {max_condition}")
        _set(self, "leg_length", leg_length)
        _set(self, "leg_force", leg_force)
        _set(self, "position_min", _frozen_array(position_min))
        _set(self, "position_max", _frozen_array(position_max))
        _set(self, "max_angle", max_angle)
        _set(self, "max_condition", max_condition)

    def to_dict(self) -> dict:
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


# ----------------------------------------------------------------------------------------------
# Geometry at a pose, as far as validation needs it.


class _Pose(NamedTuple):
    lengths: np.ndarray  # (6,) L_i, m
    jacobian: np.ndarray  # (6, 6) rows [e_i, (R p_i) x e_i]


def _check_pose(base: np.ndarray, plat: np.ndarray, hooke: np.ndarray,
                position: np.ndarray, rpy: np.ndarray) -> _Pose:
    """Leg lengths and Jacobian at a pose, after checking that every leg has a direction and that
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
            raise ConfigError(f"hooke_axes[{i}]",
                              f"parallel to leg {i} at the home pose (angle {angle:.1f} deg)")
    # The Jacobian is the kernels' (one implementation); imported here because the dynamics
    # package imports this module.
    from stewart_env.dynamics import kernels as K

    row = np.zeros((1, K.N_PARAMS))
    for key, value in (("base_joints", base), ("platform_joints", plat), ("hooke_axes", hooke)):
        row[0, K.PACKED_SLICES[key]] = value.ravel()
    jacobian = np.empty((1, 6, 6))
    K.jacobian_batch(row, position[None], rpy_to_matrix(rpy)[None], jacobian)
    return _Pose(lengths=lengths, jacobian=jacobian[0])


# ----------------------------------------------------------------------------------------------
# Fields of PlatformParams.


def _legs(value: object, key: str) -> tuple[RigidBody, ...]:
    """Six leg parts from one shared RigidBody or a sequence of six."""
    if isinstance(value, RigidBody):
        return (value,) * N_LEGS
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, Sequence) \
            or len(value) != N_LEGS:
        raise ConfigError(key, f"expected a RigidBody or a sequence of six, got {_describe(value)}")
    for i, body in enumerate(value):
        if not isinstance(body, RigidBody):
            raise ConfigError(f"{key}[{i}]", f"expected a RigidBody, got {_describe(body)}")
    return tuple(value)


def _legs_from_config(value: object, key: str) -> tuple[RigidBody, ...]:
    """Six leg parts from one shared config mapping or a list of six."""
    if isinstance(value, Mapping):
        with _within(key):
            return (RigidBody.from_dict(value),) * N_LEGS
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence):
        raise ConfigError(key, f"expected one mapping or a list of six, got {_describe(value)}")
    if len(value) != N_LEGS:
        raise ConfigError(key, f"expected one mapping or a list of six, got a list of {len(value)}")
    bodies = []
    for i, item in enumerate(value):
        with _within(f"{key}[{i}]"):
            bodies.append(RigidBody.from_dict(item))
    return tuple(bodies)


def _instance(value: object, cls: type, key: str) -> object:
    if not isinstance(value, cls):
        raise ConfigError(key, f"expected a {cls.__name__}, got {_describe(value)}")
    return value


_TOP_KEYS_REQUIRED = ("base_joints", "platform_joints", "hooke_axes", "platform", "upper_leg",
                      "lower_leg", "damping")
_TOP_KEYS_OPTIONAL = ("gravity", "limits", "home")


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

    Besides each value's own checks, the home pose must be valid: every leg of nonzero length,
    no Hooke axis parallel to its leg, leg lengths inside limits.leg_length, the position inside
    the workspace box and the Jacobian (rows [e_i, (R p_i) x e_i]) conditioned within
    limits.max_condition.
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

    def __post_init__(self) -> None:
        if not isinstance(self.name, str):
            raise ConfigError("name", f"must be a string, got {_describe(self.name)}")
        base = _array(self.base_joints, "base_joints", (N_LEGS, 3))
        plat = _array(self.platform_joints, "platform_joints", (N_LEGS, 3))
        hooke = _unit_rows(_array(self.hooke_axes, "hooke_axes", (N_LEGS, 3), (3,)))
        platform = _instance(self.platform, RigidBody, "platform")
        _check_platform_mass(platform.mass)
        eigenvalues = np.linalg.eigvalsh(platform.inertia)
        if eigenvalues[0] <= 1e-12 * eigenvalues[-1]:
            raise ConfigError("platform.inertia",
                              f"not positive definite (eigenvalues {eigenvalues.tolist()})")
        if eigenvalues[0] < _MIN_PLATFORM_INERTIA:
            raise ConfigError("platform.inertia", f"smallest principal moment {eigenvalues[0]:.3g} is "
                                                  f"below {_MIN_PLATFORM_INERTIA:g} kg m^2")
        upper = _legs(self.upper_leg, "upper_leg")
        lower = _legs(self.lower_leg, "lower_leg")
        _instance(self.damping, Damping, "damping")
        gravity = _array(self.gravity, "gravity", (3,))
        limits = _instance(self.limits, Limits, "limits")
        position = _array(self.home_position, "home.position", (3,))
        rpy = _array(self.home_rpy, "home.rpy", (3,))

        home = _check_pose(base, plat, hooke, position, rpy)
        lo, hi = limits.leg_length
        for i, length in enumerate(home.lengths):
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
        condition = float(np.linalg.cond(home.jacobian))
        if not condition <= limits.max_condition:
            raise ConfigError(
                "limits.max_condition",
                f"the Jacobian's condition number at the home pose is {condition:.4g}, "
                f"above {limits.max_condition}",
            )

        _set(self, "base_joints", _frozen_array(base))
        _set(self, "platform_joints", _frozen_array(plat))
        _set(self, "hooke_axes", _frozen_array(hooke))
        _set(self, "upper_leg", upper)
        _set(self, "lower_leg", lower)
        _set(self, "gravity", _frozen_array(gravity))
        _set(self, "home_position", _frozen_array(position))
        _set(self, "home_rpy", _frozen_array(rpy))

    @classmethod
    def from_dict(cls, d: Mapping, name: str = "custom") -> PlatformParams:
        """Build from a config mapping (schema in the module docstring), filling the documented
        defaults for `gravity`, `home` and `limits`."""
        d = _mapping(d, "", _TOP_KEYS_REQUIRED, _TOP_KEYS_OPTIONAL)
        base = _array(d["base_joints"], "base_joints", (N_LEGS, 3))
        plat = _array(d["platform_joints"], "platform_joints", (N_LEGS, 3))
        hooke = _unit_rows(_array(d["hooke_axes"], "hooke_axes", (N_LEGS, 3), (3,)))
        with _within("platform"):
            body = _mapping(d["platform"], "", ("mass", "com", "inertia"))
        # Checked before RigidBody, which accepts a massless body and would word it ">= 0".
        _check_platform_mass(_number(body["mass"], "platform.mass"))
        with _within("platform"):
            platform = RigidBody.from_dict(body)
        upper = _legs_from_config(d["upper_leg"], "upper_leg")
        lower = _legs_from_config(d["lower_leg"], "lower_leg")
        with _within("damping"):
            damping = Damping.from_dict(d["damping"])
        gravity = _array(d.get("gravity", [0.0, 0.0, -_G0]), "gravity", (3,))

        if "home" in d:
            home = _mapping(d["home"], "home", ("position",), ("rpy",))
            position = _array(home["position"], "home.position", (3,))
            rpy = _array(home.get("rpy", [0.0, 0.0, 0.0]), "home.rpy", (3,))
        else:
            position, rpy = np.zeros(3), np.zeros(3)
        try:
            pose = _check_pose(base, plat, hooke, position, rpy)
        except ConfigError as err:
            if "home" in d:
                raise
            raise ConfigError(
                "",
                "missing key 'home': the default home pose (position [0, 0, 0], rpy [0, 0, 0]) "
                f"is not valid ({err}); give home: {{position: [x, y, z], rpy: [roll, pitch, yaw]}}",
            ) from None

        with _within("limits"):
            limits = _limits_from_config(d.get("limits", {}), pose.lengths, position, gravity,
                                         platform.mass + N_LEGS * _mean_mass(upper, lower))
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
        )

    @classmethod
    def from_yaml(cls, path: str | os.PathLike) -> PlatformParams:
        """Load a YAML config file (a regular *.yaml or *.yml file of at most MAX_CONFIG_BYTES);
        the platform's name is the file stem. Errors are ConfigErrors naming the file."""
        path = Path(path)
        return _from_text(_read_config(path), path.stem, str(path))

    def to_dict(self) -> dict:
        """The config as plain lists and floats (every key written out, defaults included);
        `PlatformParams.from_dict(p.to_dict(), p.name) == p`. Legs that share their parameters
        are written as one mapping."""

        def legs(bodies: tuple[RigidBody, ...]) -> dict | list[dict]:
            if all(body == bodies[0] for body in bodies):
                return bodies[0].to_dict()
            return [body.to_dict() for body in bodies]

        return {
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

    def replace(self, **changes) -> PlatformParams:
        """A copy with some fields changed (dataclass field names), validated again."""
        return dataclasses.replace(self, **changes)


def _check_platform_mass(mass: float) -> None:
    if not mass >= _MIN_PLATFORM_MASS:
        raise ConfigError("platform.mass", f"must be >= {_MIN_PLATFORM_MASS:g} kg, got {mass}")


def _unit_rows(axes: np.ndarray) -> np.ndarray:
    """(6, 3) unit rows from (6, 3) or one shared (3,) row. Rows already unit to 1e-12 are kept as
    given, so that loading a saved config reproduces it bit for bit."""
    axes = np.broadcast_to(axes, (N_LEGS, 3)).copy()
    for i, row in enumerate(axes):
        norm = float(np.linalg.norm(row))
        if norm < 1e-12:
            raise ConfigError(f"hooke_axes[{i}]", "zero vector")
        if abs(norm - 1.0) > 1e-12:
            axes[i] = row / norm
    return axes


def _mean_mass(upper: tuple[RigidBody, ...], lower: tuple[RigidBody, ...]) -> float:
    """Mean mass of one leg (upper + lower part), kg."""
    return float(np.mean([u.mass + d.mass for u, d in zip(upper, lower)]))


def _limits_from_config(value: object, lengths: np.ndarray, position: np.ndarray,
                        gravity: np.ndarray, total_mass: float) -> Limits:
    """Limits from the config's `limits` mapping, each missing entry replaced by its default
    (module docstring), computed from the home leg lengths, home position and the weight."""
    limits = _mapping(value, "", (), ("leg_length", "leg_force", "workspace", "max_condition"))
    workspace = _mapping(limits.get("workspace", {}), "workspace", (),
                         ("position_min", "position_max", "max_angle"))
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
    )


# ----------------------------------------------------------------------------------------------
# Reading config files: every file comes from someone else, so each step is bounded.


def _read_config(path: Path) -> str:
    """The text of a config file, after checking that it is a regular *.yaml/*.yml file of at
    most MAX_CONFIG_BYTES (:func:`stewart_env.files.read_regular`: FIFOs, devices and
    directories are refused before they are read)."""
    source = str(path)
    if path.suffix.lower() not in _CONFIG_SUFFIXES:
        raise ConfigError("", "not a platform config: the file name must end in .yaml or .yml", source)
    try:
        data = read_regular(path, MAX_CONFIG_BYTES, "config file")
    except FileError as err:
        raise ConfigError("", err.problem, source) from None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise ConfigError("", f"not UTF-8 text (invalid byte at offset {err.start})", source) from None


class _ConfigLoader(yaml.SafeLoader):
    """YAML's safe loader, bounded: nesting depth, the number of values after alias expansion
    (a "billion laughs" document of nested aliases is refused before it is built) and the length
    of integer literals; duplicate keys are refused."""

    def __init__(self, stream: str):
        super().__init__(stream)
        self._depth = 0
        self._nodes = 0

    def compose_node(self, parent, index):
        # The composer recurses once per level: bound it before Python's recursion limit. Counting
        # nodes stops a long document early (PyYAML parses about 100 KB/s).
        self._depth += 1
        self._nodes += 1
        try:
            if self._depth > _MAX_YAML_DEPTH:
                raise yaml.composer.ComposerError(None, None, f"nested more than {_MAX_YAML_DEPTH} levels deep",
                                                  self.peek_event().start_mark)
            if self._nodes > _MAX_YAML_VALUES:
                raise yaml.composer.ComposerError(None, None, f"more than {_MAX_YAML_VALUES} values",
                                                  self.peek_event().start_mark)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def construct_document(self, node):
        _check_expansion(node)
        return super().construct_document(node)

    def construct_mapping(self, node, deep=False):
        # PyYAML keeps the last of two equal keys: one of two values would be dropped unseen.
        # Keys brought in by a merge (<<: *anchor) may be overridden, as YAML intends.
        if isinstance(node, yaml.MappingNode):
            seen = set()
            for key_node, _ in node.value:
                if isinstance(key_node, yaml.ScalarNode) and key_node.tag != "tag:yaml.org,2002:merge":
                    if (key_node.tag, key_node.value) in seen:
                        raise yaml.constructor.ConstructorError(
                            "while constructing a mapping", node.start_mark,
                            f"duplicate key {_key_names([key_node.value])}", key_node.start_mark)
                    seen.add((key_node.tag, key_node.value))
        return super().construct_mapping(node, deep)

    def construct_yaml_int(self, node):
        if len(node.value) > _MAX_INT_LITERAL:
            raise yaml.constructor.ConstructorError(
                None, None, f"an integer literal of {len(node.value)} characters", node.start_mark)
        return super().construct_yaml_int(node)


_ConfigLoader.add_constructor("tag:yaml.org,2002:int", _ConfigLoader.construct_yaml_int)


def _children(node: yaml.Node) -> list[yaml.Node]:
    if isinstance(node, yaml.SequenceNode):
        return node.value
    if isinstance(node, yaml.MappingNode):
        return [child for pair in node.value for child in pair]
    return []


def _check_expansion(root: yaml.Node) -> None:
    """Refuse a document that, once its aliases are expanded (an alias repeats its anchor's node
    object), holds more than _MAX_YAML_VALUES values, nests deeper than _MAX_YAML_DEPTH or
    contains itself. Iterative: a chain of aliases can be far deeper than the recursion limit."""
    sizes: dict[int, int] = {}
    depths: dict[int, int] = {}
    started: set[int] = set()
    stack = [(root, False)]
    while stack:
        node, children_done = stack.pop()
        key = id(node)
        if not children_done:
            if key in sizes:
                continue
            if key in started:  # reached again from inside its own expansion
                raise yaml.constructor.ConstructorError(None, None, "an alias refers to its own anchor",
                                                        node.start_mark)
            started.add(key)
            stack.append((node, True))
            stack.extend((child, False) for child in _children(node))
            continue
        children = _children(node)
        sizes[key] = 1 + sum(sizes[id(child)] for child in children)
        depths[key] = 1 + max((depths[id(child)] for child in children), default=0)
        started.discard(key)
        if sizes[key] > _MAX_YAML_VALUES:
            raise yaml.constructor.ConstructorError(
                None, None, f"more than {_MAX_YAML_VALUES} values (after expanding aliases)", node.start_mark)
        if depths[key] > _MAX_YAML_DEPTH:
            raise yaml.constructor.ConstructorError(
                None, None, f"nested more than {_MAX_YAML_DEPTH} levels deep (after expanding aliases)",
                node.start_mark)


def _yaml_problem(err: yaml.YAMLError) -> str:
    """Where and what went wrong, without PyYAML's snippet of the offending line."""
    if isinstance(err, yaml.reader.ReaderError):
        return f"position {err.position + 1}: character #x{err.character:04x} is not allowed"
    if isinstance(err, yaml.MarkedYAMLError):
        mark = err.problem_mark or err.context_mark
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        what = "; ".join(_excerpt(part, 2 * _EXCERPT) for part in (err.context, err.problem) if part)
        return where + what
    return type(err).__name__


def _from_text(text: str, name: str, source: str) -> PlatformParams:
    try:
        config = yaml.load(text, Loader=_ConfigLoader)
    except yaml.YAMLError as err:
        raise ConfigError("", f"not valid YAML: {_yaml_problem(err)}", source) from None
    try:
        return PlatformParams.from_dict(config, name=name)
    except ConfigError as err:
        raise ConfigError(err.key, err.problem, source) from None


# ----------------------------------------------------------------------------------------------
# Shipped configs.


def config_dir(kind: str) -> Path:
    """The directory of shipped configs of one kind, ``platforms`` or ``agents``: in the installed
    `stewart_env.configs` package, or configs/<kind> in the source tree when the package is not
    installed (running from a checkout)."""
    try:
        installed = importlib.resources.files("stewart_env.configs") / kind
    except ModuleNotFoundError:
        installed = None
    if installed is not None and installed.is_dir():
        return Path(str(installed))
    return Path(__file__).resolve().parent.parent / "configs" / kind


def available_platforms() -> list[str]:
    """Names of the shipped platform configs, sorted."""
    directory = config_dir("platforms")
    if not directory.is_dir():
        return []
    return sorted(entry.name.removesuffix(".yaml") for entry in directory.iterdir()
                  if entry.name.endswith(".yaml"))


def _exists(path: Path) -> bool:
    try:
        return path.exists()
    except (OSError, ValueError):  # a name too long for the file system, a NUL character
        return False


def load_platform(name_or_path: str | os.PathLike) -> PlatformParams:
    """Load a platform by name (a shipped config, see `available_platforms`) or from a YAML file.

    A string without a suffix or directory part that is not an existing path is a name, e.g.
    ``"dasgupta1998"``; anything else (``"my.yaml"``, ``"dir/robot"``, a Path) is read as a file,
    which must be a regular *.yaml or *.yml file of at most MAX_CONFIG_BYTES (see
    `PlatformParams.from_yaml`). Every error is a ConfigError naming the file or the key.
    """
    # a bytes path (or a PathLike giving one) is refused too: names and messages are text
    text = os.fspath(name_or_path) if isinstance(name_or_path, (str, os.PathLike)) else None
    if not isinstance(text, str):
        raise ConfigError("", f"expected a platform name or a path, got {_describe(name_or_path)}")
    candidate = Path(text)
    is_name = (isinstance(name_or_path, str) and not candidate.suffix and candidate.name == text
               and not _exists(candidate))
    if not is_name:
        return PlatformParams.from_yaml(candidate)
    if text not in available_platforms():
        available = ", ".join(available_platforms()) or "none"
        raise ConfigError("", f"unknown platform {_describe(text)}; available: {available}")
    resource = config_dir("platforms") / f"{text}.yaml"
    return _from_text(resource.read_text(encoding="utf-8"), text, f"{text}.yaml")
