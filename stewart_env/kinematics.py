"""Kinematics of the 6-UPS platform: legs from a pose (inverse), pose from legs (forward).

The per-leg equations live in the compiled kernels (:mod:`stewart_env.dynamics.kernels`); this
module calls them and solves the forward problem by Newton-Raphson.  ``docs/physics.md`` in the
repository derives them (section 4: leg vector, length, rate and acceleration, the U-joint frame,
the leg's angular velocity and acceleration with its spin, the Jacobian).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from stewart_env.dynamics import kernels as K
from stewart_env.dynamics.model import Dynamics, batch_args, pack_params
from stewart_env.dynamics.spec import ModelSpec
from stewart_env.params import PlatformParams
from stewart_env.rotations import rotvec_to_matrix


class LegKinematics(NamedTuple):
    """Leg quantities of a platform state, all in {B}; a leading batch dimension N if batched.

    Symbols as in docs/physics.md section 3.

    Attributes:
        vectors: (6,3) leg vectors S_i = t + R p_i - b_i, m.
        lengths: (6,) leg lengths L_i, m.
        units: (6,3) leg unit vectors e_i.
        frames: (6,3,3) U-joint leg frames T_i = [e_i y_i z_i] (columns).
        rates: (6,) leg rates dL_i/dt, m/s.
        accelerations: (6,) leg accelerations d2L_i/dt2, m/s^2.
        omega: (6,3) leg angular velocities, rad/s (spin about e_i included).
        alpha: (6,3) leg angular accelerations, rad/s^2.
        jacobian: (6,6) J with dL/dt = J [v; omega], rows [e_i, (R p_i) x e_i].
    """

    vectors: np.ndarray
    lengths: np.ndarray
    units: np.ndarray
    frames: np.ndarray
    rates: np.ndarray
    accelerations: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray
    jacobian: np.ndarray


class ConvergenceError(RuntimeError):
    """Forward kinematics found no pose with the requested leg lengths."""


def _packed(params: PlatformParams | Dynamics) -> np.ndarray:
    if isinstance(params, Dynamics):
        return params.packed
    if isinstance(params, PlatformParams):
        return pack_params(params)[None]
    raise ValueError(f"params: expected PlatformParams or Dynamics, got {type(params).__name__}")


def _flags(params: PlatformParams | Dynamics, model: str | ModelSpec | None) -> int:
    """The switch bits of the leg kinematics: a Dynamics' own, else those of ``model``."""
    if isinstance(params, Dynamics):
        if model is not None and ModelSpec.parse(model).flags != params.flags:
            raise ValueError(
                f"model: {model!r} disagrees with the switches of the Dynamics given, {params.name!r}; leave model out"
            )
        return params.flags
    return (ModelSpec() if model is None else ModelSpec.parse(model)).flags  # default: the improved model


