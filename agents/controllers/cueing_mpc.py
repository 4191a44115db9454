"""Model-predictive motion cueing (extra ``mpc``: OSQP): the platform's motion chosen over a horizon
so that the motion a person perceives on it matches the vehicle's, inside the workspace and with
the false cues as constraints; a policy of the cueing task in ``action_mode="pose"``.

**The model** (per pair of axes of the head frame {H}, at the control step dt, small angles).
The head's translation along an axis is a triple integrator of its jerk j, the cabin's angle about
the paired axis a double integrator of its angular acceleration alpha (inputs held over the step,
so that the acceleration and the angular velocity are continuous: the pose loop cannot follow
steps in them):

    p_{k+1} = p_k + dt v_k + dt²/2 a_k + dt³/6 j_k,   v_{k+1} = v_k + dt a_k + dt²/2 j_k,
    a_{k+1} = a_k + dt j_k,   theta_{k+1} = theta_k + dt r_k + dt²/2 alpha_k,   r_{k+1} = r_k + dt alpha_k.

The pairs are (x, pitch), (y, roll) and (z, yaw).  The rendered specific force's deviation from
rest is the head's acceleration (its mean over the step, as the task measures it) plus the
gravity the tilt brings into the axis, and the angular velocity the angle's mean rate:

    f_x = a_x - g theta_pitch,   f_y = a_y + g theta_roll,   f_z = a_z,   omega = r,

(f = R^T (0, 0, g) of a cabin at rest tilted by R: a pitch theta gives f_x = -g sin theta, a roll
phi f_y = g sin phi; washout's pitch = -asin(f_x / g) has the same sign; the tests check a held
tilt of 0.1 rad against g sin theta).  The cabin turns about the head point
(:func:`~stewart_env.agents.controllers.washout.head_pose`), so that P's origin moves by
P_x = p_x - h sin theta_pitch and P_y = p_y + h sin theta_roll (h the head's height above P's
origin): these, linearised, are the workspace constraints.

**Perception.** The otolith's and the canal's transfer functions
(:mod:`stewart_env.tasks.cueing.vestibular`, those the metrics use) are discretised with the
first-order hold, as their filters are: x_{k+1} = Phi x_k + (Gamma_1 - Gamma_2) u_k + Gamma_2 u_{k+1},
y_k = C x_k + D u_k, written with xi_k = x_k - Gamma_2 u_k as the state-space form

    xi_{k+1} = Phi xi_k + (Phi Gamma_2 + Gamma_1 - Gamma_2) u_k,   y_k = C xi_k + (C Gamma_2 + D) u_k

(:func:`foh_state_space`; the tests check it against the filters to 1e-9).  The platform's
perceived f and omega are these filters' outputs on the model's f and omega, the vehicle's on the
observed samples: the policy runs the vehicle's filters on the observations and predicts their
outputs over the horizon from the reference, the preview the environment observes
(``task_options`` ``preview``, 0-100 samples) and its last sample held after it.  It uses nothing
the environment does not observe.  With ``feedback`` the platform's perceived state is driven by
the head's motion measured from the observed platform state (the task's
:func:`~stewart_env.tasks.cueing.head.head_motion`) rather than by the model's: the perception the
metrics score.

**The QP.** Over a horizon of N steps, the inputs held over blocks of ``block`` steps (move
blocking), the controller minimises, per pair,

    sum_k w_f (fhat_p,k - fhat_v,k)² + w_w (what_p,k - what_v,k)² + w_p p_{k+1}² + w_v v_{k+1}²
          + w_t theta_{k+1}² + w_a a_{k+1}² + w_r r_{k+1}² + w_j j_k² + w_alpha alpha_k² + rho (sigma / thr)²

subject to the workspace (|P| <= the bound, |theta| <= the angle bound) and the **false-cue
constraints**, at every ``stride``-th step: where the vehicle's predicted perceived signal is above
``band`` thr, the platform's must not be below -m thr (thr the perception threshold, m < 1 a
margin); below -band thr, not above m thr; in between, within ±m thr.  These are linear in the
inputs, so the problem stays a QP; they are soft (the slacks sigma, weighed by rho), so that they
never make it infeasible.  The workspace bounds are hard: a pair whose state is already past one
gets no input for the step (its programme is infeasible).  The model is linear and time-invariant: the QP's matrices are built once and only
its linear term and bounds change with the state and the reference, so OSQP solves each step
warm-started, without refactorising.

**The pose loop.** The environment's pose mode tracks the commanded pose with its leg servos; on
dasgupta1998 each coordinate of P's pose responds to its command roughly as a lightly damped
second-order system (``loop_*``: identified from random steps, P's x and y w_n = 14 rad/s,
zeta = 0.25 and a delay of 2 steps).  The first input is applied to the model, and the pose
commanded is the inverse of that response applied to the plan (:meth:`CueingMPC.loop_command`),
so that the platform follows the planned motion rather than lagging and ringing behind it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse

from stewart_env.agents.controllers.washout import (
    _pose_mode,
    cueing_environment,
    head_pose,
    pose_actions,
    starting_rows,
)
from stewart_env.errors import UsageError
from stewart_env.extras import require
from stewart_env.rotations import rpy_to_matrix
from stewart_env.tasks.cueing.motion import STANDARD_GRAVITY
from stewart_env.tasks.cueing.vestibular import THRESHOLDS, Otolith, SemicircularCanal, first_order_hold

__all__ = ["OSQP_SETTINGS", "CueingMPC", "CueingMPCParams", "CueingMPCPolicy", "foh_state_space", "pair_model"]

#: OSQP's settings: tolerances of 1e-4 (perceived forces of about 1 m/s²), polishing off, warm start.
#: OSQP's statuses whose x is a solution (within its tolerances, or beyond its iterations' limit).
SOLVED = ("solved", "solved inaccurate", "maximum iterations reached")
OSQP_SETTINGS = {
    "verbose": False,
    "eps_abs": 1e-4,
    "eps_rel": 1e-4,
    "polishing": False,
    "warm_starting": True,
    "max_iter": 4000,
}


@dataclass(frozen=True)
class CueingMPCParams:
    """The cueing MPC's horizon, weights and bounds (module docstring).

    Attributes:
        horizon: N, the control steps predicted.
        block: the control steps an input is held (move blocking); divides ``horizon``.
        stride: the constraints' spacing in steps (the workspace's and the false cues').
        force_weight: w_f, per (m/s²)² of perceived specific-force error.
        rate_weight: w_w, per (rad/s)² of perceived angular-velocity error.
        position_weight: w_p, per m² of the head's displacement (x, y, z).
        velocity_weight: w_v, per (m/s)².
        angle_weight: w_t, per rad² of the cabin's angles (roll, pitch, yaw).
        acceleration_weight: w_a, per (m/s²)² of the head's acceleration.
        angular_rate_weight: w_r, per (rad/s)² of the angles' rates.
        jerk_weight: w_j, per (m/s³)² of the head's jerk (the input).
        angular_acceleration_weight: w_alpha, per (rad/s²)² of the angles' accelerations (the input).
        slack_weight: rho, per unit² of a false-cue constraint's violation.
        position_bound: the bounds of P's origin's offset from home (x, y, z), m.
        angle_bound: the bound of each angle (roll, pitch, yaw), rad.
        margin: m, the share of the perception threshold the constraints allow.
        band: the vehicle's perceived signal below which its sign counts as unknown, as a share
            of the threshold.
        false_cue_constraints: whether the false-cue constraints are in the QP.
        loop_frequency: w_n of the pose loop's response per coordinate of the platform's pose
            (P's x, y, z, then roll, pitch, yaw), rad/s, that the command pre-compensates; None:
            the planned pose is commanded as it is.
        loop_damping: zeta of the same responses.
        loop_delay: their delays, control steps (at most ``block`` - 1).
        feedback: whether the platform's perceived state is driven by the motion measured at the
            head (the observed platform state's step, as the task measures it) instead of the
            model's: the perception the metrics score, whatever the pose loop did.
        reference_decay: the time constant (s) with which the reference beyond the preview decays
            to rest (specific force (0, 0, g), no rotation); None: its last sample held.
    """

    horizon: int = 300
    block: int = 10
    stride: int = 5
    force_weight: float = 3.0
    rate_weight: float = 300.0
    position_weight: float = 1.0
    velocity_weight: float = 1.0
    angle_weight: float = 1.0
    acceleration_weight: float = 1e-3
    angular_rate_weight: float = 1e-2
    jerk_weight: float = 1e-2
    angular_acceleration_weight: float = 10.0
    slack_weight: float = 1e3
    position_bound: tuple[float, float, float] = (0.12, 0.12, 0.06)
    angle_bound: tuple[float, float, float] = (0.25, 0.25, 0.1)
    margin: float = 0.7
    band: float = 0.5
    false_cue_constraints: bool = True
    loop_frequency: tuple[float, ...] | None = (14.0, 14.0, 14.5, 31.5, 33.0, 38.5)
    loop_damping: tuple[float, ...] = (0.25, 0.25, 0.35, 0.45, 0.45, 0.9)
    loop_delay: tuple[int, ...] = (2, 2, 0, 0, 0, 0)
    feedback: bool = True
    reference_decay: float | None = None

    def __post_init__(self) -> None:
        """Check the horizon's integers and that every weight and bound is finite and positive."""
        for name in ("horizon", "block", "stride"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 1 <= value <= 2000:
                raise UsageError.about(name, f"must be an integer from 1 to 2000, got {value!r}")
        if self.horizon % self.block:
            raise UsageError.about("block", f"must divide the horizon {self.horizon}, got {self.block}")
        for name in (
            "force_weight",
            "rate_weight",
            "position_weight",
            "velocity_weight",
            "angle_weight",
            "acceleration_weight",
            "angular_rate_weight",
            "jerk_weight",
            "angular_acceleration_weight",
            "slack_weight",
            "margin",
            "band",
        ):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
                raise UsageError.about(name, f"must be a finite number >= 0, got {value!r}")
        for name in ("position_bound", "angle_bound"):
            value = np.asarray(getattr(self, name), dtype=float)
            if value.shape != (3,) or not np.all(np.isfinite(value)) or np.any(value <= 0):
                raise UsageError.about(name, f"must be three finite numbers > 0, got {getattr(self, name)!r}")
            object.__setattr__(self, name, tuple(float(v) for v in value))
        if self.loop_frequency is not None:
            for name in ("loop_frequency", "loop_damping", "loop_delay"):
                value = np.asarray(getattr(self, name), dtype=float)
                if value.shape != (6,) or not np.all(np.isfinite(value)) or np.any(value < 0):
                    raise UsageError.about(name, f"must be six finite numbers >= 0, got {getattr(self, name)!r}")
            if np.any(np.asarray(self.loop_frequency) <= 0):
                raise UsageError.about("loop_frequency", f"must be > 0, got {self.loop_frequency!r}")
            if any(int(d) != d or not 0 <= d < self.block for d in self.loop_delay):
                raise UsageError.about(
                    "loop_delay", f"must be whole steps from 0 to block - 1, got {self.loop_delay!r}"
                )
        if self.reference_decay is not None and not (
            isinstance(self.reference_decay, (int, float)) and 0 < self.reference_decay < math.inf
        ):
            raise UsageError.about("reference_decay", f"must be None or a time > 0 s, got {self.reference_decay!r}")


def foh_state_space(numerator, denominator, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """A transfer function discretised with the first-order hold, as a state-space model.

    The filters of :mod:`~stewart_env.tasks.cueing.vestibular` step
    x_{k+1} = Phi x_k + (Gamma_1 - Gamma_2) u_k + Gamma_2 u_{k+1}, y_k = C x_k + D u_k; with
    xi_k = x_k - Gamma_2 u_k this is xi_{k+1} = Phi xi_k + G u_k, y_k = H xi_k + J u_k with
    G = Phi Gamma_2 + Gamma_1 - Gamma_2, H = C, J = C Gamma_2 + D.

    Args:
        numerator: descending powers of s.
        denominator: descending powers of s.
        dt: the sample period, s.

    Returns:
        (Phi (n, n), G (n,), H (n,), J): xi's update and the output's map.
    """
    _, _, c, d, phi, gamma_1, gamma_2 = first_order_hold(numerator, denominator, dt)
    g = phi @ gamma_2 + gamma_1 - gamma_2
    return phi, g, c[0].copy(), float(c[0] @ gamma_2 + d[0, 0])


def pair_model(dt: float, coupling: float, arm: float):
    """The linear model of one pair of axes (module docstring) as x_{k+1} = A x_k + B u_k,
    y_k = C x_k + D u_k.

    The state x = (p, v, a, theta, r, xi_otolith (2), xi_canal (2)), the input u = (j, alpha),
    the jerk and the angular acceleration held over the step; the outputs y = (fhat, what, p', v',
    theta', P', f, omega, a', r'): the perceived specific force's deviation and angular velocity of
    the step, the displacement, velocity and angle after it, the platform origin's offset
    P' = p' + arm theta', the rendered f = (a + a') / 2 + coupling theta' and omega = (r + r') / 2
    (the step's means, as the environment measures them), and the acceleration and rate after it.

    Args:
        dt: the control step, s.
        coupling: f's gain on the angle, m/s² per rad (-g for (x, pitch), g for (y, roll), 0 for (z, yaw)).
        arm: P's offset per rad of the angle, m (-h, h, 0).

    Returns:
        (A (9, 9), B (9, 2), C (10, 9), D (10, 2)).
    """
    po, go, ho, jo = foh_state_space(*Otolith().transfer_function(), dt)
    pc, gc, hc, jc = foh_state_space(*SemicircularCanal().transfer_function(), dt)
    # the mechanics: (p, v, a) a triple integrator of the jerk, (theta, r) a double one of alpha
    mech_a = np.eye(5)
    mech_a[0, 1:3] = dt, 0.5 * dt * dt
    mech_a[1, 2] = dt
    mech_a[3, 4] = dt
    mech_b = np.zeros((5, 2))
    mech_b[:3, 0] = dt**3 / 6.0, 0.5 * dt * dt, dt
    mech_b[3:, 1] = 0.5 * dt * dt, dt
    # f and omega of the step as maps of (x, u): the means of a and r over it, the angle at its end
    f_x = np.array([0.0, 0.0, 1.0, coupling, coupling * dt])
    f_u = np.array([0.5 * dt, coupling * 0.5 * dt * dt])
    w_x = np.array([0.0, 0.0, 0.0, 0.0, 1.0])
    w_u = np.array([0.0, 0.5 * dt])
    a = np.zeros((9, 9))
    b = np.zeros((9, 2))
    a[:5, :5], b[:5] = mech_a, mech_b
    a[5:7, 5:7] = po
    a[5:7, :5] = np.outer(go, f_x)
    b[5:7] = np.outer(go, f_u)
    a[7:9, 7:9] = pc
    a[7:9, :5] = np.outer(gc, w_x)
    b[7:9] = np.outer(gc, w_u)
    c = np.zeros((10, 9))
    d = np.zeros((10, 2))
    c[0, :5], c[0, 5:7], d[0] = jo * f_x, ho, jo * f_u
    c[1, :5], c[1, 7:9], d[1] = jc * w_x, hc, jc * w_u
    for row, index in ((2, 0), (3, 1), (4, 3), (8, 2), (9, 4)):  # p', v', theta', a', r'
        c[row, :5], d[row] = mech_a[index], mech_b[index]
    c[5, :5], d[5] = mech_a[0] + arm * mech_a[3], mech_b[0] + arm * mech_b[3]
    c[6, :5], d[6] = f_x, f_u
    c[7, :5], d[7] = w_x, w_u
    return a, b, c, d


def _condensed(a, b, c, d, horizon: int):
    """Y = Psi x_0 + Gamma U over the horizon: Y stacked by output then step (outputs x N)."""
    n_y, n_x = c.shape
    n_u = b.shape[1]
    markov = [d]  # the impulse response: D, C B, C A B, ...
    power = np.eye(n_x)
    psi = np.zeros((n_y, horizon, n_x))
    for k in range(horizon):
        psi[:, k] = c @ power
        if k + 1 < horizon:
            markov.append(c @ power @ b)
        power = a @ power
    gamma = np.zeros((n_y, horizon, n_u, horizon))
    for k in range(horizon):
        for j in range(k + 1):
            gamma[:, k, :, j] = markov[k - j]
    return psi, gamma


def _siso_condensed(phi, g, h, j, horizon: int):
    """y_k = H xi_k + J u_k over the horizon from xi_0: (Psi (N, n), Gamma (N, N))."""
    n = phi.shape[0]
    psi = np.zeros((horizon, n))
    markov = [j]
    power = np.eye(n)
    for k in range(horizon):
        psi[k] = h @ power
        if k + 1 < horizon:
            markov.append(float(h @ power @ g))
        power = phi @ power
    gamma = np.zeros((horizon, horizon))
    for k in range(horizon):
        gamma[k, : k + 1] = markov[k::-1]
    return psi, gamma


class _PairQP:
    """The QP of one pair of axes, its constant matrices, and one OSQP solver per row."""

    def __init__(self, params: CueingMPCParams, dt: float, coupling: float, arm: float, axis: int, rotation: int):
        self.params = params
        self.a, self.b, self.c, self.d = pair_model(dt, coupling, arm)
        self.arm = arm
        n, blocks = params.horizon, params.horizon // params.block
        psi, gamma = _condensed(self.a, self.b, self.c, self.d, n)
        # move blocking: input u_k = U_{k // block}
        blocking = np.zeros((n, blocks))
        blocking[np.arange(n), np.arange(n) // params.block] = 1.0
        gamma = np.einsum("ykuj,jm->ykum", gamma, blocking).reshape(10, n, 2 * blocks)  # inputs (u, block)
        self.psi, self.gamma = psi, gamma
        self.points = np.arange(0, n, params.stride)
        m = len(self.points)
        self.n_inputs = 2 * blocks
        self.n_slack = 2 * m if params.false_cue_constraints else 0
        weights = np.array(
            [
                params.force_weight,
                params.rate_weight,
                params.position_weight,
                params.velocity_weight,
                params.angle_weight,
                params.acceleration_weight,
                params.angular_rate_weight,
            ]
        )
        self.tracked = [0, 1, 2, 3, 4, 8, 9]  # fhat, what, p', v', theta', a', r'
        tracked = gamma[self.tracked]
        hessian = np.einsum("y,ykm,ykl->ml", weights, tracked, tracked)
        effort = np.zeros(self.n_inputs)
        effort[:blocks] = params.jerk_weight * params.block
        effort[blocks:] = params.angular_acceleration_weight * params.block
        hessian += np.diag(effort)
        size = self.n_inputs + self.n_slack
        full = np.zeros((size, size))
        full[: self.n_inputs, : self.n_inputs] = hessian
        # the slacks in units of the thresholds: rho (sigma / thr)²
        thresholds = np.repeat(
            [THRESHOLDS["specific_force"][axis], THRESHOLDS["angular_velocity"][rotation]], self.n_slack // 2
        )
        full[self.n_inputs :, self.n_inputs :] = np.diag(params.slack_weight / thresholds**2) if self.n_slack else 0.0
        self.hessian = 2.0 * full
        self.weights = weights
        # constraints: P' and theta' at the points (hard), then fhat - s and what - s (soft)
        rows = [gamma[5][self.points], gamma[4][self.points]]
        if params.false_cue_constraints:
            rows += [gamma[0][self.points], gamma[1][self.points]]
        matrix = np.zeros((len(rows) * m, size))
        for i, block in enumerate(rows):
            matrix[i * m : (i + 1) * m, : self.n_inputs] = block
        if params.false_cue_constraints:
            matrix[2 * m : 4 * m, self.n_inputs :] = -np.eye(2 * m)
        self.constraints = matrix
        self.bounds = np.array([params.position_bound[axis]] * m + [params.angle_bound[rotation]] * m)
        self.thresholds = (
            THRESHOLDS["specific_force"][axis] * params.margin,
            THRESHOLDS["angular_velocity"][rotation] * params.margin,
        )
        self._upper = np.triu_indices(size)
        self._pattern = scipy.sparse.csc_matrix(np.triu(self.hessian))
        self._a_sparse = scipy.sparse.csc_matrix(matrix)
        self.solvers: dict[int, object] = {}

    def solver(self, row: int):
        import osqp

        if row not in self.solvers:
            size = self.n_inputs + self.n_slack
            solver = osqp.OSQP()
            rows = self.constraints.shape[0]
            solver.setup(self._pattern, np.zeros(size), self._a_sparse, -np.ones(rows), np.ones(rows), **OSQP_SETTINGS)
            self.solvers[row] = solver
        return self.solvers[row]

    def sign_bounds(self, reference: np.ndarray, threshold: float) -> tuple[np.ndarray, np.ndarray]:
        """The false-cue constraints' bounds for the vehicle's predicted perceived signal."""
        band = self.params.band * threshold / max(self.params.margin, 1e-9)
        low = np.where(reference > band, -threshold, np.where(reference < -band, -np.inf, -threshold))
        high = np.where(reference < -band, threshold, np.where(reference > band, np.inf, threshold))
        return low, high

    def solve(self, row: int, state: np.ndarray, f_ref: np.ndarray, w_ref: np.ndarray) -> tuple[np.ndarray, str]:
        """The first input (a, r) for the model state and the vehicle's perceived f and omega over the horizon."""
        free = np.einsum("ykx,x->yk", self.psi, state)  # the outputs with no input
        error = free[self.tracked]
        error[0] -= f_ref
        error[1] -= w_ref
        gradient = np.zeros(self.n_inputs + self.n_slack)
        gradient[: self.n_inputs] = 2.0 * np.einsum("y,ykm,yk->m", self.weights, self.gamma[self.tracked], error)
        low = [-self.bounds - np.concatenate([free[5][self.points], free[4][self.points]])]
        high = [self.bounds - np.concatenate([free[5][self.points], free[4][self.points]])]
        if self.params.false_cue_constraints:
            for out, ref, thr in ((0, f_ref, self.thresholds[0]), (1, w_ref, self.thresholds[1])):
                lo, hi = self.sign_bounds(ref[self.points], thr)
                low.append(lo - free[out][self.points])
                high.append(hi - free[out][self.points])
        low, high = np.concatenate(low), np.concatenate(high)
        solver = self.solver(row)
        solver.update(q=gradient, l=np.maximum(low, -1e30), u=np.minimum(high, 1e30))
        result = solver.solve(raise_error=False)
        status = result.info.status
        x = result.x
        # an infeasible programme (a state already past a hard workspace bound) returns OSQP's
        # certificate in x, not a solution: no input is the safe answer, as for a non-finite one
        if status not in SOLVED or x is None or not np.all(np.isfinite(x[: self.n_inputs])):
            return np.zeros(2), status
        blocks = self.n_inputs // 2
        return np.array([x[0], x[blocks]]), status


class CueingMPC:
    """The cueing MPC's state machine for a batch of vehicle motions side by side (module docstring).

    Args:
        params: the horizon, weights and bounds.
        dt: the control step, s.
        head_height: h, the head point's height above P's origin, m (the cabin turns about the head).

    Raises:
        ImportError: osqp is not installed (``stewart_env.extras.MissingExtra``, naming the extra ``mpc``).
    """

    def __init__(self, params: CueingMPCParams | None = None, dt: float = 0.01, head_height: float = 0.8):
        require("mpc", "the cueing MPC (stewart_env.agents.controllers.cueing_mpc)")
        self.params = params or CueingMPCParams()
        self.dt = float(dt)
        g = STANDARD_GRAVITY
        h = float(head_height)
        self.head_height = h
        # (x, pitch), (y, roll), (z, yaw): translation axis, rotation axis, coupling, arm
        self.pairs = (
            _PairQP(self.params, self.dt, -g, -h, 0, 1),
            _PairQP(self.params, self.dt, g, h, 1, 0),
            _PairQP(self.params, self.dt, 0.0, 0.0, 2, 2),
        )
        n = self.params.horizon
        self.otolith = foh_state_space(*Otolith().transfer_function(), self.dt)
        self.canal = foh_state_space(*SemicircularCanal().transfer_function(), self.dt)
        self.otolith_prediction = _siso_condensed(*self.otolith, n)
        self.canal_prediction = _siso_condensed(*self.canal, n)
        self.state: np.ndarray | None = None  # (rows, 3 pairs, 9)
        self.vehicle_otolith: np.ndarray | None = None  # (rows, 3 axes, 2)
        self.vehicle_canal: np.ndarray | None = None
        self.status: list[str] = []
        self._perceived_before: np.ndarray | None = None

    def reset(self, rows=None) -> None:
        """Start over (the rows ``rows`` of the batch, or all): the platform at home, at rest.

        Args:
            rows: a boolean mask or indices of the batch; None: everything.
        """
        if rows is None or self.state is None:
            self.state = self._perceived_before = None
            self.vehicle_otolith = self.vehicle_canal = None
            return
        rows = np.flatnonzero(np.asarray(rows)) if np.asarray(rows).dtype == bool else np.asarray(rows)
        self.state[rows] = 0.0
        if self._perceived_before is not None and self._perceived_before.shape[0] == self.state.shape[0]:
            self._perceived_before[rows] = 0.0
        self.vehicle_otolith[rows] = np.nan  # restarted steady at the next sample
        self.vehicle_canal[rows] = np.nan
        for pair in self.pairs:
            for row in rows.tolist():
                pair.solvers.pop(int(row), None)

    @staticmethod
    def _steady(model, u: np.ndarray) -> np.ndarray:
        phi, g, _, _ = model
        return np.einsum("ij,...j->...i", np.linalg.inv(np.eye(len(g)) - phi) @ g[:, None], u[..., None])

    def _advance_vehicle(self, f: np.ndarray, w: np.ndarray) -> None:
        rows = f.shape[0]
        if self.state is None or self.state.shape[0] != rows:
            self.state = np.zeros((rows, 3, 9))
            self.vehicle_otolith = np.full((rows, 3, 2), np.nan)
            self.vehicle_canal = np.full((rows, 3, 2), np.nan)
        for store, model, u in ((self.vehicle_otolith, self.otolith, f), (self.vehicle_canal, self.canal, w)):
            fresh = np.isnan(store[:, 0, 0])
            if fresh.any():
                store[fresh] = self._steady(model, u[fresh])
            phi, g, _, _ = model
            store[:] = store @ phi.T + u[..., None] * g

    def _perceived_reference(self, model_prediction, xi: np.ndarray, samples: np.ndarray) -> np.ndarray:
        psi, gamma = model_prediction
        return psi @ xi + gamma @ samples

    def step(self, specific_force, angular_velocity, preview=None) -> tuple[np.ndarray, np.ndarray]:
        """One control step: the head's displacement and the cabin's angles after it
        (:meth:`observe`, then :meth:`solve`, then :meth:`apply`).

        Args:
            specific_force: (rows, 3) the vehicle's specific force now, m/s², in {H}.
            angular_velocity: (rows, 3) its angular velocity now, rad/s.
            preview: (rows, k, 6) the next k samples [f, omega] (k may be 0), or None.

        Returns:
            (displacement (rows, 3) m, rpy (rows, 3) rad), relative to home, in {H}.
        """
        self.observe(specific_force, angular_velocity, preview)
        return self.apply(self.solve())

    def observe(self, specific_force, angular_velocity, preview=None) -> None:
        """Advance the vehicle's perception by the sample now and hold the horizon's reference: the
        samples after this one (the step's motion is compared with the next), the preview's, then
        its last held; with no preview, this sample held.

        Args:
            specific_force: (rows, 3) the vehicle's specific force now, m/s², in {H}.
            angular_velocity: (rows, 3) its angular velocity now, rad/s.
            preview: (rows, k, 6) the next k samples [f, omega] (k may be 0), or None.
        """
        f = np.array(specific_force, dtype=float, ndmin=2)
        f[:, 2] -= STANDARD_GRAVITY
        w = np.array(angular_velocity, dtype=float, ndmin=2)
        rows, n = f.shape[0], self.params.horizon
        self._advance_vehicle(f, w)
        ahead = np.zeros((rows, 0, 6)) if preview is None else np.asarray(preview, dtype=float)
        if ahead.shape[1]:
            ahead = ahead.copy()
            ahead[:, :, 2] -= STANDARD_GRAVITY
        samples = np.empty((rows, n, 6))
        if ahead.shape[1]:
            k = min(ahead.shape[1], n)
            samples[:, :k] = ahead[:, :k]
            samples[:, k:] = ahead[:, k - 1 : k]
        else:
            k = 0
            samples[:] = np.concatenate([f, w], axis=1)[:, None]
        if self.params.reference_decay is not None:
            samples[:, k:] *= np.exp(-self.dt * np.arange(1, n - k + 1) / self.params.reference_decay)[None, :, None]
        self._samples = samples
        self._perceived_before = self.state[:, :, 5:9].copy()

    def features(self) -> np.ndarray:
        """The controller's state after :meth:`observe`, what its programme starts from besides the
        reference: per pair the model's state (p, v, a, theta, r and the platform's perceived
        states, 9), then the vehicle's otolith and canal states (2 per axis each).

        Returns:
            (rows, 39) values.
        """
        rows = self.state.shape[0]
        return np.concatenate(
            [self.state.reshape(rows, 27), self.vehicle_otolith.reshape(rows, 6), self.vehicle_canal.reshape(rows, 6)],
            axis=1,
        )

    def solve(self) -> np.ndarray:
        """The first inputs of the programmes over the horizon (after :meth:`observe`); their
        solver's status per row and pair in ``status``.

        Returns:
            (rows, 3 pairs, 2) the jerk and the angular acceleration of each pair.
        """
        rows = self.state.shape[0]
        self.status = []
        inputs = np.zeros((rows, 3, 2))
        rotation_of = (1, 0, 2)  # pitch, roll, yaw: the rotation paired with x, y, z
        for i in range(rows):
            for axis, pair in enumerate(self.pairs):
                rot = rotation_of[axis]
                f_ref = self._perceived_reference(
                    self.otolith_prediction, self.vehicle_otolith[i, axis], self._samples[i, :, axis]
                )
                w_ref = self._perceived_reference(
                    self.canal_prediction, self.vehicle_canal[i, rot], self._samples[i, :, 3 + rot]
                )
                inputs[i, axis], status = pair.solve(i, self.state[i, axis], f_ref, w_ref)
                self.status.append(status)
        return inputs

    def apply(self, inputs) -> tuple[np.ndarray, np.ndarray]:
        """Move the model's state on under ``inputs``, held over the step.

        Args:
            inputs: (rows, 3 pairs, 2) the jerk and the angular acceleration of each pair.

        Returns:
            (displacement (rows, 3) m, rpy (rows, 3) rad), relative to home, in {H}.
        """
        self.inputs = np.array(inputs, dtype=float)
        rows = self.state.shape[0]
        displacement = np.zeros((rows, 3))
        rpy = np.zeros((rows, 3))
        rotation_of = (1, 0, 2)
        for i in range(rows):
            for axis, pair in enumerate(self.pairs):
                self.state[i, axis] = pair.a @ self.state[i, axis] + pair.b @ self.inputs[i, axis]
                displacement[i, axis] = self.state[i, axis, 0]
                rpy[i, rotation_of[axis]] = self.state[i, axis, 3]
        return displacement, rpy

    def correct(self, specific_force, angular_velocity) -> None:
        """Drive the platform's perceived state of the last step by the motion measured at the head.

        Args:
            specific_force: (rows, 3) the head's specific force over the last step, m/s², in {H}.
            angular_velocity: (rows, 3) its angular velocity, rad/s.
        """
        if self.state is None or self._perceived_before is None:
            return
        if self._perceived_before.shape[0] != self.state.shape[0]:
            return
        f = np.array(specific_force, dtype=float, ndmin=2)
        f[:, 2] -= STANDARD_GRAVITY
        w = np.asarray(angular_velocity, dtype=float)
        rotation_of = (1, 0, 2)
        (po, go, _, _), (pc, gc, _, _) = self.otolith, self.canal
        for axis in range(3):
            before = self._perceived_before[:, axis]
            self.state[:, axis, 5:7] = before[:, :2] @ po.T + f[:, axis, None] * go
            self.state[:, axis, 7:9] = before[:, 2:] @ pc.T + w[:, rotation_of[axis], None] * gc

    def loop_command(self) -> tuple[np.ndarray, np.ndarray]:
        """The pose command that makes the pose loop's response follow the plan (after :meth:`step`).

        The loop's response of each coordinate q of P's pose (its offset from home and its angles)
        to its command c is taken as q'' = w_n² (c(t - delay) - q) - 2 zeta w_n q' (``loop_*``);
        the command that makes q follow the planned q_d is its inverse,
        c = q_d + 2 zeta / w_n q_d' + q_d'' / w_n², of the plan ``delay`` steps after the step's end
        (the model's state moved on under the step's input, held as the block holds it).  The
        planned P = p + arm theta, its rate v + arm r, its acceleration a + arm alpha.

        Returns:
            (P's offset from home (rows, 3) m, the angles (rows, 3) rad): the pose to command.
        """
        rows = self.state.shape[0]
        planned = np.zeros((rows, 6))  # the plan's (p, theta) per coordinate, delay steps on
        rate = np.zeros((rows, 6))  # the rates and accelerations of P's offset and of the angles
        acceleration = np.zeros((rows, 6))
        delay = np.asarray(self.params.loop_delay, dtype=int)
        rotation_of = (1, 0, 2)
        for axis, pair in enumerate(self.pairs):
            rot = rotation_of[axis]
            for coordinate, steps in ((axis, delay[axis]), (3 + rot, delay[3 + rot])):
                x = self.state[:, axis].copy()
                for _ in range(int(steps)):
                    x = x @ pair.a.T + self.inputs[:, axis] @ pair.b.T
                alpha = self.inputs[:, axis, 1]
                if coordinate < 3:
                    planned[:, coordinate] = x[:, 0]
                    rate[:, coordinate] = x[:, 1] + pair.arm * x[:, 4]
                    acceleration[:, coordinate] = x[:, 2] + pair.arm * alpha
                else:
                    planned[:, coordinate] = x[:, 3]
                    rate[:, coordinate] = x[:, 4]
                    acceleration[:, coordinate] = alpha
        frequency = np.asarray(self.params.loop_frequency, dtype=float)
        damping = np.asarray(self.params.loop_damping, dtype=float)
        lead = 2.0 * damping / frequency * rate + acceleration / frequency**2
        offset = self.head_offset(planned[:, :3], planned[:, 3:]) + lead[:, :3]
        return offset, planned[:, 3:] + lead[:, 3:]

    def head_offset(self, displacement, rpy) -> np.ndarray:
        """P's offset from home of the head displaced by ``displacement``, the cabin turned by ``rpy``
        about it (in home's axes): displacement + head - R(rpy) head.

        Args:
            displacement: (..., 3) the head's displacement, m.
            rpy: (..., 3) the cabin's roll, pitch, yaw, rad.

        Returns:
            (..., 3) P's offset from home, m.
        """
        head = np.array([0.0, 0.0, self.head_height])
        return np.asarray(displacement) + head - rpy_to_matrix(np.asarray(rpy)) @ head


class CueingMPCPolicy:
    """The cueing MPC as a policy of the cueing task, with Stable-Baselines3's ``predict``, as
    :class:`~stewart_env.agents.controllers.washout.WashoutPolicy` is.

    It reads ``vehicle_specific_force``, ``vehicle_angular_velocity`` and, when the task observes
    one, ``preview`` (``decode_observation``): the reference it predicts with is what the
    environment observes, nothing more.  It commands the pose of its model's state after the step
    (``head_pose``), as the environment's pose action.

    Args:
        env: the cueing environment (single, vector or SB3 VecEnv), ``action_mode="pose"``.
        params: the MPC's parameters (default :class:`CueingMPCParams`).
        head: the head point in {P}, m (default the task's ``head``).

    Raises:
        UsageError: an environment without the vehicle parts or not in pose mode.
        ImportError: osqp is not installed (``stewart_env.extras.MissingExtra``, naming the extra ``mpc``).
    """

    PARTS = ("vehicle_specific_force", "vehicle_angular_velocity")

    def __init__(self, env, params: CueingMPCParams | None = None, head=None):
        require("mpc", "the cueing MPC (CueingMPCPolicy)")
        env = base = cueing_environment(env)
        missing = [k for k in self.PARTS if k not in base.observation_layout]
        if missing:
            raise UsageError.about("env", f"its observations lack {missing}; the cueing MPC needs task='cueing'")
        actuation = getattr(getattr(base, "_core", None), "actuation", None)
        if actuation is None or getattr(actuation, "pose_half", None) is None or not _pose_mode(base):
            raise UsageError.about("env", "the cueing MPC commands poses: make the environment with action_mode='pose'")
        if head is None:
            head = getattr(getattr(base, "task", None), "head", (0.0, 0.0, 0.0))
        self.head = np.asarray(head, dtype=float)
        if self.head.shape != (3,) or not np.all(np.isfinite(self.head)):
            raise UsageError.about("head", f"must be three finite numbers (m, in {{P}}), got {head!r}")
        self.env = env
        self.params = params or CueingMPCParams()
        self.mpc = CueingMPC(self.params, base.dt, float(self.head[2]))
        self._actuation = actuation
        self.preview = "preview" in base.observation_layout
        self._previous: tuple[np.ndarray, np.ndarray] | None = None
        if self.params.feedback and "velocity" not in base.observation_layout:
            raise UsageError.about("params", "feedback needs the platform's pose state: observation_mode='pose'")

    def reset(self) -> None:
        """Start every row over (a new batch of episodes)."""
        self.mpc.reset()
        self._previous = None

    def _measure(self, part: dict, episode_start) -> None:
        """The head's motion over the last step from the observed platform state (the task's
        ``head_motion``), into the MPC's perceived state."""
        from stewart_env.tasks.cueing.head import head_motion

        first = np.asarray(part["orientation"], dtype=float)[:, :3]
        second = np.asarray(part["orientation"], dtype=float)[:, 3:]
        rotation = np.stack([first, second, np.cross(first, second)], axis=2)
        velocity = np.asarray(part["velocity"], dtype=float)
        angular_velocity = np.asarray(part["angular_velocity"], dtype=float)
        rows = velocity.shape[0]
        if self._previous is None or self._previous[0].shape[0] != rows:
            self._previous = (np.zeros((rows, 3)), np.zeros((rows, 3)))
        elif episode_start is not None:
            starts = np.asarray(episode_start, dtype=bool).reshape(-1)
            self._previous[0][starts] = 0.0
            self._previous[1][starts] = 0.0
        platform = self.env.unwrapped.platform
        f, w = head_motion(
            rotation,
            velocity,
            angular_velocity,
            self._previous[0],
            self._previous[1],
            self.env.unwrapped.dt,
            self.head,
            np.asarray(platform.gravity, dtype=float),
            rpy_to_matrix(np.asarray(platform.home_rpy, dtype=float)),
        )
        self._previous = (velocity.copy(), angular_velocity.copy())
        self.mpc.correct(f, w)

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        """SB3's interface: (action (6,) or (N, 6), None) for one observation or a batch
        (:meth:`prepare`, the programmes' first inputs, then :meth:`command`).

        Args:
            observation: one observation (obs_dim,) or a batch (N, obs_dim).
            state: SB3's recurrent state; unused.
            episode_start: SB3's episode starts (N,) bool: those rows start over.
            deterministic: SB3's flag; unused (the policy is deterministic).

        Returns:
            (action, None).
        """
        self.prepare(observation, episode_start)
        return self.command(self.mpc.solve(), np.ndim(observation) == 1), None

    def prepare(self, observation, episode_start=None) -> np.ndarray:
        """Read an observation into the controller: the rows that start over, the platform's
        perceived state from the measured motion (``feedback``), the vehicle's sample and preview.

        Args:
            observation: one observation (obs_dim,) or a batch (N, obs_dim).
            episode_start: SB3's episode starts (N,) bool: those rows start over.

        Returns:
            (N, 39) the controller's state (:meth:`CueingMPC.features`).
        """
        obs = np.asarray(observation)
        part = self.env.unwrapped.decode_observation(np.atleast_2d(obs).astype(float))
        starts = starting_rows(episode_start)
        if starts is not None:
            self.mpc.reset(starts)
        preview = None
        if self.preview:
            values = np.asarray(part["preview"], dtype=float)
            preview = values.reshape(values.shape[0], -1, 6)
        if self.params.feedback:
            self._measure(part, episode_start)
        self.mpc.observe(part["vehicle_specific_force"], part["vehicle_angular_velocity"], preview)
        return self.mpc.features()

    def command(self, inputs, single: bool = False) -> np.ndarray:
        """The pose actions after :meth:`prepare` and the step's ``inputs`` (the programmes' or
        another policy's): the model moved on, and its pose commanded through the pose loop's inverse.

        Args:
            inputs: (N, 3 pairs, 2) the jerk and the angular acceleration of each pair.
            single: return the first row's (6,) action.

        Returns:
            The float32 pose actions, (N, 6) or (6,).
        """
        displacement, rpy = self.mpc.apply(inputs)
        if self.params.loop_frequency is None:
            position, rotation = head_pose(self.env.unwrapped.platform, self.head, displacement, rpy)
        else:
            platform = self.env.unwrapped.platform
            offset, angles = self.mpc.loop_command()
            home_rotation = rpy_to_matrix(np.asarray(platform.home_rpy, dtype=float))
            position = np.asarray(platform.home_position, dtype=float) + offset @ home_rotation.T
            rotation = home_rotation @ rpy_to_matrix(angles)
        return pose_actions(self._actuation, position, rotation, single)
