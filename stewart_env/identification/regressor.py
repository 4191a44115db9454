"""The inverse dynamics linear in the inertial parameters: ``J^T F + W = Y(x, v, a) theta``.

``Y`` comes from the compiled core (``stewart_env/_core/cpp/identification/regressor.hpp``), batched; the
parameter vector ``theta`` (:data:`N_THETA` numbers, names :data:`THETA_NAMES`) holds, per body,
the mass, the first moment (mass times CoM) and the inertia tensor about a point fixed in the body:

* the platform: about P, in {P} axes;
* each upper leg: about its platform joint P_i, in {D_i} axes;
* each lower leg: about its base joint B_i, in {D_i} axes;

then the joints' viscous coefficients C_u, C_p, C_s, then the legs' drives, shared by the six
legs: the Coulomb friction f_c (force f_c tanh(Ldot / v_s) along each leg, the drive model's
smooth sign, so that samples near zero speed stay in the fit; v_s is the platform's
``actuators.electric.friction_speed``, else :data:`FRICTION_SPEED`) and the reflected mass m_r
(force m_r Lddot).  A drive's viscous friction b acts as C_p does, so C_p holds C_p + b.
Inertias are the six tensor entries
(xx, yy, zz, xy, xz, yz).  For a model with C3 (C4) the legs' (the platform's) inertia in theta
is the one the model effectively uses, the CoM inertia plus twice the parallel-axis term, since
that model counts the term twice (docs/physics.md sections 5.6 and 6).
"""

from __future__ import annotations

import numpy as np

from stewart_env import _core
from stewart_env.actuators.transmission import BallScrew
from stewart_env.dynamics import kernels as K
from stewart_env.dynamics.model import Dynamics, batch_args
from stewart_env.params import PlatformParams

N_THETA = _core.N_THETA
#: The speed scale v_s (m/s) of the Coulomb friction's tanh for a platform without an electric drive.
FRICTION_SPEED = _core.FRICTION_SPEED
N_BODY = 10
#: Theta's index of the joints' viscous coefficients (C_u, C_p, C_s) and of the drives' (f_c, m_r).
OFF_DAMPING = N_THETA - 5
OFF_DRIVE = N_THETA - 2
INERTIA_KEYS = ("xx", "yy", "zz", "xy", "xz", "yz")
_BODY_FIELDS = ("m", "mx", "my", "mz") + tuple(f"I{k}" for k in INERTIA_KEYS)
_I6 = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))


def _names() -> tuple[str, ...]:
    names = [f"platform.{f}" for f in _BODY_FIELDS]
    for i in range(6):
        names += [f"upper_leg[{i}].{f}" for f in _BODY_FIELDS]
        names += [f"lower_leg[{i}].{f}" for f in _BODY_FIELDS]
    names += ["damping.universal", "damping.prismatic", "damping.spherical"]
    return tuple(names + ["drive.coulomb_friction", "drive.reflected_mass"])


#: The name of each entry of theta, e.g. ``"upper_leg[2].Ixy"``.
THETA_NAMES = _names()
assert len(THETA_NAMES) == N_THETA


def shifts_of(flags: int) -> tuple[float, float]:
    """Parallel-axis shifts (legs, platform) in theta's inertias: 2 under C3 (C4), else 1.

    Args:
        flags: the model's switch bits.
    """
    return (2.0 if flags & K.C3 else 1.0, 2.0 if flags & K.C4 else 1.0)


def _parallel_axis(r: np.ndarray) -> np.ndarray:
    """S(r) = |r|^2 E - r r^T."""
    return float(r @ r) * np.eye(3) - np.outer(r, r)


def body_theta(mass: float, com: np.ndarray, inertia_c: np.ndarray, shifts: float) -> np.ndarray:
    """The 10 parameters (m, m c, I) of a body with CoM c from the reference point and inertia
    I_c about the CoM: I = I_c + shifts * m S(c).

    Args:
        mass: the body's mass m, kg.
        com: its CoM c (3,) from the reference point, m, in the body's frame.
        inertia_c: its inertia I_c (3,3) about the CoM, kg m^2.
        shifts: the parallel-axis factor of :func:`shifts_of` (1 or 2).
    """
    com = np.asarray(com, float)
    inertia = np.asarray(inertia_c, float) + shifts * mass * _parallel_axis(com)
    return np.concatenate([[mass], mass * com, [inertia[a, b] for a, b in _I6]])


