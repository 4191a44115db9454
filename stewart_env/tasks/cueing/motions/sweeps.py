"""Per-channel logarithmic sine sweeps: the test signals of the whole chain's gain and phase.

Each sweep moves one channel (a specific-force component or an angular-velocity component) and
holds the others at rest (``f = (0, 0, g0)``, ``omega = 0``): a test signal, not a vehicle's
motion (a roll sweep does not tilt gravity into y).  The frequency rises logarithmically from
:data:`SWEEP_START_HZ` to :data:`SWEEP_END_HZ` over :data:`SWEEP_DURATION` seconds
(``phase(t) = 2 pi f0 T / ln(f1 / f0) (exp(t ln(f1 / f0) / T) - 1)``), the frequencies of the
objective motion cueing test (0.1 to 15.8 rad/s) inside the range; the amplitude fades in and out
over the first and last second.  The seed draws the amplitude, U(0.75, 1.25) times the nominal
amplitude (:data:`SWEEP_AMPLITUDE`), and nothing else.
"""

from __future__ import annotations

import math

import numpy as np

from stewart_env.tasks.cueing.motion import VehicleMotion
from stewart_env.tasks.cueing.motions.kinematics import motion, motion_rng, rest, smoothstep, uniform

__all__ = [
    "SWEEP_AMPLITUDE",
    "SWEEP_CHANNELS",
    "SWEEP_DURATION",
    "SWEEP_END_HZ",
    "SWEEP_START_HZ",
    "sweep",
    "sweep_frequency",
]

#: The channels, by motion name: (the channel, "f" or "omega"; the component, 0..2).
SWEEP_CHANNELS = {
    "sweep_x": ("f", 0),
    "sweep_y": ("f", 1),
    "sweep_z": ("f", 2),
    "sweep_roll": ("omega", 0),
    "sweep_pitch": ("omega", 1),
    "sweep_yaw": ("omega", 2),
}
#: The nominal amplitudes: of the specific force (m/s²) and of the angular velocity (rad/s).
SWEEP_AMPLITUDE = {"f": 1.0, "omega": 0.1}
#: The sweep's first and last frequencies (Hz) and its duration (s).
SWEEP_START_HZ, SWEEP_END_HZ, SWEEP_DURATION = 0.015, 2.6, 120.0


def sweep_frequency(t: np.ndarray) -> np.ndarray:
    """The sweep's instantaneous frequency at the times ``t``, Hz.

    Args:
        t: (T,) times, s.

    Returns:
        (T,) ``f0 (f1 / f0)^(t / T)``.
    """
    return SWEEP_START_HZ * (SWEEP_END_HZ / SWEEP_START_HZ) ** (np.asarray(t, dtype=float) / SWEEP_DURATION)


def sweep(name: str, seed: int, dt: float = 0.01) -> VehicleMotion:
    """The sweep of one channel (see the module's docstring).

    Args:
        name: a key of :data:`SWEEP_CHANNELS`.
        seed: the seed (draws the amplitude).
        dt: the sampling period, s.

    Returns:
        The sweep.
    """
    channel, axis = SWEEP_CHANNELS[name]
    rng = motion_rng(name, seed)
    amplitude = SWEEP_AMPLITUDE[channel] * uniform(rng, 0.75, 1.25)
    t = np.arange(int(round(SWEEP_DURATION / dt)) + 1) * dt
    rate = math.log(SWEEP_END_HZ / SWEEP_START_HZ) / SWEEP_DURATION
    phase = 2.0 * math.pi * SWEEP_START_HZ / rate * (np.exp(rate * t) - 1.0)
    envelope = smoothstep(t, 0.0, 1.0) * (1.0 - smoothstep(t, SWEEP_DURATION - 1.0, 1.0))
    force, omega = rest(len(t))
    (force if channel == "f" else omega)[:, axis] += amplitude * envelope * np.sin(phase)
    return motion(name, seed, dt, force, omega, amplitude=amplitude, channel=channel, axis=axis)
