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

from collections.abc import Mapping

import numpy as np

from stewart_env.params import ConfigError, Damping, PlatformParams, RigidBody, _is_sequence, _key_names, _number, _short

__all__ = ["KEYS", "Randomization"]

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
    if not _is_sequence(value) or getattr(value, "ndim", 1) != 1 or len(value) != 2:
        raise ConfigError(name, f"expected (low, high), got {_short(value)}")
    low, high = (_number(v, f"{name}[{i}]") for i, v in enumerate(value))
    if not low <= high:
        raise ConfigError(name, f"expected low <= high, got ({low}, {high})")
    lowest, highest, wording = _bounds(key)
    if low < lowest or high > highest:
        raise ConfigError(name, f"factors must be {wording}, got ({low}, {high})")
    return low, high


class Randomization:
    """A validated randomisation spec (see the module docstring).

    ``sample(rng)`` draws the factors of one episode; ``apply(params, factors)`` builds that
    episode's :class:`~stewart_env.params.PlatformParams` with ``params.replace``.
    """

    def __init__(self, spec: Mapping[str, tuple[float, float]]):
        if not isinstance(spec, Mapping):
            raise ConfigError("randomization", f"expected a dict of key -> (low, high), got {_short(spec)}")
        unknown = [k for k in spec if k not in KEYS]
        if unknown:
            raise ConfigError("randomization", f"unknown key(s) {_key_names(unknown)}; valid keys: {', '.join(KEYS)}")
        self.ranges: dict[str, tuple[float, float]] = {key: _range(spec[key], key) for key in KEYS if key in spec}

    def __bool__(self) -> bool:
        return bool(self.ranges)

    def __repr__(self) -> str:
        return f"Randomization({self.ranges})"

    def sample(self, rng: np.random.Generator) -> dict[str, float]:
        """One factor per key, uniform in its range, drawn in the order of KEYS."""
        return {key: float(rng.uniform(low, high)) for key, (low, high) in self.ranges.items()}

    def apply(self, params: PlatformParams, factors: Mapping[str, float]) -> PlatformParams:
        """``params`` with every parameter multiplied by the product of its keys' factors."""

        def factor(*keys: str) -> float:
            f = 1.0
            for k in keys:
                f *= factors.get(k, 1.0)
            return f

        def body(b: RigidBody, name: str) -> RigidBody:
            group = ("legs",) if name != "platform" else ()
            keys = {q: [f"{name}.{q}", *(f"{g}.{q}" for g in group), q] for q in _QUANTITIES}
            return RigidBody(mass=b.mass * factor(*keys["mass"]), com=b.com * factor(*keys["com"]),
                             inertia=b.inertia * factor(*keys["inertia"]))

        def legs(bodies: tuple[RigidBody, ...], name: str) -> tuple[RigidBody, ...]:
            # Legs that share one RigidBody keep sharing it (and it is validated once).
            scaled: dict[int, RigidBody] = {}
            for b in bodies:
                if id(b) not in scaled:
                    scaled[id(b)] = body(b, name)
            return tuple(scaled[id(b)] for b in bodies)

        d = params.damping
        damping = Damping(**{n: getattr(d, n) * factor("damping", f"damping.{n}") for n in _DAMPING})
        return params.replace(
            platform=body(params.platform, "platform"),
            upper_leg=legs(params.upper_leg, "upper_leg"),
            lower_leg=legs(params.lower_leg, "lower_leg"),
            damping=damping,
        )
