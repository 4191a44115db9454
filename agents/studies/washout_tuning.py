"""Tuning classical washout on training manoeuvres in the environment: a seeded, bounded
optimisation of its parameters against the perceived error the whole chain leaves, with workspace,
stroke and failure penalties.

The objective of a parameter vector (:data:`TUNED`, ten parameters, each searched on a log scale
between its bounds; the dampings stay at 1, the limits at their defaults) runs the washout
(:class:`~stewart_env.agents.controllers.washout.WashoutPolicy`) on every training motion side by
side, one row each of the cueing task's native vector environment (:class:`EnvironmentChain`): the
commanded pose (``action_mode="pose"``) tracked by the platform's inner loop and dynamics, the
motion at the head, the vestibular models and the task's metrics
(:func:`~stewart_env.agents.evaluation.cueing.episode_cueing_metrics`), and scores

    J = mean over motions of (e_f / 1 m/s² + e_omega / 0.1 rad/s)
        + 100 sum over motions of (max(0, workspace_use - reach)² + max(0, stroke_use - reach)²)
        + 10 x the motions the platform's limits end early

with e_f and e_omega the RMS errors between the perceived vehicle and platform motions (over the
steps played), the workspace and stroke use the task's and ``reach`` = 0.6, the share of the limits
the training motions may use (the held-out motions are larger).  The search is SciPy's Nelder-Mead
in the bounded, log-scaled coordinates from the defaults of
:class:`~stewart_env.agents.controllers.washout.WashoutParams`, deterministic given its inputs
(the environment is reset with seed 0 for every evaluation; ``seed`` picks the training motions).

The shipped tuning, configs/agents/washout.yaml, was written by::

    python -m stewart_env.agents.studies.washout_tuning configs/agents/washout.yaml

(training motions from seed 0, the dasgupta1998 platform, at most :data:`SHIPPED_EVALUATIONS`
evaluations), which records the motions, platform, objective and the command in the file.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import scipy.optimize

from stewart_env.agents.controllers.washout import Washout, WashoutParams, WashoutPolicy
from stewart_env.agents.evaluation.cueing import ScheduledEpisodes, kinematic_head_motion
from stewart_env.errors import UsageError
from stewart_env.files import publish
from stewart_env.tasks.cueing.motion import VehicleMotion

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
#: The share of the workspace and of the stroke the training motions may use, and the penalty's
#: weight: at 0.9 the tuning left the held-out take-off rolls, larger than the training one, at the
#: workspace's edge (both ended by the limits).
REACH = 0.6
PENALTY = 100.0
#: The objective's cost of a motion the platform's limits end early (the task's termination cost).
FAILURE_COST = 10.0
#: The shipped tuning's settings: the training motions' first seed, the platform, the evaluations.
SHIPPED_SEED = 0
SHIPPED_PLATFORM = "dasgupta1998"
SHIPPED_EVALUATIONS = 60
#: The first simplex's step, a share of each parameter's log range.
SIMPLEX_STEP = 0.25
#: The held-out seeds per manoeuvre of the comparison the tuning records.
HELD_OUT_SEEDS = 2


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


class EnvironmentChain:
    """The washout through the cueing environment's whole chain, one row of the native vector
    environment per training motion (:class:`~stewart_env.agents.evaluation.cueing.ScheduledEpisodes`
    in ``action_mode="pose"``): the commanded pose tracked by the platform's inner loop and
    dynamics, the head's motion, the vestibular models and the task's metrics.

    Args:
        episodes: the (motion name, seed) pairs, one row each (built-in motions).
        platform: a shipped platform's name or PlatformParams.
        head: the head point in {P}, m.

    Raises:
        UsageError: no episodes, an unknown motion or a bad seed (named ``episodes``).
    """

    def __init__(self, episodes: Sequence[tuple[str, int]], platform=SHIPPED_PLATFORM, head=DEFAULT_HEAD):
        options = {"head": tuple(float(h) for h in head)}
        self.episodes = ScheduledEpisodes(
            episodes, {"action_mode": "pose", "platform": platform, "task_options": options}
        )

    def run(self, params: WashoutParams) -> list[dict[str, float]]:
        """Every motion once, side by side, with the washout of ``params``.

        Args:
            params: the washout's parameters.

        Returns:
            Per motion, the metrics of :meth:`ScheduledEpisodes.run`.
        """
        return self.episodes.run(lambda env: WashoutPolicy(env, params))

    def score(self, params: WashoutParams) -> tuple[float, dict]:
        """The objective (module docstring) and its terms per motion.

        Args:
            params: the washout's parameters.

        Returns:
            (J, the terms by name, a list per motion).
        """
        return objective_of(self.run(params))

    def close(self) -> None:
        """Close the environment."""
        self.episodes.close()


def objective_of(rows: Sequence[dict[str, float]]) -> tuple[float, dict]:
    """The objective (module docstring) of the motions' metrics, and its terms per motion.

    Args:
        rows: per motion, the metrics of :meth:`~stewart_env.agents.evaluation.cueing.ScheduledEpisodes.run`.

    Returns:
        (J, the terms by name, a list per motion).
    """
    errors_f = np.array([r["rms_specific_force_error"] for r in rows])
    errors_w = np.array([r["rms_angular_velocity_error"] for r in rows])
    workspace = np.array([r["workspace_use"] for r in rows])
    stroke = np.array([r["stroke_use"] for r in rows])
    failed = np.array([r["failed"] for r in rows])
    error = float(np.mean(errors_f / FORCE_SCALE_ERROR + errors_w / ANGULAR_SCALE_ERROR))
    over = np.maximum(0.0, workspace - REACH) ** 2 + np.maximum(0.0, stroke - REACH) ** 2
    terms = {
        "rms_specific_force_error": errors_f.tolist(),
        "rms_angular_velocity_error": errors_w.tolist(),
        "specific_force_correlation": [r["specific_force_correlation"] for r in rows],
        "workspace_use": workspace.tolist(),
        "stroke_use": stroke.tolist(),
        "failed": failed.tolist(),
    }
    return error + PENALTY * float(over.sum()) + FAILURE_COST * float(failed.sum()), terms


def washout_objective(
    params: WashoutParams, episodes: Sequence[tuple[str, int]], platform=SHIPPED_PLATFORM, head=DEFAULT_HEAD
) -> float:
    """The tuning's objective (module docstring) of one parameter set, in the environment.

    Args:
        params: the washout's parameters.
        episodes: the training motions, (name, seed) pairs.
        platform: a shipped platform's name or PlatformParams.
        head: the head point in {P}, m.

    Returns:
        J, dimensionless.
    """
    chain = EnvironmentChain(episodes, platform, head)
    try:
        return chain.score(params)[0]
    finally:
        chain.close()


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
    episodes: Sequence[tuple[str, int]],
    platform=SHIPPED_PLATFORM,
    head=DEFAULT_HEAD,
    start: WashoutParams | None = None,
    max_evaluations: int = SHIPPED_EVALUATIONS,
) -> TuningResult:
    """Tune the washout on training motions in the environment (module docstring): bounded
    Nelder-Mead on log scales, deterministic given its inputs.

    Args:
        episodes: the training motions, (name, seed) pairs of built-in motions (training seeds).
        platform: a shipped platform's name or PlatformParams.
        head: the head point in {P}, m.
        start: the starting parameters (default :class:`WashoutParams`'s defaults); their
            untuned fields are kept.
        max_evaluations: the objective's evaluations at most (each runs every motion once).

    Returns:
        The tuned parameters, the objective before and after, and its terms.

    Raises:
        UsageError: no motions, an unknown motion or bad seed, a bad ``max_evaluations``.
    """
    if isinstance(max_evaluations, bool) or not isinstance(max_evaluations, int) or max_evaluations < 1:
        raise UsageError.about("max_evaluations", f"must be a positive integer, got {max_evaluations!r}")
    start = start or WashoutParams()
    chain = EnvironmentChain(episodes, platform, head)
    low = np.log([b[0] for _, _, b in TUNED])
    high = np.log([b[1] for _, _, b in TUNED])
    began = time.perf_counter()
    count = 0

    def objective(x):
        nonlocal count
        count += 1
        return chain.score(params_of(np.exp(np.clip(x, low, high)), start))[0]

    try:
        x0 = np.log(vector_of(start))
        initial = objective(x0)
        result = scipy.optimize.minimize(
            objective,
            x0,
            method="Nelder-Mead",
            bounds=list(zip(low, high)),
            options={
                "maxfev": max_evaluations,
                "xatol": 1e-3,
                "fatol": 1e-4,
                "initial_simplex": initial_simplex(x0, low, high),
            },
        )
        best = params_of(np.exp(np.clip(result.x, low, high)), start)
        value, terms = chain.score(best)
    finally:
        chain.close()
    return TuningResult(best, value, initial, terms, count, time.perf_counter() - began)


def held_out_episodes(seeds: int = HELD_OUT_SEEDS) -> list[tuple[str, int]]:
    """The held-out manoeuvres: each of ``TRAINING_MOTIONS`` at the first ``seeds`` evaluation seeds.

    Args:
        seeds: how many of ``EVALUATION_SEEDS``, 1 to 10.

    Returns:
        (name, seed) pairs, manoeuvre by manoeuvre.
    """
    from stewart_env.tasks.cueing.motions import EVALUATION_SEEDS, TRAINING_MOTIONS

    return [(name, seed) for name in TRAINING_MOTIONS for seed in EVALUATION_SEEDS[:seeds]]


def held_out_comparison(
    params: dict[str, WashoutParams], episodes: Sequence[tuple[str, int]] | None = None, platform=SHIPPED_PLATFORM
) -> dict[str, dict[str, dict[str, float]]]:
    """Washouts side by side in the environment on held-out manoeuvres: each manoeuvre's mean
    metrics over its seeds.

    Args:
        params: label -> the washout's parameters.
        episodes: (name, seed) pairs (default :func:`held_out_episodes`).
        platform: a shipped platform's name or PlatformParams.

    Returns:
        label -> manoeuvre -> metric -> the mean over the manoeuvre's seeds (the cueing metrics,
        ``failed``, ``played``).
    """
    episodes = list(episodes or held_out_episodes())
    chain = EnvironmentChain(episodes, platform)
    out: dict[str, dict[str, dict[str, float]]] = {}
    try:
        for label, values in params.items():
            rows = chain.run(values)
            table: dict[str, dict[str, float]] = {}
            for name in dict.fromkeys(n for n, _ in episodes):
                mine = [r for (n, _), r in zip(episodes, rows) if n == name]
                table[name] = {key: float(np.mean([r[key] for r in mine])) for key in mine[0]}
            table["objective"] = {"J": objective_of(rows)[0]}
            out[label] = table
    finally:
        chain.close()
    return out


def initial_simplex(x0: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Nelder-Mead's first simplex: ``x0`` and, per coordinate, ``x0`` moved by
    :data:`SIMPLEX_STEP` of its log range towards its farther bound, so that a search of a few
    dozen evaluations explores the bounds (SciPy's default moves each coordinate by 5 %).

    Args:
        x0: (n,) the start, log-scaled.
        low: (n,) the lower bounds, log-scaled.
        high: (n,) the upper bounds, log-scaled.

    Returns:
        (n + 1, n) the vertices.
    """
    simplex = np.tile(x0, (len(x0) + 1, 1))
    for i in range(len(x0)):
        step = SIMPLEX_STEP * (high[i] - low[i])
        simplex[i + 1, i] += step if high[i] - x0[i] >= x0[i] - low[i] else -step
    return simplex


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


