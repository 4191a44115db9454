"""The study's report as text: matrix.csv, differences.csv and matrix.md (the matrix with its
intervals, the simplifications' costs and their ranking, the per-seed values)."""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from stewart_env.agents.evaluation.evaluation import METRICS, Metric
from stewart_env.agents.evaluation.statistics import Interval
from stewart_env.agents.studies.mismatch.constants import (
    CPUS_PER_JOB,
    EVAL_SEED_OFFSET,
    FAILURE_THRESHOLD,
    RANKING_METRICS,
    SIMPLIFICATION_TEXT,
    TRUE_MODEL,
    statistic,
)
from stewart_env.agents.studies.mismatch.costs import PLANNING_BASES, seeds_needed
from stewart_env.agents.studies.mismatch.results import (
    COST,
    DOUBLE_DIFFERENCE,
    SHARE_REMOVED,
    Difference,
    MismatchResult,
)
from stewart_env.agents.studies.mismatch.settings import MismatchSettings
from stewart_env.agents.studies.mismatch.timing import describe, duration, scale_out
from stewart_env.files import publish, publishing

__all__ = ["format_interval", "markdown", "write_tables"]

#: Each metric's record (title, display factor, format) by its key.
METRIC: dict[str, Metric] = {m.key: m for m in METRICS}


def _fmt(value: float, factor: float, spec: str) -> str:
    return "-" if not np.isfinite(value) else format(value * factor, spec)


def format_interval(interval: Interval, factor: float, spec: str) -> str:
    """``estimate [low, high]`` in display units; '-' where undefined.

    Args:
        interval: the point estimate and its interval, in the metric's unit.
        factor: the display unit's factor (value times factor).
        spec: the format spec of a number, e.g. ``".3g"``.
    """
    if not np.isfinite(interval.estimate):
        return "-"
    return (
        f"{_fmt(interval.estimate, factor, spec)} [{_fmt(interval.low, factor, spec)}, "
        f"{_fmt(interval.high, factor, spec)}]"
    )


def _unresolved_text(cost: Difference, differences: Sequence[Difference], factor: float) -> str:
    """An unresolved cost's name, with the seeds per row that would resolve it where it rests on
    several (:func:`~.costs.seeds_needed`); ``factor`` converts SI to the table's units."""
    seeds, basis, effect = seeds_needed(cost, differences)
    if seeds is None:
        return cost.simplification
    size = PLANNING_BASES[basis].format(effect=_fmt(effect, factor, ".3g"))
    return f"{cost.simplification} (about {seeds} seeds a row would resolve it, {size})"


def _titles() -> str:
    return " | ".join(METRIC[k].title for k in RANKING_METRICS)


def _difference_table(differences: Sequence[Difference]) -> list[str]:
    """A markdown table of one family's differences: rows simplifications, columns
    :data:`~.constants.RANKING_METRICS`, entries difference [interval], resolved in bold, failed
    marked."""
    lines = ["| simplification | " + _titles() + " |", "|---|" + "---|" * len(RANKING_METRICS)]
    for name in dict.fromkeys(d.simplification for d in differences):
        cells = []
        for key in RANKING_METRICS:
            d = next(x for x in differences if x.simplification == name and x.metric == key)
            text = format_interval(d.interval, METRIC[key].factor, METRIC[key].spec)
            cells.append(f"*failed* {text}" if d.failed else f"**{text}**" if d.resolved else text)
        label = f"{name}: {SIMPLIFICATION_TEXT[name.lower()]}" if name.lower() in SIMPLIFICATION_TEXT else name
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return lines + [""]


