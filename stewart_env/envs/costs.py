"""The batch's constraint costs and the constraints that end an episode (``terminate_on=``).

:class:`BatchCosts` keeps, per row of a :class:`~stewart_env.envs.core.PlatformBatch`, what the
compiled constraint evaluation (:class:`~stewart_env.tasks.constraints.Constraints`) needs from
the step before: the leg rates after it and the leg forces applied over it.  The batch calls
:meth:`BatchCosts.reset_rows` at an episode's start and :meth:`BatchCosts.after_step` after every
step's physics, in either step kind (fused or of parts), so both give the same costs.

A step's costs are the safety-gymnasium convention: ``info["cost"]``, the sum over the
constraints, and ``info["cost_<name>"]`` of each constraint the platform has, 1.0 when any leg
(or workspace axis) is outside that limit after the step, else 0.0 (``docs/physics.md``, "Limits
and constraint costs").  The legs are measured on the nominal geometry, as the leg sensors are.

Which constraints end an episode: the task ends it at the leg stroke (``"leg_stroke"``) and the
workspace (``"workspace"``), the constraints ``leg_length`` and ``workspace``; one of them left
out of ``terminate_on`` no longer does (:meth:`~stewart_env.tasks.Task.disable_limit_reasons`),
and each other constraint in ``terminate_on`` ends a row that the task did not end, with the
constraint's own name as the termination reason and the task's termination cost.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from stewart_env import _core
from stewart_env.params import PlatformParams
from stewart_env.state import PlatformState
from stewart_env.tasks.constraints import CONSTRAINT_NAMES, ConstraintArrays, Constraints

__all__ = ["TASK_LIMIT_REASONS", "BatchCosts"]

#: The constraints that the task's own limit reasons end an episode at, and those reasons
#: (tasks.LIMIT_REASONS).
TASK_LIMIT_REASONS = {"leg_length": "leg_stroke", "workspace": "workspace"}


class BatchCosts:
    """The constraint costs of a batch of ``n`` rows, and the terminations they add.

    Args:
        platform: the platform's nominal parameters.
        control_dt: the control period, s.
        n: the batch size.
        terminate_on: the constraints that end an episode (checked against the platform's, the
            error naming ``terminate_on`` and listing them).

    Attributes:
        constraints: the platform's :class:`~stewart_env.tasks.constraints.Constraints`.
        out: the latest step's costs, a :class:`~stewart_env.tasks.constraints.ConstraintArrays`
            whose ``costs``, ``violated`` and ``cost`` are those of ``Constraints.evaluate`` bit for
            bit and whose ``code`` is 0 or 1 + the index of the first violated constraint of
            :attr:`added_reasons`; its ``values`` and ``margins`` are not kept, (n, K, 0) arrays
            (``Constraints.evaluate`` gives them).
        previous_rates: (n,6) the leg rates after the latest step, m/s (the next step's previous ones).
        previous_forces: (n,6) the leg forces applied over the latest step, N.
        added_reasons: the constraints of ``terminate_on`` that the task does not end an episode at,
            in the order of CONSTRAINT_NAMES: the termination reasons this adds.
        disabled_reasons: the task's limit reasons that no longer end an episode.

    Raises:
        UsageError: a ``terminate_on`` that names no constraint of the platform.
    """

    def __init__(self, platform: PlatformParams, control_dt: float, n: int, terminate_on: Iterable[str]):
        self.constraints = constraints = Constraints(platform, control_dt, terminate_on=terminate_on)
        k = len(CONSTRAINT_NAMES)
        # one compiled call a step fills these in place (_core.constraint_costs): no values or margins
        self.out = ConstraintArrays(
            np.empty((n, k, 0)),
            np.empty((n, k, 0)),
            np.zeros((n, k)),
            np.zeros((n, k), dtype=bool),
            np.zeros(n),
            np.zeros(n, dtype=np.int64),
        )
        self.previous_rates = np.zeros((n, 6))
        self.previous_forces = np.zeros((n, 6))
        # rows whose next step is their episode's first: no force was applied before it
        self._fresh = np.zeros(n, dtype=bool)
        chosen = constraints.terminate_on
        self.added_reasons = tuple(name for name in chosen if name not in TASK_LIMIT_REASONS)
        self.disabled_reasons = tuple(reason for name, reason in TASK_LIMIT_REASONS.items() if name not in chosen)
        # the compiled code of the added reasons, 1 + their index in CONSTRAINT_NAMES, and from it
        # each one's place in added_reasons
        self._added_mask = sum(1 << CONSTRAINT_NAMES.index(name) for name in self.added_reasons)
        self._added_place = np.zeros(k + 1, dtype=np.int64)
        for place, name in enumerate(self.added_reasons):
            self._added_place[1 + CONSTRAINT_NAMES.index(name)] = place
        self._first_code = 0  # set by the batch: the code of added_reasons[0]
        # a row's info entries on the single environment's step path: each key of a constraint
        # and its column in out.costs, as Python numbers (a row's tolist() read once)
        self._row_columns = tuple(zip(constraints.info_keys[1:], constraints.index.tolist()))

    def set_first_code(self, code: int) -> None:
        """Number the added reasons' termination codes from ``code`` on (the batch's codes after the task's).

        Args:
            code: the code of the first of :attr:`added_reasons`.
        """
        self._first_code = int(code)

    @property
    def info_keys(self) -> tuple[str, ...]:
        """The info keys of a step: ``"cost"``, then ``"cost_<name>"`` per constraint of the platform."""
        return self.constraints.info_keys

    def reset_rows(self, rows: np.ndarray, state: PlatformState) -> None:
        """Start rows ``rows`` at their start state: their previous leg rates those of the state
        (eq. L1), and their first step's force rate 0.

        Args:
            rows: (m,) int, the rows.
            state: their start states, a PlatformState of (m, ...) arrays.
        """
        self._leg_rates_into(rows, state)
        self._fresh[rows] = True

    def set_state(self, rows: np.ndarray, state: PlatformState) -> None:
        """Rows put in a state within their episode (``set_state``): their previous leg rates
        become those of the state, as if a step had ended in it; their previous forces stay.

        Args:
            rows: (m,) int, the rows.
            state: their new states, a PlatformState of (m, ...) arrays.
        """
        self._leg_rates_into(rows, state)

    def _leg_rates_into(self, rows: np.ndarray, state: PlatformState) -> None:
        """Write the leg rates of ``state`` (eq. L1, measured on the nominal geometry) into rows
        ``rows`` of :attr:`previous_rates`, in one compiled call."""
        _core.constraint_leg_rates(
            self.constraints.prm,
            *(np.ascontiguousarray(x, dtype=np.float64) for x in state),
            np.ascontiguousarray(rows, dtype=np.int64),
            self.previous_rates,
        )

    def after_step(
        self,
        state: PlatformState,
        forces: np.ndarray,
        code: np.ndarray,
        terms: dict[str, np.ndarray],
        reward: np.ndarray,
        termination_cost: float,
    ) -> None:
        """Evaluate the constraints after a step into :attr:`out`, keep this step's leg rates and
        forces for the next, and end the rows that an added constraint ends.

        A row that the task did not end (code 0) and that violates a constraint of
        :attr:`added_reasons` ends with the first such (in the order of CONSTRAINT_NAMES): its
        code is that reason's, its ``termination`` reward term -termination_cost and its reward
        the sum of its terms, as a task's failure.

        Args:
            state: the batch's state after the step, (n, ...) arrays.
            forces: (n,6) the leg forces applied over the step, N.
            code: (n,) the step's termination codes, changed in place.
            terms: the step's reward terms by name, (n,) arrays, changed in place.
            reward: (n,) the step's rewards, changed in place.
            termination_cost: the task's cost of a failure.
        """
        c, out = self.constraints, self.out
        # one compiled call: the costs, and this step's leg rates and forces kept for the next in place
        _core.constraint_costs(
            c.bounds,
            self._added_mask,
            c.prm,
            *state,
            self.previous_rates,
            self.previous_forces,
            forces,
            self._fresh,
            c.control_dt,
            out.costs,
            out.violated,
            out.cost,
            out.code,
        )
        if self._added_mask:
            ends = (code == 0) & (out.code > 0)
            if ends.any():
                rows = np.flatnonzero(ends)
                code[rows] = self._first_code + self._added_place[out.code[rows]]
                term = terms["termination"]
                term[rows] = -termination_cost
                reward[rows] = sum(t[rows] for t in terms.values())

    def info(self, row: int | None = None) -> dict[str, float | np.ndarray]:
        """The latest step's cost entries of ``info``: floats of row ``row``, or (n,) arrays of
        the batch (copies) for None.

        Args:
            row: a row, or None for every row.
        """
        if row is None:
            return self.constraints.info(self.out)
        # Constraints.info's entries of the row, read as one list rather than entry by entry
        # (the single environment's step)
        costs = self.out.costs[row].tolist()
        entries = {"cost": self.out.cost.item(row)}
        for key, column in self._row_columns:
            entries[key] = costs[column]
        return entries