def training_episodes(seed: int = SHIPPED_SEED) -> list[tuple[str, int]]:
    """The cueing task's training motions, one each, from ``seed`` (a training seed, < 2**30).

    Args:
        seed: the first seed; motion k gets seed + k.

    Returns:
        (name, seed) pairs of ``TRAINING_MOTIONS``.
    """
    from stewart_env.tasks.cueing.motions import TRAINING_MOTIONS

    return [(name, seed + k) for k, name in enumerate(TRAINING_MOTIONS)]


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
    episodes = training_episodes(SHIPPED_SEED)
    result = tune_washout(episodes, SHIPPED_PLATFORM, max_evaluations=SHIPPED_EVALUATIONS)
    print(
        f"J {result.initial_objective:.4g} -> {result.objective:.4g} in {result.evaluations} evaluations, {result.seconds:.0f} s"
    )
    held_out = held_out_comparison({"defaults": WashoutParams(), "tuned": result.params})
    print(held_out_markdown(held_out))
    publish(out, config_text(result, episodes, SHIPPED_PLATFORM, f"python -m {MODULE} {out}", held_out))
    return 0


#: The held-out comparison's metrics in the config and its table: title, format.
HELD_OUT_METRICS = {
    "rms_specific_force_error": ("RMS f err. (m/s²)", ".3f"),
    "rms_angular_velocity_error": ("RMS ω err. (rad/s)", ".3f"),
    "specific_force_correlation": ("corr. f", ".2f"),
    "workspace_use": ("workspace use", ".2f"),
    "failed": ("failed", ".2f"),
}


