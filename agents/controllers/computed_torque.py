"""Computed-torque (inverse dynamics) control of the Stewart platform, and its policy face.

The law: the controller's own dynamics model (``internal_model``, chosen independently of the
plant's, e.g. a ``classical`` controller on an ``improved`` plant) is asked for the leg forces
that produce the commanded accelerations

    a_cmd     = a_d     + Kd (v_d - v)         + Kp (t_d - t)
    alpha_cmd = alpha_d + Kd (omega_d - omega) + Kp phi,     phi = rotation vector of R_d R^T

    F = inverse_dynamics_internal(t, R, v, omega, a_cmd, alpha_cmd)

all in {B}: t, v, a of P's origin (m, m/s, m/s^2), omega and alpha in rad/s and rad/s^2.  In
terms of the internal model's mass matrix and bias (:meth:`stewart_env.Dynamics.mass_and_bias`)
this is J^T F = M [a_cmd; alpha_cmd] + h; inverse dynamics evaluates exactly that in one
compiled call, without forming M.  With
an exact internal model the closed loop is the linear error dynamics
e'' + Kd e' + Kp e = 0 on every axis (to first order in the orientation error); a wrong
internal model leaves a model-error disturbance, which is what the mismatch studies measure.

The gains are accelerations per error, 1/s^2 and 1/s: Kp = wn^2, Kd = 2 zeta wn.  The default
wn = 20 rad/s, zeta = 1 matches the bandwidth of the PD baseline in the environment
(wn * control_dt = 0.2 at the default 10 ms hold), so the two controllers differ by their model,
not by their aggressiveness.
"""

from __future__ import annotations

import math

import numpy as np

import stewart_env as se
from stewart_env.agents.controllers.pd import EnvPolicy, _gain
from stewart_env.dynamics import ModelSpec
from stewart_env.params import PlatformParams
from stewart_env.rotations import rotation_error, rotvec_to_matrix
from stewart_env.state import PlatformState, Reference

#: Default natural frequency of the error dynamics, rad/s, and its damping ratio.
DEFAULT_NATURAL_FREQUENCY = 20.0
DEFAULT_DAMPING = 1.0


class ComputedTorque:
    """The computed-torque law (see the module docstring).

    Args:
        platform: the platform's parameters, as the controller believes them.
        internal_model: name of the controller's dynamics model (``"improved"``, ``"classical"``,
            ``"improved+c2"``, ...) or its :class:`~stewart_env.ModelSpec`, independent of the plant's.
        kp, kd: six gains [x, y, z, roll, pitch, yaw] in 1/s^2 and 1/s, or a scalar for all;
            default wn^2 and 2 zeta wn with wn = 20 rad/s, zeta = 1.

    Raises:
        ValueError: ``platform`` not PlatformParams, an unknown model name (a UsageError whose
            ``argument`` is ``"internal_model"``), or a gain not six finite numbers or a scalar.

    Examples:
        A 1 cm step up: Kp e = 400/s^2 x 0.01 m = 4 m/s^2 commanded upwards, turned into leg
        forces by the internal model:

        >>> import numpy as np, stewart_env as se
        >>> from stewart_env.state import PlatformState, Reference
        >>> from stewart_env.agents.controllers.computed_torque import ComputedTorque
        >>> params = se.load_platform("dasgupta1998")
        >>> controller = ComputedTorque(params, internal_model="classical")
        >>> state = PlatformState(params.home_position, np.eye(3), np.zeros(3), np.zeros(3))
        >>> target = Reference(params.home_position + [0, 0, 0.01], np.eye(3), np.zeros(3), np.zeros(3),
        ...                    np.zeros(3), np.zeros(3))
        >>> print(np.round(controller.commanded_acceleration(state, target), 3) + 0.0)
        [0. 0. 4. 0. 0. 0.]
        >>> controller(state, target).shape
        (6,)
    """

    def __init__(self, platform: PlatformParams, internal_model: str | ModelSpec = "improved", kp=None, kd=None):
        if not isinstance(platform, PlatformParams):
            raise ValueError(f"platform: expected PlatformParams, got {type(platform).__name__}")
        self.platform = platform
        self.model = se.make_dynamics(se.ModelSpec.parse(internal_model, "internal_model"), platform)
        self.internal_model = self.model.name
        wn, zeta = DEFAULT_NATURAL_FREQUENCY, DEFAULT_DAMPING
        self.kp = _gain(wn**2 if kp is None else kp, "kp")
        self.kd = _gain(2 * zeta * wn if kd is None else kd, "kd")

    def commanded_acceleration(self, state: PlatformState, reference: Reference) -> np.ndarray:
        """The commanded acceleration: feedforward + Kd (error rate) + Kp (error).

        Args:
            state: the platform's state (may be batched).
            reference: the target, its accelerations the feedforward (may be batched).

        Returns:
            [a_cmd; alpha_cmd] (6,) or (N,6) in m/s^2 and rad/s^2, {B}.
        """
        v = np.asarray(state.velocity, float)
        w = np.asarray(state.angular_velocity, float)
        error = np.concatenate(
            [
                np.asarray(reference.position, float) - state.position,
                rotation_error(reference.rotation, state.rotation)[0],
            ],
            axis=-1,
        )
        error_rate = np.concatenate([reference.velocity - v, reference.angular_velocity - w], axis=-1)
        feedforward = np.concatenate(np.broadcast_arrays(reference.lin_acc, reference.ang_acc, v)[:2], axis=-1)
        return feedforward + self.kd * error_rate + self.kp * error

    def __call__(self, state: PlatformState, reference: Reference) -> np.ndarray:
        """Leg forces from the internal model's inverse dynamics at the commanded acceleration.

        Args:
            state: the platform's state (may be batched).
            reference: the target (may be batched).

        Returns:
            The leg forces (6,) or (N,6), N.
        """
        acc = self.commanded_acceleration(state, reference)
        return self.model.inverse(
            state.position, state.rotation, state.velocity, state.angular_velocity, acc[..., :3], acc[..., 3:]
        )


def preview_acceleration(position_step, rotation_step, velocity, angular_velocity, horizons) -> np.ndarray:
    """The reference's acceleration [lin_acc; ang_acc] from samples of its future.

    Each axis is fitted by its Taylor polynomial x(h) = x1 h + x2 h^2/2! + ... + xm h^m/m!,
    m = min(K + 1, 4), with x1 fixed by the known twist (exact interpolation for K <= 3, least
    squares beyond); x2 is the acceleration.  The rotation vector of R(t + h) R(t)^T equals
    omega h + alpha h^2 / 2 to second order, so the same fit gives the angular acceleration in {B}.

    Args:
        position_step: (N,K,3) r(t + h_k) - r(t), m.
        rotation_step: (N,K,3) rotation vectors of R(t + h_k) R(t)^T, rad.
        velocity: (N,3) the reference's velocity at t, m/s.
        angular_velocity: (N,3) the reference's angular velocity at t, rad/s.
        horizons: (K,) the sample times h_k, s.

    Returns:
        [lin_acc; ang_acc], (N,6) in m/s^2 and rad/s^2.

    Examples:
        A uniformly accelerated reference, 2 m/s^2 along x:

        >>> import numpy as np
        >>> from stewart_env.agents.controllers.computed_torque import preview_acceleration
        >>> h = np.array([0.1, 0.2, 0.3])
        >>> position_step = np.zeros((1, 3, 3)); position_step[0, :, 0] = h**2
        >>> acc = preview_acceleration(position_step, np.zeros((1, 3, 3)), np.zeros((1, 3)), np.zeros((1, 3)), h)
        >>> print(np.round(acc, 6) + 0.0)
        [[2. 0. 0. 0. 0. 0.]]
    """
    h = np.asarray(horizons, dtype=float)
    orders = range(2, min(h.size + 1, 4) + 1)
    basis = np.stack([h**n / math.factorial(n) for n in orders], axis=1)  # (K, m - 1)
    twist = np.concatenate([velocity, angular_velocity], axis=-1)  # (N, 6)
    steps = np.concatenate([position_step, rotation_step], axis=-1)  # (N, K, 6)
    residual = steps - twist[:, None, :] * h[None, :, None]
    return (np.linalg.pinv(basis) @ residual)[:, 0, :]


class ComputedTorquePolicy(EnvPolicy):
    """The computed-torque law as a policy on ``StewartPlatform-v1`` (see :class:`EnvPolicy`).

    The internal model runs on the environment's nominal platform parameters, or on ``platform``
    when given.  Feedforward: the
    environment does not expose the reference's acceleration, so on the tracking task the policy
    estimates it from the observation itself, fitting the reference preview (future reference
    poses at t + k dt_preview) and the reference twist with :func:`preview_acceleration`; without
    a preview (set point, disturbance: a fixed reference) the feedforward is zero.

    Args:
        env: the environment (or its vector environment) with ``observation_mode="pose"``.
        internal_model: the controller's dynamics model name (default ``"improved"``).
        platform: the platform the controller believes (a :class:`~stewart_env.PlatformParams`,
            e.g. an identified one); default the environment's nominal platform.
        kp, kd: gains as in :class:`ComputedTorque`.
    """

    def __init__(
        self,
        env,
        internal_model: str | ModelSpec = "improved",
        kp=None,
        kd=None,
        platform: PlatformParams | None = None,
    ):
        believed = env.unwrapped.platform if platform is None else platform
        super().__init__(env, ComputedTorque(believed, internal_model, kp, kd))
        base = env.unwrapped
        preview = getattr(base.task, "preview", 0) if "reference_preview" in base.observation_layout else 0
        self._horizons = getattr(base.task, "preview_interval", 0.0) * np.arange(1, preview + 1)

    def reference(self, state: PlatformState, part: dict[str, np.ndarray]) -> Reference:
        """The target of decoded observations, as ``EnvPolicy.reference`` reads it, with the
        accelerations fitted to the reference preview when the observation carries the preview and
        the twist errors (else zero).

        Args:
            state: the platform's decoded state (N rows).
            part: the decoded observation, entry name -> (N, size) in physical units.
        """
        ref = super().reference(state, part)
        if not self._horizons.size or "velocity_error" not in part:
            return ref
        n, k = state.position.shape[0], self._horizons.size
        preview = part["reference_preview"].reshape(n, k, 6)
        # the preview is the future reference minus the platform now; the fit wants it minus the
        # reference now
        position_step = preview[:, :, :3] - part["position_error"][:, None, :]
        future = rotvec_to_matrix(preview[:, :, 3:].reshape(n * k, 3)) @ np.repeat(state.rotation, k, axis=0)
        rotation_step = rotation_error(future, np.repeat(ref.rotation, k, axis=0))[0].reshape(n, k, 3)
        acc = preview_acceleration(position_step, rotation_step, ref.velocity, ref.angular_velocity, self._horizons)
        return ref._replace(lin_acc=acc[:, :3], ang_acc=acc[:, 3:])
