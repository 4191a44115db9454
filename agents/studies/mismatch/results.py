"""The study's records: its controllers (:class:`Row`), the simplifications' costs
(:class:`Difference`) and its numbers (:class:`MismatchResult`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from stewart_env.agents.evaluation.statistics import Interval
from stewart_env.agents.studies.mismatch.constants import TRUE_MODEL
from stewart_env.agents.studies.mismatch.timing import JobTimes

__all__ = ["COST", "DOUBLE_DIFFERENCE", "SHARE_REMOVED", "Difference", "MismatchResult", "Row"]


@dataclass
class Row:
    """One controller of the study: its label, family ("PD", "CT", "LQR", "MPC" or the RL
    algorithm), the model it was designed or trained on, and for a learned row its training seeds
    and agent folders (seed -> path).  ``kind`` is "pd", "ct", "lqr", "mpc" or "agent"; ``info``
    a note for the tables.
    ``platform`` is the platform it was designed or trained on when that is not the study's (a
    controller platform, e.g. an identified one: a name or a config's absolute path), and
    ``platform_name`` its name in the row's label; None for the study's platform."""

    label: str
    family: str
    model: str
    kind: str = "ct"
    seeds: tuple[int, ...] = ()
    agents: dict[int, Path] = field(default_factory=dict)
    info: str = ""
    randomized: bool = False
    platform: str | None = None
    platform_name: str | None = None


#: The two measures of a simplification's cost: the cost itself, between the rows built on the
#: simplified and on the exact model, both on the cost plant; and the double difference, each row's
#: change from the simplified model's plant to the cost plant, the one row's minus the other's.
COST, DOUBLE_DIFFERENCE = "cost", "double difference"
#: The third measure, of a row built on the exact model's structure on a controller platform (e.g.
#: an identified one): the share of the classical model's cost that it removes,
#: [(classical row) - (this row)] / [(classical row) - (exact row)], all on the cost plant.
SHARE_REMOVED = "share of classical cost removed"


@dataclass
class Difference:
    """The cost of one simplification to one controller family on one metric.  ``measure``
    :data:`COST`: ``interval`` of (row built on the simplified model) - (row built on the exact
    model), both on ``plant``.  :data:`DOUBLE_DIFFERENCE`: of [that row on ``plant`` - on the
    simplified model's plant] - [the exact row on ``plant`` - on the simplified model's plant]; on
    the exact plant, the sum of the two ways of building on the wrong model (the simplified row on
    the exact plant, the exact row on the simplified plant), each compared with the row built on
    that plant's model.  ``failed`` if a row succeeds in fewer than
    :data:`~.constants.FAILURE_THRESHOLD` of the episodes on a plant the measure uses."""

    family: str
    simplification: str
    label: str
    reference: str
    metric: str
    interval: Interval
    failed: bool
    plant: str = TRUE_MODEL
    measure: str = COST
    #: two-sided p of Welch's t test between the two rows' per-seed values (for a double
    #: difference, their per-seed changes between the plants); None with fewer than two seeds
    seed_p: float | None = None

    @property
    def resolved(self) -> bool:
        """Whether the difference's confidence interval excludes zero."""
        return self.interval.resolved


@dataclass
class MismatchResult:
    """The study's numbers: ``summary[row label][test model][metric]`` an :class:`Interval`;
    ``rows`` in table order; ``test_models`` the columns; ``differences`` the simplifications'
    costs; ``per_seed[row label][metric]`` a learned row's point estimate per training seed on the
    plant the costs are measured on; ``timing`` its jobs' measured wall times; ``files`` what was
    written."""

    rows: list[Row]
    test_models: list[str]
    summary: dict[str, dict[str, dict[str, Interval]]]
    episodes: int
    differences: list[Difference] = field(default_factory=list)
    per_seed: dict[str, dict[str, list[float]]] = field(default_factory=dict)
    timing: JobTimes | None = None
    files: dict[str, Path] = field(default_factory=dict)

    def matrix(self, metric: str) -> np.ndarray:
        """(rows, test models) array of one metric's point estimates.

        Args:
            metric: the metric's name.
        """
        return np.array([[self.summary[r.label][m][metric].estimate for m in self.test_models] for r in self.rows])
