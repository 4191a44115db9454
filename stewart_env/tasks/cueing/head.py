"""What a person on the platform is subjected to: the specific force and angular velocity at the head.

The head sits at a point fixed in the platform, ``head`` (m, in {P}). Its frame {H} is the base
frame's axes (x forward, y left, z up) carried along by the platform's rotation from its home
pose: at home {H} is parallel to {B}, so that a platform at rest at home gives
``f = (0, 0, |g|)``, as a vehicle at rest does (:mod:`stewart_env.tasks.cueing.motion`).

With ``R`` the platform's rotation, ``R_rel = R R_home^T`` its rotation from home, ``omega`` and
``alpha`` its angular velocity and acceleration and ``a_P`` the acceleration of P's origin (all
in {B}), and ``r = R head``::

    a_head = a_P + alpha x r + omega x (omega x r),
    f      = R_rel^T (a_head - g),        omega_H = R_rel^T omega.

``a_P`` and ``alpha`` are the mean accelerations over the control step, the velocity changes over
it divided by its length: they need nothing but the states the environment has (any plant, any
actuator, randomised parameters included), and they are the accelerations at the step's middle
to second order in the step, half a control step (5 ms by default) before the state's time,
well inside the time scales of motion perception (the vestibular models' fastest, 0.66 s).
"""

from __future__ import annotations

import numpy as np

__all__ = ["head_at_rest", "head_motion"]


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The cross product a x b of (N, 3) arrays, element by element (the same bits for a row alone or in a batch)."""
    return np.stack(
        [
            a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
            a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
            a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0],
        ],
        axis=1,
    )


def _transpose_times(rotation: np.ndarray, vector: np.ndarray) -> np.ndarray:
    """R^T v for (N, 3, 3) and (N, 3), element by element."""
    return rotation[:, 0, :] * vector[:, 0:1] + rotation[:, 1, :] * vector[:, 1:2] + rotation[:, 2, :] * vector[:, 2:3]


def _times(rotation: np.ndarray, vector: np.ndarray) -> np.ndarray:
    """R v for (N, 3, 3) and (3,) or (N, 3), element by element."""
    vector = np.broadcast_to(vector, (rotation.shape[0], 3))
    return rotation[:, :, 0] * vector[:, 0:1] + rotation[:, :, 1] * vector[:, 1:2] + rotation[:, :, 2] * vector[:, 2:3]


def head_motion(
    rotation: np.ndarray,
    velocity: np.ndarray,
    angular_velocity: np.ndarray,
    previous_velocity: np.ndarray,
    previous_angular_velocity: np.ndarray,
    dt: float,
    head: np.ndarray,
    gravity: np.ndarray,
    home_rotation: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The specific force and angular velocity at the head point in {H}, after a step of ``dt``.

    Args:
        rotation: (N, 3, 3) the platform's rotation at the step's end ({P} axes in {B}).
        velocity: (N, 3) m/s, the velocity of P's origin in {B} at the step's end.
        angular_velocity: (N, 3) rad/s, in {B}, at the step's end.
        previous_velocity: (N, 3) m/s, at the step's start.
        previous_angular_velocity: (N, 3) rad/s, at the step's start.
        dt: the step's length (s).
        head: (3,) m, the head point in {P}.
        gravity: (3,) m/s², in {B} (the platform's ``params.gravity``).
        home_rotation: (3, 3) the rotation at the home pose.

    Returns:
        The specific force (N, 3) m/s² and the angular velocity (N, 3) rad/s, in {H}.
    """
    acceleration = (velocity - previous_velocity) / dt
    angular_acceleration = (angular_velocity - previous_angular_velocity) / dt
    arm = _times(rotation, head)
    a_head = acceleration + _cross(angular_acceleration, arm) + _cross(angular_velocity, _cross(angular_velocity, arm))
    # R_rel^T x = R_home R^T x
    relative = np.broadcast_to(home_rotation, rotation.shape)
    specific_force = _times(relative, _transpose_times(rotation, a_head - gravity))
    omega = _times(relative, _transpose_times(rotation, angular_velocity))
    return specific_force, omega


def head_at_rest(gravity: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The specific force and angular velocity (3,) each in {H} of a platform at rest at home: (-g, 0).

    Args:
        gravity: (3,) m/s² in {B}.

    Returns:
        The specific force (3,) m/s² and the angular velocity (3,) rad/s.
    """
    return -np.asarray(gravity, dtype=np.float64), np.zeros(3)
