"""A linearised model-predictive controller with the leg force limits as constraints (extra ``mpc``: OSQP).

At every control step the controller linearises its internal model's control step at the current
state, under the feed-forward forces F_ff (the reference's inverse dynamics, as
:class:`~stewart_env.agents.controllers.lqr.LinearQuadraticRegulator`'s): A, B and the next state
of :meth:`~stewart_env.dynamics.Dynamics.step_jacobians`.  In the error coordinates e (the
state's tangent error about the reference, :func:`~stewart_env.agents.controllers.lqr.tangent_error`)
the prediction over the horizon is affine,

    e_{k+1} = A e_k + B u_k + d,     u_k = F_k - F_ff,

with d = e(next state under F_ff, reference moved on by one step at its twist and accelerations)
- A e_0, the same at every step of the horizon (the reference keeps its accelerations, the
Jacobians their values).  The
controller minimises

    sum_{k=1}^{N-1} e_k^T Q e_k + e_N^T P e_N + sum_{k=0}^{N-1} u_k^T R u_k

subject to the leg force limits F_min <= F_ff + u_k <= F_max (the platform's
``limits.leg_force``), a quadratic programme in the N six-vectors u_k (the states eliminated),
solved by OSQP warm-started from the previous step's solution, and applies F_ff + u_0.  Q and R
are the LQR's (Bryson's rule, ``STATE_SCALES``,
``FORCE_SCALE``) and P the LQR's Riccati solution at home,
so that with no constraint active the controller is the LQR, relinearised.  Horizon: N =
``DEFAULT_HORIZON`` = 10 steps (100 ms at the 10 ms control step, about twice the closed
loop's slowest time constant).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.sparse

from stewart_env.agents.controllers.lqr import FORCE_SCALE, LinearQuadraticRegulator, LQRPolicy, tangent_error
from stewart_env.dynamics import ModelSpec
from stewart_env.extras import require
from stewart_env.params import PlatformParams
from stewart_env.rotations import rotvec_to_matrix
from stewart_env.state import PlatformState, Reference

__all__ = ["DEFAULT_HORIZON", "OSQP_SETTINGS", "LinearisedMPC", "MPCPolicy"]

#: The prediction horizon, control steps.
DEFAULT_HORIZON = 10
#: OSQP's settings: tolerances of 1e-6 (relative to forces of hundreds of newtons, below a
#: millinewton) and polishing off, since the warm start usually meets them in a few iterations.
OSQP_SETTINGS = {"verbose": False, "eps_abs": 1e-6, "eps_rel": 1e-6, "polishing": False, "warm_starting": True}


class LinearisedMPC:
    """The linearised MPC (see the module docstring), for one platform or a batch (one QP each).

    Args:
        platform: the platform's parameters, as the controller believes them (its
            ``limits.leg_force`` the constraints).
        internal_model: the controller's dynamics model name or :class:`~stewart_env.ModelSpec`.
        control_dt: the control step, s.
        substeps: its RK4 substeps.
        horizon: N, the control steps predicted (>= 1).
        state_scales, force_scale: the weights, as in :class:`LinearQuadraticRegulator`.

    Raises:
        ValueError: as :class:`LinearQuadraticRegulator`, or a bad ``horizon``.
        ImportError: osqp is not installed (``stewart_env.extras.MissingExtra``, naming the extra ``mpc``).

    Examples:
        A 15 cm step up asks for more than the LQR's unconstrained gain allows; the MPC keeps the
        forces within the limits:

        >>> import numpy as np, stewart_env as se
        >>> from stewart_env.state import PlatformState, Reference
        >>> from stewart_env.agents.controllers.mpc import LinearisedMPC
        >>> params = se.load_platform("dasgupta1998")
        >>> mpc = LinearisedMPC(params, control_dt=0.01, substeps=10)
        >>> state = PlatformState(params.home_position, np.eye(3), np.zeros(3), np.zeros(3))
        >>> target = Reference(params.home_position + [0, 0, 0.15], np.eye(3), np.zeros(3), np.zeros(3))
        >>> forces = mpc(state, target)
        >>> bool(forces.max() <= params.limits.leg_force[1] + 1e-3)
        True
    """

    def __init__(
        self,
        platform: PlatformParams,
        internal_model: str | ModelSpec = "improved",
        control_dt: float = 0.01,
        substeps: int = 1,
        horizon: int = DEFAULT_HORIZON,
        state_scales=None,
        force_scale: float = FORCE_SCALE,
    ):
        require("mpc", "the model-predictive controller (stewart_env.agents.controllers.mpc)")
        if isinstance(horizon, bool) or not isinstance(horizon, (int, np.integer)) or not 1 <= horizon <= 1000:
            raise ValueError(f"horizon: expected an integer number of control steps from 1 to 1000, got {horizon!r}")
        self.lqr = LinearQuadraticRegulator(platform, internal_model, control_dt, substeps, state_scales, force_scale)
        self.model = self.lqr.model
        self.internal_model = self.lqr.internal_model
        self.control_dt, self.substeps, self.horizon = float(control_dt), int(substeps), int(horizon)
        self.force_limits = tuple(float(f) for f in platform.limits.leg_force)
        n = 6 * self.horizon
        # the weights over the horizon: Q at steps 1..N-1, P at N; R on every input
        self._q_bar = scipy.linalg.block_diag(*([self.lqr.Q] * (self.horizon - 1) + [self.lqr.P]))
        self._r_bar = np.kron(np.eye(self.horizon), self.lqr.R)
        rows, cols = np.nonzero(np.triu(np.ones((n, n))))
        order = np.lexsort((rows, cols))  # CSC order of the upper triangle: by column, then row
        self._upper = (rows[order], cols[order])
        self._pattern = scipy.sparse.csc_matrix((np.ones(order.size), self._upper), shape=(n, n))
        self._solvers: dict[int, object] = {}
        self.solve_status: list[str] = []

    def _solver(self, row: int):
        import osqp

        if row not in self._solvers:
            n = 6 * self.horizon
            solver = osqp.OSQP()
            solver.setup(
                self._pattern,
                np.zeros(n),
                scipy.sparse.identity(n, format="csc"),
                -np.ones(n),
                np.ones(n),
                **OSQP_SETTINGS,
            )
            self._solvers[row] = solver
        return self._solvers[row]

    def prediction(self, A: np.ndarray, B: np.ndarray):
        """The condensed prediction E = S_x e_0 + S_u U + S_d of e_1..e_N over the horizon.

        Args:
            A: (12,12) the step's state Jacobian.
            B: (12,6) its force Jacobian.

        Returns:
            The matrices S_x (12N, 12), S_u (12N, 6N) and S_1 (12N, 12), S_1 d the affine term's part.
        """
        n = self.horizon
        powers = [np.eye(12)]
        for _ in range(n):
            powers.append(A @ powers[-1])
        s_x = np.vstack(powers[1:])
        s_u = np.zeros((12 * n, 6 * n))
        s_1 = np.zeros((12 * n, 12))
        for k in range(n):  # e_{k+1} = A^{k+1} e_0 + sum_{j<=k} A^{k-j} (B u_j + d)
            for j in range(k + 1):
                s_u[12 * k : 12 * k + 12, 6 * j : 6 * j + 6] = powers[k - j] @ B
            s_1[12 * k : 12 * k + 12] = sum(powers[: k + 1])
        return s_x, s_u, s_1

    def __call__(self, state: PlatformState, reference: Reference) -> np.ndarray:
        """Leg forces: the first of the horizon's optimal forces (see the module docstring).

        Args:
            state: the platform's state (may be batched: one QP per row, each warm-started from
                its row's previous solution).
            reference: the target (may be batched).

        Returns:
            The leg forces (6,) or (N,6), N.
        """
        batched = np.ndim(state.position) == 2 or np.ndim(reference.position) == 2
        feedforward = np.atleast_2d(self.lqr.feedforward(reference))
        e0 = np.atleast_2d(tangent_error(state, reference))
        count = max(feedforward.shape[0], e0.shape[0])
        feedforward, e0 = (np.broadcast_to(a, (count, a.shape[1])) for a in (feedforward, e0))
        position, rotation, velocity, angular_velocity = (
            np.broadcast_to(np.asarray(x, float), (count, *np.shape(x)[-k:]))
            for x, k in (
                (state.position, 1),
                (state.rotation, 2),
                (state.velocity, 1),
                (state.angular_velocity, 1),
            )
        )
        step = self.model.step_jacobians(
            position,
            rotation,
            velocity,
            angular_velocity,
            np.ascontiguousarray(feedforward),
            self.control_dt,
            self.substeps,
        )
        moved = _advanced(reference, self.control_dt)
        d_all = tangent_error(step.state, moved) - np.einsum("nij,nj->ni", step.A, e0)
        low, high = self.force_limits
        out = np.empty((count, 6))
        self.solve_status = []
        for i in range(count):
            if not np.isfinite(step.A[i]).all():  # a singular pose: no model to predict with
                out[i] = feedforward[i]
                self.solve_status.append("singular pose")
                continue
            s_x, s_u, s_1 = self.prediction(step.A[i], step.B[i])
            free = s_x @ e0[i] + s_1 @ d_all[i]
            weighted = s_u.T @ self._q_bar
            hessian = 2.0 * (weighted @ s_u + self._r_bar)
            gradient = 2.0 * weighted @ free
            solver = self._solver(i)
            ff = np.tile(feedforward[i], self.horizon)
            solver.update(Px=hessian[self._upper], q=gradient, l=low - ff, u=high - ff)
            result = solver.solve(raise_error=False)
            self.solve_status.append(result.info.status)
            u0 = result.x[:6] if result.x is not None and np.isfinite(result.x[:6]).all() else np.zeros(6)
            out[i] = feedforward[i] + u0
        return out if batched else out[0]


def _advanced(reference: Reference, dt: float) -> Reference:
    """The reference moved on by ``dt`` s at its twist and accelerations (held over the step):
    position + v dt + a dt^2/2, exp([w dt + alpha dt^2/2]x) R, v + a dt, w + alpha dt."""
    velocity, angular_velocity = np.asarray(reference.velocity, float), np.asarray(reference.angular_velocity, float)
    lin_acc, ang_acc = np.asarray(reference.lin_acc, float), np.asarray(reference.ang_acc, float)
    position = np.asarray(reference.position, float) + dt * velocity + 0.5 * dt**2 * lin_acc
    rotation = rotvec_to_matrix(dt * angular_velocity + 0.5 * dt**2 * ang_acc) @ reference.rotation
    return Reference(position, rotation, velocity + dt * lin_acc, angular_velocity + dt * ang_acc)


class MPCPolicy(LQRPolicy):
    """The linearised MPC as a policy on ``StewartPlatform-v1``: the state and the target as the
    LQR's and computed torque's policies read them, the prediction for the environment's control
    step (``control_dt`` and its RK4 substeps) on the controller's model of the environment's
    nominal platform, or of ``platform``.

    Args:
        env: the environment (or its vector environment) with ``observation_mode="pose"``.
        internal_model: the controller's dynamics model name (default ``"improved"``).
        platform: the platform the controller believes (default the environment's nominal one).
        horizon: N, the control steps predicted (default ``DEFAULT_HORIZON``).
        state_scales, force_scale: the weights, as in :class:`LinearQuadraticRegulator`.

    Raises:
        ImportError: osqp is not installed (``stewart_env.extras.MissingExtra``, naming the extra ``mpc``).
    """

    def __init__(
        self,
        env,
        internal_model: str | ModelSpec = "improved",
        platform: PlatformParams | None = None,
        horizon: int = DEFAULT_HORIZON,
        state_scales=None,
        force_scale: float = FORCE_SCALE,
    ):
        from stewart_env.agents.controllers.lqr import env_substeps

        require("mpc", "the model-predictive controller (MPCPolicy)")
        super().__init__(env, internal_model, platform, state_scales, force_scale)
        believed = env.unwrapped.platform if platform is None else platform
        self.controller = LinearisedMPC(
            believed, internal_model, env.unwrapped.dt, env_substeps(env), horizon, state_scales, force_scale
        )
