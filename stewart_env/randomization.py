"""Domain randomisation: per-episode scale factors on the platform's inertial and friction parameters.

A spec is a dict from a key to a (low, high) range; every episode draws one factor per key,
uniformly in its range, and multiplies the matching parameters of the nominal platform by it:

====================  ==========================================================================
key                   scales
====================  ==========================================================================
platform.mass         platform mass m_p
platform.inertia      platform inertia (the whole 3x3 matrix)
platform.com          platform CoM offset R0 (the vector, in {P})
upper_leg.mass        the six upper-leg masses (one factor for all six); likewise
upper_leg.inertia,    upper_leg.inertia and upper_leg.com (r_u0)
upper_leg.com
lower_leg.mass, ...   the same for the lower legs
legs.mass, ...        upper and lower legs together (one factor)
mass, inertia, com    every body: platform, upper and lower legs
damping               the three joint damping coefficients Cu, Cp, Cs
damping.universal,    one coefficient
damping.prismatic,
damping.spherical
====================  ==========================================================================

Keys that cover the same parameter multiply (``{"mass": (0.9, 1.1), "platform.mass": (0.5, 2)}``
draws two factors and scales m_p by their product).  A mass factor does not scale the inertia:
randomise ``inertia`` too for a body that gets heavier in proportion.  Ranges are pairs of finite
numbers, low <= high: mass and inertia factors in [1e-3, 1e3], damping factors in [0, 1e3] (0 turns
the friction off), CoM factors in [-1e3, 1e3] (a negative one mirrors the CoM).  An invalid spec
raises :class:`~stewart_env.params.ConfigError` (a ``ValueError``) naming the key.  Factors are
drawn in the order of :data:`KEYS`, whatever the order of the dict, so a seed gives the same episode.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from stewart_env import _core
from stewart_env.dynamics import kernels as K
from stewart_env.params import ConfigError, Damping, PlatformParams, RigidBody
from stewart_env.params.checks import MAX_MAGNITUDE, is_sequence, key_names, number, short
from stewart_env.params.platform import MIN_PLATFORM_INERTIA, MIN_PLATFORM_MASS

__all__ = ["KEYS", "Randomization", "ScaledRows", "draw_unit_rows"]

_BODIES = ("platform", "upper_leg", "lower_leg")
_QUANTITIES = ("mass", "inertia", "com")
_DAMPING = ("universal", "prismatic", "spherical")

#: Every valid key, in the order factors are drawn.
KEYS: tuple[str, ...] = (
    *(f"{body}.{q}" for body in (*_BODIES, "legs") for q in _QUANTITIES),
    *_QUANTITIES,
    "damping",
    *(f"damping.{d}" for d in _DAMPING),
)


# Factors beyond a thousandfold change describe another machine, not an uncertain one; the bounds
# also keep the product of the (up to three) factors on one parameter far from overflow.
_MAX_FACTOR = 1e3
_MIN_POSITIVE_FACTOR = 1e-3


def _bounds(key: str) -> tuple[float, float, str]:
    """(lowest, highest, wording) of the factors of ``key``."""
    if key.startswith("damping"):
        return 0.0, _MAX_FACTOR, f">= 0 and <= {_MAX_FACTOR:g}"
    if key.endswith("com"):
        return -_MAX_FACTOR, _MAX_FACTOR, f"within [{-_MAX_FACTOR:g}, {_MAX_FACTOR:g}]"
    return _MIN_POSITIVE_FACTOR, _MAX_FACTOR, f"> 0 and within [{_MIN_POSITIVE_FACTOR:g}, {_MAX_FACTOR:g}]"


def _range(value: object, key: str) -> tuple[float, float]:
    """A checked (low, high) range of the factors of ``key``."""
    name = f"randomization[{key!r}]"
    if not is_sequence(value) or getattr(value, "ndim", 1) != 1 or len(value) != 2:
        raise ConfigError(name, f"expected (low, high), got {short(value)}")
    low, high = (number(v, f"{name}[{i}]") for i, v in enumerate(value))
    if not low <= high:
        raise ConfigError(name, f"expected low <= high, got ({low}, {high})")
    lowest, highest, wording = _bounds(key)
    if low < lowest or high > highest:
        raise ConfigError(name, f"factors must be {wording}, got ({low}, {high})")
    return low, high


def draw_unit_rows(rngs: Sequence[np.random.Generator], out: np.ndarray) -> None:
    """Row j of ``out`` the numbers ``rngs[j].random(k)`` draws, bit for bit, in one compiled call.

    A numpy Generator's ``random()`` is its bit generator's ``next_double``, so the compiled call
    draws each row through the bit generator's capsule, holding the generator's lock, as
    ``Generator.random`` does (``_core.draw_uniform_rows``); rows whose generator it does not know
    (not a ``numpy.random.Generator``, or without the capsule) draw through ``random(out=...)``.
    The generators may be of any numpy bit generator; each row's must be its own (a generator
    shared by rows draws their rows one after the other, as row by row calls would).

    Args:
        rngs: one generator per row of ``out``.
        out: (m, k) float64, C-contiguous, overwritten.
    """
    rngs = rngs if type(rngs) is list else list(rngs)
    drawn = _core.draw_uniform_rows(rngs, np.random.Generator, out)
    for rng, row in zip(rngs[drawn:], out[drawn:]):
        rng.random(out=row)


class Randomization:
    """A validated randomisation spec (see the module docstring).

    ``sample(rng)`` draws the factors of one episode; ``apply(params, factors)`` builds that
    episode's :class:`~stewart_env.params.PlatformParams` with ``params.replace``, and
    ``scale_packed(nominal_row, factors, out_row)`` writes the same parameters packed for the
    kernels (``kernels.PACKED_LAYOUT``) without building them, so a randomised reset does not
    pay for validating a new PlatformParams.

    Args:
        spec: a dict from a key of :data:`KEYS` to a (low, high) range of its factors.

    Raises:
        ConfigError: an unknown key or an invalid range (the message names the key).

    Examples:
        >>> import numpy as np, stewart_env as se
        >>> from stewart_env.randomization import Randomization
        >>> spec = Randomization({"platform.mass": (0.8, 1.2)})
        >>> factors = spec.sample(np.random.default_rng(0))
        >>> params = se.load_platform("dasgupta1998")
        >>> heavier = spec.apply(params, factors)
        >>> bool(heavier.platform.mass == params.platform.mass * factors["platform.mass"])
        True
    """

    def __init__(self, spec: Mapping[str, tuple[float, float]]):
        if not isinstance(spec, Mapping):
            raise ConfigError("randomization", f"expected a dict of key -> (low, high), got {short(spec)}")
        unknown = [k for k in spec if k not in KEYS]
        if unknown:
            raise ConfigError("randomization", f"unknown key(s) {key_names(unknown)}; valid keys: {', '.join(KEYS)}")
        self.ranges: dict[str, tuple[float, float]] = {key: _range(spec[key], key) for key in KEYS if key in spec}
        self._moment_cache: tuple[bytes, float] | None = None

    def __bool__(self) -> bool:
        return bool(self.ranges)

    def __repr__(self) -> str:
        return f"Randomization({self.ranges})"

    def sample(self, rng: np.random.Generator) -> dict[str, float]:
        """One factor per key, uniform in its range, drawn in the order of KEYS.

        Args:
            rng: the generator to draw from (the environment's ``np_random``).

        Returns:
            A dict from each key of the spec to its factor.
        """
        return {key: float(rng.uniform(low, high)) for key, (low, high) in self.ranges.items()}

    def sample_rows(self, rngs: Sequence[np.random.Generator]) -> np.ndarray:
        """:meth:`sample` for many rows at once: the same numbers, row j from ``rngs[j]``.

        ``uniform(low, high)`` is ``low + (high - low) * random()`` of the same draw, so one
        ``random(k)`` call per row gives the k factors of :meth:`sample` bit for bit, in the order
        of KEYS; the scaling is done for all rows at once.

        Args:
            rngs: one generator per row.

        Returns:
            (m, k) float64, row j the factors of row j in the order of ``self.ranges``.
        """
        unit = np.empty((len(rngs), len(self.ranges)))
        draw_unit_rows(rngs, unit)
        return self.factors_of(unit)

    def factors_of(self, unit: np.ndarray) -> np.ndarray:
        """The factors of rows whose ``random()`` draws are ``unit``: ``low + (high - low) * u``
        per key, the numbers :meth:`sample` draws from the same generator state (a caller that
        draws more from each row than the factors takes them in one call and hands these here).

        Args:
            unit: (m, k) draws of ``random()`` in [0, 1), column c for the c-th key of ``self.ranges``.

        Returns:
            (m, k) float64, the factors in the order of ``self.ranges``.
        """
        _, lows, highs = self._row_tables()
        return lows + (highs - lows) * unit

    def scale_packed_rows(self, nominal_row: np.ndarray, factors: np.ndarray, out: np.ndarray) -> None:
        """:meth:`scale_packed` for many rows at once: bit for bit the same packed rows.

        Args:
            nominal_row: ``pack_params(params)`` (N_PARAMS,) of a valid PlatformParams.
            factors: (m, k) factors in the order of ``self.ranges`` (what :meth:`sample_rows` draws).
            out: (m, N_PARAMS) float64, overwritten.

        Raises:
            ConfigError: as :meth:`scale_packed`, for the first row it refuses.
        """
        m = factors.shape[0]
        columns, lows, highs = self._row_tables()
        factors = np.ascontiguousarray(factors, dtype=np.float64)
        ok = np.empty(m, dtype=bool)
        direct = out.flags.c_contiguous and out.dtype == np.float64
        rows = out if direct else np.empty((m, K.N_PARAMS))
        # the multipliers of _multipliers, the packed rows and the checks of every row in one compiled pass
        _core.scale_randomized_rows(
            nominal_row,
            factors,
            _PART_OF,
            columns,
            lows,
            highs,
            K.OFF_MP,
            MIN_PLATFORM_MASS,
            MAX_MAGNITUDE,
            _INERTIA_PART,
            self._smallest_moment(nominal_row),
            MIN_PLATFORM_INERTIA,
            rows,
            ok,
        )
        if not direct:
            out[...] = rows
        if ok.all():
            return
        for j in np.flatnonzero(~ok):
            # the row by row check raises the error that names the parameter
            self.scale_packed(nominal_row, dict(zip(self.ranges, factors[j].tolist())), out[j])

    def _row_tables(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What :meth:`scale_packed_rows` looks up for every batch, made once per spec: each part's
        factor columns in the order multiplied, (len(_PARTS), keys) with -1 past a part's last, and
        the ranges' lows and highs (k,)."""
        key = tuple(self.ranges.items())
        cached = self.__dict__.get("_scale_tables_cache")
        if cached is None or cached[0] != key:
            column = {name: c for c, name in enumerate(self.ranges)}
            columns = np.full((len(_PARTS), max(len(keys) for _, _, keys in _PARTS)), -1, dtype=np.int64)
            for p, (_, _, keys) in enumerate(_PARTS):
                used = [column[name] for name in keys if name in column]
                columns[p, : len(used)] = used
            lows, highs = (np.array([r[i] for r in self.ranges.values()], dtype=np.float64) for i in (0, 1))
            cached = self._scale_tables_cache = (key, (columns, lows, highs))
        return cached[1]

    def rows_params(self, params: PlatformParams, factors: np.ndarray) -> ScaledRows:
        """The PlatformParams of rows drawn together, each built only when asked for.

        Args:
            params: the nominal platform.
            factors: (m, k) the rows' factors in the order of ``self.ranges`` (what
                :meth:`sample_rows` draws), kept as given.

        Returns:
            A :class:`ScaledRows`, ``rows(j)`` the :meth:`apply` of row j's factors: the source of
            the rows' parameters that :meth:`stewart_env.dynamics.Dynamics.set_packed_rows` takes.
        """
        return ScaledRows(self, params, factors)

    def apply(self, params: PlatformParams, factors: Mapping[str, float]) -> PlatformParams:
        """``params`` with every parameter multiplied by the product of its keys' factors.

        Args:
            params: the nominal platform.
            factors: a factor per key of the spec (what :meth:`sample` draws).

        Returns:
            The episode's :class:`~stewart_env.params.PlatformParams`.

        Raises:
            ConfigError: factors that :meth:`check_factors` refuses.
        """
        scale = dict(zip(_PART_NAMES, _multipliers(factors)))

        def body(b: RigidBody, name: str) -> RigidBody:
            return RigidBody(
                mass=b.mass * scale[f"{name}.mass"],
                com=b.com * scale[f"{name}.com"],
                inertia=b.inertia * scale[f"{name}.inertia"],
            )

        def legs(bodies: tuple[RigidBody, ...], name: str) -> tuple[RigidBody, ...]:
            # Legs that share one RigidBody keep sharing it (and it is validated once).
            scaled: dict[int, RigidBody] = {}
            for b in bodies:
                if id(b) not in scaled:
                    scaled[id(b)] = body(b, name)
            return tuple(scaled[id(b)] for b in bodies)

        d = params.damping
        damping = Damping(**{n: getattr(d, n) * scale[f"damping.{n}"] for n in _DAMPING})
        return params.replace(
            platform=body(params.platform, "platform"),
            upper_leg=legs(params.upper_leg, "upper_leg"),
            lower_leg=legs(params.lower_leg, "lower_leg"),
            damping=damping,
        )

    def check_factors(self, factors: Mapping[str, float]) -> None:
        """Check factors against the spec.

        Args:
            factors: a factor per key of the spec.

        Raises:
            ConfigError: a key not of this spec, or a factor that is not a number within its range
                (what :meth:`sample` draws); the message names the key.
        """
        if not isinstance(factors, Mapping):
            raise ConfigError("factors", f"expected a dict of key -> factor, got {short(factors)}")
        for key, f in factors.items():
            if key not in self.ranges:
                raise ConfigError("factors", f"key {key!r} is not in the randomisation spec ({', '.join(self.ranges)})")
            low, high = self.ranges[key]
            if isinstance(f, bool) or not (isinstance(f, (float, int, np.floating, np.integer)) and low <= f <= high):
                raise ConfigError(f"factors[{key!r}]", f"expected a number within [{low}, {high}], got {short(f)}")

    def scale_packed(self, nominal_row: np.ndarray, factors: Mapping[str, float], out_row: np.ndarray) -> None:
        """Write the packed parameters of ``apply(params, factors)`` without building PlatformParams:
        the reset of a randomised row.

        Equal bit for bit to ``pack_params(self.apply(params, factors))``.  The factors are checked
        against the spec (:meth:`check_factors`).  Scaling a valid platform by factors in range changes
        only what the checks of PlatformParams on masses and inertias see, so only those run again, on
        the scaled numbers: the platform's mass and smallest principal moment (the nominal's times the
        inertia factor), and every number's magnitude.

        Args:
            nominal_row: ``pack_params(params)`` (N_PARAMS,); the caller promises it is the packed
                row of a valid PlatformParams (e.g. a model's ``packed[0]``).
            factors: a factor per key of the spec.
            out_row: (N_PARAMS,) float64, overwritten.

        Raises:
            ConfigError: factors out of the spec, or a scaled parameter PlatformParams would refuse
                (the message names it, as :meth:`apply` would).
        """
        for name, row in (("nominal_row", nominal_row), ("out_row", out_row)):
            if not (isinstance(row, np.ndarray) and row.dtype == np.float64 and row.shape == (K.N_PARAMS,)):
                raise ValueError(f"{name}: expected a float64 array of shape ({K.N_PARAMS},), got {short(row)}")
        if not out_row.flags.writeable:
            raise ValueError("out_row: read-only; pass a writeable array (a model's packed rows are read-only)")
        self.check_factors(factors)
        multipliers = _multipliers(factors)
        np.multiply(nominal_row, np.array([1.0, *multipliers])[_PART_OF], out=out_row)
        mass = out_row[K.OFF_MP]
        if not mass >= MIN_PLATFORM_MASS:
            raise ConfigError("platform.mass", f"must be >= {MIN_PLATFORM_MASS:g} kg, got {mass}")
        if np.abs(out_row).max() > MAX_MAGNITUDE:  # only scaled entries can grow
            key = next(name for name, part, _ in _PARTS if np.abs(out_row[part]).max() > MAX_MAGNITUDE)
            raise ConfigError(key, f"a randomised value exceeds {MAX_MAGNITUDE:g} in magnitude")
        # a positive factor scales every principal moment alike
        smallest = multipliers[_PART_NAMES.index("platform.inertia")] * self._smallest_moment(nominal_row)
        if smallest < MIN_PLATFORM_INERTIA:
            raise ConfigError(
                "platform.inertia", f"smallest principal moment {smallest:.3g} is below {MIN_PLATFORM_INERTIA:g} kg m^2"
            )

    def _smallest_moment(self, nominal_row: np.ndarray) -> float:
        """The smallest principal moment of the platform inertia in ``nominal_row``, kept for the
        last nominal seen: a randomised batch scales one nominal row again and again."""
        inertia = nominal_row[K.PACKED_SLICES["platform.inertia"]]
        key = inertia.tobytes()
        if self._moment_cache is None or self._moment_cache[0] != key:
            self._moment_cache = (key, float(np.linalg.eigvalsh(inertia.reshape(3, 3))[0]))
        return self._moment_cache[1]


class ScaledRows:
    """The PlatformParams of m rows scaled by their factors (:meth:`Randomization.rows_params`):
    calling it with j builds row j's, ``spec.apply(params, factors of row j)``.

    Args:
        spec: the randomisation spec.
        params: the nominal platform.
        factors: (m, k) the rows' factors in the order of ``spec.ranges``.
    """

    def __init__(self, spec: Randomization, params: PlatformParams, factors: np.ndarray):
        self.spec, self.params, self.factors = spec, params, factors

    def __call__(self, j: int) -> PlatformParams:
        """Row j's PlatformParams.

        Args:
            j: the row's index among the m rows.
        """
        return self.spec.apply(self.params, dict(zip(self.spec.ranges, self.factors[j].tolist())))


def _parts() -> tuple[tuple[str, slice, tuple[str, ...]], ...]:
    """The randomised parts of the packed row (``kernels.PACKED_LAYOUT``): (parameter name, its
    slice of the row, the keys whose factors multiply it, in the order they are multiplied)."""
    parts = []
    for name in _BODIES:
        group = ("legs",) if name != "platform" else ()
        for q in _QUANTITIES:
            parts.append(
                (f"{name}.{q}", K.PACKED_SLICES[f"{name}.{q}"], (f"{name}.{q}", *(f"{g}.{q}" for g in group), q))
            )
    for j, coefficient in enumerate(_DAMPING):
        start = K.OFF_DAMP + j
        parts.append((f"damping.{coefficient}", slice(start, start + 1), ("damping", f"damping.{coefficient}")))
    return tuple(parts)


_PARTS = _parts()
_PART_NAMES = [name for name, _, _ in _PARTS]
#: The part of the platform's inertia, whose multiplier scales its smallest principal moment.
_INERTIA_PART = _PART_NAMES.index("platform.inertia")


def _part_of() -> np.ndarray:
    """For each number of the packed row, 1 + the index of its part in ``_PARTS``, or 0 where
    nothing is randomised (the multiplier 1)."""
    index = np.zeros(K.N_PARAMS, dtype=np.int64)
    for k, (_, part, _) in enumerate(_PARTS):
        index[part] = k + 1
    return index


_PART_OF = _part_of()


def _multipliers(factors: Mapping[str, float]) -> list[float]:
    """The multiplier of each part of ``_PARTS``: the product of the factors of every key that
    covers it, multiplied in one order (body key, leg group, quantity), so that
    :meth:`Randomization.apply` and :meth:`Randomization.scale_packed` give the same numbers."""
    out = []
    for _, _, keys in _PARTS:
        f = 1.0
        for k in keys:
            f *= factors.get(k, 1.0)
        out.append(f)
    return out
