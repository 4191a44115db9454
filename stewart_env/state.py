"""The two records every layer passes around: a platform's state and a reference to follow.

Both hold arrays for one platform, or for a batch with a leading dimension N.
"""

from typing import NamedTuple

import numpy as np


class PlatformState(NamedTuple):
    """The platform's state in {B}; (N, ...) for a batch.

    Attributes:
        position: (3,) position of P's origin, m.
        rotation: (3,3) rotation matrix, columns = {P} axes.
        velocity: (3,) velocity of P's origin, m/s.
        angular_velocity: (3,) angular velocity, rad/s.
    """

    position: np.ndarray
    rotation: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray


class _ReferenceFields(NamedTuple):
    position: np.ndarray
    rotation: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray
    lin_acc: np.ndarray
    ang_acc: np.ndarray


class Reference(_ReferenceFields):
    """A reference (target) motion in {B}: a pose, its twist and its accelerations.

    The accelerations may be left out: ``Reference(p, R, v, w)`` has zero accelerations, new
    arrays shaped like ``velocity`` (so a buffer a task fills in place can be made that way too).

    Attributes:
        position: (3,) or (N,3) position of P's origin, m, as in :class:`PlatformState`.
        rotation: (3,3) or (N,3,3) rotation matrix, columns = {P} axes.
        velocity: (3,) or (N,3) velocity of P's origin, m/s (zero for a set point).
        angular_velocity: (3,) or (N,3) angular velocity, rad/s (zero for a set point).
        lin_acc: (3,) or (N,3) acceleration of P's origin, m/s^2 (the feedforward of computed
            torque).
        ang_acc: (3,) or (N,3) angular acceleration, rad/s^2.
    """

    __slots__ = ()

    def __new__(cls, position, rotation, velocity, angular_velocity, lin_acc=None, ang_acc=None):
        """The reference; the accelerations left out are zero, of the shape of ``velocity``."""
        return super().__new__(
            cls,
            position,
            rotation,
            velocity,
            angular_velocity,
            np.zeros(np.shape(velocity)) if lin_acc is None else lin_acc,
            np.zeros(np.shape(velocity)) if ang_acc is None else ang_acc,
        )
