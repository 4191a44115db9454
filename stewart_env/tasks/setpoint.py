"""Setpoint: bring the platform from a start pose at rest to a fixed target pose and hold it."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from stewart_env import _core
from stewart_env.kinematics import inverse_kinematics, leg_sensors_inplace
from stewart_env.params import PlatformParams
from stewart_env.randomization import draw_unit_rows
from stewart_env.rotations import rpy_to_matrix
from stewart_env.state import PlatformState
from stewart_env.tasks.base import Task, motion_ranges, option, pose_margins
from stewart_env.validation import flag, vector

# The case study of He et al. (2018), as offsets from the home pose (0, 0, 0.4) of the dasgupta1998
# platform, where they give its absolute poses: start (0.1, 0, 0.395), target (0.1, 0, 0.4),
# rpy (0, 0, -0.2) for both, at rest.
PAPER_START_OFFSET = np.array([0.1, 0.0, -0.005])
PAPER_TARGET_OFFSET = np.array([0.1, 0.0, 0.0])
PAPER_RPY_OFFSET = np.array([0.0, 0.0, -0.2])
# Rejection sampling of random poses gives up after this many draws (each draw is kept with a
# probability close to 1 for the default ranges).
_MAX_DRAWS = 1000
# A drawn pose keeps this fraction of each half-range clear of the limits (pose_margins' default).
_MARGIN = 0.1
# Fixed poses are checked against the limits; beyond this (m or rad) the check itself would overflow.
_MAX_POSE = 1e3


class Candidates(NamedTuple):
    """Candidate poses of the set-point task's random draws, M of them."""

    position: np.ndarray  #: (M,3) m
    rotation: np.ndarray  #: (M,3,3)
    ok: np.ndarray  #: (M,) bool, whether each lies safely inside the limits (pose_margins)
    #: their leg lengths (M,6) m, rates (M,6) m/s and condition numbers (M,) at rest, as measured
    #: for the check (the numbers of leg_sensors_inplace for the nominal parameters)
    sensors: tuple[np.ndarray, np.ndarray, np.ndarray]


class PaperCase(NamedTuple):
    """The poses of the case study on one platform, in {B}: positions m, angles rpy rad."""

    start_position: np.ndarray
    start_rpy: np.ndarray
    target_position: np.ndarray
    target_rpy: np.ndarray


def paper_case(params: PlatformParams, *, check_stroke: bool = True) -> PaperCase:
    """The case study of He et al. (2018) on ``params``: the paper's poses as offsets from home.

    The case is defined on the dasgupta1998 geometry, and on another platform the same offsets
    need not be reachable.

    Args:
        params: the platform.
        check_stroke: whether to check that every leg stays within limits.leg_length at the start
            and the target pose.

    Returns:
        The start and target poses, a :class:`PaperCase`.

    Raises:
        ValueError: with ``check_stroke``, a leg outside the stroke, naming the platform and every
            such leg.
    """
    home_p, home_r = params.home_position, params.home_rpy
    case = PaperCase(
        home_p + PAPER_START_OFFSET, home_r + PAPER_RPY_OFFSET, home_p + PAPER_TARGET_OFFSET, home_r + PAPER_RPY_OFFSET
    )
    if not check_stroke:
        return case
    lo, hi = params.limits.leg_length
    problems = []
    for which, position, rpy in (
        ("start", case.start_position, case.start_rpy),
        ("target", case.target_position, case.target_rpy),
    ):
        lengths, _ = inverse_kinematics(params, position, rpy_to_matrix(rpy))
        problems += [
            f"at the {which} pose leg {i} is {length:.4f} m long"
            for i, length in enumerate(lengths)
            if not lo <= length <= hi
        ]
    if problems:
        raise ValueError(
            f"platform {params.name!r}: the case study of He et al. (2018) (home + {PAPER_START_OFFSET.tolist()} m "
            f"to home + {PAPER_TARGET_OFFSET.tolist()} m, rpy home + {PAPER_RPY_OFFSET.tolist()} rad) leaves "
            f"the leg stroke limits.leg_length = [{lo}, {hi}] m: " + "; ".join(problems)
        )
    return case


