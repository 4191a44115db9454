"""A linear-quadratic regulator around the home pose, from the exact Jacobians of the control step.

The law.  With the error x - x_d in the tangent coordinates of the state
(:mod:`stewart_env.dynamics.derivatives`): e = (t - t_d, dtheta, v - v_d, w - w_d), dtheta the
rotation vector of R R_d^T (a left perturbation in {B}), the controller asks for the leg forces

    F = F_ff - K e,    F_ff = inverse_dynamics(t_d, R_d, v_d, w_d, a_d, alpha_d)

of its internal model (``internal_model``, independent of the plant's, as computed torque's): the
feed-forward is the reference's inverse dynamics, the holding forces at a set point (gravity
compensation) and, on the tracking task, the forces of the reference's motion too.  K is the
discrete-time LQR gain of the control step linearised at home: A = d x_next / d x and
B = d x_next / d F of :meth:`~stewart_env.dynamics.Dynamics.step_jacobians` at the home pose, at
rest, under the holding forces (``substeps`` RK4 substeps of ``control_dt`` with the forces held,
the environment's own step), and P the stabilising solution of the discrete algebraic Riccati
equation (:func:`scipy.linalg.solve_discrete_are`), K = (R + B^T P B)^-1 B^T P A.

The weights, by Bryson's rule (each the inverse square of what one accepts of it):
Q = diag(1/dx_max^2), R = I / F_max^2 with the maxima ``STATE_SCALES`` (3 mm of position,
0.01 rad of orientation, 0.05 m/s, 0.5 rad/s) and ``FORCE_SCALE`` (200 N per leg).  On the
dasgupta1998 platform they place the closed loop's slowest pole at a modulus of 0.84 per
10 ms step (:meth:`LinearQuadraticRegulator.spectral_radius`), a time constant of about 60 ms,
comparable with computed torque's wn = 20 rad/s.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

import stewart_env as se
from stewart_env.agents.controllers.computed_torque import ComputedTorquePolicy
from stewart_env.dynamics import ModelSpec
from stewart_env.params import PlatformParams
from stewart_env.rotations import rotation_error
from stewart_env.state import PlatformState, Reference

__all__ = [
    "FORCE_SCALE",
    "STATE_SCALES",
    "LQRPolicy",
    "LinearQuadraticRegulator",
    "home_linearisation",
    "tangent_error",
]

#: Bryson's maxima of the state's error: position (m), orientation (rad), velocity (m/s), angular
#: velocity (rad/s), three of each: Q = diag(1 / STATE_SCALES^2).
STATE_SCALES = np.repeat([3e-3, 1e-2, 5e-2, 0.5], 3)
#: Bryson's maximum of each leg's force about the feed-forward, N: R = I / FORCE_SCALE^2.
FORCE_SCALE = 200.0


def tangent_error(state: PlatformState, reference: Reference) -> np.ndarray:
    """The state's error in the tangent coordinates: (t - t_d, dtheta, v - v_d, w - w_d), R = exp([dtheta]x) R_d.

    Args:
        state: the platform's state, fields (3,) / (3,3) or batched (N, ...).
        reference: the target, likewise (broadcast against the state).

    Returns:
        e (12,) or (N,12): m, rad, m/s, rad/s, {B}.
    """
    dtheta = rotation_error(state.rotation, reference.rotation)[0]
    parts = np.broadcast_arrays(
        np.asarray(state.position, float) - reference.position,
        dtheta,
        np.asarray(state.velocity, float) - reference.velocity,
        np.asarray(state.angular_velocity, float) - reference.angular_velocity,
    )
    return np.concatenate(parts, axis=-1)


def home_linearisation(model: se.Dynamics, control_dt: float, substeps: int = 1):
    """The control step linearised at the home pose, at rest, under the holding forces.

    Args:
        model: the dynamics model (its first parameter row).
        control_dt: the control step, s.
        substeps: its RK4 substeps.

    Returns:
        (A (12,12), B (12,6), holding forces (6,) N) in the tangent coordinates
        (:mod:`stewart_env.dynamics.derivatives`).
    """
    params = model.params[0]
    home = (params.home_position, se.rpy_to_matrix(params.home_rpy), np.zeros(3), np.zeros(3))
    holding = model.inverse(*home, np.zeros(3), np.zeros(3))
    step = model.step_jacobians(*home, holding, control_dt, substeps)
    return step.A, step.B, holding


class LinearQuadraticRegulator:
    """The LQR law F = F_ff - K e (see the module docstring).

    Args:
        platform: the platform's parameters, as the controller believes them.
        internal_model: the controller's dynamics model name or :class:`~stewart_env.ModelSpec`
            (its Jacobians and its feed-forward), independent of the plant's.
        control_dt: the control step the gain is computed for, s.
        substeps: the step's RK4 substeps.
        state_scales: Bryson's maxima of the error (12,) (default ``STATE_SCALES``).
        force_scale: Bryson's maximum of each leg's force, N (default ``FORCE_SCALE``).

    Raises:
        ValueError: ``platform`` not PlatformParams, an unknown model (a UsageError naming
            ``internal_model``), or scales not positive and finite.

    Examples:
        At the reference the law gives the feed-forward alone, the holding forces at home:

        >>> import numpy as np, stewart_env as se
        >>> from stewart_env.state import PlatformState, Reference
        >>> from stewart_env.agents.controllers.lqr import LinearQuadraticRegulator
        >>> params = se.load_platform("dasgupta1998")
        >>> lqr = LinearQuadraticRegulator(params, control_dt=0.01, substeps=10)
        >>> at_home = (params.home_position, np.eye(3), np.zeros(3), np.zeros(3))
        >>> print(np.round(lqr(PlatformState(*at_home), Reference(*at_home)), 1))
        [193.9 145.4 153.1 172.3 159.6 188.9]
        >>> bool(lqr.spectral_radius() < 1)    # the sampled closed loop is stable
        True
    """

    def __init__(
        self,
        platform: PlatformParams,
        internal_model: str | ModelSpec = "improved",
        control_dt: float = 0.01,
        substeps: int = 1,
        state_scales=None,
        force_scale: float = FORCE_SCALE,
    ):
        if not isinstance(platform, PlatformParams):
            raise ValueError(f"platform: expected PlatformParams, got {type(platform).__name__}")
        scales = STATE_SCALES if state_scales is None else np.asarray(state_scales, dtype=float)
        if scales.shape != (12,) or not np.all(np.isfinite(scales)) or np.any(scales <= 0):
            raise ValueError(f"state_scales: expected 12 positive finite numbers, got {state_scales!r}")
        if not (np.isfinite(force_scale) and force_scale > 0):
            raise ValueError(f"force_scale: expected a positive number of newtons, got {force_scale!r}")
        self.platform = platform
        self.model = se.make_dynamics(ModelSpec.parse(internal_model, "internal_model"), platform)
        self.internal_model = self.model.name
        self.control_dt = float(control_dt)
        self.A, self.B, self.holding_forces = home_linearisation(self.model, control_dt, substeps)
        self.Q = np.diag(1.0 / scales**2)
        self.R = np.eye(6) / force_scale**2
        self.P = scipy.linalg.solve_discrete_are(self.A, self.B, self.Q, self.R)
        self.K = np.linalg.solve(self.R + self.B.T @ self.P @ self.B, self.B.T @ self.P @ self.A)

    def spectral_radius(self) -> float:
        """The largest modulus of the eigenvalues of A - B K, the closed loop at home (< 1: stable)."""
        return float(np.abs(np.linalg.eigvals(self.A - self.B @ self.K)).max())

    def feedforward(self, reference: Reference) -> np.ndarray:
        """The internal model's inverse dynamics at the reference (its twist and accelerations).

        Args:
            reference: the target (may be batched).

        Returns:
            The leg forces (6,) or (N,6), N.
        """
        return self.model.inverse(
            reference.position,
            reference.rotation,
            reference.velocity,
            reference.angular_velocity,
            reference.lin_acc,
            reference.ang_acc,
        )

    def __call__(self, state: PlatformState, reference: Reference) -> np.ndarray:
        """Leg forces F_ff - K e for a state and a reference.

        Args:
            state: the platform's state (may be batched).
            reference: the target (may be batched).

        Returns:
            The leg forces (6,) or (N,6), N.
        """
        return self.feedforward(reference) - tangent_error(state, reference) @ self.K.T


def env_substeps(env) -> int:
    """The RK4 substeps of one control step of ``env``'s closed-form plant.

    Args:
        env: a ``StewartPlatform-v1`` environment (or its vector environment).
    """
    return int(env.unwrapped._core.config.physics.substeps)


class LQRPolicy(ComputedTorquePolicy):
    """The LQR law as a policy on ``StewartPlatform-v1``: it reads the state and the target (with
    the reference's accelerations fitted to the preview on the tracking task) as computed
    torque's policy does, and maps the forces to actions likewise (:class:`EnvPolicy
    <stewart_env.agents.controllers.pd.EnvPolicy>`).

    The gain is computed for the environment's control step (``control_dt`` and its RK4
    substeps) on the controller's model of the environment's nominal platform, or of ``platform``.

    Args:
        env: the environment (or its vector environment) with ``observation_mode="pose"``.
        internal_model: the controller's dynamics model name (default ``"improved"``).
        platform: the platform the controller believes (default the environment's nominal one).
        state_scales, force_scale: the weights, as in :class:`LinearQuadraticRegulator`.

    Examples:
        >>> import gymnasium as gym
        >>> from stewart_env.agents.controllers.lqr import LQRPolicy
        >>> env = gym.make("StewartPlatform-v1", task="setpoint")
        >>> policy = LQRPolicy(env, "classical")
        >>> observation, info = env.reset(seed=0)
        >>> policy.predict(observation)[0].shape
        (6,)
    """

    def __init__(
        self,
        env,
        internal_model: str | ModelSpec = "improved",
        platform: PlatformParams | None = None,
        state_scales=None,
        force_scale: float = FORCE_SCALE,
    ):
        super().__init__(env, internal_model, platform=platform)
        believed = env.unwrapped.platform if platform is None else platform
        self.controller = LinearQuadraticRegulator(
            believed, internal_model, env.unwrapped.dt, env_substeps(env), state_scales, force_scale
        )