def leg_kinematics(
    params: PlatformParams | Dynamics,
    position,
    rotation,
    velocity=None,
    angular_velocity=None,
    lin_acc=None,
    ang_acc=None,
    model: str | None = None,
) -> LegKinematics:
    """Inverse kinematics to second order: leg vectors, lengths, frames, rates, accelerations,
    leg angular velocities and accelerations, and the Jacobian.

    docs/physics.md section 4 derives every quantity.  Every state argument may carry a leading
    batch dimension N; missing rates are zero.

    Args:
        params: the platform's parameters, or a :class:`~stewart_env.dynamics.Dynamics` (its
            parameter rows and switches).
        position: (3,) position t of P's origin in {B}, m.
        rotation: (3,3) rotation R of {P} in {B}.
        velocity: (3,) velocity v of P's origin, m/s, or None.
        angular_velocity: (3,) angular velocity omega, rad/s, or None.
        lin_acc: (3,) acceleration a of P's origin, m/s^2, or None.
        ang_acc: (3,) angular acceleration alpha, rad/s^2, or None.
        model: the model whose switches decide whether the leg spin is included
            (``"classical"`` or a ``+c1`` name leaves it out); default ``"improved"``, or the
            switches of ``params`` when it is a Dynamics (a ``model`` disagreeing with them raises).

    Returns:
        The :class:`LegKinematics`.

    Raises:
        ValueError: a bad argument, named in the message.

    Examples:
        >>> import numpy as np, stewart_env as se
        >>> params = se.load_platform("dasgupta1998")
        >>> legs = se.leg_kinematics(params, params.home_position, np.eye(3))
        >>> legs.lengths.shape, legs.jacobian.shape
        ((6,), (6, 6))
    """
    flags = _flags(params, model)
    packed = _packed(params)
    z3 = np.zeros(3)
    n, batched, a = batch_args(
        packed.shape[0],
        position=(position, (3,)),
        rotation=(rotation, (3, 3)),
        velocity=(z3 if velocity is None else velocity, (3,)),
        angular_velocity=(z3 if angular_velocity is None else angular_velocity, (3,)),
        lin_acc=(z3 if lin_acc is None else lin_acc, (3,)),
        ang_acc=(z3 if ang_acc is None else ang_acc, (3,)),
    )
    acc = np.concatenate([a["lin_acc"], a["ang_acc"]], axis=1)
    frames = np.empty((n, 6, 3, 3))
    lengths, rates, accels = np.empty((n, 6)), np.empty((n, 6)), np.empty((n, 6))
    omega, alpha, jac = np.empty((n, 6, 3)), np.empty((n, 6, 3)), np.empty((n, 6, 6))
    K.leg_kinematics_batch(
        packed,
        flags,
        a["position"],
        a["rotation"],
        a["velocity"],
        a["angular_velocity"],
        acc,
        frames,
        lengths,
        rates,
        accels,
        omega,
        alpha,
        jac,
    )
    units = frames[..., :, 0]
    out = LegKinematics(units * lengths[..., None], lengths, units, frames, rates, accels, omega, alpha, jac)
    return out if batched else LegKinematics(*(x[0] for x in out))


def inverse_kinematics(params: PlatformParams | Dynamics, position, rotation):
    """Leg lengths and unit vectors of a pose.

    Args:
        params: the platform's parameters, or a :class:`~stewart_env.dynamics.Dynamics`.
        position: (3,) position of P's origin in {B}, m; (N,3) for a batch.
        rotation: (3,3) rotation of {P} in {B}; (N,3,3) for a batch.

    Returns:
        The pair (lengths, units), leg lengths L_i (6,) m and unit vectors e_i (6,3), batched like
    the pose.

    Raises:
        ValueError: a bad argument, named in the message.
    """
    k = leg_kinematics(params, position, rotation)
    return k.lengths, k.units


def jacobian(params: PlatformParams | Dynamics, position, rotation) -> np.ndarray:
    """The 6x6 leg Jacobian J of a pose, dL/dt = J [v; omega] (docs/physics.md section 4.4).

    Args:
        params: the platform's parameters, or a :class:`~stewart_env.dynamics.Dynamics`.
        position: (3,) position of P's origin in {B}, m; (N,3) for a batch.
        rotation: (3,3) rotation of {P} in {B}; (N,3,3) for a batch.

    Returns:
        J, (6,6) or (N,6,6), rows [e_i, (R p_i) x e_i].

    Raises:
        ValueError: a bad argument, named in the message.
    """
    packed = _packed(params)
    n, batched, a = batch_args(packed.shape[0], position=(position, (3,)), rotation=(rotation, (3, 3)))
    J = np.empty((n, 6, 6))
    K.jacobian_batch(packed, a["position"], a["rotation"], J)
    return J if batched else J[0]