class SetpointTask(Task):
    """Reach a target pose from a start pose at rest, then hold it.

    The options are the environment's ``task_options``.

    Args:
        params: the platform's nominal parameters.
        control_dt: the control step, s.
        randomize: True (default) draws the start and the target pose of every episode
            independently and uniformly: positions in home +- position_range, angles in home rpy
            +- angle_range, each pose redrawn until it lies safely inside the limits (10 %
            margins, see :func:`~stewart_env.tasks.base.pose_margins`).  False gives the fixed
            poses below every episode.
        position_range: (3,) m, or one number for all axes, at most the workspace half-size;
            default 0.4 x the workspace half-size (dasgupta1998: 0.1, 0.1, 0.06).
        angle_range: (3,) rad, or one number, at most limits.max_angle; default 0.4 x
            limits.max_angle (dasgupta1998: 0.2).
        start_position, start_rpy, target_position, target_rpy: the fixed poses used when
            randomize is False, in {B} (m, rad).  Defaults: the paper's case study written as
            offsets from home, i.e. start home + (0.1, 0, -0.005) with rpy home + (0, 0, -0.2),
            target home + (0.1, 0, 0) with the same rpy; for dasgupta1998 exactly the paper's
            start (0.1, 0, 0.395) and target (0.1, 0, 0.4), rpy (0, 0, -0.2).  Each must lie
            inside the platform's limits.
        **weights: the reward weights and scales of :class:`~stewart_env.tasks.RewardWeights`.

    Raises:
        ValueError: an unknown option or one out of its range (the message names it).
    """

    name = "setpoint"

    def __init__(
        self,
        params: PlatformParams,
        control_dt: float,
        *,
        randomize: bool = True,
        position_range=None,
        angle_range=None,
        start_position=None,
        start_rpy=None,
        target_position=None,
        target_rpy=None,
        **weights,
    ):
        super().__init__(params, control_dt, **weights)
        self.randomize = flag(option("randomize"), randomize)
        # (home pose, ranges, nominal packed row) of the compiled candidates, made at their first draw
        self._pose_tables: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self.position_range, self.angle_range = motion_ranges(
            params, position_range, angle_range, ("position_range", "angle_range")
        )
        # unchecked: random episodes never use these defaults, and fixed ones are checked below
        case = paper_case(params, check_stroke=False)
        poses = {
            "start_position": (start_position, case.start_position),
            "start_rpy": (start_rpy, case.start_rpy),
            "target_position": (target_position, case.target_position),
            "target_rpy": (target_rpy, case.target_rpy),
        }
        fixed = {
            k: (default if v is None else vector(option(k), v, 3, -_MAX_POSE, _MAX_POSE))
            for k, (v, default) in poses.items()
        }
        self.start_position, self.start_rpy = fixed["start_position"], fixed["start_rpy"]
        self.target_position, self.target_rpy = fixed["target_position"], fixed["target_rpy"]
        if not self.randomize:
            for which in ("start", "target"):
                p, r = fixed[f"{which}_position"], fixed[f"{which}_rpy"]
                if not pose_margins(params, p, r, margin=0.0)[0]:
                    raise ValueError(
                        f"task_options[{which + '_position'!r}], [{which + '_rpy'!r}]: the pose {p.tolist()}, "
                        f"rpy {r.tolist()} lies outside the limits of platform {params.name!r}"
                    )

    def episode_fields(self):
        """The episode arrays (see :meth:`Task.episode_fields`): the target pose."""
        return {"target_position": (3,), "target_rotation": (3, 3)}

    def _draw_pose(self, rng: np.random.Generator, draws: int = _MAX_DRAWS) -> tuple[np.ndarray, np.ndarray]:
        """A random pose (position, rotation) safely inside the limits, in at most ``draws``
        draws (of the _MAX_DRAWS allowed, the rest of a pose begun by :meth:`initialize_episodes`)."""
        p = self.params
        for _ in range(draws):
            position = p.home_position + rng.uniform(-1.0, 1.0, 3) * self.position_range
            rpy = p.home_rpy + rng.uniform(-1.0, 1.0, 3) * self.angle_range
            rotation = rpy_to_matrix(rpy)
            if pose_margins(self.kinematics, position, rpy, margin=_MARGIN, rotation=rotation)[0]:
                return position, rotation
        raise RuntimeError(
            f"setpoint: no pose inside the limits of platform {p.name!r} in {_MAX_DRAWS} draws; "
            "reduce task_options['position_range'] or ['angle_range']"
        )

    def _candidates(self, unit: np.ndarray) -> Candidates:
        """Candidate poses of :meth:`_draw_pose` from its draws ``unit`` (M, 6) of ``random()``
        (``uniform(-1, 1)`` is ``-1 + 2 random()``, the same number): their :class:`Candidates`,
        made, measured and checked in one compiled call (``_core.setpoint_candidates``: the
        numbers of home + uniform(-1, 1) * range, ``rpy_to_matrix`` and :func:`pose_margins`)."""
        p = self.params
        lim = p.limits
        if getattr(self, "_pose_tables", None) is None:  # a task pickled before it kept them
            self._pose_tables = (
                np.concatenate((p.home_position, p.home_rpy)),
                np.concatenate((self.position_range, self.angle_range)),
                np.ascontiguousarray(self.kinematics.packed[:1]),
            )
        home, ranges, prm = self._pose_tables
        unit = np.ascontiguousarray(unit, dtype=np.float64)
        m = len(unit)
        position, rpy, rotation = np.empty((m, 3)), np.empty((m, 3)), np.empty((m, 3, 3))
        sensors = (np.empty((m, 6)), np.empty((m, 6)), np.empty(m))
        ok = np.empty(m, dtype=bool)
        _core.setpoint_candidates(
            unit,
            home,
            ranges,
            prm,
            lim.position_min,
            lim.position_max,
            p.home_rpy,
            lim.max_angle,
            lim.leg_length[0],
            lim.leg_length[1],
            lim.max_condition,
            _MARGIN,
            position,
            rpy,
            rotation,
            *sensors,
            ok,
        )
        return Candidates(position, rotation, ok, sensors)

    @property
    def episode_draws(self) -> int:
        """The ``random()`` numbers of a row's first two candidate poses (12) when the poses are
        drawn, else 0 (see :attr:`Task.episode_draws`)."""
        return 12 if self.randomize else 0

    def initialize_episodes(self, rngs, unit=None):
        """The start and target poses of every row at once, bit for bit those of
        :meth:`initialize_episode` row by row: each row draws its first two candidates (start,
        target) in one call, all are checked together, and the few rows that rejected one go on
        drawing row by row, as :meth:`_draw_pose` would have.

        Args:
            rngs: one generator per row.
            unit: None, or (m, 12) those first two candidates' draws, already taken from the rows'
                generators (see :attr:`Task.episode_draws`).

        Returns:
            The rows' start states and their target poses, as :meth:`Task.initialize_episodes`.
        """
        start, episode, _ = self.initialize_episodes_measured(rngs, unit)
        return start, episode

    def initialize_episodes_measured(self, rngs, unit=None):
        """:meth:`initialize_episodes` and, with random poses, the start poses' leg sensors at
        rest, measured once as the candidates are checked (see :meth:`Task.initialize_episodes_measured`).

        Args:
            rngs: one generator per row.
            unit: as :meth:`initialize_episodes`.

        Returns:
            The rows' start states, their target poses, and the start states' leg lengths (m,6),
            rates (m,6) and condition numbers (m,) (None with fixed poses).
        """
        if not self.randomize:
            return (*super().initialize_episodes(rngs, unit), None)
        m = len(rngs)
        if unit is None:
            unit = np.empty((m, 12))
            draw_unit_rows(rngs, unit)  # random(12) of each row's generator, in one compiled call
        candidates = self._candidates(np.reshape(unit, (2 * m, 6)))
        position, rotation, ok = candidates[0], candidates[1], candidates[2]
        position, rotation, ok = position.reshape(m, 2, 3), rotation.reshape(m, 2, 3, 3), ok.reshape(m, 2)
        sensors = getattr(candidates, "sensors", None)
        zero = np.zeros((m, 3))
        if ok.all():
            # every row's first two candidates accepted (nearly every reset with the default ranges):
            # the start the first, the target the second, without the selection below
            return (
                PlatformState(position[:, 0].copy(), rotation[:, 0].copy(), zero, zero.copy()),
                {"target_position": position[:, 1].copy(), "target_rotation": rotation[:, 1].copy()},
                None if sensors is None else (sensors[0][0::2], sensors[1][0::2], sensors[2][0::2]),
            )
        # a rejected start: the second candidate is the start's next draw (both rejected: redrawn below)
        start_second = ~ok[:, 0]
        start_p = np.where(start_second[:, None], position[:, 1], position[:, 0])
        start_r = np.where(start_second[:, None, None], rotation[:, 1], rotation[:, 0])
        # the start candidate's leg sensors (the check's numbers, at rest), if the check gave them
        if sensors is not None:
            lengths, rates = (np.where(start_second[:, None], x[1::2], x[0::2]) for x in sensors[:2])
            condition = np.where(start_second, sensors[2][1::2], sensors[2][0::2])
        target_p, target_r = position[:, 1].copy(), rotation[:, 1].copy()
        redrawn = []
        for j in np.flatnonzero(start_second | ~ok[:, 1]).tolist():
            rng = rngs[j]
            if not ok[j, 0] and not ok[j, 1]:
                start_p[j], start_r[j] = self._draw_pose(rng, _MAX_DRAWS - 2)
                target_p[j], target_r[j] = self._draw_pose(rng)
                redrawn.append(j)
            else:
                # the start is accepted; the target had one rejected draw if the start was the first
                target_p[j], target_r[j] = self._draw_pose(rng, _MAX_DRAWS - int(ok[j, 0]))
        if sensors is not None and redrawn:
            # starts drawn row by row: their sensors as the check measured them, at rest
            k = len(redrawn)
            out = (np.empty((k, 6)), np.empty((k, 6)), np.empty(k))
            rest = np.zeros((k, 3))
            leg_sensors_inplace(
                self.kinematics,
                np.ascontiguousarray(start_p[redrawn]),
                np.ascontiguousarray(start_r[redrawn]),
                rest,
                rest,
                self.params.limits.max_condition,
                *out,
            )
            lengths[redrawn], rates[redrawn], condition[redrawn] = out
        return (
            PlatformState(start_p, start_r, zero, zero.copy()),
            {"target_position": target_p, "target_rotation": target_r},
            None if sensors is None else (lengths, rates, condition),
        )

    def initialize_episode(self, rng):
        """Draw one row's episode (see :meth:`Task.initialize_episode`): the start and target poses, drawn when randomized, else the given ones.

        Args:
            rng: the row's generator.
        """
        if self.randomize:
            start_p, start_r = self._draw_pose(rng)
            target_p, target_r = self._draw_pose(rng)
        else:
            start_p, start_r = self.start_position, rpy_to_matrix(self.start_rpy)
            target_p, target_r = self.target_position, rpy_to_matrix(self.target_rpy)
        start = PlatformState(start_p.copy(), start_r, np.zeros(3), np.zeros(3))
        return start, {"target_position": target_p, "target_rotation": target_r}
