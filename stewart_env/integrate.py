"""Time integration: classical RK4 over a batch of platforms, in compiled code, with the leg forces
held constant or given at every RK4 stage by a compiled control law (docs/physics.md section 5.6;
the laws: :mod:`stewart_env.dynamics.rk4`)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from stewart_env import _core, validation
from stewart_env.dynamics import rk4
from stewart_env.dynamics.model import Dynamics, batch_args, check_step

__all__ = ["Trajectory", "rollout", "rollout_inplace"]


class Trajectory(NamedTuple):
    """A rollout sampled every ``record_every`` steps, the start included (T samples).

    A batch carries a leading N: (N,T,...).  All in {B}.

    Attributes:
        time: (T,) s.
        position: (T,3) position of P's origin, m.
        rotation: (T,3,3) rotation of {P}.
        velocity: (T,3) m/s.
        angular_velocity: (T,3) rad/s.
        leg_forces: (T,6) N, the forces applied at each sample's state (the control law's there, or
            the held forces).
    """

    time: np.ndarray
    position: np.ndarray
    rotation: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray
    leg_forces: np.ndarray


def rollout(
    model: Dynamics,
    position,
    rotation,
    velocity,
    angular_velocity,
    leg_forces=None,
    dt: float = 1e-3,
    steps: int = 1000,
    external_wrench=None,
    check_finite: bool = True,
    *,
    control_law=None,
    control_params=None,
    start_time: float = 0.0,
    record_every: int | None = None,
):
    """Integrate the forward dynamics with classical RK4, the wrench held constant and the leg
    forces either held constant or given by a compiled control law at every RK4 stage.

    The orientation is integrated as a unit quaternion, so the returned rotation is orthonormal to
    rounding.  The arguments are checked as every entry point checks them
    (:func:`stewart_env.dynamics.model.batch_args`): shapes, finite values, and a rotation
    orthonormal with determinant +1 within :data:`~stewart_env.dynamics.model.ROTATION_TOLERANCE`.
    Each state, force and wrench argument may carry a leading batch dimension N.

    Args:
        model: the :class:`~stewart_env.dynamics.Dynamics` to integrate.
        position: (3,) position of P's origin in {B}, m.
        rotation: (3,3) rotation matrix of {P} in {B}.
        velocity: (3,) velocity of P's origin, m/s.
        angular_velocity: (3,) angular velocity, rad/s.
        leg_forces: (6,) leg forces F, N, held over the steps (None with a ``control_law``).
        dt: the step, s.
        steps: the number of steps, >= 0.
        external_wrench: (6,) [force at P, N; moment, N m], or None for none.
        check_finite: raise FloatingPointError when a state stops being finite; without it
            those rows come back non-finite (recorded samples too, from the first non-finite
            one on) for the caller to handle.
        control_law: a compiled control law, :class:`stewart_env.dynamics.rk4.ControlLaw` (or a
            numba ``cfunc`` or ctypes function it wraps), ``law(time, position, rotation,
            velocity, angular_velocity, params, n_params, forces)``, that writes the six leg
            forces (N) for the state at ``time`` s (:mod:`stewart_env.dynamics.rk4` gives the
            contract; :data:`stewart_env.dynamics.rk4.PD_CONTROL_LAW` is the package's PD law).
            It replaces ``leg_forces``.
        control_params: the law's ``params``: (P,), one parameter row for every platform, or
            (N, P), one per batch row.
        start_time: the time of the first stage, s.
        record_every: a positive divisor of ``steps``: return every ``record_every``-th state.

    Returns:
        The final (position, rotation, velocity, angular_velocity); with ``record_every`` a
        :class:`Trajectory` of every ``record_every``-th state instead, the start and the end
        included.

    Raises:
        ValueError: a bad argument (named in the message).
        FloatingPointError: with ``check_finite``, a state that stops being finite (the message
            names the batch rows).

    Examples:
        Held at its holding forces, the platform stays at home:

        >>> import numpy as np, stewart_env as se
        >>> params = se.load_platform("dasgupta1998")
        >>> model = se.make_dynamics("improved", params)
        >>> state = (params.home_position, np.eye(3), np.zeros(3), np.zeros(3))
        >>> forces = model.inverse(*state, np.zeros(3), np.zeros(3))
        >>> position, rotation, velocity, angular_velocity = se.rollout(
        ...     model, *state, forces, dt=1e-3, steps=100)
        >>> print(np.round(position, 6) + 0.0)
        [0.  0.  0.4]
    """
    dt, steps = check_step(dt, steps)
    start_time = validation.real("start_time", start_time)
    if record_every is not None:
        record_every = validation.integer("record_every", record_every, 1, max(steps, 1))
        if steps % record_every:
            raise ValueError(f"record_every: must be a positive integer dividing steps = {steps}, got {record_every}")
    if control_law is None:
        if control_params is not None:
            raise ValueError("control_params: given without a control_law")
        if leg_forces is None:
            raise ValueError("leg_forces: required without a control_law")
        control = {"leg_forces": (leg_forces, (6,))}
    else:
        control_law = rk4.as_control_law(control_law)
        if leg_forces is not None:
            raise ValueError("leg_forces: the control_law gives the leg forces; pass one or the other")
        params = np.zeros(0) if control_params is None else control_params
        if np.ndim(params) not in (1, 2):
            raise ValueError(f"control_params: expected an array (P,) or (N, P), got shape {np.shape(params)}")
        control = {"control_params": (params, np.shape(params)[-1:])}
    if external_wrench is None:
        external_wrench = np.zeros(6)
    n, batched, a = batch_args(
        model.packed.shape[0],
        position=(position, (3,)),
        rotation=(rotation, (3, 3)),
        velocity=(velocity, (3,)),
        angular_velocity=(angular_velocity, (3,)),
        external_wrench=(external_wrench, (6,)),
        **control,
    )
    t, R, v, w = (a[k].copy() for k in ("position", "rotation", "velocity", "angular_velocity"))
    trajectory = None
    if control_law is None and record_every is None:
        _core.rollout_batch(model.packed, model.flags, t, R, v, w, a["leg_forces"], a["external_wrench"], dt, steps)
    else:
        law, ctrl = (
            (rk4.CONSTANT_FORCES, a["leg_forces"]) if control_law is None else (control_law, a["control_params"])
        )
        rk4.check_law_params(law, ctrl)
        every = record_every or 0  # 0: record nothing
        samples = steps // every + 1 if every else 0
        try:
            rec = (
                np.empty((n, samples, 3)),
                np.empty((n, samples, 3, 3)),
                np.empty((n, samples, 3)),
                np.empty((n, samples, 3)),
                np.empty((n, samples, 6)),
            )
        except MemoryError:
            raise ValueError(
                f"record_every: {samples} samples of {n} platforms need {n * samples * 24 * 8 / 2**30:.1f} "
                "GiB; record less often"
            ) from None
        _core.rollout_law_batch(
            model.packed,
            model.flags,
            t,
            R,
            v,
            w,
            law.address,
            ctrl,
            a["external_wrench"],
            start_time,
            dt,
            steps,
            every,
            *rec,
        )
        if record_every is not None:
            trajectory = Trajectory(
                start_time + dt * every * np.arange(samples), *(x if batched else x[0] for x in rec)
            )
    if check_finite:
        bad = ~(np.isfinite(t).all(1) & np.isfinite(R).all((1, 2)) & np.isfinite(v).all(1) & np.isfinite(w).all(1))
        if bad.any():
            raise FloatingPointError(
                f"rollout: state became non-finite in batch rows {np.flatnonzero(bad).tolist()} "
                "(singular pose, diverging forces, or a control law that left a leg force unwritten)"
            )
    if trajectory is not None:
        return trajectory
    return (t, R, v, w) if batched else (t[0], R[0], v[0], w[0])


def rollout_inplace(
    model: Dynamics, position, rotation, velocity, angular_velocity, leg_forces, external_wrench, dt: float, steps: int
) -> None:
    """:func:`rollout` with the leg forces held, without argument checks, overwriting the state
    arrays in place.

    For callers that step every control period and keep their own preallocated, C-contiguous
    float64 batch arrays.  Rows that stop being finite stay so.

    Args:
        model: the dynamics model.
        position: (N,3), m, overwritten.
        rotation: (N,3,3), overwritten.
        velocity: (N,3), m/s, overwritten.
        angular_velocity: (N,3), rad/s, overwritten.
        leg_forces: (N,6), N, held.
        external_wrench: (N,6) [force at P, N; moment, N m], held.
        dt: the step, s.
        steps: the number of steps.
    """
    _core.rollout_batch(
        model.packed,
        model.flags,
        position,
        rotation,
        velocity,
        angular_velocity,
        leg_forces,
        external_wrench,
        float(dt),
        int(steps),
    )