def _cost_lines(result: MismatchResult) -> list[str]:
    """The markdown sections of the simplifications' costs: per family a table (rows:
    simplifications, columns: metrics, entries: difference [interval], resolved in bold, failed
    marked), then per metric the ranking of the resolved costs that are not failed; then the
    double differences, per family a table."""
    costs = [d for d in result.differences if d.measure == COST]
    if not costs:
        return []
    plant = costs[0].plant
    lines = [
        f"## The cost of each simplification on the {plant} plant",
        "",
        f"Each entry: (controller built on the simplified model) - (the same controller built on the "
        f"{TRUE_MODEL} model), both on the {plant} plant, paired by episode, with its 95 % interval "
        "(stratified bootstrap over seeds and episodes). **Bold**: resolved (the interval excludes zero). "
        f"*failed*: one of the two rows succeeds in fewer than {FAILURE_THRESHOLD:.0%} of the episodes, so "
        "the difference measures the failure and is not ranked.",
        "",
    ]
    for family in dict.fromkeys(d.family for d in costs):
        mine = [d for d in costs if d.family == family]
        lines += [f"### {family}", "", *_difference_table(mine)]
        for key in RANKING_METRICS:
            metric = METRIC[key]
            ranked = sorted(
                (d for d in mine if d.metric == key and d.resolved and not d.failed),
                key=lambda d: -abs(d.interval.estimate),
            )
            unresolved = [
                _unresolved_text(d, result.differences, metric.factor)
                for d in mine
                if d.metric == key and not d.resolved and not d.failed
            ]
            failed = [d.simplification for d in mine if d.metric == key and d.failed]
            text = (
                ", ".join(f"{d.simplification} ({_fmt(d.interval.estimate, metric.factor, '+.3g')})" for d in ranked)
                or "none resolved"
            )
            rest = (f"; not resolved: {', '.join(unresolved)}" if unresolved else "") + (
                f"; failed, not ranked: {', '.join(failed)}" if failed else ""
            )
            lines.append(f"- {metric.title}, resolved costs, largest first: {text}{rest}.")
        lines.append("")
    doubles = [d for d in result.differences if d.measure == DOUBLE_DIFFERENCE]
    if doubles:
        lines += [
            f"## Double differences on the {plant} plant",
            "",
            f"Each entry: [controller built on the simplified model, on the {plant} plant - on the simplified "
            f"model's plant] - [the same for the controller built on the {TRUE_MODEL} model], with its 95 % "
            "interval. Each controller is compared with itself, seed by seed and episode by episode, so a "
            "training seed's own bias cancels, and so does the difference between the two plants. On the "
            "exact plant it is the sum of the two costs of building on the wrong model: the simplified "
            "controller on the exact plant, and the exact controller on the simplified plant, each against "
            "the controller built on its plant's model. Zero where the simplification costs nothing either "
            "way; not ranked.",
            "",
        ]
        for family in dict.fromkeys(d.family for d in doubles):
            lines += [f"### {family}", "", *_difference_table([d for d in doubles if d.family == family])]
    return lines + _share_lines(result, plant)


def _share_lines(result: MismatchResult, plant: str) -> list[str]:
    """The markdown section of the shares of the classical model's cost that the rows built on a
    controller platform (with the exact model's structure) remove."""
    shares = [d for d in result.differences if d.measure == SHARE_REMOVED]
    if not shares:
        return []
    lines = [
        f"## Share of the classical model's cost removed on the {plant} plant",
        "",
        f"Each entry: [(controller built on the classical model) - (this one)] / [(controller built on the "
        f"classical model) - (the same controller built on the {TRUE_MODEL} model)], all on the {plant} plant "
        "and paired by episode, in per cent, with its 95 % interval: 100 % where the controller built on "
        "this platform is as good as the one built on the plant's own model, 0 % where it is no better than "
        "the classical one. Meaningful where the classical model's cost above is resolved.",
        "",
    ]
    for family in dict.fromkeys(d.family for d in shares):
        mine = [d for d in shares if d.family == family]
        lines += [f"### {family}", "", "| platform | " + _titles() + " |", "|---|" + "---|" * len(RANKING_METRICS)]
        for name in dict.fromkeys(d.simplification for d in mine):
            cells = []
            for key in RANKING_METRICS:
                d = next(x for x in mine if x.simplification == name and x.metric == key)
                text = format_interval(d.interval, 100.0, ".3g")
                cells.append(f"*failed* {text}" if d.failed else text)
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
        lines.append("")
    return lines


