"""Derivatives of the dynamics: the Jacobians of the forward dynamics and of one control step.

:meth:`Dynamics.acceleration_jacobians` and :meth:`Dynamics.step_jacobians` (methods this module
defines on :class:`~stewart_env.dynamics.model.Dynamics`, as :mod:`~stewart_env.dynamics.workspace`
defines ``Dynamics.workspace``, so that the model imports nothing built on it) give the exact
Jacobians of the platform's acceleration and of one control step (RK4 with the leg forces held),
for a platform or a batch, from the same compiled kernels as the values (forward-mode automatic
differentiation, docs/physics.md section 11).  :func:`central_differences` computes the same
Jacobians by central differences, for checking.

Tangent coordinates (docs/physics.md section 11.1).  A rotation has no global minimal coordinates,
so the Jacobians are taken in the tangent space of the state: x = (dt, dtheta, v, w) in R^12,

* dt (3,): a displacement of P's origin, m, {B};
* dtheta (3,): the rotation vector, rad, of a perturbation applied on the LEFT in {B},
  R' = exp([dtheta]x) R (a small rotation of the platform about axes fixed in the base, the same
  frame as the angular velocity w);
* v (3,), w (3,): the velocity of P's origin and the angular velocity, {B}.

The acceleration is (a, alpha), as :meth:`Dynamics.forward` returns it: the acceleration of P's
origin and the angular acceleration, {B}.  A step's A = d x_next / d x and B = d x_next / d F, with
the next state's dtheta about the next rotation: R_next' = exp([dtheta_next]x) R_next.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from stewart_env import _core, validation
from stewart_env.dynamics.model import MAX_STEPS, Dynamics
from stewart_env.rotations import rotation_error, rotvec_to_matrix
from stewart_env.state import PlatformState

__all__ = [
    "CENTRAL_DIFFERENCE_STEP",
    "AccelerationJacobians",
    "StepJacobians",
    "central_differences",
]

#: The relative step of :func:`central_differences`: h = 1e-5 (max(1, |x_k|)) per tangent
#: coordinate.  The truncation error of a central difference is O(h^2) ~ 1e-10 times the third
#: derivative, the rounding error O(eps / h) ~ 2e-11 times the value: both far below the 1e-6
#: relative agreement the checks ask for, and 1e-5 sits near the optimum (eps^(1/3) ~ 6e-6).
CENTRAL_DIFFERENCE_STEP = 1e-5


class AccelerationJacobians(NamedTuple):
    """The platform's acceleration and its Jacobians, (N, ...) for a batch.

    A row whose numbers are not all finite (a singular pose: a leg of zero length or along its
    U joint's fixed axis) is NaN throughout, and :attr:`finite` says which rows are.

    Attributes:
        acceleration: (6,) [a; alpha]: acceleration of P's origin, m/s^2, and angular
            acceleration, rad/s^2, {B} (as :meth:`Dynamics.forward` gives them).
        d_pose: (6,6) d acceleration / d (dt, dtheta): columns the displacement of P (m, {B}) and
            the left rotation vector dtheta (rad, {B}; R' = exp([dtheta]x) R).
        d_twist: (6,6) d acceleration / d (v, w), {B}.
        d_forces: (6,6) d acceleration / d F, the leg forces, N.
    """

    acceleration: np.ndarray
    d_pose: np.ndarray
    d_twist: np.ndarray
    d_forces: np.ndarray

    @property
    def finite(self):
        """Whether each row's numbers are finite (a bool, or (N,) for a batch)."""
        return np.isfinite(self.acceleration).all(axis=-1)


class StepJacobians(NamedTuple):
    """The next state of one control step and its Jacobians, (N, ...) for a batch.

    A row whose numbers are not all finite (the step runs through a singular pose) is NaN
    throughout, and :attr:`finite` says which rows are.

    Attributes:
        state: the next :class:`~stewart_env.state.PlatformState` (the rollout's, bit for bit).
        A: (12,12) d x_next / d x in the tangent coordinates x = (dt, dtheta, v, w) (module docstring).
        B: (12,6) d x_next / d F, the leg forces held over the step, N.
    """

    state: PlatformState
    A: np.ndarray
    B: np.ndarray

    @property
    def finite(self):
        """Whether each row's numbers are finite (a bool, or (N,) for a batch)."""
        return np.isfinite(self.state.position).all(axis=-1)


def _step_args(dt, steps) -> tuple[float, int]:
    """The control step dt (s, positive and finite) and its RK4 substep count (>= 1), checked."""
    dt = validation.real("dt", dt, 0.0, math.inf, low_open=True)
    steps = validation.integer("steps", steps, 1, MAX_STEPS)
    return dt, steps


def _args(model: Dynamics, position, rotation, velocity, angular_velocity, leg_forces, external_wrench, reflected_mass):
    extra = {} if reflected_mass is None else {"reflected_mass": (reflected_mass, (6,))}
    n, batched, a = model._args(
        position,
        rotation,
        velocity,
        angular_velocity,
        leg_forces=(leg_forces, (6,)),
        external_wrench=external_wrench,
        **extra,
    )
    if reflected_mass is not None and not (a["reflected_mass"] >= 0.0).all():
        raise ValueError("reflected_mass: expected masses >= 0 kg")
    return n, batched, a


def _nan_rows(finite: np.ndarray, *arrays: np.ndarray) -> None:
    """Set the rows not ``finite`` of every array to NaN (a partly finite Jacobian is no Jacobian)."""
    bad = ~finite
    if bad.any():
        for a in arrays:
            a[bad] = np.nan


def _row_finite(*arrays: np.ndarray) -> np.ndarray:
    n = arrays[0].shape[0]
    return np.logical_and.reduce([np.isfinite(a.reshape(n, -1)).all(axis=1) for a in arrays])


def acceleration_jacobians(  # noqa: D417  (self: a method of Dynamics, below)
    self: Dynamics,
    position,
    rotation,
    velocity,
    angular_velocity,
    leg_forces,
    external_wrench=None,
    *,
    reflected_mass=None,
) -> AccelerationJacobians:
    """The platform's acceleration and its exact Jacobians with respect to pose, twist and leg forces.

    Forward-mode automatic differentiation of the forward dynamics kernel (docs/physics.md
    section 11): the same equations as :meth:`forward`, the same acceleration bit for bit.  The
    pose's tangent coordinates are (dt, dtheta), dtheta the rotation vector of a perturbation
    applied on the left in {B}, R' = exp([dtheta]x) R (module docstring).  Every argument may
    carry a leading batch dimension N.

    Args:
        position: (3,) position of P's origin, m.
        rotation: (3,3) rotation matrix of {P} in {B}.
        velocity: (3,) velocity of P's origin, m/s.
        angular_velocity: (3,) angular velocity, rad/s.
        leg_forces: (6,) actuator forces F along the legs, N, positive extends the leg.
        external_wrench: (6,) [force at P, N; moment, N m], or None for none.
        reflected_mass: (6,) the legs' reflected drive masses m_r, kg (docs/physics.md section
            10.2), or None for none; F are then the drive forces.

    Returns:
        The :class:`AccelerationJacobians` (acceleration (6,), d_pose, d_twist, d_forces (6,6)),
        each with a leading N for a batch; rows at a singular pose NaN (``.finite`` False).

    Raises:
        ValueError: a wrong shape, a non-finite value or a rotation that is not orthonormal (as
            :meth:`forward`).
    """
    n, batched, a = _args(
        self, position, rotation, velocity, angular_velocity, leg_forces, external_wrench, reflected_mass
    )
    out = _acceleration_jacobians(self, a)
    return out if batched else AccelerationJacobians(*(x[0] for x in out))


def step_jacobians(  # noqa: D417  (self: a method of Dynamics, below)
    self: Dynamics,
    position,
    rotation,
    velocity,
    angular_velocity,
    leg_forces,
    dt,
    steps=1,
    external_wrench=None,
    *,
    reflected_mass=None,
) -> StepJacobians:
    """One control step and its exact Jacobians with respect to the state and the leg forces.

    The step is ``steps`` classical RK4 substeps of ``dt / steps`` seconds with the leg forces and
    the external wrench held (the integrator of :func:`stewart_env.rollout`: the next state is
    ``rollout(..., dt=dt / steps, steps=steps)``'s bit for bit).  A = d x_next / d x and
    B = d x_next / d F in the tangent coordinates x = (dt, dtheta, v, w) (module docstring), the
    next state's dtheta about the next rotation; by forward-mode automatic differentiation of the
    same kernels (docs/physics.md section 11).  Every array argument may carry a leading batch
    dimension N.

    Args:
        position: (3,) position of P's origin, m.
        rotation: (3,3) rotation matrix of {P} in {B}.
        velocity: (3,) velocity of P's origin, m/s.
        angular_velocity: (3,) angular velocity, rad/s.
        leg_forces: (6,) actuator forces F, N, held over the step.
        dt: the control step, s (> 0).
        steps: the RK4 substeps it is integrated in (>= 1).
        external_wrench: (6,) [force at P, N; moment, N m], held, or None for none.
        reflected_mass: (6,) the legs' reflected drive masses m_r, kg (docs/physics.md section
            10.2), or None for none; F are then the drive forces.

    Returns:
        The :class:`StepJacobians` (state: the next PlatformState, A (12,12), B (12,6)), each
        with a leading N for a batch; rows whose step meets a singular pose NaN (``.finite`` False).

    Raises:
        ValueError: a wrong shape, a non-finite value, a rotation that is not orthonormal, or a
            ``dt`` or ``steps`` out of range (named in the message).
    """
    dt, steps = _step_args(dt, steps)
    n, batched, a = _args(
        self, position, rotation, velocity, angular_velocity, leg_forces, external_wrench, reflected_mass
    )
    out = _step_jacobians(self, a, dt, steps)
    if batched:
        return out
    return StepJacobians(PlatformState(*(x[0] for x in out.state)), out.A[0], out.B[0])


# ---- the computation ---------------------------------------------------------------------------


def _acceleration_jacobians(model: Dynamics, a: dict) -> AccelerationJacobians:
    """The compiled kernel on checked arguments (batch_args' arrays)."""
    n = a["position"].shape[0]
    acc, jac, finite = np.empty((n, 6)), np.empty((n, 6, 18)), np.empty(n, dtype=bool)
    _core.acceleration_jacobian_batch(
        model.packed,
        model.flags,
        a["position"],
        a["rotation"],
        a["velocity"],
        a["angular_velocity"],
        a["leg_forces"],
        a["external_wrench"],
        a.get("reflected_mass"),
        acc,
        jac,
        finite,
    )
    return AccelerationJacobians(acc, jac[:, :, 0:6].copy(), jac[:, :, 6:12].copy(), jac[:, :, 12:18].copy())


def _step_jacobians(model: Dynamics, a: dict, dt: float, steps: int) -> StepJacobians:
    """The compiled kernel on checked arguments (batch_args' arrays); dt the whole control step."""
    n = a["position"].shape[0]
    t, R, v, w = np.empty((n, 3)), np.empty((n, 3, 3)), np.empty((n, 3)), np.empty((n, 3))
    jac, finite = np.empty((n, 12, 18)), np.empty(n, dtype=bool)
    _core.step_jacobian_batch(
        model.packed,
        model.flags,
        a["position"],
        a["rotation"],
        a["velocity"],
        a["angular_velocity"],
        a["leg_forces"],
        a["external_wrench"],
        a.get("reflected_mass"),
        dt / steps,
        steps,
        t,
        R,
        v,
        w,
        jac,
        finite,
    )
    return StepJacobians(PlatformState(t, R, v, w), jac[:, :, :12].copy(), jac[:, :, 12:].copy())


# ---- central differences -----------------------------------------------------------------------


def _forward(model: Dynamics, m_r, t, R, v, w, F, W) -> np.ndarray:
    out = np.empty((t.shape[0], 6))
    if m_r is None:
        _core.forward_batch(model.packed, model.flags, t, R, v, w, F, W, out)
    else:
        _core.forward_reflected_batch(model.packed, model.flags, t, R, v, w, F, W, m_r, out)
    return out


def _rollout(model: Dynamics, m_r, t, R, v, w, F, W, dt: float, steps: int):
    """The next state of the step: rollout_batch's, or with reflected masses the step's values of
    step_jacobian_batch (no other binding integrates them; its values are rollout_batch's
    arithmetic, which the tests check without them)."""
    if m_r is None:
        t, R, v, w = (np.array(x) for x in (t, R, v, w))
        _core.rollout_batch(model.packed, model.flags, t, R, v, w, F, W, dt / steps, steps)
        return t, R, v, w
    return _step_jacobians(
        model,
        {
            "position": t,
            "rotation": R,
            "velocity": v,
            "angular_velocity": w,
            "leg_forces": F,
            "external_wrench": W,
            "reflected_mass": m_r,
        },
        dt,
        steps,
    ).state


def _perturbed(t, R, v, w, F, k: int, h: np.ndarray):
    """The state and forces moved by h (N,) along tangent coordinate k (0..17: x then F)."""
    t, R, v, w, F = (np.array(x) for x in (t, R, v, w, F))
    if k < 3:
        t[:, k] += h
    elif k < 6:
        phi = np.zeros((t.shape[0], 3))
        phi[:, k - 3] = h
        R = np.ascontiguousarray(rotvec_to_matrix(phi) @ R)
    elif k < 9:
        v[:, k - 6] += h
    elif k < 12:
        w[:, k - 9] += h
    else:
        F[:, k - 12] += h
    return t, R, v, w, F


def _steps_of(t, R, v, w, F, h_rel: float) -> np.ndarray:
    """The central-difference step (N, 18) of each tangent coordinate: h_rel max(1, |x_k|)."""
    n = t.shape[0]
    scale = np.ones((n, 18))
    scale[:, 0:3] = np.maximum(1.0, np.abs(t))
    scale[:, 6:9] = np.maximum(1.0, np.abs(v))
    scale[:, 9:12] = np.maximum(1.0, np.abs(w))
    scale[:, 12:18] = np.maximum(1.0, np.abs(F))
    return h_rel * scale


def _cd_acceleration(model: Dynamics, a: dict, h_rel: float) -> AccelerationJacobians:
    t, R, v, w = a["position"], a["rotation"], a["velocity"], a["angular_velocity"]
    F, W, m_r = a["leg_forces"], a["external_wrench"], a.get("reflected_mass")
    acc = _forward(model, m_r, t, R, v, w, F, W)
    h = _steps_of(t, R, v, w, F, h_rel)
    jac = np.empty((t.shape[0], 6, 18))
    for k in range(18):
        plus = _forward(model, m_r, *_perturbed(t, R, v, w, F, k, h[:, k]), W)
        minus = _forward(model, m_r, *_perturbed(t, R, v, w, F, k, -h[:, k]), W)
        jac[:, :, k] = (plus - minus) / (2.0 * h[:, k, None])
    out = AccelerationJacobians(acc, jac[:, :, 0:6].copy(), jac[:, :, 6:12].copy(), jac[:, :, 12:18].copy())
    _nan_rows(_row_finite(*out), *out)
    return out


def _tangent_state(t, R, v, w, R_about) -> np.ndarray:
    """(t, phi, v, w) (N,12) with phi the left rotation vector that takes R_about to R."""
    phi, _ = rotation_error(R, R_about)
    return np.concatenate([t, np.reshape(phi, (-1, 3)), v, w], axis=1)


def _cd_step(model: Dynamics, a: dict, dt: float, steps: int, h_rel: float) -> StepJacobians:
    t, R, v, w = a["position"], a["rotation"], a["velocity"], a["angular_velocity"]
    F, W, m_r = a["leg_forces"], a["external_wrench"], a.get("reflected_mass")
    nt, nR, nv, nw = _rollout(model, m_r, t, R, v, w, F, W, dt, steps)
    h = _steps_of(t, R, v, w, F, h_rel)
    jac = np.empty((t.shape[0], 12, 18))
    for k in range(18):
        plus = _tangent_state(*_rollout(model, m_r, *_perturbed(t, R, v, w, F, k, h[:, k]), W, dt, steps), nR)
        minus = _tangent_state(*_rollout(model, m_r, *_perturbed(t, R, v, w, F, k, -h[:, k]), W, dt, steps), nR)
        jac[:, :, k] = (plus - minus) / (2.0 * h[:, k, None])
    out = StepJacobians(PlatformState(nt, nR, nv, nw), jac[:, :, :12].copy(), jac[:, :, 12:].copy())
    _nan_rows(_row_finite(nt, nR, nv, nw, out.A, out.B), nt, nR, nv, nw, out.A, out.B)
    return out


def central_differences(
    model: Dynamics,
    position,
    rotation,
    velocity,
    angular_velocity,
    leg_forces,
    dt=None,
    steps=1,
    external_wrench=None,
    *,
    reflected_mass=None,
    step_size: float = CENTRAL_DIFFERENCE_STEP,
):
    """The Jacobians of :meth:`Dynamics.acceleration_jacobians` (``dt`` None) or of
    :meth:`Dynamics.step_jacobians` (``dt`` given) by central differences, for checking.

    Each tangent coordinate k (module docstring; the rotation perturbed on the left,
    exp([h e_k]x) R) moves by +-h_k, h_k = step_size max(1, |x_k|) (:data:`CENTRAL_DIFFERENCE_STEP`
    says why 1e-5); the next state's rotation is read back as the left rotation vector about the
    unperturbed next rotation.  36 evaluations of the forward dynamics or of the step.

    Args:
        model: the :class:`~stewart_env.dynamics.Dynamics`.
        position: (3,) position of P's origin, m.
        rotation: (3,3) rotation matrix of {P} in {B}.
        velocity: (3,) velocity of P's origin, m/s.
        angular_velocity: (3,) angular velocity, rad/s.
        leg_forces: (6,) actuator forces F, N.
        dt: None for the acceleration's Jacobians, or the control step, s, for the step's.
        steps: the RK4 substeps of the step (>= 1).
        external_wrench: (6,) [force at P, N; moment, N m], or None for none.
        reflected_mass: (6,) the legs' reflected drive masses m_r, kg, or None for none.
        step_size: the relative difference step (> 0).

    Returns:
        An :class:`AccelerationJacobians` (``dt`` None) or a :class:`StepJacobians`, shaped as the
        methods' results.

    Raises:
        ValueError: a bad argument (named in the message).
    """
    if not isinstance(model, Dynamics):
        raise ValueError(f"model: expected a Dynamics, got {type(model).__name__}")
    step_size = validation.real("step_size", step_size, 0.0, 1.0, low_open=True)
    if dt is not None:
        dt, steps = _step_args(dt, steps)
    n, batched, a = _args(
        model, position, rotation, velocity, angular_velocity, leg_forces, external_wrench, reflected_mass
    )
    if dt is None:
        out = _cd_acceleration(model, a, step_size)
        return out if batched else AccelerationJacobians(*(x[0] for x in out))
    out = _cd_step(model, a, dt, steps, step_size)
    if batched:
        return out
    return StepJacobians(PlatformState(*(x[0] for x in out.state)), out.A[0], out.B[0])


# The model's derivatives are defined here, beside their results, so that imports run one way,
# model <- derivatives (the package's __init__ imports both, so every Dynamics has the methods).
acceleration_jacobians.__qualname__ = "Dynamics.acceleration_jacobians"
step_jacobians.__qualname__ = "Dynamics.step_jacobians"
Dynamics.acceleration_jacobians = acceleration_jacobians
Dynamics.step_jacobians = step_jacobians
