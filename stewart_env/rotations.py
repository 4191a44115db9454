"""Roll-pitch-yaw angles and rotation matrices: R = Rz(yaw) Ry(pitch) Rx(roll).

Angles are for configs, observations and control laws; the dynamics works with R and omega.
Every function accepts one leading batch dimension.
"""

import numpy as np


def rpy_to_matrix(rpy):
    """Rotation matrix of roll-pitch-yaw angles.

    rpy (..., 3) rad [roll, pitch, yaw] -> R (..., 3, 3), columns = {P} axes in {B}.
    """
    rpy = np.asarray(rpy, dtype=float)
    if rpy.shape[-1:] != (3,):
        raise ValueError(f"rpy: expected shape (..., 3), got {rpy.shape}")
    cr, sr = np.cos(rpy[..., 0]), np.sin(rpy[..., 0])
    cp, sp = np.cos(rpy[..., 1]), np.sin(rpy[..., 1])
    cy, sy = np.cos(rpy[..., 2]), np.sin(rpy[..., 2])
    R = np.empty(rpy.shape[:-1] + (3, 3))
    R[..., 0, 0] = cy * cp
    R[..., 0, 1] = cy * sp * sr - sy * cr
    R[..., 0, 2] = cy * sp * cr + sy * sr
    R[..., 1, 0] = sy * cp
    R[..., 1, 1] = sy * sp * sr + cy * cr
    R[..., 1, 2] = sy * sp * cr - cy * sr
    R[..., 2, 0] = -sp
    R[..., 2, 1] = cp * sr
    R[..., 2, 2] = cp * cr
    return R


def matrix_to_rpy(R):
    """Roll-pitch-yaw angles of a rotation matrix, pitch in [-pi/2, pi/2].

    R (..., 3, 3) -> rpy (..., 3) rad.  At pitch = +-pi/2 (gimbal lock) roll is set to 0.
    """
    R = np.asarray(R, dtype=float)
    if R.shape[-2:] != (3, 3):
        raise ValueError(f"rotation: expected shape (..., 3, 3), got {R.shape}")
    pitch = np.arcsin(np.clip(-R[..., 2, 0], -1.0, 1.0))
    roll = np.arctan2(R[..., 2, 1], R[..., 2, 2])
    yaw = np.arctan2(R[..., 1, 0], R[..., 0, 0])
    return np.stack([roll, pitch, yaw], axis=-1)


def rpy_rate_matrix(rpy):
    """E (..., 3, 3) with omega = E(rpy) d(rpy)/dt, omega in {B}.

    Used to turn angular velocity into angle rates (the PD law's error rate).
    """
    rpy = np.asarray(rpy, dtype=float)
    cp, sp = np.cos(rpy[..., 1]), np.sin(rpy[..., 1])
    cy, sy = np.cos(rpy[..., 2]), np.sin(rpy[..., 2])
    E = np.zeros(rpy.shape[:-1] + (3, 3))
    E[..., 0, 0] = cy * cp
    E[..., 1, 0] = sy * cp
    E[..., 2, 0] = -sp
    E[..., 0, 1] = -sy
    E[..., 1, 1] = cy
    E[..., 2, 2] = 1.0
    return E