def held_out_markdown(held_out: dict[str, dict[str, dict[str, float]]]) -> str:
    """A Markdown table of :func:`held_out_comparison`: per manoeuvre, each washout's metrics.

    Args:
        held_out: label -> manoeuvre -> metric -> mean.

    Returns:
        The table.
    """
    head = ["manoeuvre", "washout", *(title for title, _ in HELD_OUT_METRICS.values())]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    labels = list(held_out)
    for manoeuvre in held_out[labels[0]]:
        if manoeuvre == "objective":
            continue
        for label in labels:
            row = held_out[label][manoeuvre]
            cells = [format(row[m], spec) for m, (_, spec) in HELD_OUT_METRICS.items()]
            lines.append(f"| {manoeuvre} | {label} | " + " | ".join(cells) + " |")
    objective = ", ".join(f"{label} {held_out[label]['objective']['J']:.4g}" for label in labels)
    return "\n".join(lines) + f"\n\nThe objective J on the held-out manoeuvres: {objective}."


def config_text(
    result: TuningResult,
    episodes: Sequence[tuple[str, int]],
    platform: str,
    command: str,
    held_out: dict[str, dict[str, dict[str, float]]] | None = None,
) -> str:
    """The config file of a tuning: a comment with the command, ``params`` and ``tuning`` mappings.

    Args:
        result: the tuning.
        episodes: its motions, (name, seed) pairs.
        platform: its platform's name.
        command: the command that ran it.
        held_out: :func:`held_out_comparison`'s means, recorded under ``tuning: held_out`` (rounded).

    Returns:
        The YAML text.
    """
    import yaml

    document = {
        "params": result.params.as_dict(),
        "tuning": {
            "motions": [f"{name} seed {seed}" for name, seed in episodes],
            "platform": platform,
            "objective": round(result.objective, 6),
            "initial_objective": round(result.initial_objective, 6),
            "evaluations": result.evaluations,
        },
    }
    if held_out:
        document["tuning"]["held_out"] = {
            label: {
                manoeuvre: {m: round(float(v), 4) for m, v in row.items() if m in HELD_OUT_METRICS or m == "J"}
                for manoeuvre, row in table.items()
            }
            for label, table in held_out.items()
        }
    head = (
        "# Classical washout tuned on the cueing task's training motions in the environment (see\n"
        "# stewart_env.agents.studies.washout_tuning for the objective). Written by:\n"
        f"#   {command}\n"
    )
    return head + yaml.safe_dump(document, sort_keys=False)


if __name__ == "__main__":
    raise SystemExit(main())