def body_from_theta(p: np.ndarray, shifts: float) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass, com, inertia about the CoM (3,3)) of a body's 10 parameters; the inverse of
    :func:`body_theta` for a positive mass.

    Args:
        p: the body's 10 parameters (m, m c, I).
        shifts: the parallel-axis factor of :func:`shifts_of` (1 or 2).
    """
    m = float(p[0])
    com = p[1:4] / m if m > 0 else np.zeros(3)
    inertia = np.zeros((3, 3))
    for k, (a, b) in enumerate(_I6):
        inertia[a, b] = inertia[b, a] = p[4 + k]
    return m, com, inertia - shifts * m * _parallel_axis(com)


def friction_speed(params: PlatformParams) -> float:
    """The speed scale v_s (m/s) of the Coulomb friction's tanh: the electric drive's, else
    :data:`FRICTION_SPEED`.

    Args:
        params: the platform.

    Returns:
        v_s, m/s.
    """
    electric = params.actuators.electric
    return FRICTION_SPEED if electric is None else float(electric.friction_speed)


def drive_terms(params: PlatformParams) -> tuple[float, float, float]:
    """The electric drive's (viscous friction b, Coulomb friction f_c, reflected mass m_r), zeros
    without an ``actuators.electric`` section.

    Args:
        params: the platform.

    Returns:
        (b N s/m, f_c N, m_r kg).
    """
    electric = params.actuators.electric
    if electric is None:
        return 0.0, 0.0, 0.0
    return (
        float(electric.viscous_friction),
        float(electric.coulomb_friction),
        BallScrew.from_params(electric).reflected_mass,
    )


def theta_of(params: PlatformParams, flags: int = 0, drive: bool = False) -> np.ndarray:
    """Theta (N_THETA,) of a platform for the model with switch bits ``flags``.

    Args:
        params: the platform.
        flags: the model's switch bits (default 0, none set).
        drive: the forces are the drives' (motor currents): the electric drive's friction and
            reflected mass are in theta (:func:`drive_terms`); False (load cells): zeros.

    Returns:
        Theta (N_THETA,).
    """
    leg_shift, plat_shift = shifts_of(flags)
    parts = [body_theta(params.platform.mass, params.platform.com, params.platform.inertia, plat_shift)]
    for i in range(6):
        for body in (params.upper_leg[i], params.lower_leg[i]):
            parts.append(body_theta(body.mass, body.com, body.inertia, leg_shift))
    d = params.damping
    b, fc, mr = drive_terms(params) if drive else (0.0, 0.0, 0.0)
    parts.append(np.array([d.universal, d.prismatic + b, d.spherical, fc, mr]))
    return np.concatenate(parts)


def regressor_matrix(
    dynamics: Dynamics, position, rotation, velocity, angular_velocity, lin_acc, ang_acc, speed_scale=None
) -> np.ndarray:
    """Y (N, 6, N_THETA) (or (6, N_THETA) for one state) with J^T F + W = Y theta for the model
    of ``dynamics`` (its name's switches; its first platform gives the geometry and gravity).

    Arguments as in :meth:`Dynamics.inverse`, {B}.  docs/physics.md section 5.7.

    Args:
        dynamics: the dynamics model.
        position: (3,) position of P's origin, m.
        rotation: (3,3) rotation matrix of {P} in {B}.
        velocity: (3,) velocity of P's origin, m/s.
        angular_velocity: (3,) angular velocity, rad/s.
        lin_acc: (3,) acceleration a of P's origin, m/s^2.
        ang_acc: (3,) angular acceleration alpha, rad/s^2.
        speed_scale: v_s (m/s) of the Coulomb column's tanh (None: :func:`friction_speed` of the
            model's first platform).

    Returns:
        Y (N, 6, N_THETA), or (6, N_THETA) for one state.
    """
    n, batched, a = batch_args(
        1,
        position=(position, (3,)),
        rotation=(rotation, (3, 3)),
        velocity=(velocity, (3,)),
        angular_velocity=(angular_velocity, (3,)),
        lin_acc=(lin_acc, (3,)),
        ang_acc=(ang_acc, (3,)),
    )
    acc = np.ascontiguousarray(np.concatenate([a["lin_acc"], a["ang_acc"]], axis=1))
    Y = np.empty((n, 6, N_THETA))
    _core.regressor_batch(
        np.ascontiguousarray(dynamics.packed[:1]),
        dynamics.flags,
        a["position"],
        a["rotation"],
        a["velocity"],
        a["angular_velocity"],
        acc,
        Y,
        friction_speed(dynamics.params[0]) if speed_scale is None else float(speed_scale),
    )
    return Y if batched else Y[0]