def _per_seed_lines(result: MismatchResult, plant: str) -> list[str]:
    """The markdown table of the learned rows' estimates per training seed on ``plant``."""
    if not result.per_seed:
        return []
    from scipy.stats import norm, t

    seeds = max(len(r.seeds) for r in result.rows if r.label in result.per_seed)
    # the percentile bootstrap of a mean of n values has the spread of sqrt((n - 1) / n) standard
    # errors and normal quantiles; a t interval has t quantiles on n - 1 degrees of freedom
    wider = t.ppf(0.975, seeds - 1) * math.sqrt(seeds / (seeds - 1)) / norm.ppf(0.975) if seeds > 1 else math.nan
    lines = [
        f"## Per training seed on the {plant} plant",
        "",
        "Each learned row's point estimate for each of its training seeds alone (the cells' statistic). "
        "With few seeds the bootstrap intervals above cannot reach beyond the seeds at hand, so they are "
        "narrower than 95 % intervals should be"
        + (
            f" (with {seeds} seeds a t interval on a mean of these values would be {wider:.2g} times as wide)"
            if seeds > 1
            else ""
        )
        + "; these values let any other test be applied.",
        "",
        "| controller | seed | " + _titles() + " |",
        "|---|---|" + "---|" * len(RANKING_METRICS),
    ]
    for r in result.rows:
        if r.label in result.per_seed:
            for i, seed in enumerate(r.seeds):
                lines.append(
                    f"| {r.label} | {seed} | "
                    + " | ".join(
                        _fmt(result.per_seed[r.label][k][i], METRIC[k].factor, METRIC[k].spec) for k in RANKING_METRICS
                    )
                    + " |"
                )
    tested = [d for d in result.differences if d.seed_p is not None]
    if tested:
        lines += [
            "",
            "Welch's two-sided t test on these per-seed values, each row against the row built on the "
            f"{TRUE_MODEL} model (for a double difference: on each agent's change between the two plants), "
            "p per metric ('-': nothing to test):",
            "",
            "| simplification | " + _titles() + " |",
            "|---|" + "---|" * len(RANKING_METRICS),
        ]
        p_values: dict[tuple[str, str, str], dict[str, float]] = {}
        for d in tested:
            p_values.setdefault((d.family, d.simplification, d.measure), {})[d.metric] = d.seed_p
        for (family, name, measure), p in p_values.items():
            label = f"{family}: {name}" + (", double diff." if measure == DOUBLE_DIFFERENCE else "")
            lines.append(
                f"| {label} | " + " | ".join("-" if p.get(k) is None else f"{p[k]:.2g}" for k in RANKING_METRICS) + " |"
            )
    return lines + [""]


def _scale_out_lines(result: MismatchResult) -> list[str]:
    """The jobs' measured times and the study's makespan on 1, 2, 5 and 10 machines of this
    machine's CPU count (:func:`~.timing.scale_out`)."""
    times = result.timing
    if times is None:
        return []
    cpus = os.cpu_count() or 1
    lines = [
        "## Scale-out",
        "",
        f"The study's jobs, each given {CPUS_PER_JOB} CPU: {len(times.training)} training"
        f"{'s' if len(times.training) != 1 else ''}, {describe(times.training)} (each agent's run.json: "
        f"the training loop, without a worker's start or the agent's transfer); "
        f"{len(times.evaluation) + times.untimed_cells} evaluations, "
        + (
            describe(times.evaluation)
            if not times.untimed_cells
            else f"{times.untimed_cells} of them written without their time (by an earlier version), so the "
            "evaluations are not projected"
        )
        + ".",
        "",
        f"What the same jobs take on N machines of {cpus} CPUs (this machine's count), scheduled from "
        "these measured times: the trainings first, then the evaluations, each job to the first free CPU, "
        "longest first:",
        "",
        "| machines | CPUs | training | evaluation | total |",
        "|---|---|---|---|---|",
    ]
    for row in scale_out(times, cpus):
        total = None if row["evaluation"] is None else row["training"] + row["evaluation"]
        lines.append(
            f"| {row['machines']} | {row['cpus']} | {duration(row['training'])} | "
            f"{duration(row['evaluation'])} | {duration(total)} |"
        )
    return lines + [""]


