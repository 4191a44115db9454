"""The observation of a batch: its layout, scaling, noise, delay and error integral.

:class:`ObservationPipeline` turns what the batch measures after a step (a
:class:`~stewart_env.tasks.StepView`) into the observation every row returns: the pose block or
the leg sensors, the lagged leg forces, the task's terms and the error integral, laid out by
term name, scaled by the platform's limits, with Gaussian noise drawn from each row's Generator,
and delayed through a ring of the last observations (the environment card, Observation Space).
It also makes the observation safe: no row returns a value that is not finite or beyond the
float32 range.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from stewart_env import _core
from stewart_env.envs.config import ObservationConfig
from stewart_env.params import PlatformParams
from stewart_env.tasks import Scales, StepView
from stewart_env.tasks.base import Task

__all__ = ["ObservationPipeline"]

# The largest float32: an observation entry beyond it would become inf in the returned float32 array.
_FLOAT32_MAX = float(np.finfo(np.float32).max)


def finite_or_marked(raw: np.ndarray, reward: np.ndarray) -> np.ndarray | None:
    """The rows of an observation batch or its reward with an entry that is not finite or beyond
    the float32 range, their observation entries made finite in place (NaN 0, the rest clipped to
    the float32 range), in one compiled pass.

    Args:
        raw: (rows, D) float64, the observations before scaling to float32, changed in place.
        reward: (rows,) float64, their rewards.

    Returns:
        The marked rows, (rows,) bool, or None when every row is fine.
    """
    if _core.within_float32(raw, reward, _FLOAT32_MAX):
        return None
    bad = ~((np.abs(raw) <= _FLOAT32_MAX).all(axis=1) & np.isfinite(reward))
    raw[bad] = np.clip(np.nan_to_num(raw[bad], nan=0.0), -_FLOAT32_MAX, _FLOAT32_MAX)
    return bad


class ObservationPipeline:
    """The observation of ``n`` rows of one platform under one task (see the module docstring).

    Public: ``mode``, ``layout`` (term name -> slice), ``dim`` (D), ``scale`` and ``offset`` (D,)
    (observed = (physical - offset) / scale), ``noise_std`` (D,) or None, ``delay`` (control
    steps), ``error_integral`` (n,6) [m s; rad s] or None when off, its ``error_integral_bound``
    (6,) and ``error_integral_band`` (6,) or None, and :attr:`latest`, the observation every row
    returns now (n, D).
    """

    def __init__(
        self,
        config: ObservationConfig,
        platform: PlatformParams,
        task: Task,
        lagged_forces: bool,
        control_dt: float,
        n: int,
        actuator_report: tuple[np.ndarray, np.ndarray, Any] | None = None,
    ):
        lim = platform.limits
        self._task = task
        self.mode = config.observation_mode
        self.control_dt = control_dt
        scales = Scales.of(platform)
        box_centre = 0.5 * (lim.position_min + lim.position_max)
        stroke_mid = 0.5 * (lim.leg_length[0] + lim.leg_length[1])
        force_mid = 0.5 * (lim.leg_force[0] + lim.leg_force[1])
        ang = np.full(3, scales.angle)
        # (name, scale, offset): observed value = (physical - offset) / scale when normalised.
        terms: list[tuple[str, np.ndarray, np.ndarray]] = []
        if self.mode == "pose":
            terms += [
                ("position", scales.position, box_centre),
                ("orientation", np.ones(6), np.zeros(6)),
                ("velocity", scales.position, np.zeros(3)),
                ("angular_velocity", ang, np.zeros(3)),
            ]
        else:
            terms += [
                ("leg_lengths", np.full(6, scales.leg_length), np.full(6, stroke_mid)),
                ("leg_rates", np.full(6, scales.leg_length), np.zeros(6)),
            ]
        if lagged_forces:
            terms.append(("leg_forces", np.full(6, scales.leg_force), np.full(6, force_mid)))
        # the states a drive reports (scale, offset, and the batch's reported(rows) giving them)
        self._actuator_states = None
        if actuator_report is not None:
            scale, offset, self._actuator_states = actuator_report
            terms.append(("actuator_states", scale, offset))
        terms += [(name, scale, np.zeros(scale.size)) for name, scale in task.observation_terms(scales)]
        self.error_integral_limit = config.error_integral_limit
        # Anti-windup bound (6,) [m s; rad s]: error_integral_limit seconds of an error of one
        # observation scale (h, A); the normalised integral is the integral over this bound.
        self.error_integral_bound = self.error_integral_limit * np.concatenate([scales.position, ang])
        band = config.error_integral_band
        # Conditional integration (6,) [m; rad]: an error component adds to the integral only
        # while within band x its observation scale, so that approaching the target (large
        # errors) does not wind the integral up and it holds mostly the steady-state bias.
        self.error_integral_band = None if band is None else band * np.concatenate([scales.position, ang])
        # The time integral (n,6) [m s; rad s] of (position_error, orientation_error); None when off.
        self.error_integral = np.zeros((n, 6)) if config.error_integral else None
        self._integral_step = np.zeros((n, 6))
        if config.error_integral:
            terms.append(("error_integral", self.error_integral_bound, np.zeros(6)))
        self.normalize = config.normalize_observation
        self.layout: dict[str, slice] = {}
        start = 0
        for name, scale, _ in terms:
            self.layout[name] = slice(start, start + scale.size)
            start += scale.size
        self.dim = start
        if self.normalize:
            self.scale = np.concatenate([t[1] for t in terms])
            self.offset = np.concatenate([t[2] for t in terms])
        else:
            self.scale = np.ones(start)
            self.offset = np.zeros(start)
        self._inv_scale = 1.0 / self.scale
        self._raw = np.zeros((n, start))
        self.noise_std = self._noise(config.observation_noise)
        self.delay = config.observation_delay
        # A ring of the last delay + 1 observations; the slot after the head, the slot written
        # last, is the oldest.  The head is an array that the compiled step advances in place.
        self._history = np.zeros((self.delay + 1, n, start))
        self._head = np.zeros(1, dtype=np.int64)
        # Rows whose start observation was not finite: their first step terminates ("non_finite").
        self._pending = np.zeros(n, dtype=bool)
        self._any_pending = False
        self._raw_views = self._views_of(self._raw)

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        del state["_raw_views"]  # views of _raw: a copy of a view is no longer one
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._raw_views = self._views_of(self._raw)

    def _views_of(self, raw: np.ndarray) -> dict[str, np.ndarray]:
        return {name: raw[:, sl] for name, sl in self.layout.items()}

    def _noise(self, value: Any) -> np.ndarray | None:
        """Per-entry noise std (D,) in observation units, or None for no noise; ``value`` is the
        checked number or dict of :class:`~stewart_env.envs.config.ObservationConfig`."""
        std = np.zeros(self.dim)
        if isinstance(value, dict):
            unknown = [k for k in value if k not in self.layout]
            if unknown:
                raise ValueError(
                    f"observation_noise: unknown observation term(s) {', '.join(map(repr, unknown))}; "
                    f"terms: {', '.join(self.layout)}"
                )
            for name, s in value.items():
                std[self.layout[name]] = s
        else:
            std[:] = value
        return std if std.any() else None

    @property
    def compiled(self) -> bool:
        """Whether the environment's compiled step can make the observation (:meth:`step_record`):
        the task observes only the position and orientation errors, as :class:`Task` does."""
        task = type(self._task)
        own = task.observe is Task.observe and task.observation_terms is Task.observation_terms
        # the drives' states are measured here, after the compiled step
        return own and self._actuator_states is None

    def step_record(self) -> _core.ObservationRecord | None:
        """The observation's part of the environment's compiled step (docs/layout.md, "The
        compiled step's contract"): the layout, the clean rows, the delay ring and its head, the
        scaling, the error integral and the pending rows, all held by the record.  After each step
        the compiled step makes, call :meth:`after_compiled_step`.

        Returns:
            A new ``_core.ObservationRecord``, or None when the task observes terms of its
            own (see :attr:`compiled`; the caller then makes the observation with :meth:`step`).
        """
        if not self.compiled:
            return None
        at = {
            name: self.layout[name].start if name in self.layout else -1
            for name in (
                "leg_lengths",
                "leg_rates",
                "leg_forces",
                "position_error",
                "orientation_error",
                "error_integral",
            )
        }
        return _core.ObservationRecord(
            self.mode == "pose",
            at["leg_lengths"],
            at["leg_rates"],
            at["leg_forces"],
            at["position_error"],
            at["orientation_error"],
            at["error_integral"],
            self._raw,
            self._history,
            self._head,
            self.normalize,
            self.offset,
            self._inv_scale,
            self.error_integral,
            self.error_integral_bound,
            self.error_integral_band,
            self._pending,
            _FLOAT32_MAX,
        )

    def draw_noise(self, rngs: Sequence[np.random.Generator], skip: np.ndarray | None) -> np.ndarray | None:
        """This step's observation noise (n, D), drawn from rngs[i] for every row i not in ``skip``
        (the others' rows are left unset), or None without noise.

        Args:
            rngs: one Generator per row.
            skip: optional (n,) bool, the rows that draw no noise.
        """
        if self.noise_std is None:
            return None
        noise = np.empty(self._raw.shape)
        for i in range(noise.shape[0]):
            if skip is None or not skip[i]:
                noise[i] = rngs[i].normal(size=self.dim) * self.noise_std
        return noise

    def after_compiled_step(self) -> None:
        """Take note of a step whose observation the compiled step made (:meth:`step_record`): it
        advanced the ring's head and reported and cleared the pending rows itself."""
        self._any_pending = False

    @property
    def latest(self) -> np.ndarray:
        """The observation every row returns now (n, D): scaled, noisy and delayed as configured."""
        return self._history[(self._head.item() + 1) % (self.delay + 1)]

    def decode(self, observation: np.ndarray) -> dict[str, np.ndarray]:
        """Observation(s) (..., D) back to physical units, by layout name.

        Args:
            observation: (..., D) scaled observation rows.
        """
        physical = np.asarray(observation, dtype=np.float64) * self.scale + self.offset
        return {name: physical[..., sl] for name, sl in self.layout.items()}

    # -- episode start ----------------------------------------------------------------------------

    def reset_rows(self, rows: np.ndarray, view: StepView, rngs: Sequence[np.random.Generator]) -> None:
        """Start rows ``rows`` (the rows of ``view``, a view of them alone): a zero error
        integral, and the start observation, noise drawn from rngs[j] for row rows[j], in every
        slot of the delay ring (a delayed sensor has seen only the start).  A row whose start
        observation is not finite terminates at its first step.

        Args:
            rows: (m,) int, the rows to start.
            view: the :class:`~stewart_env.tasks.StepView` of those rows alone.
            rngs: one Generator per row of ``rows``.
        """
        m = len(rows)
        integral = None
        if self.error_integral is not None:
            self.error_integral[rows] = 0.0
            integral = self.error_integral[rows]
        raw = np.empty((m, self.dim))
        self._measure(view, integral, raw, rows)
        noise = self.draw_start_noise(rngs)
        if noise is not None:
            raw += noise
        bad = finite_or_marked(raw, np.zeros(m))
        self._pending[rows] = False if bad is None else bad
        self._any_pending = bool(self._pending.any())
        self._history[:, rows] = raw

    def draw_start_noise(self, rngs: Sequence[np.random.Generator]) -> np.ndarray | None:
        """The noise of rows' start observations (m, D), row j drawn from rngs[j], or None without
        noise: what :meth:`reset_rows` adds, and what the environment's compiled reset adds when
        it makes the start observation itself (:meth:`after_compiled_reset`).

        Args:
            rngs: one Generator per row.
        """
        if self.noise_std is None:
            return None
        noise = np.empty((len(rngs), self.dim))
        for j, rng in enumerate(rngs):
            noise[j] = rng.normal(size=self.dim) * self.noise_std
        return noise

    def after_compiled_reset(self, made_finite: int) -> None:
        """Take note of rows whose start observation the compiled reset made (:meth:`step_record`,
        ``BatchStep.reset`` with ``observe``): it wrote their error integral, delay ring and
        pending flags as :meth:`reset_rows` does.

        Args:
            made_finite: the rows whose start observation was not finite (they are pending).
        """
        self._any_pending = bool(made_finite) or bool(self._pending.any())

    # -- control step -----------------------------------------------------------------------------

    def step(
        self, view: StepView, reward: np.ndarray, rngs: Sequence[np.random.Generator], skip: np.ndarray | None
    ) -> np.ndarray | None:
        """The observation after a step, seen through ``view`` (every row): the error integral
        advanced, the observation measured, noise drawn from rngs[i] for every row i not in
        ``skip``, and pushed into the delay ring.

        Args:
            view: the batch's :class:`~stewart_env.tasks.StepView` after the step.
            reward: (n,) the step's rewards.
            rngs: one Generator per row.
            skip: optional (n,) bool, the rows that draw no noise.

        Returns:
            The rows, (n,) bool, whose observation or ``reward`` was not finite (their observation
            made finite) or whose start observation was not, or None when there are none.
        """
        if self.error_integral is not None:
            self._integrate(view.errors)
        raw = self._raw
        self._measure(view, self.error_integral, raw)
        if self.noise_std is not None:
            for i in range(raw.shape[0]):
                if skip is None or not skip[i]:
                    raw[i] += rngs[i].normal(size=self.dim) * self.noise_std
        bad = finite_or_marked(raw, reward)
        if self._any_pending:
            bad = self._pending.copy() if bad is None else bad | self._pending
            self._pending[:] = False
            self._any_pending = False
        head = (self._head.item() + 1) % (self.delay + 1)
        self._head[0] = head
        self._history[head] = raw
        return bad

    def _integrate(self, errors) -> None:
        """Add this step's errors times control_dt to the error integral (rectangle rule on the
        errors after the step; with a band, only the components within it), clipped elementwise
        to +-error_integral_bound (anti-windup)."""
        step = self._integral_step
        step[:, :3] = errors.position
        step[:, 3:] = errors.orientation
        if self.error_integral_band is not None:
            step[np.abs(step) > self.error_integral_band] = 0.0
        step *= self.control_dt
        s = self.error_integral
        s += step
        np.clip(s, -self.error_integral_bound, self.error_integral_bound, out=s)

    def _measure(self, view: StepView, integral, raw: np.ndarray, rows=slice(None)) -> None:
        """Write the clean observation of a batch (any number of rows) seen through ``view`` into
        ``raw``; integral is the batch's error integral (rows, 6), or None when it is not observed;
        rows: the batch's rows that ``view`` shows (for the drives' reported states)."""
        views = self._raw_views if raw is self._raw else self._views_of(raw)
        if self.mode == "pose":
            _core.pose_block(*view.state, raw)
        else:
            views["leg_lengths"][:] = view.leg_lengths
            views["leg_rates"][:] = view.leg_rates
        if "leg_forces" in views:
            views["leg_forces"][:] = view.leg_forces
        self._task.observe(view, views)
        if integral is not None:
            views["error_integral"][:] = integral
        if self._actuator_states is not None:
            views["actuator_states"][:] = self._actuator_states(rows)
        if self.normalize:
            _core.normalize(raw, self.offset, self._inv_scale)
