"""Roll-pitch-yaw angles and rotation matrices: R = Rz(yaw) Ry(pitch) Rx(roll).

Angles are for configs, observations and control laws; the dynamics works with R and omega.
Every function accepts one leading batch dimension.  Also rotation vectors: exp([phi]x) and the
rotation vector between two orientations.
"""

import numpy as np

from stewart_env import _core


def rpy_to_matrix(rpy):
    """Rotation matrix of roll-pitch-yaw angles, R = Rz(yaw) Ry(pitch) Rx(roll).

    Args:
        rpy: (..., 3) angles [roll, pitch, yaw], rad.

    Returns:
        R (..., 3, 3), columns = {P} axes in {B}.

    Raises:
        ValueError: ``rpy`` whose last dimension is not 3.

    Examples:
        >>> import numpy as np
        >>> from stewart_env import rpy_to_matrix, matrix_to_rpy
        >>> R = rpy_to_matrix([0.1, -0.2, 0.3])
        >>> print(np.round(matrix_to_rpy(R), 6))
        [ 0.1 -0.2  0.3]
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

    At pitch = +-pi/2 (gimbal lock) roll is set to 0.

    Args:
        R: (..., 3, 3) rotation matrices.

    Returns:
        rpy (..., 3) [roll, pitch, yaw], rad.

    Raises:
        ValueError: ``R`` whose last two dimensions are not (3, 3).
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

    Args:
        rpy: (..., 3) angles [roll, pitch, yaw], rad.

    Returns:
        E, (..., 3, 3).
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


def rotvec_to_matrix(phi):
    """exp([phi]x): rotation matrices (..., 3, 3) of rotation vectors (Rodrigues' formula).

    Args:
        phi: rotation vectors (..., 3), rad: the axis times the angle.
    """
    phi = np.asarray(phi, dtype=float)
    angle = np.linalg.norm(phi, axis=-1)[..., None, None]
    k = np.zeros(phi.shape[:-1] + (3, 3))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -phi[..., 2], phi[..., 1], -phi[..., 0]
    k = k - np.swapaxes(k, -1, -2)
    small = angle < 1e-8
    # sin(a)/a and (1 - cos a)/a^2 by their series near zero, where the quotients lose digits
    safe = np.where(small, 1.0, angle)
    s = np.where(small, 1.0 - angle**2 / 6, np.sin(safe) / safe)
    c = np.where(small, 0.5 - angle**2 / 24, (1 - np.cos(safe)) / safe**2)
    return np.eye(3) + s * k + c * k @ k


def rotation_error(rotation_ref: np.ndarray, rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rotation that takes R to R_ref: rotation vector phi of R_ref R^T and its angle, in {B}.

    With M = R_ref R^T = sum_k r_k c_k^T (r_k, c_k the k-th columns of R_ref and R), trace(M) =
    sum(R_ref * R) and the axial vector of M - M^T is sum_k c_k x r_k = 2 sin(angle) axis; so
    angle = atan2(|s|, (trace - 1) / 2) with s the half axial vector.  Accurate for angles below
    pi (at pi the axis is undefined and phi comes back zero).

    Args:
        rotation_ref: R_ref, (3,3) or (N,3,3).
        rotation: R, (3,3) or (N,3,3).

    Returns:
        The pair (phi, angle), phi (N,3) rad and |phi| (N,) rad; one pair of rotations gives (3,)
    and a scalar.
    """
    # the compiled kernel the tasks' step uses, so both give the same bits
    ref = np.ascontiguousarray(rotation_ref, dtype=np.float64)
    cur = np.ascontiguousarray(rotation, dtype=np.float64)
    single = cur.ndim == 2
    ref, cur = np.broadcast_arrays(ref.reshape(-1, 3, 3), cur.reshape(-1, 3, 3))
    n = cur.shape[0]
    phi, angle = np.empty((n, 3)), np.empty(n)
    _core.rotation_error_rows(np.ascontiguousarray(ref), np.ascontiguousarray(cur), phi, angle)
    return (phi[0], angle[0]) if single and ref.shape[0] == 1 else (phi, angle)
