"""Time integration: classical RK4 over a batch of platforms, in compiled code."""

from __future__ import annotations

import numpy as np

from stewart_env.dynamics import kernels as K
from stewart_env.dynamics.model import Dynamics, batch_args


def rollout(model: Dynamics, position, rotation, velocity, angular_velocity, leg_forces,
            dt: float = 1e-3, steps: int = 1000, external_wrench=None, check_finite: bool = True):
    """Integrate the forward dynamics with classical RK4, leg forces and wrench held constant.

    position (3,) m, rotation (3,3), velocity (3,) m/s, angular_velocity (3,) rad/s of the
    platform in {B}; leg_forces (6,) N; external_wrench (6,) [force at P; moment] or None; each
    may carry a leading batch dimension N.  ``dt`` s, ``steps`` >= 0.  The orientation is
    integrated as a unit quaternion, so the returned rotation is orthonormal to rounding.  The
    arguments are checked as every entry point checks them (:func:`stewart_env.dynamics.model.batch_args`):
    shapes, finite values, and a rotation orthonormal with determinant +1 within
    :data:`~stewart_env.dynamics.model.ROTATION_TOLERANCE`.

    Returns the final (position, rotation, velocity, angular_velocity).  With ``check_finite``
    a state that stops being finite raises FloatingPointError naming the batch rows; without it
    those rows come back non-finite for the caller to handle.
    """
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt: must be a positive finite number of seconds, got {dt}")
    if int(steps) != steps or steps < 0:
        raise ValueError(f"steps: must be a non-negative integer, got {steps}")
    if external_wrench is None:
        external_wrench = np.zeros(6)
    _, batched, a = batch_args(
        model.packed.shape[0],
        position=(position, (3,)), rotation=(rotation, (3, 3)), velocity=(velocity, (3,)),
        angular_velocity=(angular_velocity, (3,)), leg_forces=(leg_forces, (6,)),
        external_wrench=(external_wrench, (6,)),
    )
    t, R, v, w = (a[k].copy() for k in ("position", "rotation", "velocity", "angular_velocity"))
    K.rollout_batch(model.packed, model.flags, t, R, v, w, a["leg_forces"], a["external_wrench"],
                    float(dt), int(steps))
    if check_finite:
        bad = ~(np.isfinite(t).all(1) & np.isfinite(R).all((1, 2)) & np.isfinite(v).all(1) & np.isfinite(w).all(1))
        if bad.any():
            raise FloatingPointError(
                f"rollout: state became non-finite in batch rows {np.flatnonzero(bad).tolist()} "
                "(singular pose or diverging forces)"
            )
    return (t, R, v, w) if batched else (t[0], R[0], v[0], w[0])


def rollout_inplace(model: Dynamics, position, rotation, velocity, angular_velocity, leg_forces,
                    external_wrench, dt: float, steps: int) -> None:
    """:func:`rollout` without argument checks, overwriting the state arrays in place.

    For callers that step every control period and keep their own preallocated, C-contiguous
    float64 batch arrays: position (N,3), rotation (N,3,3), velocity (N,3), angular_velocity
    (N,3), leg_forces (N,6), external_wrench (N,6).  Rows that stop being finite stay so.
    """
    K.rollout_batch(model.packed, model.flags, position, rotation, velocity, angular_velocity,
                    leg_forces, external_wrench, float(dt), int(steps))
