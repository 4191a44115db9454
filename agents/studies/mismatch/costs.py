"""The cost of each simplification to each controller family, with its interval, the seeds'
own test of it, and the seeds a row would need to resolve a cost not yet resolved."""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence

import numpy as np

from stewart_env.agents.evaluation.statistics import (
    double_difference,
    paired_difference,
    point_estimate,
    seeds_to_resolve,
    share_removed,
)
from stewart_env.agents.studies.mismatch.constants import (
    FAILURE_THRESHOLD,
    RANKING_METRICS,
    SIMPLIFICATIONS,
    TRUE_MODEL,
    statistic,
)
from stewart_env.agents.studies.mismatch.results import (
    DOUBLE_DIFFERENCE,
    SHARE_REMOVED,
    Difference,
    MismatchResult,
    Row,
)

__all__ = ["PLANNING_BASES", "per_seed_estimates", "seeds_needed", "simplification_costs"]


def _compared_rows(result: MismatchResult, family: str) -> list[tuple[str, Row]]:
    """(name, row) of the ``family``'s rows built on a simplified model, or with domain
    randomisation, or on a controller platform: the whole classical model, C1..C4, DR, then each
    row built on a controller platform (named by its platform, and its model where that is not the
    exact one)."""
    by_model = {r.model: r for r in result.rows if r.family == family and not r.randomized and r.platform is None}
    out = [("classical model", by_model["classical"])] if "classical" in by_model else []
    out += [(c.upper(), by_model[f"improved+{c}"]) for c in SIMPLIFICATIONS if f"improved+{c}" in by_model]
    out += [("domain randomisation", r) for r in result.rows if r.family == family and r.randomized]
    out += [
        (f"platform {r.platform_name}" if r.model == TRUE_MODEL else f"{r.model} model, platform {r.platform_name}", r)
        for r in result.rows
        if r.family == family and r.platform is not None
    ]
    return out


def simplification_costs(
    result: MismatchResult, values: Callable[[Row, str, str], np.ndarray], plant: str = TRUE_MODEL
) -> list[Difference]:
    """Per controller family with a row built on the exact model: for each simplification and each
    of :data:`~.constants.RANKING_METRICS`, the paired difference on ``plant`` of the row built on
    the simplified model minus the exact-model row, with its interval; and where the simplified
    model is a test plant too, the double difference (see :class:`~.results.Difference`); and for
    each row built on the exact model's structure on a controller platform, the share of the
    classical row's cost it removes (:data:`~.results.SHARE_REMOVED`).
    ``values(row, plant, metric)`` gives a cell's values (seeds, episodes), e.g.
    :func:`~.cells.cell_values` of a study's directory.

    Args:
        result: the study's numbers.
        values: ``values(row, plant, metric)``: a cell's values (seeds, episodes).
        plant: the test plant the costs are measured on.
    """
    if plant not in result.test_models:
        return []
    differences = []
    for family in dict.fromkeys(r.family for r in result.rows):
        exact = next(
            (
                r
                for r in result.rows
                if r.family == family and r.model == TRUE_MODEL and not r.randomized and r.platform is None
            ),
            None,
        )
        if exact is None:
            continue
        for name, row in _compared_rows(result, family):
            home = (
                row.model
                if row.model in result.test_models
                and row.model != plant
                and not row.randomized
                and row.platform is None
                else None
            )
            for metric in RANKING_METRICS:
                mine, theirs = values(row, plant, metric), values(exact, plant, metric)
                differences.append(
                    Difference(
                        family,
                        name,
                        row.label,
                        exact.label,
                        metric,
                        paired_difference(mine, theirs, statistic(metric)),
                        _failed(result, (row, exact), (plant,)),
                        plant,
                        seed_p=_seed_test(mine, theirs, statistic(metric)),
                    )
                )
                if home is not None:
                    mine_home, theirs_home = values(row, home, metric), values(exact, home, metric)
                    differences.append(
                        Difference(
                            family,
                            name,
                            row.label,
                            exact.label,
                            metric,
                            double_difference(mine, mine_home, theirs, theirs_home, statistic(metric)),
                            _failed(result, (row, exact), (plant, home)),
                            plant,
                            DOUBLE_DIFFERENCE,
                            _seed_test(mine - mine_home, theirs - theirs_home, statistic(metric)),
                        )
                    )
        classical = next((r for name, r in _compared_rows(result, family) if name == "classical model"), None)
        for row in result.rows:
            if classical is None or row.family != family or row.platform is None or row.model != TRUE_MODEL:
                continue
            for metric in RANKING_METRICS:
                differences.append(
                    Difference(
                        family,
                        f"platform {row.platform_name}",
                        row.label,
                        classical.label,
                        metric,
                        share_removed(
                            values(classical, plant, metric),
                            values(row, plant, metric),
                            values(exact, plant, metric),
                            statistic(metric),
                        ),
                        _failed(result, (row, classical, exact), (plant,)),
                        plant,
                        SHARE_REMOVED,
                    )
                )
    return differences


