"""The platform's limits as constraints with indicator costs, for constrained RL (the
safety-gymnasium convention: a constraint's cost on a step is 1.0 when any of its legs violates
its limit, else 0.0, and the step's cost is their sum, 0 inside every limit).

:class:`Constraints` is built once from a platform's limits
(:class:`~stewart_env.params.Limits`): which constraints the platform has, in the compiled order
of :data:`CONSTRAINT_NAMES`, and which of them end an episode (``terminate_on=``). Its
:meth:`~Constraints.evaluate` fills preallocated :class:`ConstraintArrays` for a batch with one
compiled call (``_core.evaluate_constraints``, ``stewart_env/_core/cpp/tasks/constraints.hpp``)
and :meth:`~Constraints.info` gives the entries of ``info``: ``"cost"`` and ``"cost_<name>"`` of
each constraint the platform has. ``docs/physics.md``, "Limits and constraint costs", defines
every value, margin and cost (eqs. L1-L7) with its units.

The caller keeps the previous control step's leg rates and leg forces, (N,6) each: after a step it
copies ``values[:, LEG_VELOCITY]`` and the applied forces into them; at an episode's start it sets
the rates to those of the start state (:meth:`Constraints.leg_rates`) and the forces to the first
step's, so that the first step's force rate is 0 (no force was applied before it).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import NamedTuple

import numpy as np

from stewart_env import _core
from stewart_env.dynamics.model import pack_params
from stewart_env.errors import UsageError
from stewart_env.params import PlatformParams
from stewart_env.state import PlatformState
from stewart_env.validation import real

__all__ = [
    "CONSTRAINT_NAMES",
    "DEFAULT_TERMINATE_ON",
    "ConstraintArrays",
    "Constraints",
]

#: Every constraint, in the order of the compiled evaluation's arrays (the leg stroke, leg rate,
#: leg acceleration, leg force, force rate, universal-joint cone, spherical-joint cone and the
#: workspace, the box and the angles about home).
CONSTRAINT_NAMES: tuple[str, ...] = tuple(_core.CONSTRAINT_NAMES)
#: The constraints that end an episode by default, the leg stroke and the workspace (the
#: termination reasons ``leg_stroke`` and ``workspace`` of every task, tasks.LIMIT_REASONS).
DEFAULT_TERMINATE_ON = ("leg_length", "workspace")
# A platform has these whatever its config says (Limits requires them).
_ALWAYS = ("leg_length", "leg_force", "workspace")
# The bound of each optional constraint, a Limits field: inf when the platform has none.
_BOUNDS = {
    "leg_velocity": "max_leg_velocity",
    "leg_acceleration": "max_leg_acceleration",
    "force_rate": "max_force_rate",
    "universal_joint": "max_universal_angle",
    "spherical_joint": "max_spherical_angle",
}
#: Entries of a constraint per row: one per leg (the workspace's x, y, z, roll, pitch, yaw).
N_ENTRIES = 6


class ConstraintArrays(NamedTuple):
    """The evaluation of a batch of N rows, K = len(CONSTRAINT_NAMES) constraints in that order
    (every constraint, also those the platform has not; theirs have margin inf and cost 0).

    Attributes:
        values: (N, K, 6) float64, per leg: length L_i (m), rate Ldot_i (m/s), acceleration
            Lddot_i (m/s^2), force F_i (N), force rate Fdot_i (N/s), universal and spherical cone
            angles (rad); the workspace's x, y, z of P (m) and roll, pitch, yaw about home (rad).
        margins: (N, K, 6) float64, the distance of each value inside its limit in its units
            (negative outside; -inf for a value that is no number; inf with no limit).
        costs: (N, K) float64, 1.0 where the constraint is violated, else 0.0.
        violated: (N, K) bool.
        cost: (N,) float64, the sum of costs over the constraints.
        code: (N,) int64, 0, or 1 + the index in CONSTRAINT_NAMES of the first violated
            constraint that ends an episode.
    """

    values: np.ndarray
    margins: np.ndarray
    costs: np.ndarray
    violated: np.ndarray
    cost: np.ndarray
    code: np.ndarray


class Constraints:
    """A platform's constraints and which end an episode, built once; evaluated per batch.

    Args:
        params: the platform's nominal parameters (its limits and geometry).
        control_dt: the control period, s, > 0: the step of the leg acceleration and force rate.
        terminate_on: the names of the constraints that end an episode, a subset of
            ``names`` (default :data:`DEFAULT_TERMINATE_ON`); () for none.

    Attributes:
        params: the platform's parameters.
        control_dt: the control period, s.
        names: the constraints the platform has, in the order of CONSTRAINT_NAMES (every
            constraint whose bound is not absent).
        index: (len(names),) int64, their indices in CONSTRAINT_NAMES.
        terminate_on: the constraints that end an episode, in the order of CONSTRAINT_NAMES.
        bounds: the compiled bounds (``_core.ConstraintBounds``).
        prm: (1, N_PARAMS) the platform's packed parameters, whose geometry the legs are
            measured with.

    Raises:
        UsageError: a ``terminate_on`` entry that names no constraint of the platform (the message
            lists the choices), or a control_dt that is not a finite number > 0.
    """

    def __init__(
        self, params: PlatformParams, control_dt: float, *, terminate_on: Iterable[str] = DEFAULT_TERMINATE_ON
    ):
        if not isinstance(params, PlatformParams):
            raise UsageError.about("params", f"expected a PlatformParams, got {type(params).__name__}")
        self.params = params
        self.control_dt = real("control_dt", control_dt, 0.0, math.inf, low_open=True)
        lim = params.limits
        self.names = tuple(
            name for name in CONSTRAINT_NAMES if name in _ALWAYS or getattr(lim, _BOUNDS[name]) != math.inf
        )
        self.index = np.array([CONSTRAINT_NAMES.index(name) for name in self.names], dtype=np.int64)
        self.terminate_on = self._checked_terminate_on(terminate_on)
        self._terminate_mask = sum(1 << CONSTRAINT_NAMES.index(name) for name in self.terminate_on)
        self.bounds = _core.ConstraintBounds(
            lim.leg_length[0],
            lim.leg_length[1],
            lim.max_leg_velocity,
            lim.max_leg_acceleration,
            lim.leg_force[0],
            lim.leg_force[1],
            lim.max_force_rate,
            lim.max_universal_angle,
            lim.max_spherical_angle,
            lim.universal_axes,
            lim.spherical_axes,
            lim.position_min,
            lim.position_max,
            params.home_rpy,
            lim.max_angle,
        )
        self.prm = pack_params(params)[None]
        self._info_keys = ("cost", *(f"cost_{name}" for name in self.names))

    def _checked_terminate_on(self, terminate_on: Iterable[str]) -> tuple[str, ...]:
        """``terminate_on`` as a tuple in the order of CONSTRAINT_NAMES, each entry checked."""
        if isinstance(terminate_on, str) or not isinstance(terminate_on, Iterable):
            raise UsageError.about(
                "terminate_on", f"expected a tuple of constraint names, got {type(terminate_on).__name__}"
            )
        chosen = set()
        for name in terminate_on:
            if name not in self.names:
                absent = ""
                if name in CONSTRAINT_NAMES:
                    key = f"{name}.max_angle" if name.endswith("_joint") else name
                    absent = f" ({self.params.name!r} has no {name} limit: limits.{key} is absent)"
                shown = repr(name)[:40] if isinstance(name, str) else type(name).__name__
                raise UsageError.about(
                    "terminate_on", f"unknown constraint {shown}{absent}; choose from {', '.join(self.names)}"
                )
            chosen.add(name)
        return tuple(name for name in self.names if name in chosen)

    def __repr__(self) -> str:
        return f"Constraints(platform={self.params.name!r}, terminate_on={self.terminate_on})"

    def __reduce__(self):
        # The compiled bounds are rebuilt from the parameters, so a copy is checked as the original.
        return _rebuild, (self.params, self.control_dt, self.terminate_on)

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return (self.params, self.control_dt, self.terminate_on) == (other.params, other.control_dt, other.terminate_on)

    def __hash__(self) -> int:
        return hash((self.params, self.control_dt, self.terminate_on))

    def termination_reason(self, code: int) -> str | None:
        """The constraint that ended an episode, from a code of :attr:`ConstraintArrays.code`.

        Args:
            code: 0 (none) or 1 + an index in CONSTRAINT_NAMES.

        Returns:
            The constraint's name, or None for code 0.
        """
        return CONSTRAINT_NAMES[code - 1] if code else None

    def arrays(self, n: int) -> ConstraintArrays:
        """New arrays of :meth:`evaluate` for a batch of ``n`` rows (made once, filled each step).

        Args:
            n: the batch size, >= 1.

        Returns:
            The :class:`ConstraintArrays`, zero-filled.
        """
        k = len(CONSTRAINT_NAMES)
        return ConstraintArrays(
            np.zeros((n, k, N_ENTRIES)),
            np.zeros((n, k, N_ENTRIES)),
            np.zeros((n, k)),
            np.zeros((n, k), dtype=bool),
            np.zeros(n),
            np.zeros(n, dtype=np.int64),
        )

    def evaluate(
        self,
        state: PlatformState,
        previous_rates: np.ndarray,
        previous_forces: np.ndarray,
        forces: np.ndarray,
        out: ConstraintArrays,
        prm: np.ndarray | None = None,
    ) -> ConstraintArrays:
        """Evaluate the constraints of a batch of N rows after a control step, into ``out``.

        Args:
            state: the state after the step, a PlatformState of (N, ...) float64 arrays.
            previous_rates: (N,6) the leg rates after the previous control step, m/s.
            previous_forces: (N,6) the leg forces applied over the previous control step, N.
            forces: (N,6) the leg forces applied over this step, N.
            out: the arrays of :meth:`arrays` (N), written into.
            prm: (1 or N, N_PARAMS) packed parameter rows to measure the legs with (the rows of
                a randomised geometry); default ``self.prm``, the nominal platform's.

        Returns:
            ``out``.

        Raises:
            ValueError: an array of the wrong shape or dtype (the message names it).
        """
        _core.evaluate_constraints(
            self.bounds,
            self._terminate_mask,
            self.prm if prm is None else prm,
            state.position,
            state.rotation,
            state.velocity,
            state.angular_velocity,
            previous_rates,
            previous_forces,
            forces,
            self.control_dt,
            *out,
        )
        return out

    def leg_rates(self, state: PlatformState, prm: np.ndarray | None = None) -> np.ndarray:
        """The leg rates Ldot_i = J_i [v; omega] (eq. L1) of a batch, m/s: the previous rates of
        an episode's first step.

        Args:
            state: a PlatformState of (N, ...) float64 arrays.
            prm: packed parameter rows as in :meth:`evaluate`.

        Returns:
            (N,6) float64.
        """
        n = state.position.shape[0]
        out = self.arrays(n)
        zeros = np.zeros((n, 6))
        self.evaluate(state, zeros, zeros, zeros, out, prm)
        return out.values[:, CONSTRAINT_NAMES.index("leg_velocity")].copy()

    def info(self, out: ConstraintArrays, row: int | None = None) -> dict[str, float | np.ndarray]:
        """The ``info`` entries of an evaluation: ``"cost"`` (the sum) and ``"cost_<name>"`` of
        each constraint the platform has (``names``).

        Args:
            out: the evaluated arrays.
            row: a row's index, for a single environment's floats; None for (N,) arrays (copies)
                of the whole batch.

        Returns:
            The entries by key, floats for a row and (N,) float64 arrays for the batch.
        """
        if row is None:
            entries = {"cost": out.cost.copy()}
            entries.update({key: out.costs[:, k].copy() for key, k in zip(self._info_keys[1:], self.index)})
            return entries
        costs = out.costs[row]
        entries = {"cost": float(out.cost[row])}
        entries.update({key: float(costs[k]) for key, k in zip(self._info_keys[1:], self.index)})
        return entries

    @property
    def info_keys(self) -> tuple[str, ...]:
        """The keys of :meth:`info`, in its order: ``"cost"``, then ``"cost_<name>"`` per
        constraint of ``names``."""
        return self._info_keys


def _rebuild(params: PlatformParams, control_dt: float, terminate_on: tuple[str, ...]) -> Constraints:
    """A :class:`Constraints` from its arguments (its pickled form)."""
    return Constraints(params, control_dt, terminate_on=terminate_on)
