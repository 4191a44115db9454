"""What the generators share: the seeded random stream, smooth steps, and the motion at the head.

Every generator computes the specific force at a reference point of its vehicle (a car's or an
aircraft's centre of mass) and the vehicle's angular velocity, both in the vehicle's body axes
(x forward, y left, z up); :func:`at_head` moves the specific force to the person's head, a point
fixed in the body, by the rigid body's acceleration field.
"""

from __future__ import annotations

import zlib

import numpy as np

from stewart_env.tasks.cueing.motion import STANDARD_GRAVITY, VehicleMotion

__all__ = ["at_head", "euler_rates_to_body", "motion", "motion_rng", "rest", "rotate_to_body", "smoothstep", "uniform"]


def motion_rng(name: str, seed: int) -> np.random.Generator:
    """The random stream of the motion ``name`` drawn with ``seed``: the same pair always gives the
    same stream, and two motions drawn with one seed draw independently.

    Args:
        name: the motion's name.
        seed: the seed, an integer >= 0.

    Returns:
        A NumPy generator (PCG64) seeded with ``(seed, crc32(name))``.
    """
    return np.random.default_rng(np.random.SeedSequence([int(seed), zlib.crc32(name.encode())]))


def uniform(rng: np.random.Generator, low: float, high: float) -> float:
    """One draw from U(low, high), as a Python float.

    Args:
        rng: the motion's stream.
        low: the lower bound.
        high: the upper bound.

    Returns:
        The draw.
    """
    return float(rng.uniform(low, high))


def smoothstep(t: np.ndarray, start: float, duration: float) -> np.ndarray:
    """0 before ``start``, 1 after ``start + duration``, and a half cosine in between: a step whose
    first derivative is continuous (no infinite jerk in a motion built on it).

    Args:
        t: (T,) times, s.
        start: where the step starts, s.
        duration: how long it takes, s (> 0).

    Returns:
        (T,) values in [0, 1].
    """
    x = np.clip((np.asarray(t, dtype=float) - start) / duration, 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * x)


def rotate_to_body(vectors: np.ndarray, roll: np.ndarray, pitch: np.ndarray) -> np.ndarray:
    """Vectors given in the heading frame (level, turned with the vehicle's heading) expressed in
    the body axes tilted by ``roll`` about x and then ``pitch`` about y (z-y-x Euler angles).

    With y left and z up, a positive roll raises the left side and a positive pitch lowers the nose.

    Args:
        vectors: (T, 3) in the heading frame.
        roll: (T,) rad.
        pitch: (T,) rad.

    Returns:
        (T, 3) in the body axes: ``(R_y(pitch) R_x(roll))^T v``.
    """
    cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    x, y, z = vectors[:, 0], vectors[:, 1], vectors[:, 2]
    # R_y(pitch)^T first, then R_x(roll)^T: R = R_y R_x takes body to heading frame
    x1 = cp * x - sp * z
    z1 = sp * x + cp * z
    return np.stack([x1, cr * y + sr * z1, -sr * y + cr * z1], axis=1)


def euler_rates_to_body(roll: np.ndarray, pitch: np.ndarray, dt: float, yaw_rate: np.ndarray) -> np.ndarray:
    """The body angular velocity of z-y-x Euler angles (heading, pitch, roll) from their rates.

    Args:
        roll: (T,) rad.
        pitch: (T,) rad.
        dt: the sampling period, s (the rates of roll and pitch are their central differences).
        yaw_rate: (T,) the heading's rate, rad/s.

    Returns:
        (T, 3) ``omega`` in the body axes, rad/s.
    """
    roll_rate, pitch_rate = np.gradient(roll, dt), np.gradient(pitch, dt)
    cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    return np.stack(
        [
            roll_rate - yaw_rate * sp,
            pitch_rate * cr + yaw_rate * sr * cp,
            -pitch_rate * sr + yaw_rate * cr * cp,
        ],
        axis=1,
    )


def at_head(specific_force: np.ndarray, angular_velocity: np.ndarray, head: tuple, dt: float) -> np.ndarray:
    """The specific force at the head, a point ``head`` fixed in the body, from the specific force
    at the reference point: ``f_H = f_ref + omega_dot x r + omega x (omega x r)``.

    Args:
        specific_force: (T, 3) at the reference point, body axes, m/s².
        angular_velocity: (T, 3) body axes, rad/s.
        head: (x, y, z) the head from the reference point, body axes, m.
        dt: the sampling period, s (``omega_dot`` is the central difference).

    Returns:
        (T, 3) the specific force at the head, body axes, m/s².
    """
    r = np.broadcast_to(np.asarray(head, dtype=float), angular_velocity.shape)
    omega_dot = np.gradient(angular_velocity, dt, axis=0)
    return specific_force + np.cross(omega_dot, r) + np.cross(angular_velocity, np.cross(angular_velocity, r))


def rest(n_samples: int) -> tuple[np.ndarray, np.ndarray]:
    """A vehicle at rest on level ground for ``n_samples`` samples.

    Args:
        n_samples: T.

    Returns:
        ``(specific_force, angular_velocity)``, (T, 3) each: ``(0, 0, g0)`` and zeros.
    """
    force = np.zeros((n_samples, 3))
    force[:, 2] = STANDARD_GRAVITY
    return force, np.zeros((n_samples, 3))


def motion(name: str, seed: int, dt: float, force: np.ndarray, omega: np.ndarray, **meta) -> VehicleMotion:
    """The record of a generated motion, its source ``"<name> seed <seed>"`` and its drawn parameters.

    Args:
        name: the motion's name.
        seed: its seed.
        dt: the sampling period, s.
        force: (T, 3) the specific force at the head, m/s².
        omega: (T, 3) the angular velocity, rad/s.
        **meta: the drawn parameters, in SI units, for reports.

    Returns:
        The motion.
    """
    return VehicleMotion(name, dt, force, omega, source=f"{name} seed {seed}", meta={"seed": int(seed), **meta})