def forward_kinematics(
    params: PlatformParams | Dynamics,
    leg_lengths,
    position_guess,
    rotation_guess,
    tol: float = 1e-12,
    max_iter: int = 50,
):
    """The platform pose with the given leg lengths, by Newton-Raphson from a guess.

    Each iteration solves J [dt; dphi] = L - L(pose) and updates t += dt, R = exp([dphi]x) R
    (docs/physics.md section 4.4).  One platform at a time.

    Args:
        params: the platform's parameters, or a :class:`~stewart_env.dynamics.Dynamics`.
        leg_lengths: (6,) leg lengths L, m.
        position_guess: (3,) starting position of P's origin in {B}, m.
        rotation_guess: (3,3) starting rotation of {P} in {B}.
        tol: the largest leg length residual accepted, m.
        max_iter: the most Newton-Raphson iterations.

    Returns:
        (position, rotation), once max |L - L(pose)| < tol.

    Raises:
        ConvergenceError: no pose within ``max_iter`` iterations, or a singular Jacobian.
        ValueError: a bad argument (a batch, a non-positive length), named in the message.

    Examples:
        The leg lengths of the home pose give the home pose back:

        >>> import numpy as np, stewart_env as se
        >>> params = se.load_platform("dasgupta1998")
        >>> lengths, _ = se.inverse_kinematics(params, params.home_position, np.eye(3))
        >>> position, rotation = se.forward_kinematics(params, lengths, params.home_position + 0.01, np.eye(3))
        >>> print(np.round(position, 9) + 0.0)
        [0.  0.  0.4]
    """
    _, batched, a = batch_args(
        1,
        leg_lengths=(leg_lengths, (6,)),
        position_guess=(position_guess, (3,)),
        rotation_guess=(rotation_guess, (3, 3)),
    )
    if batched:
        raise ValueError(
            "leg_lengths, position_guess, rotation_guess: forward kinematics solves one platform at a time"
        )
    target, t, R = a["leg_lengths"][0], a["position_guess"][0], a["rotation_guess"][0]
    if np.any(target <= 0):
        raise ValueError(f"leg_lengths: expected six positive lengths, got {target}")
    residual = np.inf
    for _ in range(max_iter):
        k = leg_kinematics(params, t, R)
        r = target - k.lengths
        residual = np.abs(r).max()
        if residual < tol:
            return t, R
        try:
            step = np.linalg.solve(k.jacobian, r)
        except np.linalg.LinAlgError:
            raise ConvergenceError("forward kinematics: singular Jacobian at an iterate") from None
        t = t + step[:3]
        R = rotvec_to_matrix(step[3:]) @ R
    raise ConvergenceError(
        f"forward kinematics did not converge in {max_iter} iterations (leg length residual {residual:.3e} m)"
    )


def leg_sensors_inplace(
    params: PlatformParams | Dynamics,
    position,
    rotation,
    velocity,
    angular_velocity,
    max_condition,
    lengths,
    rates,
    condition,
) -> None:
    """Leg lengths (N,6) m, rates (N,6) m/s and Jacobian condition numbers (N,) of a batch of
    states, written into preallocated arrays; no argument checks (the environment's per-step
    path).  State arrays as in :func:`stewart_env.integrate.rollout_inplace`.  ``condition`` is
    exact where it exceeds ``max_condition`` and an upper bound at most ``max_condition``
    elsewhere, so comparing it with ``max_condition`` decides singularity exactly.

    Args:
        params: the platform's parameters, or a model of it.
        position: the platforms' positions (N, 3), m, {B}.
        rotation: their rotation matrices (N, 3, 3), {P} in {B}.
        velocity: their velocities (N, 3), m/s.
        angular_velocity: their angular velocities (N, 3), rad/s.
        max_condition: the condition number of the Jacobian beyond which a pose is singular.
        lengths: the output of the leg lengths (N, 6), m.
        rates: the output of the leg rates (N, 6), m/s.
        condition: the output of the condition numbers (N,).
    """
    K.leg_sensors_batch(
        _packed(params), position, rotation, velocity, angular_velocity, float(max_condition), lengths, rates, condition
    )
