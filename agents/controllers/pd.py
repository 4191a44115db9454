"""Task-space PD control of the Stewart platform (He et al. 2018, eq. 56), as a compiled control
law and as a policy.

The law: with the pose error e = [t_d - t; theta_d - theta] (position of P's origin in {B}, m;
roll-pitch-yaw angles, rad) and its rate edot = [v_d - v; thetadot_d - thetadot] (angle rates from
the angular velocity, thetadot = E(theta)^-1 omega), the controller asks for the platform wrench

    W = Kp e + Kd edot        (force at P's origin, N; moment, N m; both in {B})

and realises it with the leg forces F = J^-T W, since leg forces F act on the platform as the
wrench J^T F (J the leg Jacobian, dL/dt = J [v; omega]).  Optionally the static holding forces
of the current pose are added (gravity compensation, see :class:`TaskSpacePD`).

The law is written once, as ``pd_control_law``, a control law compiled into the package's
extension for :func:`stewart_env.rollout` (evaluated at every RK4 stage: continuous control, as in
:mod:`stewart_env.agents.studies.reproduce`); its parameter row is built by :func:`pd_control_params`
(layout: :data:`PD_LAYOUT`).  Two faces call it:

* :class:`TaskSpacePD` maps a platform state and a :class:`~stewart_env.state.Reference` to leg
  forces, for one platform or a batch.
* :class:`PDPolicy` wraps it for the environment with Stable-Baselines3's ``predict``: it reads
  the state and the target out of the observation, and maps the forces to actions.

Gains.  The paper's gains (:data:`PAPER_KP`, :data:`PAPER_KD`) belong to continuous control: on
the 45 kg platform they put the vertical axis at about 300 rad/s, which the environment's 10 ms
zero-order hold cannot follow (the sampled loop is unstable, see :func:`zoh_spectral_radius`).
:func:`zoh_pd_gains` places the poles of every axis instead: Kp_j = M_jj wn^2,
Kd_j = 2 zeta M_jj wn, with M the task-space inertia at the home pose and wn = bandwidth /
control_dt.  The default bandwidth 0.2 (wn = 20 rad/s at 10 ms) and zeta = 1 give a sampled loop
with spectral radius 0.88 on the dasgupta1998 platform, still stable if the inertia is halved
or doubled (settling times measured on the set-point task: docs/results/mismatch-setpoint.md).
As the law is specified, the environment policy has no gravity compensation by default, and the
weight carried by the legs (480 N) makes the platform sag by 480 N / Kp_z = 27 mm at these gains (4.3 mm at bandwidth 0.5,
where the sampled loop contracts fastest, spectral radius 0.74).  ``gravity_compensation=True``
adds the holding forces: the sag goes, and what is left is the difference between the plant's
statics and the compensation's (measured in the evaluation guide, docs/guides/evaluation.md).

The policies take the environment's observation as the current state: they do not model an
actuator lag (``actuator_tau``) or an observation delay.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

import stewart_env as se
from stewart_env.dynamics import ModelSpec
from stewart_env.dynamics.model import batch_args, pack_params
from stewart_env.dynamics.rk4 import PD_CONTROL_LAW, PD_LAYOUT, law_forces
from stewart_env.params import PlatformParams
from stewart_env.rotations import rotvec_to_matrix
from stewart_env.state import PlatformState, Reference

#: Proportional gains of the paper's case study, [x, y, z, roll, pitch, yaw]: N/m and N m/rad.
PAPER_KP = np.array([4e5, 4e5, 4e6, 5e4, 5e4, 1e5])
#: Derivative gains of the paper's case study: N s/m and N m s/rad.
PAPER_KD = np.array([1e4, 1e4, 2e4, 1e3, 1e3, 2e3])

#: The task-space PD law F = J^-T (Kp e + Kd edot) [+ holding forces] (paper eq. 56), compiled: a
#: :class:`stewart_env.dynamics.rk4.ControlLaw` for :func:`stewart_env.rollout`.  params: the row
#: of :func:`pd_control_params` (layout :data:`PD_LAYOUT`: kp, kd, the reference's position,
#: rotation (row-major), velocity and angular velocity in {B}, gravity_compensation 1.0 or 0.0,
#: gravity_flags (the switch bits of the model giving the holding forces) and the controller's
#: packed platform row, whose geometry gives J).  Time-invariant: the reference is fixed in params.
pd_control_law = PD_CONTROL_LAW
#: Offset of each entry of :data:`PD_LAYOUT` in the row.
PD_OFFSETS = {name: int(sum(size for _, size in PD_LAYOUT[:k])) for k, (name, _) in enumerate(PD_LAYOUT)}
#: Length of the row.
PD_N_PARAMS = sum(size for _, size in PD_LAYOUT)
#: The pose and twist fields of a state or reference, with the shape of one platform's.
_STATE_FIELDS = (("position", (3,)), ("rotation", (3, 3)), ("velocity", (3,)), ("angular_velocity", (3,)))


def pd_control_params(
    platform: PlatformParams,
    reference: Reference,
    kp=PAPER_KP,
    kd=PAPER_KD,
    gravity_compensation: bool = False,
    gravity_model: str | ModelSpec = "improved",
) -> np.ndarray:
    """The parameter row of ``pd_control_law`` for a reference.

    Args:
        platform: the platform's parameters (its geometry gives J).
        reference: the target in {B}, fields (N, ...) for a batch (its accelerations are not used).
        kp: proportional gains Kp, as in :class:`TaskSpacePD`.
        kd: derivative gains Kd, as in :class:`TaskSpacePD`.
        gravity_compensation: add the holding forces, as in :class:`TaskSpacePD`.
        gravity_model: the model of the holding forces, as in :class:`TaskSpacePD`.

    Returns:
        The row (PD_N_PARAMS,), or (N, PD_N_PARAMS) for a batched reference.

    Raises:
        ValueError: ``platform`` not PlatformParams, bad gains, an unknown model or a bad reference.
    """
    if not isinstance(platform, PlatformParams):
        raise ValueError(f"platform: expected PlatformParams, got {type(platform).__name__}")
    flags = ModelSpec.parse(gravity_model, "gravity_model").flags
    n, batched, ref = batch_args(
        1,
        position=(reference.position, (3,)),
        rotation=(reference.rotation, (3, 3)),
        velocity=(reference.velocity, (3,)),
        angular_velocity=(reference.angular_velocity, (3,)),
    )
    row = {
        "kp": _gain(kp, "kp"),
        "kd": _gain(kd, "kd"),
        "gravity_compensation": float(bool(gravity_compensation)),
        "gravity_flags": float(flags),
        "platform": pack_params(platform),
    }
    params = np.empty((n, PD_N_PARAMS))
    for name, size in PD_LAYOUT:
        value = ref[name].reshape(n, size) if name in ref else row[name]
        params[:, PD_OFFSETS[name] : PD_OFFSETS[name] + size] = value
    return params if batched else params[0]


def _gain(value, name: str) -> np.ndarray:
    """Six non-negative gains from a scalar or a sequence of six."""
    g = np.full(6, float(value)) if np.ndim(value) == 0 else np.asarray(value, dtype=float)
    if g.shape != (6,) or not np.all(np.isfinite(g)) or np.any(g < 0):
        raise ValueError(f"{name}: expected six non-negative finite gains [x, y, z, roll, pitch, yaw], got {value!r}")
    return g


def task_space_inertia(model: se.Dynamics, position, rotation) -> np.ndarray:
    """The platform's 6x6 task-space inertia at a pose: the model's mass matrix, legs included.

    M maps [lin_acc of P's origin; ang_acc] (m/s^2, rad/s^2, in {B}) to the wrench the legs must
    add to the one they supply at rest (see :meth:`stewart_env.Dynamics.mass_and_bias`).

    Args:
        model: the dynamics model.
        position: (3,) position of P's origin in {B}, m.
        rotation: (3,3) rotation of {P} in {B}.

    Returns:
        The mass matrix M (6,6) in kg, kg m, kg m^2, moments about P.
    """
    return model.mass_matrix(position, rotation)


def zoh_pd_gains(model: se.Dynamics, control_dt: float, bandwidth: float = 0.2, damping: float = 1.0):
    """Diagonal task-space PD gains for a sampled (zero-order-hold) loop, by pole placement per axis.

    Each axis j is treated as a double integrator of inertia M_jj (:func:`task_space_inertia` at
    the platform's home pose) and given the closed-loop poles of s^2 + 2 zeta wn s + wn^2 with
    wn = bandwidth / control_dt, rad/s: Kp_j = M_jj wn^2, Kd_j = 2 zeta M_jj wn.  A bandwidth of
    0.2 keeps the poles well inside what a hold of ``control_dt`` s can realise.

    Args:
        model: the dynamics model (its first parameter row is used).
        control_dt: the hold, s.
        bandwidth: wn * control_dt, in (0, 1).
        damping: the damping ratio zeta, > 0.

    Returns:
        The pair (kp, kd), each (6,) [x, y, z, roll, pitch, yaw] in N/m, N m/rad and N s/m,
        N m s/rad.

    Raises:
        ValueError: a bad ``control_dt``, ``bandwidth`` or ``damping``.

    Examples:
        >>> import numpy as np, stewart_env as se
        >>> from stewart_env.agents.controllers.pd import zoh_pd_gains, zoh_spectral_radius
        >>> model = se.make_dynamics("improved", se.load_platform("dasgupta1998"))
        >>> kp, kd = zoh_pd_gains(model, control_dt=0.01)
        >>> bool(zoh_spectral_radius(model, kp, kd, control_dt=0.01) < 1)    # the sampled loop is stable
        True
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

    Args:
        model: the dynamics model (its first parameter row is used).
        kp: proportional gains Kp, six or a scalar, as in :class:`TaskSpacePD`.
        kd: derivative gains Kd, six or a scalar, as in :class:`TaskSpacePD`.
        control_dt: the hold, s.
        inertia_scale: factor on M.

    Returns:
        The largest modulus of the closed loop's eigenvalues.
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
    """The task-space PD law F = J^-T (Kp e + Kd edot) [+ holding forces] (paper eq. 56): calls
    ``pd_control_law`` on a state and a reference.

    Args:
        platform: the platform's parameters (its geometry gives J).
        kp, kd: six gains [x, y, z, roll, pitch, yaw] (N/m, N m/rad; N s/m, N m s/rad), or a
            scalar for all; default the paper's (:data:`PAPER_KP`, :data:`PAPER_KD`).
        gravity_compensation: add the static holding forces of the current pose, i.e. the
            inverse dynamics at rest of ``gravity_model``; off by default, as in the paper's law
            as we have it.  With it the PD terms only have to produce accelerations, so a set
            point is reached without the droop weight / Kp.
        gravity_model: dynamics model name (or :class:`~stewart_env.dynamics.ModelSpec`) for the
            holding forces; ``"improved"`` is exact at rest.

    Raises:
        ValueError: ``platform`` not PlatformParams, a gain not six finite numbers or a scalar,
            or an unknown ``gravity_model``.

    Examples:
        At the reference, the law gives the holding forces alone:

        >>> import numpy as np, stewart_env as se
        >>> from stewart_env.state import PlatformState, Reference
        >>> from stewart_env.agents.controllers.pd import TaskSpacePD
        >>> params = se.load_platform("dasgupta1998")
        >>> at_home = (params.home_position, np.eye(3), np.zeros(3), np.zeros(3))
        >>> pd = TaskSpacePD(params, gravity_compensation=True)
        >>> forces = pd(PlatformState(*at_home), Reference(*at_home, np.zeros(3), np.zeros(3)))
        >>> print(np.round(forces, 1))
        [193.9 145.4 153.1 172.3 159.6 188.9]
    """

    def __init__(
        self,
        platform: PlatformParams,
        kp=PAPER_KP,
        kd=PAPER_KD,
        gravity_compensation: bool = False,
        gravity_model: str | ModelSpec = "improved",
    ):
        if not isinstance(platform, PlatformParams):
            raise ValueError(f"platform: expected PlatformParams, got {type(platform).__name__}")
        self.platform = platform
        self.kp = _gain(kp, "kp")
        self.kd = _gain(kd, "kd")
        self.gravity_compensation = bool(gravity_compensation)
        self.gravity_spec = ModelSpec.parse(gravity_model, "gravity_model")
        self.gravity_model = self.gravity_spec.name

    def control_params(self, reference: Reference) -> np.ndarray:
        """``pd_control_law``'s parameter row for this controller and a reference.

        Args:
            reference: the target in {B} (fields (N, ...) for a batch).

        Returns:
            The row (PD_N_PARAMS,), or (N, PD_N_PARAMS) for a batched reference, which
            :func:`stewart_env.rollout` takes as ``control_params`` for this controller.
        """
        return pd_control_params(
            self.platform, reference, self.kp, self.kd, self.gravity_compensation, self.gravity_spec
        )

    def __call__(self, state: PlatformState, reference: Reference) -> np.ndarray:
        """Leg forces for a state and a reference (see the class docstring).

        Args:
            state: the platform's state; may be batched.
            reference: the target; may be batched (the other is broadcast).

        Returns:
            The leg forces (6,) or (N,6), N.
        """
        n, batched, a = batch_args(
            1,
            **{
                f"{record}.{name}": (getattr(value, name), tail)
                for record, value in (("state", state), ("reference", reference))
                for name, tail in _STATE_FIELDS
            },
        )
        params = self.control_params(Reference(*(a[f"reference.{name}"] for name, _ in _STATE_FIELDS)))
        out = law_forces(pd_control_law, np.atleast_2d(params), *(a[f"state.{name}"] for name, _ in _STATE_FIELDS))
        return out if batched else out[0]


def _columns_to_matrix(cols: np.ndarray) -> np.ndarray:
    """Rotation (N,3,3) from its first two columns (N,6) = [x-axis, y-axis], re-orthonormalised
    (observation noise makes them slightly non-orthogonal)."""
    x = cols[:, :3] / np.linalg.norm(cols[:, :3], axis=1, keepdims=True)
    y = cols[:, 3:6] - np.sum(x * cols[:, 3:6], axis=1, keepdims=True) * x
    y /= np.linalg.norm(y, axis=1, keepdims=True)
    return np.stack([x, y, np.cross(x, y)], axis=-1)


class EnvPolicy:
    """Base of the controllers' environment face, with Stable-Baselines3's ``predict``.

    It reads the platform state and the target out of observations of ``StewartPlatform-v1`` (or
    of its vector environment) in physical units, through the environment's
    ``decode_observation``, asks the controller for leg forces and maps them to actions with the
    environment's affine map F = mid + a half (mid, half of ``limits.leg_force``), clipped to
    [-1, 1].  It needs the pose observation (``observation_mode="pose"``): position, orientation,
    velocity, angular_velocity, position_error, orientation_error; a task's velocity_error and
    angular_velocity_error (tracking) give the reference's twist, which is zero otherwise.

    Subclasses set the controller (a callable (PlatformState, Reference) -> leg forces) and may
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

    def decode(self, observation) -> tuple[PlatformState, Reference]:
        """State and target (batched, N rows) of observations (obs_dim,) or (N, obs_dim).

        Args:
            observation: one observation (obs_dim,) or a batch (N, obs_dim).
        """
        part = self.env.unwrapped.decode_observation(np.atleast_2d(np.asarray(observation, dtype=float)))
        rotation = _columns_to_matrix(part["orientation"])
        state = PlatformState(part["position"], rotation, part["velocity"], part["angular_velocity"])
        return state, self.reference(state, part)

    def reference(self, state: PlatformState, part: dict[str, np.ndarray]) -> Reference:
        """The target of decoded observations ``part`` (name -> (N, size), physical units): its
        twist is zero unless the observation carries the twist errors; its accelerations zero.

        Args:
            state: the platform's decoded state (N rows).
            part: the decoded observation, entry name -> (N, size) in physical units.
        """
        zero = np.zeros_like(state.velocity)
        velocity = state.velocity + part["velocity_error"] if "velocity_error" in part else zero
        angular_velocity = (
            state.angular_velocity + part["angular_velocity_error"] if "angular_velocity_error" in part else zero
        )
        return Reference(
            state.position + part["position_error"],
            rotvec_to_matrix(part["orientation_error"]) @ state.rotation,
            velocity,
            angular_velocity,
        )

    def forces_to_action(self, forces) -> np.ndarray:
        """Actions in [-1, 1] for leg forces (N): the environment's affine map inverted, clipped.

        Args:
            forces: the leg forces (6,) or (N, 6), N.
        """
        return np.clip((np.asarray(forces) - self._mid) / self._half, -1.0, 1.0).astype(np.float32)

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        """SB3's interface: (action (6,) or (N,6), None) for one observation or a batch.

        Args:
            observation: one observation (obs_dim,) or a batch (N, obs_dim).
            state: SB3's recurrent state; unused (the policy has none).
            episode_start: SB3's episode starts; unused.
            deterministic: SB3's flag; unused (the policy is deterministic).
        """
        obs = np.asarray(observation)
        platform_state, reference = self.decode(obs)
        action = self.forces_to_action(self.controller(platform_state, reference))
        return (action[0] if obs.ndim == 1 else action), None


class PDPolicy(EnvPolicy):
    """The task-space PD law as a policy on ``StewartPlatform-v1`` (see :class:`EnvPolicy`).

    The controller knows the platform's geometry and, with the compensation, its statics, nothing
    of the plant's model: those of the environment's nominal platform, or of ``platform`` when
    given.

    Args:
        env: the environment (or its vector environment) with ``observation_mode="pose"``.
        kp, kd: six gains or a scalar; default :func:`zoh_pd_gains` for the environment's control
            step.
        gravity_compensation: add the holding forces of ``gravity_model``; off by default, as in
            the law itself.
        bandwidth, damping: of :func:`zoh_pd_gains`, for the default gains.
        gravity_model: dynamics model name for the holding forces.
        platform: the platform the controller believes (a :class:`~stewart_env.PlatformParams`,
            e.g. an identified one); default the environment's nominal platform.

    Examples:
        >>> import gymnasium as gym
        >>> from stewart_env.agents.controllers.pd import PDPolicy
        >>> env = gym.make("StewartPlatform-v1", task="setpoint")
        >>> policy = PDPolicy(env, gravity_compensation=True)
        >>> observation, info = env.reset(seed=0)
        >>> action, _ = policy.predict(observation)
        >>> action.shape
        (6,)
    """

    def __init__(
        self,
        env,
        kp=None,
        kd=None,
        gravity_compensation: bool = False,
        bandwidth: float = 0.2,
        damping: float = 1.0,
        gravity_model: str = "improved",
        platform: PlatformParams | None = None,
    ):
        base = env.unwrapped
        believed = base.platform if platform is None else platform
        if kp is None or kd is None:
            tuned = zoh_pd_gains(se.make_dynamics(ModelSpec(), believed), base.dt, bandwidth, damping)
            kp = tuned[0] if kp is None else kp
            kd = tuned[1] if kd is None else kd
        super().__init__(
            env, TaskSpacePD(believed, kp, kd, gravity_compensation=gravity_compensation, gravity_model=gravity_model)
        )
