"""The vehicle motions of the cueing task: built-in generators, seeded, and the motion file.

:func:`make_motion` draws a motion by name and seed (:data:`MOTIONS` lists the generators):
driving manoeuvres of a single-track car model (:mod:`.driving`), flight manoeuvres
(:mod:`.flight`) and per-channel sine sweeps (:mod:`.sweeps`).  Training draws seeds below
:data:`TRAINING_SEED_BOUND` (2**30); :data:`EVALUATION_SEEDS` lie at or above it, so no training
episode ever sees an evaluation motion.  :func:`read_motion` and :func:`write_motion` read and
write a user's recorded motion in the documented CSV format (:mod:`.motion_file`,
docs/guides/motion-format.md); :mod:`.jsbsim_reference` flies JSBSim's aircraft for flight
references (the extra ``jsbsim``).
"""

from __future__ import annotations

import functools
import math
import numbers
from collections.abc import Callable

from stewart_env.errors import UsageError
from stewart_env.tasks.cueing.motion import VehicleMotion
from stewart_env.tasks.cueing.motions import driving, flight
from stewart_env.tasks.cueing.motions.motion_file import MotionFileError, read_motion, write_motion
from stewart_env.tasks.cueing.motions.sweeps import SWEEP_CHANNELS, sweep

__all__ = [
    "EVALUATION_MOTIONS",
    "EVALUATION_SEEDS",
    "MOTIONS",
    "TRAINING_MOTIONS",
    "TRAINING_SEED_BOUND",
    "MotionFileError",
    "make_motion",
    "read_motion",
    "write_motion",
]

#: Every generator by name: ``generator(seed, dt) -> VehicleMotion``.
MOTIONS: dict[str, Callable[[int, float], VehicleMotion]] = {
    "double_lane_change": driving.double_lane_change,
    "braking": driving.braking,
    "acceleration": driving.acceleration,
    "slalom": driving.slalom,
    "coordinated_turn": flight.coordinated_turn,
    "takeoff_roll": flight.takeoff_roll,
    "turbulence": flight.turbulence,
    **{name: functools.partial(sweep, name) for name in SWEEP_CHANNELS},
}
#: The vehicle manoeuvres a cueing agent or a washout's tuning trains on (seeds < 2**30).
TRAINING_MOTIONS: tuple[str, ...] = tuple(name for name in MOTIONS if name not in SWEEP_CHANNELS)
#: The motions an evaluation scores (at :data:`EVALUATION_SEEDS`): the manoeuvres and the sweeps
#: (test signals of the gain and phase table, never trained on).
EVALUATION_MOTIONS: tuple[str, ...] = tuple(MOTIONS)
#: Training draws its seeds from [0, 2**30).
TRAINING_SEED_BOUND = 2**30
#: The held-out seeds of evaluation, all >= :data:`TRAINING_SEED_BOUND`.
EVALUATION_SEEDS: tuple[int, ...] = tuple(TRAINING_SEED_BOUND + k for k in range(10))
#: The largest seed (NumPy's seed sequences take any non-negative integer; 2**63 keeps it an int64).
_MAX_SEED = 2**63 - 1


def make_motion(name: str, seed: int, dt: float = 0.01) -> VehicleMotion:
    """The motion ``name`` drawn with ``seed``, sampled every ``dt`` seconds.

    The same name, seed and dt always give the same motion, bit for bit.

    Args:
        name: a key of :data:`MOTIONS`.
        seed: an integer in [0, 2**63); training seeds are below 2**30, :data:`EVALUATION_SEEDS`
            at or above.
        dt: the sampling period, s, in (0, 0.1].

    Returns:
        The motion at the person's head, in the head frame {H}.

    Raises:
        UsageError: an unknown name, a seed or dt out of range (the message names the argument).
    """
    if not isinstance(name, str) or name not in MOTIONS:
        raise UsageError.about("name", f"unknown motion {name!r}; the motions are {', '.join(MOTIONS)}")
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or not 0 <= int(seed) <= _MAX_SEED:
        raise UsageError.about("seed", f"must be an integer in [0, 2**63), got {seed!r}")
    if isinstance(dt, bool) or not isinstance(dt, numbers.Real) or not math.isfinite(dt) or not 0.0 < dt <= 0.1:
        raise UsageError.about("dt", f"must be a number of seconds in (0, 0.1], got {dt!r}")
    return MOTIONS[name](int(seed), float(dt))
