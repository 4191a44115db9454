"""A vehicle motion: what the person in the vehicle is subjected to, the cueing task's reference.

The motion is given where the person's head is, in the head frame {H}: x forward, y left, z up
(the platform frame's axes at home). Two channels of three components each, sampled uniformly:

- the specific force ``f = a - g`` (m/s²): what an accelerometer at the head reads; a vehicle at
  rest on level ground gives ``(0, 0, +9.81)``;
- the angular velocity ``omega`` (rad/s) of the vehicle, in {H}.

Generators (driving, flight, sweeps) and readers (recorded files) all return this record, and the
cueing task and its baselines take nothing else.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from stewart_env.errors import UsageError

STANDARD_GRAVITY = 9.80665
"""g0 (m/s²), the standard acceleration of gravity (CGPM 1901): the specific force at rest."""


@dataclass(frozen=True)
class VehicleMotion:
    """A vehicle's specific force and angular velocity at the head, sampled every ``dt`` seconds.

    Attributes:
        name: What the motion is (``"double_lane_change"``, a file's stem, ...).
        dt: The sampling period (s), > 0.
        specific_force: (T, 3) float64, ``f = a - g`` in {H} (m/s²).
        angular_velocity: (T, 3) float64, ``omega`` in {H} (rad/s).
        source: Where it came from (a generator and its seed, a file), for reports.
    """

    name: str
    dt: float
    specific_force: np.ndarray
    angular_velocity: np.ndarray
    source: str = ""
    meta: dict = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        """Check the record once: finite, (T, 3) each, the same T >= 2, dt > 0; arrays read-only."""
        if not isinstance(self.dt, (int, float)) or not math.isfinite(self.dt) or self.dt <= 0.0:
            raise UsageError.about("dt", f"must be a finite positive number of seconds, got {self.dt!r}")
        arrays = {}
        for argument in ("specific_force", "angular_velocity"):
            value = np.array(getattr(self, argument), dtype=np.float64, copy=True)
            if value.ndim != 2 or value.shape[1] != 3:
                raise UsageError.about(argument, f"must have shape (T, 3), got {value.shape}")
            if not np.isfinite(value).all():
                row = int(np.argwhere(~np.isfinite(value))[0][0])
                raise UsageError.about(argument, f"has a non-finite value at sample {row}")
            value.setflags(write=False)
            arrays[argument] = value
        n_f, n_w = len(arrays["specific_force"]), len(arrays["angular_velocity"])
        if n_f != n_w:
            raise UsageError.about("angular_velocity", f"specific_force has {n_f} samples and angular_velocity {n_w}")
        if n_f < 2:
            raise UsageError.about("specific_force", f"a motion needs at least 2 samples, got {n_f}")
        object.__setattr__(self, "dt", float(self.dt))
        for argument, value in arrays.items():
            object.__setattr__(self, argument, value)

    @property
    def n_samples(self) -> int:
        """T, the number of samples."""
        return len(self.specific_force)

    @property
    def duration(self) -> float:
        """(T - 1) dt (s)."""
        return (self.n_samples - 1) * self.dt

    @property
    def time(self) -> np.ndarray:
        """(T,) the sample times (s), from 0."""
        return np.arange(self.n_samples) * self.dt
