"""What every task shares: the batched containers, the tracking-error reward and pose checks.

A task says what the platform should do and owns how it is scored (dm_control's Task, kept
batched): how an episode starts, the reference pose over time, an optional external wrench, its
observation terms, its reward terms with their weights, and its termination, each reason a
success or a failure.  It is given a read-only :class:`StepView` of the batch (state, errors,
leg lengths, rates and forces, time, its episode arrays) and knows nothing of integrators or of
the environment around it, which adds nothing to what the task returns.  Every per-step method
works on a batch (a leading dimension N, one row per platform) and is a pure function of its
arguments; all randomness is drawn once per episode, per row, in :meth:`Task.initialize_episode`
from the numpy Generator it is given.  So one implementation serves the single environment (N = 1) and the vector
environment, and a row of the vector environment reproduces a single environment bit for bit.

Frames and units: {B} is the base frame, z up; positions in m, angles in rad, velocities of P's
origin in m/s, angular velocities in {B} in rad/s, forces in N, moments in N m.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from stewart_env import _core
from stewart_env.dynamics import Dynamics, ModelSpec, make_dynamics
from stewart_env.kinematics import leg_sensors_inplace
from stewart_env.params import PlatformParams
from stewart_env.rotations import rpy_rate_matrix, rpy_to_matrix
from stewart_env.state import PlatformState, Reference
from stewart_env.validation import real, vector

__all__ = [
    "FINAL_WINDOW",
    "LIMIT_REASONS",
    "ORIENTATION_TOLERANCE",
    "POSITION_TOLERANCE",
    "Errors",
    "RewardWeights",
    "Scales",
    "StepView",
    "SuccessCriterion",
    "SuccessTracker",
    "Task",
    "check_option_names",
    "error_norm",
    "motion_ranges",
    "option",
    "pose_margins",
    "sinusoid_reference",
    "tracking_errors",
    "zero_reference",
]


class Errors(NamedTuple):
    """Tracking errors of a batch, reference minus actual, in {B}.

    Attributes:
        position: (N,3) position error, m.
        orientation: (N,3) rotation vector of R_ref R^T (the rotation that takes the platform to
            the reference), rad.
        velocity: (N,3) velocity error, m/s.
        angular_velocity: (N,3) angular velocity error, rad/s.
        position_norm: (N,) norm of the position error, m.
        orientation_norm: (N,) the orientation error's angle, rad.
        velocity_norm: (N,) m/s.
        angular_velocity_norm: (N,) rad/s.
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

    Rates use the same scales per second.  ``Scales.of(params)`` makes them.

    Attributes:
        position: (3,) half the workspace box, m.
        angle: limits.max_angle, rad.
        leg_length: half the stroke, m.
        leg_force: half the force range, N.
    """

    position: np.ndarray
    angle: float
    leg_length: float
    leg_force: float

    @classmethod
    def of(cls, params: PlatformParams) -> Scales:
        """The scales of a platform: the half-ranges of its workspace box, leg stroke and leg force.

        Args:
            params: the platform, whose ``limits`` give the ranges.

        Returns:
            The platform's :class:`Scales`.
        """
        lim = params.limits
        return cls(
            position=0.5 * (lim.position_max - lim.position_min),
            angle=lim.max_angle,
            leg_length=0.5 * (lim.leg_length[1] - lim.leg_length[0]),
            leg_force=0.5 * (lim.leg_force[1] - lim.leg_force[0]),
        )


#: Bounds of the reward weights and scales (see :class:`RewardWeights`).
MAX_WEIGHT = 1e6
MAX_SCALE = 1e6
#: Bound of the tasks' sinusoid frequencies, Hz (their frequency_range options lie in (0, it]).
MAX_FREQUENCY = 1000.0


#: Reward scales (m, rad) of the position and orientation terms: every task's defaults, but for
#: the tracking and disturbance tasks of the environment's version 1 (``PRECISE_REWARD_SCALES``).
BASE_REWARD_SCALES = (0.05, 0.1)
#: Reward scales (m, rad) of the tasks whose question is millimetre precision all episode long
#: (tracking, disturbance) since the environment's version 1.  At the base task's scales an error inside the default success band
#: barely changes the reward, so a learned agent has little to gain from closing it; these sharper
#: scales make the band worth holding (results: docs/results/mismatch-tracking-disturbance.md).
PRECISE_REWARD_SCALES = (0.01, 0.02)
#: The options of a precise task whose defaults were BASE_REWARD_SCALES under version 0 of the
#: environment (``StewartPlatform-v0``): its ``Task.version_defaults`` entry.
BASE_SCALE_OPTIONS = {"position_reward_scale": BASE_REWARD_SCALES[0], "orientation_reward_scale": BASE_REWARD_SCALES[1]}


@dataclass(frozen=True)
class RewardWeights:
    """Weights and scales of the tracking-error reward: options of every task (``task_options``).

        r = position_reward_weight * exp(-|e_p| / position_reward_scale)
          + orientation_reward_weight * exp(-|e_o| / orientation_reward_scale)
          - velocity_cost_weight * (1 - exp(-(|e_v| / velocity_cost_scale
                                              + |e_w| / angular_velocity_cost_scale)))
          - ctrl_cost_weight * mean(a^2)
          - termination_cost on the step that terminates with a failure.

    Weights lie in [0, MAX_WEIGHT] (the sign is fixed by the term), scales in (0, MAX_SCALE], so
    that no term and no sum of them overflows.  The defaults are those of :class:`Task`.

    Attributes:
        position_reward_weight: weight of the position term.
        position_reward_scale: scale of the position error e_p, m.
        orientation_reward_weight: weight of the orientation term.
        orientation_reward_scale: scale of the orientation error e_o, rad.
        velocity_cost_weight: weight of the velocity cost.
        velocity_cost_scale: scale of the velocity error e_v, m/s.
        angular_velocity_cost_scale: scale of the angular velocity error e_w, rad/s.
        ctrl_cost_weight: weight of the control cost, on the actions a in [-1, 1].
        termination_cost: the cost of a failure.

    Raises:
        ValueError: a weight or scale out of its range (the message names the option).
    """

    # No defaults here: Task.__init__'s keyword defaults are the one source of them.
    position_reward_weight: float
    position_reward_scale: float
    orientation_reward_weight: float
    orientation_reward_scale: float
    velocity_cost_weight: float
    velocity_cost_scale: float
    angular_velocity_cost_scale: float
    ctrl_cost_weight: float
    termination_cost: float

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            checked = (
                real(option(name), value, 0.0, MAX_SCALE, low_open=True)
                if name.endswith("_scale")
                else real(option(name), value, 0.0, MAX_WEIGHT)
            )
            object.__setattr__(self, name, checked)


def empty_errors(n: int) -> tuple[Errors, np.ndarray]:
    """Preallocated :class:`Errors` of n rows and the (n, 4) array that holds their norms.

    Args:
        n: the number of rows.
    """
    return errors_in(np.empty((4, n, 3)), np.empty((4, n)))


def errors_in(vectors: np.ndarray, norms: np.ndarray) -> tuple[Errors, np.ndarray]:
    """:class:`Errors` whose fields are views of ``vectors`` (4, n, 3) and ``norms`` (4, n), and
    the (n, 4) view of the norms that :func:`tracking_errors` writes.

    Args:
        vectors: (4, n, 3) float64, the position, orientation, velocity and angular velocity errors.
        norms: (4, n) float64, their norms.
    """
    return Errors(*vectors, *norms), norms.T


def tracking_errors(state: PlatformState, reference: Reference, out: tuple[Errors, np.ndarray] | None = None) -> Errors:
    """Reference minus actual, for a batch (see :class:`Errors`).

    Args:
        state: the platform states, C-contiguous float64 (N, ...) arrays.
        reference: the references, likewise.
        out: an :func:`empty_errors` pair to write into (else new arrays).

    Returns:
        The :class:`Errors`.
    """
    errors, norms = out if out is not None else empty_errors(state.position.shape[0])
    _core.tracking_errors(
        *state,
        reference.position,
        reference.rotation,
        reference.velocity,
        reference.angular_velocity,
        *errors[:4],
        norms.T,
    )
    return errors


def zero_reference(n: int) -> Reference:
    """A :class:`Reference` of n rows of zeros (rotation (n,3,3), every other field (n,3)).

    Args:
        n: the number of rows.
    """
    return Reference(*(np.zeros((n, 3, 3) if name == "rotation" else (n, 3)) for name in Reference._fields))


# -- success ---------------------------------------------------------------------------------------

#: Default tolerances of the success band, 2 mm and 0.01 rad (0.57 deg).
POSITION_TOLERANCE = 2e-3
ORIENTATION_TOLERANCE = 1e-2
#: Default final window of the success criterion, as a fraction of the episode's duration.
FINAL_WINDOW = 0.1


def error_norm(vectors):
    """The norm sqrt((x^2 + y^2) + z^2) of error vectors (x, y, z).

    The squares are summed in that order, numpy's order for a norm over a last axis of three
    (``np.linalg.norm(e, axis=-1)`` gives the same bits), in both forms, so that the environment's
    errors, one row at a time or a batch at once, and the evaluation harness's, over a recorded
    episode, are the same numbers.

    Args:
        vectors: an array (..., 3), or one vector as a list or tuple of three Python floats (a
            fraction of the array form's cost, for one row at a time).

    Returns:
        The norms, an array (...) for an array, a float for a list or tuple.
    """
    if type(vectors) in (list, tuple):  # (not isinstance: this is on the environment's step path)
        x, y, z = vectors
        return math.sqrt(x * x + y * y + z * z)
    squares = np.square(vectors)
    return np.sqrt(squares[..., 0] + squares[..., 1] + squares[..., 2])


@dataclass(frozen=True)
class SuccessCriterion:
    """When an episode succeeds: it ran to its end without termination and held the success
    band over its final window.

    The episode's samples are its errors at t_0 = 0 (reset) and after every control step, up to
    its last, t_end.  Inside the band: ``|e_p| <= position_tolerance`` and the orientation error's
    angle ``|e_o| <= orientation_tolerance`` (:func:`error_norm` of the vectors of
    :class:`Errors`).  The final window: the samples at t >= t_end - final_window (t_end - t_0),
    and at least the last.  The episode succeeds when it was not terminated (for any reason) and
    every sample of its final window lies inside the band; equivalently, when the latest sample
    outside the band, if any, comes before the window (:meth:`holds`), which is how
    :class:`SuccessTracker` follows it step by step with one number per episode.  The evaluation
    harness (``stewart_env.agents.evaluation``) and the environment's ``info["is_success"]`` both
    apply it.

    Attributes:
        position_tolerance: m, positive.
        orientation_tolerance: rad, positive.
        final_window: a fraction of the episode's duration, in [0, 1].

    Raises:
        ValueError: a tolerance that is not positive, or a final window outside [0, 1] (the
            message names it).
    """

    position_tolerance: float = POSITION_TOLERANCE
    orientation_tolerance: float = ORIENTATION_TOLERANCE
    final_window: float = FINAL_WINDOW

    def __post_init__(self) -> None:
        if not (self.position_tolerance > 0 and self.orientation_tolerance > 0):
            raise ValueError(
                f"position_tolerance, orientation_tolerance: must be positive, got "
                f"{self.position_tolerance}, {self.orientation_tolerance}"
            )
        if not 0 <= self.final_window <= 1:
            raise ValueError(f"final_window: a fraction of the episode in [0, 1], got {self.final_window}")

    def inside(self, position_norm, orientation_norm):
        """Whether samples lie inside the band: floats give a bool, arrays a bool array.

        Args:
            position_norm: |e_p|, m.
            orientation_norm: |e_o|, rad.
        """
        return (position_norm <= self.position_tolerance) & (orientation_norm <= self.orientation_tolerance)

    def window_start(self, start_time, end_time):
        """The time t_end - final_window (t_end - t_0) from which samples are in the final window
        of an episode from ``start_time`` to ``end_time`` (s; floats or arrays).

        Args:
            start_time: t_0, the episode's first sample time, s.
            end_time: t_end, its last sample time, s.
        """
        return end_time - self.final_window * (end_time - start_time)

    def final_window_mask(self, time) -> np.ndarray:
        """The samples of an episode in its final window, (T,) bool.

        Args:
            time: (T,) s, the sample times, increasing.
        """
        time = np.asarray(time, dtype=float)
        mask = time >= self.window_start(time[0], time[-1])
        mask[-1] = True
        return mask

    def holds(self, latest_outside, start_time, end_time):
        """Whether an episode from ``start_time`` to ``end_time`` (s) whose latest sample outside
        the band is at ``latest_outside`` (s; -inf if none) holds the band over its final window.

        With the samples' times increasing, the latest sample outside the band comes before the
        window exactly when every sample of the window is inside (the last sample, always in the
        window, among them).  Floats give a bool, arrays a bool array.

        Args:
            latest_outside: the time of the latest sample outside the band, s (-inf if none).
            start_time: t_0, the episode's first sample time, s.
            end_time: t_end, its last sample time, s.
        """
        return latest_outside < self.window_start(start_time, end_time)

    def succeeded(self, time, inside, terminated: bool) -> bool:
        """Whether one recorded episode succeeds.

        Args:
            time: (T,) s, the sample times, increasing.
            inside: (T,) bool, the samples inside the band (:meth:`inside`).
            terminated: whether the episode ended early.

        Returns:
            The verdict.
        """
        if terminated:
            return False
        time = np.asarray(time, dtype=float)
        outside = np.flatnonzero(~np.asarray(inside, dtype=bool))
        latest = time[outside[-1]] if outside.size else -math.inf
        return bool(self.holds(latest, time[0], time[-1]))


class SuccessTracker:
    """A :class:`SuccessCriterion` applied to the n episodes of a batch as they run.

    Per row it keeps one number, the time of the episode's latest sample outside the band (-inf
    if none), so that after every step it says, without the episode's history, whether the
    episode would succeed if it ended there; at an episode's last step that is the criterion's
    verdict on the whole episode, whatever its length.  Episodes start at t = 0.

    Args:
        criterion: the criterion.
        n: the number of rows.
    """

    def __init__(self, criterion: SuccessCriterion, n: int):
        self.criterion = criterion
        #: The time (s) of each row's latest sample outside the band (n,), -inf if none.
        self.latest_outside = np.full(n, -math.inf)

    def start(self, rows: np.ndarray, position_norm: np.ndarray, orientation_norm: np.ndarray) -> None:
        """Start the episodes of ``rows`` with their samples at t = 0.

        Args:
            rows: (m,) the rows' indices.
            position_norm: (m,) m, |e_p| at t = 0.
            orientation_norm: (m,) rad, |e_o| at t = 0.
        """
        self.latest_outside[rows] = np.where(self.criterion.inside(position_norm, orientation_norm), -math.inf, 0.0)

    def start_row(self, row: int, position_norm: float, orientation_norm: float) -> None:
        """:meth:`start` for one row, in Python numbers.

        Args:
            row: the row's index.
            position_norm: |e_p| at t = 0, m.
            orientation_norm: |e_o| at t = 0, rad.
        """
        self.latest_outside[row] = -math.inf if self.criterion.inside(position_norm, orientation_norm) else 0.0

    def step(
        self, time: np.ndarray, position_norm: np.ndarray, orientation_norm: np.ndarray, terminated: np.ndarray
    ) -> np.ndarray:
        """Take every row's sample after a step and judge its episode as if it ended there.

        Args:
            time: (n,) s, the sample's time.
            position_norm: (n,) m.
            orientation_norm: (n,) rad.
            terminated: (n,) bool, the rows whose episode the step ended with a failure (an end
                for one of the task's ``success_reasons`` is none).

        Returns:
            Whether each episode, ended at this step, succeeds, (n,) bool.
        """
        criterion = self.criterion
        np.copyto(self.latest_outside, time, where=~criterion.inside(position_norm, orientation_norm))
        return ~terminated & criterion.holds(self.latest_outside, 0.0, time)

    def step_row(self, row: int, time: float, position_norm: float, orientation_norm: float, terminated: bool) -> bool:
        """:meth:`step` for one row, in Python numbers (a fraction of the array version's cost,
        for a batch of a few rows): the same comparisons of the same numbers.

        Args:
            row: the row's index.
            time: the sample's time, s.
            position_norm: |e_p|, m.
            orientation_norm: |e_o|, rad.
            terminated: whether the step ended the row's episode with a failure.

        Returns:
            Whether the row's episode, ended at this step, succeeds.
        """
        criterion = self.criterion
        if not criterion.inside(position_norm, orientation_norm):
            self.latest_outside[row] = time
            return False  # the last sample is always in the final window
        return not terminated and criterion.holds(self.latest_outside.item(row), 0.0, time)


def pose_margins(
    params: PlatformParams | Dynamics,
    position: np.ndarray,
    rpy: np.ndarray,
    margin: float = 0.1,
    rotation: np.ndarray | None = None,
    sensors: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """Whether poses lie safely inside the platform's limits, (M,) bool.

    Safe means: position inside the workspace box shrunk by ``margin`` of its half-size on each side, each
    angle within (1 - margin) max_angle of the home angle, every leg within the stroke shrunk by
    ``margin`` of its half-length at each end, and the Jacobian's condition number at most
    limits.max_condition (the leg lengths and the condition number from the kernel's leg sensors).

    Args:
        params: the platform, or a :class:`~stewart_env.dynamics.Dynamics` of it (its packed
            parameters are then not packed again: the fast way for repeated calls).
        position: (M,3) m, the positions of P's origin in {B}.
        rpy: (M,3) rad, the roll, pitch and yaw angles.
        margin: the fraction of each half-range kept clear.
        rotation: (M,3,3) the rotation matrices of ``rpy``, if already known.
        sensors: None, or the arrays (M,6), (M,6), (M,) float64 (C-contiguous) that receive the
            leg lengths, rates and condition numbers of the poses at rest, as measured for the
            check (the numbers of ``stewart_env.kinematics.leg_sensors_inplace``).

    Returns:
        Whether each pose is safe, (M,) bool.
    """
    model = params if isinstance(params, Dynamics) else make_dynamics(ModelSpec(), params)
    p = model.params_of(0)
    lim = p.limits
    position = np.ascontiguousarray(np.atleast_2d(position), dtype=np.float64)
    rpy = np.atleast_2d(np.asarray(rpy, dtype=np.float64))
    rotation = rpy_to_matrix(rpy) if rotation is None else np.ascontiguousarray(rotation, dtype=np.float64)
    m = position.shape[0]
    lengths, rates, condition = (np.empty((m, 6)), np.empty((m, 6)), np.empty(m)) if sensors is None else sensors
    rest = np.zeros((m, 3))
    leg_sensors_inplace(
        model, position, rotation.reshape(m, 3, 3), rest, rest, lim.max_condition, lengths, rates, condition
    )
    ok = np.empty(m, dtype=bool)
    _core.within_margins(
        position,
        np.ascontiguousarray(rpy),
        lengths,
        condition,
        lim.position_min,
        lim.position_max,
        p.home_rpy,
        lim.max_angle,
        lim.leg_length[0],
        lim.leg_length[1],
        lim.max_condition,
        float(margin),
        ok,
    )
    return ok


def sinusoid_reference(
    home_position: np.ndarray,
    home_rpy: np.ndarray,
    amplitude: np.ndarray,
    omega: np.ndarray,
    phase: np.ndarray,
    time: np.ndarray,
    out: Reference,
) -> None:
    """Pose offsets a_k sin(omega_k t + phi_k) about home on x, y, z, roll, pitch, yaw.

    Writes the reference pose, twist and accelerations into ``out``, all analytic: angular velocity = E(rpy) d(rpy)/dt (see
    :func:`stewart_env.rotations.rpy_rate_matrix`) and angular acceleration = E d2(rpy)/dt2 +
    (dE/dt) d(rpy)/dt.

    Args:
        home_position: (3,) m, the home position of P's origin in {B}.
        home_rpy: (3,) rad, the home roll, pitch and yaw.
        amplitude: (N,6) a_k, m on x, y, z and rad on roll, pitch, yaw.
        omega: (N,6) omega_k, rad/s.
        phase: (N,6) phi_k, rad.
        time: (N,) t, s.
        out: the :class:`Reference` (N rows) written into.
    """
    arg = omega * time[:, None] + phase
    sin = np.sin(arg)
    offset = amplitude * sin
    rate = amplitude * omega * np.cos(arg)
    accel = -(amplitude * omega * omega) * sin
    rpy = home_rpy + offset[:, 3:]
    out.position[:] = home_position + offset[:, :3]
    out.rotation[:] = rpy_to_matrix(rpy)
    out.velocity[:] = rate[:, :3]
    out.lin_acc[:] = accel[:, :3]
    E = rpy_rate_matrix(rpy)
    d, dd = rate[:, 3:], accel[:, 3:]
    out.angular_velocity[:] = E[:, :, 0] * d[:, 0:1] + E[:, :, 1] * d[:, 1:2] + E[:, :, 2] * d[:, 2:3]
    # dE/dt: only E's first two columns move, with pitch p and yaw y.
    cp, sp = np.cos(rpy[:, 1:2]), np.sin(rpy[:, 1:2])
    cy, sy = np.cos(rpy[:, 2:3]), np.sin(rpy[:, 2:3])
    dp, dy = d[:, 1:2], d[:, 2:3]
    e0_dot = np.concatenate([-sy * cp * dy - cy * sp * dp, cy * cp * dy - sy * sp * dp, -cp * dp], axis=1)
    e1_dot = np.concatenate([-cy * dy, -sy * dy, np.zeros_like(dy)], axis=1)
    out.ang_acc[:] = (
        E[:, :, 0] * dd[:, 0:1]
        + E[:, :, 1] * dd[:, 1:2]
        + E[:, :, 2] * dd[:, 2:3]
        + e0_dot * d[:, 0:1]
        + e1_dot * d[:, 1:2]
    )


def check_option_names(task_cls: type, options: dict[str, Any]) -> None:
    """Refuse task options the task's constructor does not take, naming them and the valid ones:
    its keyword-only arguments and, while a constructor passes ``**options`` on, those of the
    class it extends (the reward weights of :class:`Task`).

    Args:
        task_cls: the task's class.
        options: the task options, name -> value.

    Raises:
        ValueError: an option the task does not take, named with the valid ones.
    """
    valid: list[str] = []
    for cls in task_cls.__mro__:
        if "__init__" not in vars(cls):
            continue
        params = inspect.signature(cls.__init__).parameters.values()
        valid += [p.name for p in params if p.kind == p.KEYWORD_ONLY and p.name not in valid]
        if not any(p.kind == p.VAR_KEYWORD for p in params):
            break
    unknown = [k for k in options if k not in valid]
    if unknown:
        raise ValueError(
            f"task_options: unknown option(s) {', '.join(map(repr, unknown))} for task {task_cls.name!r}; "
            f"valid options: {', '.join(valid) or 'none'}"
        )


def option(name: str) -> str:
    """How errors name a task option: ``task_options['name']``.

    Args:
        name: the option's name.
    """
    return f"task_options[{name!r}]"


def motion_ranges(params: PlatformParams, position, angle, names: tuple[str, str]) -> tuple[np.ndarray, np.ndarray]:
    """A task's per-axis motion bounds: ``position`` (3,) m and ``angle`` (3,) rad as given (at
    most the workspace box's half-size and ``limits.max_angle``: beyond, no motion fits the
    limits), or by default 40 % of them, which leaves room for the platform to overshoot inside
    the limits.

    Args:
        params: the platform, whose ``limits`` bound the ranges.
        position: (3,) m, the position amplitudes, or None for the default.
        angle: (3,) rad, the angle amplitudes, or None for the default.
        names: the option names of ``position`` and ``angle``, for errors.

    Returns:
        The position bounds (3,) m and the angle bounds (3,) rad.

    Raises:
        UsageError: a bound outside its range, naming the option.
    """
    lim = params.limits
    half = 0.5 * (lim.position_max - lim.position_min)
    return (
        0.4 * half if position is None else vector(option(names[0]), position, 3, 0.0, half),
        np.full(3, 0.4 * lim.max_angle) if angle is None else vector(option(names[1]), angle, 3, 0.0, lim.max_angle),
    )


#: The platform's limits as termination reasons, by priority: the state is no longer finite, the
#: leg Jacobian's condition number exceeds limits.max_condition, a leg leaves its stroke, P leaves
#: the workspace box or an angle leaves home +- max_angle (see :meth:`Task.termination`).  Every
#: task's reasons begin with them, all failures.
LIMIT_REASONS = ("non_finite", "singularity", "leg_stroke", "workspace")


class StepView(NamedTuple):
    """What a task sees of a batch of N platforms: read-only arrays, frames and units of the
    environment card.

    Before a step (:meth:`Task.external_wrench`) the state, time and episode are those the step
    starts from.

    Attributes:
        state: a :class:`PlatformState` of (N, ...) arrays after the step.
        reference: the reference at the state's time.
        errors: reference minus actual, :class:`Errors`.
        action: (N,6) in [-1, 1] as applied over the step.
        leg_forces: (N,6) N applied over the step.
        leg_lengths: (N,6) m.
        leg_rates: (N,6) m/s.
        condition: (N,) the leg Jacobian's condition number (exact above limits.max_condition).
        external_wrench: (N,6) [N; N m] in {B} applied over the step.
        time: (N,) s.
        non_finite: (N,) bool, the rows whose state stopped being finite in the step (the state is
            then the last finite one).
        episode: the task's episode arrays by name, (N, *shape).
    """

    state: PlatformState
    reference: Reference
    errors: Errors
    action: np.ndarray
    leg_forces: np.ndarray
    leg_lengths: np.ndarray
    leg_rates: np.ndarray
    condition: np.ndarray
    external_wrench: np.ndarray
    time: np.ndarray
    non_finite: np.ndarray
    episode: Mapping[str, np.ndarray]


class Task:
    """Base class of the tasks: a reference pose to reach and hold, scored by the tracking-error
    reward (:class:`RewardWeights`) and ended by the platform's limits (:data:`LIMIT_REASONS`).

    A subclass sets ``name`` and implements :meth:`initialize_episode` and
    :meth:`episode_fields`; it may override :meth:`reference` (a moving reference; the default
    is a fixed target read from the episode arrays ``target_position`` and ``target_rotation``),
    :meth:`external_wrench`, :meth:`observation_terms`/:meth:`observe`, :meth:`reward_terms`,
    :meth:`termination` (extending ``termination_reasons``) and :meth:`termination_reward`.
    Whether the reference moves and whether there is an external wrench follow from which methods
    it overrides.  Options are keyword-only arguments of the subclass constructor (the
    environment's ``task_options``), the reward weights of :class:`RewardWeights` among them
    (a subclass passes ``**weights`` on to this constructor, which reads :meth:`episode_fields`,
    so a subclass sets what those depend on first); the platform's nominal parameters come first.

    Args:
        params: the platform's nominal parameters.
        control_dt: the control step, s.
        position_reward_weight, position_reward_scale, orientation_reward_weight,
            orientation_reward_scale, velocity_cost_weight, velocity_cost_scale,
            angular_velocity_cost_scale, ctrl_cost_weight, termination_cost: the reward's weights
            and scales (:class:`RewardWeights`), keyword-only.

    Raises:
        ValueError: a weight or scale out of its range (the message names the option).
        TypeError: a subclass whose ``termination_reasons`` do not begin with
            :data:`LIMIT_REASONS` or do not hold every success reason.
    """

    name = "task"
    #: Names of the termination codes 1, 2, ... of :meth:`termination`: the platform's limits
    #: first, then a subclass's own reasons.
    termination_reasons: tuple[str, ...] = LIMIT_REASONS
    #: The reasons that end an episode with a success: no termination cost is paid.
    success_reasons: tuple[str, ...] = ()
    #: The options whose defaults differ under an earlier version of the environment (its
    #: ``version`` argument), as version -> {option: its default under that version}; an option
    #: the user gives wins.  Empty when the task is the same under every version.
    version_defaults: Mapping[int, Mapping[str, Any]] = {}
    #: When an episode of the task succeeds (the environment's ``info["is_success"]``): by default
    #: the evaluation harness's criterion, 2 mm and 0.01 rad over the final tenth of the episode.
    success_criterion: SuccessCriterion = SuccessCriterion()

    def __init__(
        self,
        params: PlatformParams,
        control_dt: float,
        *,
        position_reward_weight: float = 0.5,
        position_reward_scale: float = BASE_REWARD_SCALES[0],
        orientation_reward_weight: float = 0.5,
        orientation_reward_scale: float = BASE_REWARD_SCALES[1],
        velocity_cost_weight: float = 0.1,
        velocity_cost_scale: float = 0.5,
        angular_velocity_cost_scale: float = 1.0,
        ctrl_cost_weight: float = 0.1,
        termination_cost: float = 10.0,
    ):
        self.params = params
        self.control_dt = float(control_dt)
        #: The platform's packed parameters for :func:`pose_margins` (packed once).
        self.kinematics = make_dynamics(ModelSpec(), params)
        self.weights = RewardWeights(
            position_reward_weight,
            position_reward_scale,
            orientation_reward_weight,
            orientation_reward_scale,
            velocity_cost_weight,
            velocity_cost_scale,
            angular_velocity_cost_scale,
            ctrl_cost_weight,
            termination_cost,
        )
        reasons = self.termination_reasons
        if reasons[: len(LIMIT_REASONS)] != LIMIT_REASONS or not set(self.success_reasons) <= set(reasons):
            raise TypeError(
                f"task {self.name!r}: termination_reasons must begin with {LIMIT_REASONS} and "
                f"hold every success reason, got {reasons} and {self.success_reasons}"
            )
        # Code -> whether it ends the episode with a failure (code 0: no end, no failure).
        self._failure = np.array([False] + [r not in self.success_reasons for r in reasons])
        lim = params.limits
        self._limits = (
            lim.position_min,
            lim.position_max,
            params.home_rpy,
            lim.max_angle,
            lim.leg_length[0],
            lim.leg_length[1],
            lim.max_condition,
        )
        if not self.moving_reference and not {"target_position", "target_rotation"} <= set(self.episode_fields()):
            raise TypeError(
                f"task {self.name!r}: a task with a fixed target declares the episode fields "
                "'target_position' and 'target_rotation', or overrides reference()"
            )

    def __repr__(self) -> str:
        return f"{type(self).__name__}(platform={self.params.name!r})"

    @property
    def moving_reference(self) -> bool:
        """Whether the reference moves (the task overrides :meth:`reference`); else the
        environment evaluates it at episode start only."""
        return type(self).reference is not Task.reference

    @property
    def has_external_wrench(self) -> bool:
        """Whether the task applies an external wrench (it overrides :meth:`external_wrench`)."""
        return type(self).external_wrench is not Task.external_wrench

    # -- episode ----------------------------------------------------------------------------------

    def episode_fields(self) -> dict[str, tuple[int, ...]]:
        """The per-row episode arrays, name -> shape without the batch dimension; the environment
        keeps them as (N, *shape) arrays and fills row i from :meth:`initialize_episode`."""
        raise NotImplementedError

    def initialize_episode(self, rng: np.random.Generator) -> tuple[PlatformState, dict[str, np.ndarray]]:
        """Draw one row's episode: its initial state and its ``episode_fields`` values.

        Args:
            rng: the row's generator.
        """
        raise NotImplementedError

    #: How many ``random()`` numbers each row's episode starts with when drawn by
    #: :meth:`initialize_episodes` (0: none known in advance).  A caller that draws from the rows'
    #: generators just before (the randomisation factors) may draw these in the same call per row
    #: and hand them over as ``unit``.
    episode_draws: int = 0

    def initialize_episodes(
        self, rngs: Sequence[np.random.Generator], unit: np.ndarray | None = None
    ) -> tuple[PlatformState, dict[str, np.ndarray]]:
        """Draw the episodes of m rows, row j from ``rngs[j]`` (each a different generator): the
        same numbers as :meth:`initialize_episode` row by row.  This default calls it per row; a
        task may draw all rows at once.

        Args:
            rngs: one generator per row.
            unit: None, or (m, :attr:`episode_draws`) the first ``random()`` numbers of each row's
                episode, already drawn from its generator (only with ``episode_draws`` > 0).

        Returns:
            The rows' initial states (a PlatformState of (m, ...) arrays) and their
            ``episode_fields`` values, (m, ...) each.
        """
        m = len(rngs)
        start = PlatformState(np.empty((m, 3)), np.empty((m, 3, 3)), np.empty((m, 3)), np.empty((m, 3)))
        episode = {k: np.empty((m, *shape)) for k, shape in self.episode_fields().items()}
        for j, rng in enumerate(rngs):
            state, values = self.initialize_episode(rng)
            for dst, src in zip(start, state):
                dst[j] = src
            for k, v in values.items():
                episode[k][j] = v
        return start, episode

    def initialize_episodes_measured(
        self, rngs: Sequence[np.random.Generator], unit: np.ndarray | None = None
    ) -> tuple[PlatformState, dict[str, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray] | None]:
        """:meth:`initialize_episodes`, and the leg sensors of the start states if the task
        measured them while drawing (checking candidate poses), so that the environment need not
        measure them again.  This default measures nothing.

        Args:
            rngs: one generator per row.
            unit: as :meth:`initialize_episodes`.

        Returns:
            The rows' initial states, their episode arrays, and None or the start states' leg
            lengths (m,6), rates (m,6) and condition numbers (m,) as
            ``stewart_env.kinematics.leg_sensors_inplace`` gives them for the nominal
            parameters and limits.max_condition.
        """
        # without unit, called as a task of its own that overrides initialize_episodes(rngs) expects
        start, episode = self.initialize_episodes(rngs) if unit is None else self.initialize_episodes(rngs, unit)
        return start, episode, None

    def reference(self, episode: Mapping[str, np.ndarray], time: np.ndarray, out: Reference) -> None:
        """Write the reference at ``time`` (N,) s into ``out`` (N rows).  This default is a fixed
        target at rest: the pose ``episode["target_position"]``, ``["target_rotation"]``, every
        rate zero.

        Args:
            episode: the episode arrays, name -> (N, ...).
            time: (N,) s, the rows' times.
            out: the :class:`Reference` (N rows) written into.
        """
        out.position[:] = episode["target_position"]
        out.rotation[:] = episode["target_rotation"]
        for name in out._fields[2:]:
            getattr(out, name)[:] = 0.0

    def external_wrench(self, view: StepView, dt: float, out: np.ndarray) -> None:
        """Write the wrench [F_ext at P (3), N; M_ext (3), N m] in {B} held over the step
        [view.time, view.time + dt] from the state ``view.state`` into ``out`` (N,6).  This
        default applies none (the environment keeps zeros and does not call it).

        Args:
            view: the batch's :class:`StepView` at the step's start.
            dt: the step's length, s.
            out: (N,6) the wrench written into.
        """

    # -- observation ------------------------------------------------------------------------------

    def observation_terms(self, scales: Scales) -> list[tuple[str, np.ndarray]]:
        """(name, scale) of each task observation term, scale (size,) in the term's units.

        Args:
            scales: the platform's :class:`Scales`.
        """
        angle = np.full(3, scales.angle)
        return [("position_error", scales.position.copy()), ("orientation_error", angle)]

    def observe(self, view: StepView, out: dict[str, np.ndarray]) -> None:
        """Write each term of :meth:`observation_terms`, in physical units, into ``out[name]``
        (N, size).

        Args:
            view: the batch's :class:`StepView`.
            out: the terms' arrays, name -> (N, size).
        """
        out["position_error"][:] = view.errors.position
        out["orientation_error"][:] = view.errors.orientation

    # -- reward and termination -------------------------------------------------------------------

    def _kernel_weights(self) -> tuple[float, ...]:
        """The reward weights and scales in the order the compiled reward takes them (its Python
        call and the step's task record both read this)."""
        w = self.weights
        return (
            w.position_reward_weight,
            w.position_reward_scale,
            w.orientation_reward_weight,
            w.orientation_reward_scale,
            w.velocity_cost_weight,
            w.velocity_cost_scale,
            w.angular_velocity_cost_scale,
            w.ctrl_cost_weight,
        )

    def reward_terms(self, view: StepView) -> dict[str, np.ndarray]:
        """Reward terms (N,) each, by name, of a step that does not end (see :class:`RewardWeights`;
        the end of an episode adds :meth:`termination_reward`).

        Args:
            view: the batch's :class:`StepView` after the step.
        """
        e = view.errors
        out = np.empty((4, view.time.shape[0]))
        _core.tracking_reward(
            e.position_norm,
            e.orientation_norm,
            e.velocity_norm,
            e.angular_velocity_norm,
            view.action,
            *self._kernel_weights(),
            out,
        )
        return {"position": out[0], "orientation": out[1], "velocity": out[2], "control": out[3]}

    def termination_reward(self, code: np.ndarray) -> np.ndarray:
        """The reward term ``termination`` (N,) of termination codes ``code``: -termination_cost
        where the episode ends with a failure, 0 where it goes on or ends with a success.

        Args:
            code: (N,) int64, the termination codes of :meth:`termination`.
        """
        return -self.weights.termination_cost * self._failure[code]

    def step_record(self) -> Any:
        """This task's part of the environment's compiled step (docs/layout.md, "The compiled
        step's contract"): the platform's limits, the reward weights and which termination codes
        are failures, the numbers of :meth:`termination`, :meth:`reward_terms` and
        :meth:`termination_reward`.

        Returns:
            A new ``_core.TaskRecord`` (the compiled extension's type), or None when a subclass has its own termination,
            reward terms or termination reward (the step then calls them between its parts).
        """
        if any(
            getattr(type(self), name) is not getattr(Task, name)
            for name in ("termination", "reward_terms", "termination_reward")
        ):
            return None
        position_min, position_max, home_rpy, max_angle, length_min, length_max, max_condition = self._limits
        weights = np.array(self._kernel_weights())
        return _core.TaskRecord(
            position_min,
            position_max,
            home_rpy,
            max_angle,
            length_min,
            length_max,
            max_condition,
            weights,
            self.weights.termination_cost,
            self._failure,
        )

    def termination(self, view: StepView) -> np.ndarray:
        """Termination codes (N,) int64: 0 where the episode goes on, else k for the reason
        ``termination_reasons[k - 1]``.  This default ends an episode at the platform's limits
        (:data:`LIMIT_REASONS`, by priority); a subclass adds its own reasons after them with
        :meth:`end`.

        Args:
            view: the batch's :class:`StepView` after the step.
        """
        code = np.empty(view.time.shape[0], dtype=np.int64)
        state = view.state
        _core.limit_codes(
            state.position, state.rotation, view.leg_lengths, view.condition, view.non_finite, *self._limits, code
        )
        return code

    def disable_limit_reasons(self, reasons: Iterable[str]) -> None:
        """Stop limit reasons from ending an episode (the environment's ``terminate_on`` without
        their constraints): their bounds become infinite in :meth:`termination` and the compiled
        step's task record, which this must precede; the constraint costs still measure them.

        Args:
            reasons: a subset of ("leg_stroke", "workspace").

        Raises:
            ValueError: another reason.
        """
        position_min, position_max, home_rpy, max_angle, length_min, length_max, max_condition = self._limits
        for reason in reasons:
            if reason == "leg_stroke":
                length_min, length_max = -math.inf, math.inf
            elif reason == "workspace":
                position_min, position_max, max_angle = np.full(3, -math.inf), np.full(3, math.inf), math.inf
            else:
                raise ValueError(f"reasons: expected 'leg_stroke' or 'workspace', got {reason!r}")
        self._limits = (position_min, position_max, home_rpy, max_angle, length_min, length_max, max_condition)

    def step_info(self) -> dict[str, np.ndarray]:
        """What the task adds to the last step's ``info``, by key: (N, ...) arrays of their own.
        This default adds nothing.

        Returns:
            The arrays by info key.
        """
        return {}

    def end(self, code: np.ndarray, where: np.ndarray, reason: str) -> None:
        """Set ``code`` to ``reason`` in the rows ``where`` that do not end for an earlier reason.

        Args:
            code: (N,) int64, the termination codes, changed in place.
            where: (N,) bool, the rows that end for ``reason``.
            reason: one of ``termination_reasons``.
        """
        code[where & (code == 0)] = self.termination_reasons.index(reason) + 1
