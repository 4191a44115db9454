"""Tuning classical washout on training manoeuvres: a seeded, bounded optimisation of its
parameters against the perceived error, with workspace and stroke penalties.

The objective of a parameter vector (:data:`TUNED`, ten parameters, each searched on a log scale
between its bounds; the dampings stay at 1, the limits at their defaults) runs the washout
(:class:`~stewart_env.agents.controllers.washout.Washout`) over every training motion side by
side, puts the cabin exactly where it commands (:func:`~stewart_env.agents.evaluation.cueing.kinematic_head_motion`:
the cueing algorithm alone, as the literature tunes it, not the platform's dynamics) and scores

    J = mean over motions of (e_f / 1 m/s² + e_omega / 0.1 rad/s)
        + 100 sum over motions of (max(0, workspace_use - reach)² + max(0, stroke_use - reach)²)

with e_f and e_omega the RMS errors between the perceived vehicle and platform motions (the
cueing metrics' definitions, :mod:`~stewart_env.agents.evaluation.cueing`), the workspace and
stroke use of the commanded poses on ``platform`` (inverse kinematics) and ``reach`` = 0.9, the
share of the limits the kinematic chain may use (the rest is the platform's dynamics' margin).
The search is SciPy's Nelder-Mead in the bounded, log-scaled coordinates from the defaults of
:class:`~stewart_env.agents.controllers.washout.WashoutParams`, deterministic given its inputs
(``seed`` picks the training motions' seeds).

The shipped tuning, configs/agents/washout.yaml, was written by::

    python -m stewart_env.agents.studies.washout_tuning configs/agents/washout.yaml

(training motions from seed 0, the dasgupta1998 platform, 300 evaluations: under 5 minutes on
one core), which records the motions, platform, objective and the command in the file.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import scipy.optimize

import stewart_env as se
from stewart_env.agents.controllers.washout import Washout, WashoutParams, head_pose
from stewart_env.agents.evaluation.cueing import kinematic_head_motion
from stewart_env.errors import UsageError
from stewart_env.files import publish
from stewart_env.rotations import matrix_to_rpy
from stewart_env.tasks.cueing.motion import STANDARD_GRAVITY, VehicleMotion
from stewart_env.tasks.cueing.vestibular import Otolith, SemicircularCanal

__all__ = ["TUNED", "TuningResult", "kinematic_chain", "tune_washout", "washout_objective"]

#: This module's name, as ``python -m`` runs it.
MODULE = "stewart_env.agents.studies.washout_tuning"
#: The tuned parameters: name, the fields and entries it sets, and its bounds.
TUNED = (
    ("force_scale_xy", ("force_scale", (0, 1)), (0.1, 1.0)),
    ("force_scale_z", ("force_scale", (2,)), (0.1, 1.0)),
    ("translational_frequency_xy", ("translational_frequency", (0, 1)), (0.5, 6.0)),
    ("translational_frequency_z", ("translational_frequency", (2,)), (0.5, 8.0)),
    ("translational_break_xy", ("translational_break", (0, 1)), (0.05, 2.0)),
    ("tilt_frequency", ("tilt_frequency", (0, 1)), (0.3, 6.0)),
    ("angular_scale_roll_pitch", ("angular_scale", (0, 1)), (0.1, 1.0)),
    ("angular_scale_yaw", ("angular_scale", (2,)), (0.1, 1.0)),
    ("rotational_frequency_roll_pitch", ("rotational_frequency", (0, 1)), (0.1, 4.0)),
    ("rotational_frequency_yaw", ("rotational_frequency", (2,)), (0.1, 4.0)),
)
#: The head point in {P} (m): the cueing task's default, a seated person's eyes 0.8 m above P.
DEFAULT_HEAD = (0.0, 0.0, 0.8)
#: The scales of the errors in the objective: 1 m/s² of specific force weighs as 0.1 rad/s.
FORCE_SCALE_ERROR = 1.0
ANGULAR_SCALE_ERROR = 0.1
#: The share of the workspace and of the stroke the kinematic chain may use, and the penalty's weight.
REACH = 0.9
PENALTY = 100.0


def params_of(vector, base: WashoutParams | None = None) -> WashoutParams:
    """The washout parameters of a vector of :data:`TUNED`'s values (the rest from ``base``).

    Args:
        vector: (len(TUNED),) the values, in their units.
        base: the parameters not tuned (default :class:`WashoutParams`'s defaults).

    Returns:
        The parameters.
    """
    base = base or WashoutParams()
    fields: dict[str, list[float]] = {}
    for value, (_, (field, entries), _) in zip(vector, TUNED):
        current = fields.setdefault(field, list(getattr(base, field)))
        for entry in entries:
            current[entry] = float(value)
    return replace(base, **{k: tuple(v) for k, v in fields.items()})


def vector_of(params: WashoutParams) -> np.ndarray:
    """The values of :data:`TUNED` in ``params`` (the first entry of each group), clipped to the bounds.

    Args:
        params: the parameters.

    Returns:
        (len(TUNED),) the values.
    """
    return np.array([np.clip(getattr(params, field)[entries[0]], *bounds) for _, (field, entries), bounds in TUNED])


class _Chain:
    """The training motions side by side (padded at rest to the longest), their perceived vehicle
    motion once, and the platform's limits."""

    def __init__(self, motions: Sequence[VehicleMotion], platform, head):
        if not motions:
            raise UsageError.about("motions", "give at least one training motion")
        dts = {m.dt for m in motions}
        if len(dts) != 1:
            raise UsageError.about("motions", f"must share one sample period, got {sorted(dts)}")
        self.dt = dts.pop()
        self.lengths = [m.n_samples for m in motions]
        n = max(self.lengths)
        self.f = np.tile([0.0, 0.0, STANDARD_GRAVITY], (n, len(motions), 1))
        self.w = np.zeros((n, len(motions), 3))
        for j, m in enumerate(motions):
            self.f[: m.n_samples, j] = m.specific_force
            self.w[: m.n_samples, j] = m.angular_velocity
        self.platform = platform
        self.head = np.asarray(head, dtype=float)
        self._otolith, self._canal = Otolith().discretize(self.dt), SemicircularCanal().discretize(self.dt)
        self.vehicle = self.perceive(self.f, self.w)
        lim = platform.limits
        self.box_mid = 0.5 * (lim.position_min + lim.position_max)
        self.box_half = 0.5 * (lim.position_max - lim.position_min)
        self.max_angle = lim.max_angle
        self.stroke_mid = 0.5 * (lim.leg_length[0] + lim.leg_length[1])
        self.stroke_half = 0.5 * (lim.leg_length[1] - lim.leg_length[0])

    def perceive(self, f, w) -> tuple[np.ndarray, np.ndarray]:
        """The perceived motions (T, M, 3) each of a batch of motions, from rest at the start."""
        otolith, canal = self._otolith, self._canal
        deviation = f - np.array([0.0, 0.0, STANDARD_GRAVITY])
        otolith.reset(deviation[0])
        canal.reset(w[0])
        return (
            np.stack([otolith.step(u) for u in deviation]),
            np.stack([canal.step(u) for u in w]),
        )

    def score(self, params: WashoutParams) -> tuple[float, dict]:
        """The objective (module docstring) and its terms."""
        displacement, rpy = Washout(params, self.dt).run(self.f, self.w)
        head_f = np.empty_like(self.f)
        head_w = np.empty_like(self.w)
        for j in range(self.f.shape[1]):
            head_f[:, j], head_w[:, j] = kinematic_head_motion(displacement[:, j], rpy[:, j], self.dt)
        felt_f, felt_w = self.perceive(head_f, head_w)
        errors_f, errors_w, workspace, stroke = [], [], [], []
        for j, n in enumerate(self.lengths):
            e_f = self.vehicle[0][:n, j] - felt_f[:n, j]
            e_w = self.vehicle[1][:n, j] - felt_w[:n, j]
            errors_f.append(math.sqrt(np.mean(np.sum(e_f * e_f, axis=1))))
            errors_w.append(math.sqrt(np.mean(np.sum(e_w * e_w, axis=1))))
            position, rotation = head_pose(self.platform, self.head, displacement[:n, j], rpy[:n, j])
            angles = matrix_to_rpy(rotation) - np.asarray(self.platform.home_rpy)
            workspace.append(
                max(
                    float(np.max(np.abs(position - self.box_mid) / self.box_half)),
                    float(np.max(np.abs(angles)) / self.max_angle),
                )
            )
            lengths = se.leg_kinematics(self.platform, position, rotation).lengths
            stroke.append(float(np.max(np.abs(lengths - self.stroke_mid)) / self.stroke_half))
        error = float(np.mean(np.array(errors_f) / FORCE_SCALE_ERROR + np.array(errors_w) / ANGULAR_SCALE_ERROR))
        over = np.maximum(0.0, np.array(workspace) - REACH) ** 2 + np.maximum(0.0, np.array(stroke) - REACH) ** 2
        terms = {
            "rms_specific_force_error": errors_f,
            "rms_angular_velocity_error": errors_w,
            "workspace_use": workspace,
            "stroke_use": stroke,
        }
        return error + PENALTY * float(over.sum()), terms


def washout_objective(
    params: WashoutParams, motions: Sequence[VehicleMotion], platform="dasgupta1998", head=(0.0, 0.0, 0.0)
) -> float:
    """The tuning's objective (module docstring) of one parameter set.

    Args:
        params: the washout's parameters.
        motions: the training motions, one sample period.
        platform: a shipped platform's name or PlatformParams: its workspace and stroke.
        head: the head point in {P}, m.

    Returns:
        J, dimensionless.
    """
    platform = se.load_platform(platform) if isinstance(platform, str) else platform
    return _Chain(motions, platform, head).score(params)[0]


@dataclass(frozen=True)
class TuningResult:
    """A tuning's outcome.

    Attributes:
        params: the tuned parameters.
        objective: J at them.
        initial_objective: J at the starting parameters.
        terms: the objective's terms per motion at the tuned parameters.
        evaluations: the objective's evaluations.
        seconds: the wall time, s.
    """

    params: WashoutParams
    objective: float
    initial_objective: float
    terms: dict
    evaluations: int
    seconds: float


def tune_washout(
    motions: Sequence[VehicleMotion],
    platform="dasgupta1998",
    head=DEFAULT_HEAD,
    start: WashoutParams | None = None,
    max_evaluations: int = 300,
) -> TuningResult:
    """Tune the washout on training motions (module docstring): bounded Nelder-Mead on log scales.

    Args:
        motions: the training motions (the cueing task's split="train"), one sample period.
        platform: a shipped platform's name or PlatformParams: its workspace and stroke.
        head: the head point in {P}, m.
        start: the starting parameters (default :class:`WashoutParams`'s defaults); their
            untuned fields are kept.
        max_evaluations: the objective's evaluations at most.

    Returns:
        The tuned parameters, the objective before and after, and its terms.

    Raises:
        UsageError: no motions, motions of different sample periods, a bad ``max_evaluations``.
    """
    if isinstance(max_evaluations, bool) or not isinstance(max_evaluations, int) or max_evaluations < 1:
        raise UsageError.about("max_evaluations", f"must be a positive integer, got {max_evaluations!r}")
    platform = se.load_platform(platform) if isinstance(platform, str) else platform
    start = start or WashoutParams()
    chain = _Chain(motions, platform, head)
    low = np.log([b[0] for _, _, b in TUNED])
    high = np.log([b[1] for _, _, b in TUNED])
    began = time.perf_counter()
    count = 0

    def objective(x):
        nonlocal count
        count += 1
        return chain.score(params_of(np.exp(np.clip(x, low, high)), start))[0]

    x0 = np.log(vector_of(start))
    initial = objective(x0)
    result = scipy.optimize.minimize(
        objective,
        x0,
        method="Nelder-Mead",
        bounds=list(zip(low, high)),
        options={"maxfev": max_evaluations, "xatol": 1e-3, "fatol": 1e-4},
    )
    best = params_of(np.exp(np.clip(result.x, low, high)), start)
    value, terms = chain.score(best)
    return TuningResult(best, value, initial, terms, count, time.perf_counter() - began)


def kinematic_chain(params: WashoutParams, dt: float = 0.01):
    """The washout alone as a chain for the gain and phase table
    (:func:`~stewart_env.agents.evaluation.cueing.frequency_response_table`): the cabin follows its
    commanded pose exactly.

    Args:
        params: the washout's parameters.
        dt: the control step, s.

    Returns:
        motion -> (specific force (T, 3), angular velocity (T, 3)) at the head.
    """

    def chain(motion: VehicleMotion) -> tuple[np.ndarray, np.ndarray]:
        displacement, rpy = Washout(params, dt).run(motion.specific_force, motion.angular_velocity)
        return kinematic_head_motion(displacement, rpy, dt)

    return chain


def training_motions(seed: int = 0) -> list[VehicleMotion]:
    """The cueing task's training motions, one each, from ``seed`` (a training seed, < 2**30).

    Args:
        seed: the first seed; motion k gets seed + k.

    Returns:
        The motions of ``TRAINING_MOTIONS`` at 10 ms.
    """
    from stewart_env.tasks.cueing.motions import TRAINING_MOTIONS, make_motion

    return [make_motion(name, seed + k, 0.01) for k, name in enumerate(TRAINING_MOTIONS)]


#: The shipped tuning's settings: the training motions' first seed, the platform, the evaluations.
SHIPPED_SEED = 0
SHIPPED_PLATFORM = "dasgupta1998"
SHIPPED_EVALUATIONS = 300


def main(argv: Sequence[str] | None = None) -> int:
    """Tune with the shipped settings and write the config: ``python -m
    stewart_env.agents.studies.washout_tuning [OUT]`` (default configs/agents/washout.yaml).

    Args:
        argv: the command line's arguments after the module (default sys.argv's): at most OUT.

    Returns:
        The exit status: 0, or 2 with a one-line usage error.
    """
    import sys

    argv = sys.argv[1:] if argv is None else list(argv)
    if len(argv) > 1 or (argv and argv[0].startswith("-")):
        print(f"usage: python -m {MODULE} [OUT]  (got {' '.join(argv)})", file=sys.stderr)
        return 2
    out = argv[0] if argv else "configs/agents/washout.yaml"
    motions = training_motions(SHIPPED_SEED)
    result = tune_washout(motions, SHIPPED_PLATFORM, max_evaluations=SHIPPED_EVALUATIONS)
    publish(out, config_text(result, motions, SHIPPED_PLATFORM, f"python -m {MODULE} {out}"))
    print(
        f"J {result.initial_objective:.4g} -> {result.objective:.4g} in {result.evaluations} evaluations, {result.seconds:.0f} s"
    )
    return 0


def config_text(result: TuningResult, motions: Sequence[VehicleMotion], platform: str, command: str) -> str:
    """The config file of a tuning: a comment with the command, ``params`` and ``tuning`` mappings.

    Args:
        result: the tuning.
        motions: its motions.
        platform: its platform's name.
        command: the command that ran it.

    Returns:
        The YAML text.
    """
    import yaml

    document = {
        "params": result.params.as_dict(),
        "tuning": {
            "motions": [m.source or m.name for m in motions],
            "platform": platform,
            "objective": round(result.objective, 6),
            "initial_objective": round(result.initial_objective, 6),
            "evaluations": result.evaluations,
        },
    }
    head = (
        "# Classical washout tuned on the cueing task's training motions (the kinematic chain; see\n"
        "# stewart_env.agents.studies.washout_tuning for the objective). Written by:\n"
        f"#   {command}\n"
    )
    return head + yaml.safe_dump(document, sort_keys=False)


if __name__ == "__main__":
    raise SystemExit(main())