def markdown(result: MismatchResult, settings: MismatchSettings, wall_time: float) -> str:
    """matrix.md: the matrix of every metric with its intervals, the costs, the per-seed values.

    Args:
        result: the study's numbers.
        settings: the study's settings.
        wall_time: the study's wall time, s.
    """
    seeds = settings.seeds
    built_on = settings.env_kwargs.get("actuator", "ideal")
    lines = [
        f"# Model mismatch on the {settings.task} task, platform {settings.platform}",
        "",
        *(
            [
                f"The plants' actuators: {settings.plant_actuator}; the controllers' ({built_on}) are not the plants'.",
                "",
            ]
            if settings.plant_actuator is not None
            else []
        ),
        f"Rows: controllers and the dynamics model they were designed or trained on; columns: the plant "
        f"they run on. Each cell: the point estimate and its 95 % interval, a stratified bootstrap over "
        f"the training seeds ({', '.join(map(str, seeds))}; one for the model-based rows) and the "
        f"{result.episodes} episode{'s' if result.episodes != 1 else ''} (evaluation seeds "
        f"{EVAL_SEED_OFFSET}..{EVAL_SEED_OFFSET + result.episodes - 1}, "
        "the same for every cell). Success: the mean; every other metric: the interquartile mean, over the "
        "episodes where it is defined ('-' where none). An episode succeeds if it runs to its time limit and "
        f"ends within {1e3 * settings.position_tolerance:g} mm and "
        f"{1e3 * settings.orientation_tolerance:g} mrad over its final window; a "
        f"cell succeeding in fewer than {FAILURE_THRESHOLD:.0%} of its episodes is marked failed.",
        "",
    ]
    notes = [f"- {r.label}: {r.info}" for r in result.rows if r.info]
    if notes:
        lines += ["Controllers:", "", *dict.fromkeys(notes), ""]
    for metric in METRICS:
        lines += [
            f"## {metric.title}",
            "",
            "| controller | " + " | ".join(result.test_models) + " |",
            "|---|" + "---|" * len(result.test_models),
        ]
        for r in result.rows:
            cells = [
                format_interval(result.summary[r.label][m][metric.key], metric.factor, metric.spec)
                for m in result.test_models
            ]
            lines.append(f"| {r.label} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += _cost_lines(result) + _per_seed_lines(result, str(settings.cost_plant)) + _scale_out_lines(result)
    lines.append(f"Backend: {settings.backend}. Wall time of this run: {wall_time:.0f} s.")
    return "\n".join(lines) + "\n"


def write_tables(
    result: MismatchResult, out: Path, settings: MismatchSettings, wall_time: float = 0.0
) -> dict[str, Path]:
    """matrix.csv, differences.csv and matrix.md into ``out`` (no figure); returns {name: path}.

    Args:
        result: the study's numbers.
        out: the study's folder.
        settings: the study's settings.
        wall_time: the study's wall time, s.
    """
    files = {"csv": out / "matrix.csv", "markdown": out / "matrix.md", "differences": out / "differences.csv"}
    with publishing(files["csv"]) as tmp, tmp.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(
            ["controller", "family", "design_model", "test_model", "seeds", "episodes"]
            + [f"{m.key}{suffix}" for m in METRICS for suffix in ("", "_ci_low", "_ci_high", "_n")]
        )
        for r in result.rows:
            for m in result.test_models:
                s = result.summary[r.label][m]
                first = s[METRICS[0].key]
                values = []
                for metric in METRICS:
                    interval = s[metric.key]
                    n = "" if interval.n is None else interval.n
                    values += [f"{interval.estimate:.9g}", f"{interval.low:.9g}", f"{interval.high:.9g}", n]
                writer.writerow([r.label, r.family, r.model, m, first.seeds, first.episodes] + values)
    with publishing(files["differences"]) as tmp, tmp.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(
            [
                "family",
                "simplification",
                "measure",
                "controller",
                "reference",
                "plant",
                "metric",
                "statistic",
                "difference",
                "ci_low",
                "ci_high",
                "resolved",
                "failed",
                "seeds_to_resolve",
                "seeds_sized_for",
                "seed_welch_p",
            ]
        )
        for d in result.differences:
            seeds, basis, _ = seeds_needed(d, result.differences) if d.measure == COST else (None, "", 0.0)
            writer.writerow(
                [
                    d.family,
                    d.simplification,
                    d.measure,
                    d.label,
                    d.reference,
                    d.plant,
                    d.metric,
                    statistic(d.metric),
                    f"{d.interval.estimate:.9g}",
                    f"{d.interval.low:.9g}",
                    f"{d.interval.high:.9g}",
                    int(d.resolved),
                    int(d.failed),
                    *(("", "") if seeds is None else (seeds, basis)),
                    "" if d.seed_p is None else f"{d.seed_p:.3g}",
                ]
            )
    publish(files["markdown"], markdown(result, settings, wall_time))
    return files
