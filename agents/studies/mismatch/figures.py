"""The study's figures, drawn only when asked: the forest plot of the simplifications' costs and
one heatmap per metric."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from stewart_env.agents.evaluation.evaluation import METRICS, Metric
from stewart_env.agents.studies.mismatch.constants import FAILURE_THRESHOLD, RANKING_METRICS
from stewart_env.agents.studies.mismatch.results import DOUBLE_DIFFERENCE, SHARE_REMOVED, MismatchResult
from stewart_env.files import publishing

__all__ = ["forest_figure", "heatmap", "heatmap_figure", "write_figures"]


def write_figures(result: MismatchResult, out: Path) -> dict[str, Path]:
    """forest.png (where the study has costs) and heatmap_<metric>.png per metric into ``out``;
    returns {name: path}.

    Args:
        result: the study's numbers.
        out: the study's folder.
    """
    files = {}
    if result.differences:
        files["forest"] = out / "forest.png"
        with publishing(files["forest"]) as tmp:
            forest_figure(result).savefig(tmp, dpi=110)
    for metric in METRICS:
        path = out / f"heatmap_{metric.key}.png"
        heatmap(result, metric, path)
        files[f"heatmap {metric.key}"] = path
    return files


def forest_figure(result: MismatchResult, metrics: Sequence[Metric] = METRICS):
    """Every simplification's cost with its 95 % interval, one panel per metric of
    :data:`~.constants.RANKING_METRICS` (titles and units from ``metrics``), one line per (family,
    simplification), and one per double difference where the study has them (labelled "double
    diff."): filled where resolved, hollow where the interval includes zero, grey crosses where a
    row failed.  The x axis is symmetric-log: costs to computed torque (micrometres) and to learned
    agents (millimetres) share it.

    Args:
        result: the study's numbers.
        metrics: the metrics, whose titles and units the panels show.
    """
    from matplotlib.ticker import FixedLocator, NullLocator

    from stewart_env.agents.evaluation.evaluation import new_figure

    meta = {m.key: m for m in metrics}
    # the shares of the classical cost removed are ratios, not costs: in the tables only
    shown = [d for d in result.differences if d.measure != SHARE_REMOVED]
    entries = list(dict.fromkeys((d.family, d.simplification, d.measure) for d in shown))
    columns = 2
    fig = new_figure(
        figsize=(13.0, 1.4 + 0.3 * len(entries) * math.ceil(len(RANKING_METRICS) / columns)), layout="constrained"
    )
    axes = fig.subplots(math.ceil(len(RANKING_METRICS) / columns), columns, sharey=True, squeeze=False).ravel()
    y = {e: len(entries) - 1 - i for i, e in enumerate(entries)}
    for ax, key in zip(axes, RANKING_METRICS):
        factor = meta[key].factor
        mine = [d for d in shown if d.metric == key]
        magnitudes = [
            abs(v) * factor
            for d in mine
            for v in (d.interval.estimate, d.interval.low, d.interval.high)
            if np.isfinite(v) and v != 0
        ]
        ax.axvline(0.0, color="0.3", lw=0.8)
        for d in mine:
            i = y[d.family, d.simplification, d.measure]
            e, lo, hi = (v * factor for v in (d.interval.estimate, d.interval.low, d.interval.high))
            if not np.isfinite(e):
                continue
            colour = "0.6" if d.failed else ("C3" if d.resolved else "C0")
            ax.plot([lo, hi], [i, i], color=colour, lw=2.0, solid_capstyle="butt")
            ax.plot(
                [e],
                [i],
                marker="x" if d.failed else "o",
                ms=7,
                color=colour,
                mfc=colour if d.resolved and not d.failed else "white",
                mew=1.5,
            )
        if magnitudes:
            low, high = (math.floor(math.log10(v)) for v in (min(magnitudes), max(magnitudes)))
            # at most about four labelled decades a side (more overlap); the linear part around zero
            # as wide as one labelled step, so that its three labels do not overlap either
            step = max(1, math.ceil((high - low + 1) / 4))
            ax.set_xscale("symlog", linthresh=10.0**low, linscale=step)
            # zero and every step-th decade down from the largest, none at the linear part's edges
            decades = [10.0**k for k in range(high + 1, low, -step)]
            ax.xaxis.set_major_locator(FixedLocator(sorted([0.0] + decades + [-d for d in decades])))
            ax.xaxis.set_minor_locator(NullLocator())
        ax.set_title(meta[key].title, fontsize=10)
        ax.set_xlabel("difference to the exact-model row")
        ax.grid(alpha=0.3, axis="x")
        for i in range(1, len(entries)):
            if entries[i][0] != entries[i - 1][0]:
                ax.axhline(y[entries[i]] + 0.5, color="0.75", lw=0.8)
    for ax in axes[::columns]:
        ax.set_yticks(
            [y[e] for e in entries],
            [f"{f}: {s}" + (" (double diff.)" if m == DOUBLE_DIFFERENCE else "") for f, s, m in entries],
        )
        ax.set_ylim(-0.7, len(entries) - 0.3)
    fig.suptitle(
        f"The cost of each simplification on the {result.differences[0].plant} plant, 95 % intervals\n"
        "(red filled: resolved; "
        f"blue hollow: includes zero; grey x: a row failed, success < {FAILURE_THRESHOLD:.0%})",
        fontsize=11,
    )
    return fig


def heatmap(result: MismatchResult, metric: Metric, path: Path) -> None:
    """Write :func:`heatmap_figure` of one metric to ``path`` (PNG).

    Args:
        result: the study's numbers.
        metric: the metric.
        path: the PNG file.
    """
    with publishing(path) as tmp:
        heatmap_figure(result, metric).savefig(tmp, dpi=110)


def heatmap_figure(result: MismatchResult, metric: Metric):
    """One metric's point estimates as a rows x test-plants heatmap with the values written in the
    cells (in the metric's display unit and format); a log colour scale when the values span more
    than two decades (model errors do).  Failed cells (success below
    :data:`~.constants.FAILURE_THRESHOLD`) are hatched grey and say so, outside the colour scale,
    so that a controller that loses the platform is never coloured as the best.

    Args:
        result: the study's numbers.
        metric: the metric.
    """
    from matplotlib import colormaps
    from matplotlib.colors import LogNorm, Normalize
    from matplotlib.patches import Rectangle
    from matplotlib.ticker import PercentFormatter

    from stewart_env.agents.evaluation.evaluation import new_figure

    key = metric.key
    values = result.matrix(key) * metric.factor
    failed = result.matrix("success") < FAILURE_THRESHOLD
    finite = values[np.isfinite(values) & ~failed]
    positive = finite[finite > 0]
    if key == "success":  # a share of the episodes: one fixed scale for every study
        norm = Normalize(0.0, 1.0)
    elif positive.size and positive.size == finite.size and positive.max() > 100 * positive.min():
        norm = LogNorm(positive.min(), positive.max())
    else:
        norm = Normalize(*(finite.min(), finite.max()) if finite.size else (0, 1))
    cmap = colormaps["viridis" if key == "success" else "viridis_r"].with_extremes(bad="white")
    n_rows, n_cols = values.shape
    # at least as wide as the two-line title of a study with few plants
    fig = new_figure(figsize=(max(2.0 + 1.6 * n_cols, 7.0), 1.6 + 0.42 * n_rows), layout="constrained")
    ax = fig.subplots()
    image = ax.imshow(np.ma.masked_where(~np.isfinite(values) | failed, values), cmap=cmap, norm=norm, aspect="auto")
    for i, j in zip(*np.nonzero(failed)):
        ax.add_patch(Rectangle((j - 0.5, i - 0.5), 1.0, 1.0, facecolor="0.82", edgecolor="0.55", hatch="///", lw=0.0))
    for i in range(n_rows):
        for j in range(n_cols):
            v = values[i, j]
            text = "-" if not np.isfinite(v) else format(v, metric.spec)
            if failed[i, j]:
                ax.text(
                    j,
                    i,
                    f"failed ({text})",
                    ha="center",
                    va="center",
                    fontsize=8,
                    color="black",
                    bbox=dict(boxstyle="round,pad=0.15", facecolor="0.82", edgecolor="none"),
                )
                continue
            # viridis is dark at its low end, viridis_r at its high end
            dark = np.isfinite(v) and (norm(v) < 0.5 if key == "success" else norm(v) > 0.5)
            ax.text(j, i, text, ha="center", va="center", fontsize=8, color="white" if dark else "black")
    for i in range(1, n_rows):  # a white rule between controller families
        if result.rows[i].family != result.rows[i - 1].family:
            ax.axhline(i - 0.5, color="white", lw=2.5)
    ax.set_xticks(range(n_cols), result.test_models)
    ax.set_yticks(range(n_rows), [r.label for r in result.rows])
    ax.set_xlabel("test plant (dynamics model simulated)")
    ax.set_ylabel("controller [design / training model]")
    note = f"\nhatched: failed (success < {FAILURE_THRESHOLD:.0%}), value in brackets" if failed.any() else ""
    ax.set_title(metric.title + note, fontsize=11 if not note else 10)
    fig.colorbar(image, ax=ax, shrink=0.9, format=PercentFormatter(1.0) if key == "success" else None)
    return fig
