"""What every task shares: the batched containers, the tracking-error reward and pose checks.

A task says what the platform should do: how an episode starts, the reference pose over time,
an optional external wrench, its observation terms and its reward terms.  It knows nothing of
integrators or of the environment around it.  Every per-step method works on a batch (a leading
dimension N, one row per platform) and is a pure function of its arguments; all randomness is
drawn once per episode, per row, in :meth:`Task.initialize_episode` from the numpy Generator it
is given.  So one implementation serves the single environment (N = 1) and the vector
environment, and a row of the vector environment reproduces a single environment bit for bit.

Frames and units: {B} is the base frame, z up; positions in m, angles in rad, velocities of P's
origin in m/s, angular velocities in {B} in rad/s, forces in N, moments in N m.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from stewart_env.params import PlatformParams
from stewart_env.rotations import rotation_error_rows, rpy_rate_matrix, rpy_to_matrix
from stewart_env.state import PlatformState, Reference
from stewart_env.validation import real, vector

__all__ = [
    "Errors",
    "RewardWeights",
    "Scales",
    "Task",
    "check_option_names",
    "motion_ranges",
    "option",
    "pose_margins",
    "sinusoid_reference",
    "tracking_errors",
]


class Errors(NamedTuple):
    """Tracking errors of a batch, reference minus actual, in {B}.

    position (N,3) m; orientation (N,3) rad, the rotation vector of R_ref R^T (the rotation that
    takes the platform to the reference); velocity (N,3) m/s; angular_velocity (N,3) rad/s; and
    their norms position_norm, orientation_norm (the angle), velocity_norm,
    angular_velocity_norm, each (N,).
    """

    position: np.ndarray
    orientation: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray
    position_norm: np.ndarray
    orientation_norm: np.ndarray
    velocity_norm: np.ndarray
    angular_velocity_norm: np.ndarray


class Scales(NamedTuple):
    """Observation scales of a platform, from its limits (see the environment's card).

    position (3,) m: half the workspace box; angle rad: limits.max_angle; leg_length m: half the
    stroke; leg_force N: half the force range.  Rates use the same scales per second.
    """

    position: np.ndarray
    angle: float
    leg_length: float
    leg_force: float

    @classmethod
    def of(cls, params: PlatformParams) -> Scales:
        lim = params.limits
        return cls(position=0.5 * (lim.position_max - lim.position_min), angle=lim.max_angle,
                   leg_length=0.5 * (lim.leg_length[1] - lim.leg_length[0]),
                   leg_force=0.5 * (lim.leg_force[1] - lim.leg_force[0]))


#: Bounds of the reward weights and scales (see :class:`RewardWeights`).
MAX_WEIGHT = 1e6
MAX_SCALE = 1e6
#: Bound of the tasks' sinusoid frequencies, Hz (their frequency_range options lie in (0, it]).
MAX_FREQUENCY = 1000.0


@dataclass(frozen=True)
class RewardWeights:
    """Weights and scales of the tracking-error reward (the environment's keyword arguments).

    r = position_reward_weight * exp(-|e_p| / position_reward_scale)
      + orientation_reward_weight * exp(-|e_o| / orientation_reward_scale)
      - velocity_cost_weight * (1 - exp(-(|e_v| / velocity_cost_scale
                                          + |e_w| / angular_velocity_cost_scale)))
      - ctrl_cost_weight * mean(a^2)
      - termination_cost on the step that terminates.

    Weights lie in [0, MAX_WEIGHT] (the sign is fixed by the term), scales in (0, MAX_SCALE], so
    that no term and no sum of them overflows.
    """

    position_reward_weight: float = 0.5
    position_reward_scale: float = 0.05
    orientation_reward_weight: float = 0.5
    orientation_reward_scale: float = 0.1
    velocity_cost_weight: float = 0.1
    velocity_cost_scale: float = 0.5
    angular_velocity_cost_scale: float = 1.0
    ctrl_cost_weight: float = 0.1
    termination_cost: float = 10.0

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            checked = (real(name, value, 0.0, MAX_SCALE, low_open=True) if name.endswith("_scale")
                       else real(name, value, 0.0, MAX_WEIGHT))
            object.__setattr__(self, name, checked)


@njit(cache=True)
def _error_rows(t, R, v, w, rt, rR, rv, rw, ep, eo, ev, ew, norms):
    """Reference minus actual for every row; norms (N,4): |ep|, angle, |ev|, |ew|."""
    rotation_error_rows(rR, R, eo, norms[:, 1])
    for b in range(t.shape[0]):
        sp = 0.0
        sv = 0.0
        sw = 0.0
        for j in range(3):
            ep[b, j] = rt[b, j] - t[b, j]
            ev[b, j] = rv[b, j] - v[b, j]
            ew[b, j] = rw[b, j] - w[b, j]
            sp += ep[b, j] * ep[b, j]
            sv += ev[b, j] * ev[b, j]
            sw += ew[b, j] * ew[b, j]
        norms[b, 0] = np.sqrt(sp)
        norms[b, 2] = np.sqrt(sv)
        norms[b, 3] = np.sqrt(sw)


def tracking_errors(state: PlatformState, reference: Reference) -> Errors:
    """Reference minus actual, for a batch (see :class:`Errors`); C-contiguous float64 inputs."""
    n = state.position.shape[0]
    ep, eo, ev, ew = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
    norms = np.empty((4, n)).T  # columns contiguous, so each norm below is a contiguous array
    _error_rows(*state, *reference, ep, eo, ev, ew, norms)
    return Errors(ep, eo, ev, ew, norms[:, 0], norms[:, 1], norms[:, 2], norms[:, 3])


def pose_margins(params: PlatformParams, position: np.ndarray, rpy: np.ndarray,
                 margin: float = 0.1) -> np.ndarray:
    """Whether poses lie safely inside the platform's limits, (M,) bool.

    position (M,3) m, rpy (M,3) rad.  Safe means: position inside the workspace box shrunk by
    ``margin`` of its half-size on each side, each angle within (1 - margin) max_angle of the home
    angle, every leg within the stroke shrunk by ``margin`` of its half-length at each end, and the
    Jacobian's condition number below limits.max_condition.  Used at episode start, never per step.
    """
    lim = params.limits
    position = np.atleast_2d(position)
    rpy = np.atleast_2d(rpy)
    half = 0.5 * (lim.position_max - lim.position_min)
    ok = np.all((position >= lim.position_min + margin * half)
                & (position <= lim.position_max - margin * half), axis=1)
    ok &= np.all(np.abs(rpy - params.home_rpy) <= (1.0 - margin) * lim.max_angle, axis=1)
    R = rpy_to_matrix(rpy)
    q = np.einsum("mij,lj->mli", R, params.platform_joints)  # R p_i, (M,6,3)
    legs = position[:, None, :] + q - params.base_joints
    lengths = np.sqrt((legs * legs).sum(axis=2))
    lo, hi = lim.leg_length
    stroke_margin = margin * 0.5 * (hi - lo)
    ok &= np.all((lengths >= lo + stroke_margin) & (lengths <= hi - stroke_margin), axis=1)
    if not ok.any():
        return ok  # the condition number (an SVD per pose) is needed only where all else holds
    e = legs / lengths[..., None]
    jac = np.concatenate([e, q[..., [1, 2, 0]] * e[..., [2, 0, 1]] - q[..., [2, 0, 1]] * e[..., [1, 2, 0]]], axis=2)
    ok &= np.linalg.cond(jac) < lim.max_condition
    return ok


def sinusoid_reference(home_position: np.ndarray, home_rpy: np.ndarray, amplitude: np.ndarray,
                       omega: np.ndarray, phase: np.ndarray, time: np.ndarray, out: Reference) -> None:
    """Pose offsets a_k sin(omega_k t + phi_k) about home on x, y, z, roll, pitch, yaw.

    amplitude, omega (rad/s), phase: (N,6); time (N,) s.  Writes the reference pose and twist into
    ``out`` (angular velocity = E(rpy) d(rpy)/dt, see :func:`stewart_env.rotations.rpy_rate_matrix`).
    """
    arg = omega * time[:, None] + phase
    offset = amplitude * np.sin(arg)
    rate = amplitude * omega * np.cos(arg)
    rpy = home_rpy + offset[:, 3:]
    out.position[:] = home_position + offset[:, :3]
    out.rotation[:] = rpy_to_matrix(rpy)
    out.velocity[:] = rate[:, :3]
    E = rpy_rate_matrix(rpy)
    d = rate[:, 3:]
    out.angular_velocity[:] = E[:, :, 0] * d[:, 0:1] + E[:, :, 1] * d[:, 1:2] + E[:, :, 2] * d[:, 2:3]


def check_option_names(task_cls: type, options: dict[str, Any]) -> None:
    """Refuse task options the task's constructor does not take, naming them and the valid ones."""
    params = list(inspect.signature(task_cls.__init__).parameters.values())
    valid = [p.name for p in params if p.kind == p.KEYWORD_ONLY]
    unknown = [k for k in options if k not in valid]
    if unknown:
        raise ValueError(
            f"task_options: unknown option(s) {', '.join(map(repr, unknown))} for task {task_cls.name!r}; "
            f"valid options: {', '.join(valid) or 'none'}"
        )


def option(name: str) -> str:
    """How errors name a task option: ``task_options['name']``."""
    return f"task_options[{name!r}]"


def motion_ranges(params: PlatformParams, position, angle, names: tuple[str, str]) -> tuple[np.ndarray, np.ndarray]:
    """A task's per-axis motion bounds: ``position`` (3,) m and ``angle`` (3,) rad as given (at
    most the workspace box's half-size and ``limits.max_angle``: beyond, no motion fits the
    limits), or by default 40 % of them, which leaves room for the platform to overshoot inside
    the limits.  ``names`` are the option names for errors."""
    lim = params.limits
    half = 0.5 * (lim.position_max - lim.position_min)
    return (0.4 * half if position is None else vector(option(names[0]), position, 3, 0.0, half),
            np.full(3, 0.4 * lim.max_angle) if angle is None
            else vector(option(names[1]), angle, 3, 0.0, lim.max_angle))


class Task:
    """Base class of the tasks: a fixed or moving reference pose to reach and hold.

    Subclasses set ``name`` and ``episode_fields`` and implement :meth:`initialize_episode` and
    :meth:`reference`; they may add an external wrench, observation terms, reward terms and a
    termination of their own.  Options are keyword-only arguments of the subclass constructor
    (the environment's ``task_options``); the platform's nominal parameters come first.
    """

    name = "task"
    #: Per-row episode parameters, name -> shape without the batch dimension; the environment
    #: keeps them as (N, *shape) arrays and fills row i from :meth:`initialize_episode`.
    episode_fields: dict[str, tuple[int, ...]] = {}
    #: Whether :meth:`external_wrench` produces a wrench (else the environment keeps zeros).
    has_external_wrench = False
    #: Whether the reference moves (else the environment computes it at reset only).
    moving_reference = False
    #: Names of this task's own termination reasons, codes 1, 2, ... of :meth:`termination`.
    termination_reasons: tuple[str, ...] = ()

    def __init__(self, params: PlatformParams, control_dt: float):
        self.params = params
        self.control_dt = float(control_dt)

    def __repr__(self) -> str:
        return f"{type(self).__name__}(platform={self.params.name!r})"

    # -- episode ----------------------------------------------------------------------------------

    def initialize_episode(self, rng: np.random.Generator) -> tuple[PlatformState, dict[str, np.ndarray]]:
        """Draw one row's episode: its initial state and its ``episode_fields`` values."""
        raise NotImplementedError

    def reference(self, episode: dict[str, np.ndarray], time: np.ndarray, out: Reference) -> None:
        """Write the reference at ``time`` (N,) s into ``out`` (N rows)."""
        raise NotImplementedError

    def external_wrench(self, episode: dict[str, np.ndarray], time: np.ndarray, dt: float,
                        out: np.ndarray) -> None:
        """Write the wrench [F_ext at P (3), N; M_ext (3), N m] in {B} held over [time, time + dt]
        into ``out`` (N,6).  Only called when ``has_external_wrench``."""
        raise NotImplementedError

    # -- observation ------------------------------------------------------------------------------

    def observation_terms(self, scales: Scales) -> list[tuple[str, np.ndarray]]:
        """(name, scale) of each task observation term, scale (size,) in the term's units."""
        angle = np.full(3, scales.angle)
        return [("position_error", scales.position.copy()), ("orientation_error", angle)]

    def observe(self, state: PlatformState, errors: Errors, episode: dict[str, np.ndarray],
                time: np.ndarray, out: dict[str, np.ndarray]) -> None:
        """Write each term of :meth:`observation_terms`, in physical units, into ``out[name]``
        (N, size)."""
        out["position_error"][:] = errors.position
        out["orientation_error"][:] = errors.orientation

    # -- reward and termination -------------------------------------------------------------------

    def reward_terms(self, errors: Errors, action: np.ndarray, weights: RewardWeights) -> dict[str, np.ndarray]:
        """Reward terms (N,) each, by name (see :class:`RewardWeights`); action (N,6) in [-1, 1]."""
        w = weights
        a2 = action * action
        return {
            "position": w.position_reward_weight * np.exp(-errors.position_norm / w.position_reward_scale),
            "orientation": w.orientation_reward_weight * np.exp(-errors.orientation_norm / w.orientation_reward_scale),
            "velocity": -w.velocity_cost_weight * -np.expm1(
                -(errors.velocity_norm / w.velocity_cost_scale
                  + errors.angular_velocity_norm / w.angular_velocity_cost_scale)),
            "control": -w.ctrl_cost_weight * (a2.sum(axis=1) / 6.0),
        }

    def termination(self, state: PlatformState, errors: Errors, time: np.ndarray) -> np.ndarray | None:
        """This task's own termination: (N,) int codes (0 none, k for termination_reasons[k-1]),
        or None when the task never terminates an episode itself."""
        return None
