"""Scoring controllers: the evaluation harness and the statistics of its results.

The package, one module per job: :mod:`~stewart_env.agents.evaluation.evaluation` (seeded
episodes of a policy, their metrics, defined in its docstring, the reports and figures) and
:mod:`~stewart_env.agents.evaluation.statistics` (the interquartile mean, the stratified bootstrap
and the paired differences of results grouped by training seed).
"""

from stewart_env.agents.evaluation.evaluation import (
    METRICS,
    EvaluationResult,
    Metric,
    compact_table,
    compare,
    episode_metrics,
    evaluate,
    markdown_table,
    write_report,
)
from stewart_env.agents.evaluation.statistics import (
    Interval,
    double_difference,
    iqm,
    paired_difference,
    point_estimate,
    seeds_to_resolve,
    share_removed,
    stratified_bootstrap,
)

__all__ = [
    "METRICS",
    "EvaluationResult",
    "Interval",
    "Metric",
    "compact_table",
    "compare",
    "double_difference",
    "episode_metrics",
    "evaluate",
    "iqm",
    "markdown_table",
    "paired_difference",
    "point_estimate",
    "seeds_to_resolve",
    "share_removed",
    "stratified_bootstrap",
    "write_report",
]