def per_seed_estimates(values: np.ndarray, statistic_name: str) -> list[float]:
    """A cell's point estimate for each training seed alone: ``values`` (seeds, episodes).

    Args:
        values: the cell's values (seeds, episodes).
        statistic_name: the metric's statistic, ``"mean"`` or ``"iqm"``.
    """
    return [point_estimate(v, statistic_name) for v in values]


def _seed_test(values: np.ndarray, reference: np.ndarray, statistic_name: str) -> float | None:
    """Two-sided p of Welch's t test between two cells' per-seed point estimates: a check of a
    difference that does not lean on the bootstrap, which with few seeds is too narrow; None with
    fewer than two seeds a cell or no spread to test."""
    from scipy.stats import ttest_ind

    if min(len(values), len(reference)) < 2:
        return None
    mine, theirs = per_seed_estimates(values, statistic_name), per_seed_estimates(reference, statistic_name)
    # seeds that agree to rounding (a deterministic part of the controller): scipy warns, the p stands
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        p = float(ttest_ind(mine, theirs, equal_var=False).pvalue)
    return p if np.isfinite(p) else None


def _failed(result: MismatchResult, rows: Sequence[Row], plants: Sequence[str]) -> bool:
    """Whether any of ``rows`` succeeds in fewer than :data:`~.constants.FAILURE_THRESHOLD` of its
    episodes on any of ``plants``."""
    return min(result.summary[r.label][p]["success"].estimate for r in rows for p in plants) < FAILURE_THRESHOLD


#: What a planning figure (:func:`seeds_needed`) is sized for, as the text that follows it.
PLANNING_BASES = {
    "estimate": "at its own estimate",
    "double difference": "at half the double difference, {effect}",
    "double difference bound": "at the most it can be, half the double difference's larger bound, "
    "{effect}; so at least that many",
}


def seeds_needed(cost: Difference, differences: Sequence[Difference]) -> tuple[int | None, str, float]:
    """About how many training seeds per row would resolve an unresolved cost
    (:func:`~stewart_env.agents.evaluation.statistics.seeds_to_resolve`), what the figure is sized for (a key
    of :data:`PLANNING_BASES`) and the size.  Where the study has the double difference of the same
    family, simplification and metric, it sizes the figure: it is the sum of the costs of the two
    directions, measured without the seeds' spread, so half of it is a far better guess of the
    cost than the cost's own estimate, which at few seeds is mostly their spread; where it is not
    resolved, half its larger bound bounds the cost, and the figure is a lower bound.

    Args:
        cost: the unresolved cost.
        differences: the study's differences, among which its double difference is looked for.
    """
    double = next(
        (
            d
            for d in differences
            if d.measure == DOUBLE_DIFFERENCE
            and (d.family, d.simplification, d.metric) == (cost.family, cost.simplification, cost.metric)
        ),
        None,
    )
    if double is None or not np.isfinite(double.interval.estimate):
        effect, basis = cost.interval.estimate, "estimate"
    elif double.resolved:
        effect, basis = 0.5 * double.interval.estimate, "double difference"
    else:
        effect, basis = 0.5 * max(abs(double.interval.low), abs(double.interval.high)), "double difference bound"
    return seeds_to_resolve(cost.interval, effect), basis, abs(effect)
