"""The two records every layer passes around: a platform's state and a reference to follow.

Both hold arrays for one platform, or for a batch with a leading dimension N.
"""

from typing import NamedTuple

import numpy as np


class PlatformState(NamedTuple):
    """The platform's state in {B}: position (3,) m of P's origin, rotation (3,3) (columns = {P}
    axes), velocity (3,) m/s of P's origin, angular_velocity (3,) rad/s; (N, ...) for a batch."""

    position: np.ndarray
    rotation: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray


class Reference(NamedTuple):
    """A task's reference (target) pose and twist in {B}; fields, shapes and units as in
    :class:`PlatformState` (velocities zero for a set point)."""

    position: np.ndarray
    rotation: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray
