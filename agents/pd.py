"""Task-space PD control of the Stewart platform (He et al. 2018, eq. 56), and its policy face.

The law: with the pose error e = [t_d - t; theta_d - theta] (position of P's origin in {B}, m;
roll-pitch-yaw angles, rad) and its rate edot = [v_d - v; thetadot_d - thetadot] (angle rates from
the angular velocity, thetadot = E(theta)^-1 omega), the controller asks for the platform wrench

    W = Kp e + Kd edot        (force at P's origin, N; moment, N m; both in {B})

and realises it with the leg forces F = J^-T W, since leg forces F act on the platform as the
wrench J^T F (J the leg Jacobian, dL/dt = J [v; omega]).  Optionally the static holding forces
of the current pose are added (gravity compensation, see :class:`TaskSpacePD`).

Two faces:

* :class:`TaskSpacePD` maps a platform state and a :class:`DesiredMotion` to leg forces; it is a
  continuous-time law, called at every integrator stage in :mod:`stewart_env.agents.reproduce`.
* :class:`PDPolicy` wraps it for the environment with Stable-Baselines3's ``predict``: it reads
  the state and the target out of the observation, and maps the forces to actions.

Gains.  The paper's gains (:data:`PAPER_KP`, :data:`PAPER_KD`) belong to continuous control: on
the 45 kg platform they put the vertical axis at about 300 rad/s, which the environment's 10 ms
zero-order hold cannot follow (the sampled loop is unstable, see :func:`zoh_spectral_radius`).
:func:`zoh_pd_gains` places the poles of every axis instead: Kp_j = M_jj wn^2,
Kd_j = 2 zeta M_jj wn, with M the task-space inertia at the home pose and wn = bandwidth /
control_dt.  The default bandwidth 0.2 (wn = 20 rad/s at 10 ms) and zeta = 1 give a sampled loop
with spectral radius 0.88 on the dasgupta1998 platform, still stable if the inertia is halved
or doubled, and settle the set-point task to 2 mm in about 0.3 s.  As the law is specified, the
environment policy has no gravity compensation by default, and the weight carried by the legs
(480 N) makes the platform sag by 480 N / Kp_z = 27 mm at these gains (4.3 mm at bandwidth 0.5,
where the sampled loop contracts fastest, spectral radius 0.74).  ``gravity_compensation=True``
adds the holding forces: the sag goes, and what is left on a plant whose statics differ from the
compensation's (the classical model) is about 0.02 mm.

The policies take the environment's observation as the current state: they do not model an
actuator lag (``actuator_tau``) or an observation delay.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.linalg

import stewart_env as se
from stewart_env.params import PlatformParams
from stewart_env.rotations import rotvec_to_matrix, rpy_rate_matrix
from stewart_env.state import PlatformState

#: Proportional gains of the paper's case study, [x, y, z, roll, pitch, yaw]: N/m and N m/rad.
PAPER_KP = np.array([4e5, 4e5, 4e6, 5e4, 5e4, 1e5])
#: Derivative gains of the paper's case study: N s/m and N m s/rad.
PAPER_KD = np.array([1e4, 1e4, 2e4, 1e3, 1e3, 2e3])


class DesiredMotion(NamedTuple):
    """A desired motion of the platform in {B}; fields as in :class:`~stewart_env.state.PlatformState`.

    lin_acc (3,) m/s^2 and ang_acc (3,) rad/s^2 are the reference accelerations (feedforward of
    the computed-torque law).  Rates and accelerations left as None are zero (a set point).
    """

    position: np.ndarray
    rotation: np.ndarray
    velocity: np.ndarray | None = None
    angular_velocity: np.ndarray | None = None
    lin_acc: np.ndarray | None = None
    ang_acc: np.ndarray | None = None


def _rates(value, like: np.ndarray) -> np.ndarray:
    """A reference rate broadcast to the shape of ``like`` (None means zero)."""
    return np.zeros_like(like) if value is None else np.broadcast_to(np.asarray(value, float), like.shape)


def _gain(value, name: str) -> np.ndarray:
    """Six non-negative gains from a scalar or a sequence of six."""
    g = np.full(6, float(value)) if np.ndim(value) == 0 else np.asarray(value, dtype=float)
    if g.shape != (6,) or not np.all(np.isfinite(g)) or np.any(g < 0):
        raise ValueError(f"{name}: expected six non-negative finite gains [x, y, z, roll, pitch, yaw], got {value!r}")
    return g


def wrap_angle(angle):
    """Angles wrapped to [-pi, pi), rad: an rpy error of 2 pi - d is an error of -d."""
    return (np.asarray(angle) + np.pi) % (2 * np.pi) - np.pi


def task_space_inertia(model: se.Dynamics, position, rotation) -> np.ndarray:
    """The platform's 6x6 task-space inertia at a pose: the model's mass matrix, legs included.

    M maps [lin_acc of P's origin; ang_acc] (m/s^2, rad/s^2, in {B}) to the wrench the legs must
    add to the one they supply at rest (see :meth:`stewart_env.Dynamics.mass_and_bias`).
    position (3,) m, rotation (3,3).
    """
    return model.mass_matrix(position, rotation)


def zoh_pd_gains(model: se.Dynamics, control_dt: float, bandwidth: float = 0.2, damping: float = 1.0):
    """Diagonal task-space PD gains for a sampled (zero-order-hold) loop, by pole placement per axis.

    Each axis j is treated as a double integrator of inertia M_jj (:func:`task_space_inertia` at
    the platform's home pose) and given the closed-loop poles of s^2 + 2 zeta wn s + wn^2 with
    wn = bandwidth / control_dt, rad/s: Kp_j = M_jj wn^2, Kd_j = 2 zeta M_jj wn.  A bandwidth of
    0.2 keeps the poles well inside what a hold of ``control_dt`` s can realise.
    Returns (kp, kd), each (6,) [x, y, z, roll, pitch, yaw] in N/m, N m/rad and N s/m, N m s/rad.
    """
    if not (np.isfinite(control_dt) and control_dt > 0):
        raise ValueError(f"control_dt: must be a positive number of seconds, got {control_dt}")
    if not 0 < bandwidth < 1:
        raise ValueError(f"bandwidth: wn * control_dt must lie in (0, 1), got {bandwidth}")
    if not damping > 0:
        raise ValueError(f"damping: must be positive, got {damping}")
    params = model.params[0]
    inertia = np.diag(task_space_inertia(model, params.home_position, se.rpy_to_matrix(params.home_rpy)))
    wn = bandwidth / control_dt
    return inertia * wn**2, 2.0 * damping * inertia * wn


def zoh_spectral_radius(model: se.Dynamics, kp, kd, control_dt: float, inertia_scale: float = 1.0) -> float:
    """Spectral radius of the sampled PD loop linearised at the home pose (< 1: stable).

    The plant is M [a; alpha] = W with M the task-space inertia (times ``inertia_scale``, for
    robustness checks), discretised exactly with a zero-order hold of ``control_dt`` s; the
    controller is W = -Kp dx - Kd dxdot on the sampled state.
    """
    params = model.params[0]
    inertia = inertia_scale * task_space_inertia(model, params.home_position, se.rpy_to_matrix(params.home_rpy))
    a = np.zeros((18, 18))
    a[:6, 6:12] = np.eye(6)
    a[6:12, 12:] = np.linalg.inv(inertia)
    step = scipy.linalg.expm(a * control_dt)
    closed = step[:12, :12] - step[:12, 12:] @ np.hstack([np.diag(_gain(kp, "kp")), np.diag(_gain(kd, "kd"))])
    return float(np.abs(np.linalg.eigvals(closed)).max())


class TaskSpacePD:
    """The task-space PD law F = J^-T (Kp e + Kd edot) [+ holding forces] (paper eq. 56).

    Args:
        platform: the platform's parameters (its geometry gives J).
        kp, kd: six gains [x, y, z, roll, pitch, yaw] (N/m, N m/rad; N s/m, N m s/rad), or a
            scalar for all; default the paper's (:data:`PAPER_KP`, :data:`PAPER_KD`).
        gravity_compensation: add the static holding forces of the current pose, i.e. the
            inverse dynamics at rest of ``gravity_model``; off by default, as in the paper's law
            as we have it.  With it the PD terms only have to produce accelerations, so a set
            point is reached without the droop weight / Kp.
        gravity_model: dynamics model name for the holding forces; ``"improved"`` is exact at rest.
    """

    def __init__(self, platform: PlatformParams, kp=PAPER_KP, kd=PAPER_KD, gravity_compensation: bool = False,
                 gravity_model: str = "improved"):
        if not isinstance(platform, PlatformParams):
            raise ValueError(f"platform: expected PlatformParams, got {type(platform).__name__}")
        self.platform = platform
        self.kp = _gain(kp, "kp")
        self.kd = _gain(kd, "kd")
        self.gravity_compensation = bool(gravity_compensation)
        # the Jacobian needs only the geometry; a Dynamics packs the parameters once, not per call
        self._geometry = se.make_dynamics("improved", platform)
        self._gravity = se.make_dynamics(gravity_model, platform) if self.gravity_compensation else None

    def wrench(self, state: PlatformState, reference: DesiredMotion) -> np.ndarray:
        """The PD wrench W (6,) or (N,6): force at P's origin (N) and moment (N m), in {B}."""
        rpy = se.matrix_to_rpy(state.rotation)
        rpy_d = se.matrix_to_rpy(reference.rotation)
        w = np.asarray(state.angular_velocity, float)
        rate = np.linalg.solve(rpy_rate_matrix(rpy), w[..., None])[..., 0]
        w_d = _rates(reference.angular_velocity, w)
        rate_d = np.linalg.solve(rpy_rate_matrix(rpy_d), w_d[..., None])[..., 0]
        v = np.asarray(state.velocity, float)
        error = np.concatenate([np.asarray(reference.position) - state.position, wrap_angle(rpy_d - rpy)], axis=-1)
        error_rate = np.concatenate([_rates(reference.velocity, v) - v, rate_d - rate], axis=-1)
        return self.kp * error + self.kd * error_rate

    def __call__(self, state: PlatformState, reference: DesiredMotion) -> np.ndarray:
        """Leg forces (6,) or (N,6), N, for a state and a reference (see the class docstring)."""
        jac = se.jacobian(self._geometry, state.position, state.rotation)
        forces = np.linalg.solve(np.swapaxes(jac, -1, -2), self.wrench(state, reference)[..., None])[..., 0]
        if self._gravity is not None:
            zero = np.zeros_like(np.asarray(state.velocity, float))
            forces = forces + self._gravity.inverse(state.position, state.rotation, zero, zero, zero, zero)
        return forces


def _columns_to_matrix(cols: np.ndarray) -> np.ndarray:
    """Rotation (N,3,3) from its first two columns (N,6) = [x-axis, y-axis], re-orthonormalised
    (observation noise makes them slightly non-orthogonal)."""
    x = cols[:, :3] / np.linalg.norm(cols[:, :3], axis=1, keepdims=True)
    y = cols[:, 3:6] - np.sum(x * cols[:, 3:6], axis=1, keepdims=True) * x
    y /= np.linalg.norm(y, axis=1, keepdims=True)
    return np.stack([x, y, np.cross(x, y)], axis=-1)


class EnvPolicy:
    """Base of the controllers' environment face, with Stable-Baselines3's ``predict``.

    It reads the platform state and the target out of observations of ``StewartPlatform-v0`` (or
    of its vector environment) in physical units, through the environment's
    ``decode_observation``, asks the controller for leg forces and maps them to actions with the
    environment's affine map F = mid + a half (mid, half of ``limits.leg_force``), clipped to
    [-1, 1].  It needs the pose observation (``observation_mode="pose"``): position, orientation,
    velocity, angular_velocity, position_error, orientation_error; a task's velocity_error and
    angular_velocity_error (tracking) give the reference's twist, which is zero otherwise.

    Subclasses set the controller (a callable (PlatformState, DesiredMotion) -> leg forces) and may
    override :meth:`reference` to add what else the observation tells about the target.
    """

    REQUIRED = ("position", "orientation", "velocity", "angular_velocity", "position_error", "orientation_error")

    def __init__(self, env, controller):
        base = env.unwrapped
        missing = [k for k in self.REQUIRED if k not in base.observation_layout]
        if missing:
            raise ValueError(f"env: its observations lack {missing}; the controllers need observation_mode='pose'")
        self.env = env
        self.controller = controller
        low, high = base.platform.limits.leg_force
        self._mid, self._half = 0.5 * (low + high), 0.5 * (high - low)

    def decode(self, observation) -> tuple[PlatformState, DesiredMotion]:
        """State and target (batched, N rows) of observations (obs_dim,) or (N, obs_dim)."""
        part = self.env.unwrapped.decode_observation(np.atleast_2d(np.asarray(observation, dtype=float)))
        rotation = _columns_to_matrix(part["orientation"])
        state = PlatformState(part["position"], rotation, part["velocity"], part["angular_velocity"])
        return state, self.reference(state, part)

    def reference(self, state: PlatformState, part: dict[str, np.ndarray]) -> DesiredMotion:
        """The target of decoded observations ``part`` (name -> (N, size), physical units)."""
        velocity = state.velocity + part["velocity_error"] if "velocity_error" in part else None
        angular_velocity = (state.angular_velocity + part["angular_velocity_error"]
                            if "angular_velocity_error" in part else None)
        return DesiredMotion(state.position + part["position_error"],
                         rotvec_to_matrix(part["orientation_error"]) @ state.rotation, velocity, angular_velocity)

    def forces_to_action(self, forces) -> np.ndarray:
        """Actions in [-1, 1] for leg forces (N): the environment's affine map inverted, clipped."""
        return np.clip((np.asarray(forces) - self._mid) / self._half, -1.0, 1.0).astype(np.float32)

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        """SB3's interface: (action (6,) or (N,6), None) for one observation or a batch."""
        obs = np.asarray(observation)
        platform_state, reference = self.decode(obs)
        action = self.forces_to_action(self.controller(platform_state, reference))
        return (action[0] if obs.ndim == 1 else action), None


class PDPolicy(EnvPolicy):
    """The task-space PD law as a policy on ``StewartPlatform-v0`` (see :class:`EnvPolicy`).

    Default gains: :func:`zoh_pd_gains` for the environment's control step.  Gravity compensation
    (the holding forces of the ``improved`` model) is off by default, as in the law itself; the
    controller knows the platform's geometry and, with the compensation, its statics, nothing of
    the plant's model.
    """

    def __init__(self, env, kp=None, kd=None, gravity_compensation: bool = False, bandwidth: float = 0.2,
                 damping: float = 1.0):
        base = env.unwrapped
        if kp is None or kd is None:
            tuned = zoh_pd_gains(se.make_dynamics("improved", base.platform), base.dt, bandwidth, damping)
            kp = tuned[0] if kp is None else kp
            kd = tuned[1] if kd is None else kd
        super().__init__(env, TaskSpacePD(base.platform, kp, kd, gravity_compensation=gravity_compensation))
