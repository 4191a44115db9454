"""The batched core of the environments: N platforms, a task, and one compiled call per step.

:class:`PlatformBatch` holds the state of N platforms in preallocated arrays and does everything
of a control step for all of them at once: action to leg forces, actuator lag, the task's
external wrench, one call of its plant (:mod:`stewart_env.envs.plant`: the compiled closed-form
rollout, or MuJoCo), the leg sensors; the task, given a read-only
:class:`~stewart_env.tasks.StepView` of the batch, decides termination and reward, and the
observation pipeline (:mod:`stewart_env.envs.observation`) makes every row's observation.  With
the closed-form plant and a task that keeps :class:`~stewart_env.tasks.Task`'s termination and
reward, all of that but the task's Python hooks (a moving reference, an external wrench, its own
observation terms) is one call of the compiled batch (``_core.BatchStep``,
``stewart_env/_core/cpp/env/env_step.hpp``), the same arithmetic as the step of parts.  That step is
made of typed records, each built once by its owner (the batch's state and actuators here, the
plant's, the task's and the observation's by them; docs/layout.md, "The compiled step's
contract").  The step is one object, chosen when the batch is made and by
:meth:`PlatformBatch.set_step_mode`: a :class:`FusedStep` (that call) or a :class:`StepOfParts`
(the plant, the task's hooks, the observation pipeline, one after the other).  The
single environment is a batch of one, the vector environment a batch of N; both give a platform
the same arithmetic, so a vector row reproduces a single environment bit for bit.  Per-row
Python loops run only at episode start and for observation noise (each row draws from its own
Generator).
"""

from __future__ import annotations

from collections.abc import Sequence
from types import MappingProxyType
from typing import Any

import numpy as np

from stewart_env import _core
from stewart_env.dynamics import Dynamics
from stewart_env.envs.action_delay import ActionDelay
from stewart_env.envs.actuation import Actuation
from stewart_env.envs.config import CLOSED_FORM, EnvConfig
from stewart_env.envs.costs import BatchCosts
from stewart_env.envs.observation import ObservationPipeline
from stewart_env.envs.plant import Plant, make_plant
from stewart_env.errors import UsageError
from stewart_env.kinematics import leg_sensors_inplace
from stewart_env.params import PlatformParams
from stewart_env.randomization import draw_unit_rows
from stewart_env.rotations import rpy_to_matrix
from stewart_env.state import PlatformState, Reference
from stewart_env.tasks import LIMIT_REASONS, StepView, make_task, tracking_errors
from stewart_env.tasks.base import Errors, SuccessTracker, error_norm, errors_in, zero_reference

__all__ = ["TERMINATION_REASONS", "FusedStep", "PlatformBatch", "StepOfParts"]

#: The platform's limits as termination reasons, by priority: every task's reasons begin with them.
TERMINATION_REASONS = LIMIT_REASONS
#: The name of termination code 0, a step that does not terminate (``info["termination"]`` is
#: the code, an index into an environment's ``termination_reasons``).
NOT_TERMINATED = ""
#: The code of "non_finite", the first of every task's reasons.
NON_FINITE = 1
#: The terms of the tracking-error reward, in the order of the compiled step's terms (5, n).
REWARD_TERMS = ("position", "orientation", "velocity", "control", "termination")
#: The largest float64: a position error beyond it (a state set absurdly far away) is reported as it,
#: so that no inf leaves the environment.
_LARGEST = float(np.finfo(np.float64).max)
#: The values of :meth:`PlatformBatch.set_step_mode`: the fused compiled step where the plant,
#: the task and the observation allow it, that step or an error, the step of parts.
STEP_MODES = ("auto", "fused", "parts")
#: Up to this many rows, :meth:`PlatformBatch.track_success` goes row by row in Python numbers,
#: which then costs less than numpy's overhead per call on the whole batch.
_ROW_BY_ROW = 4


def _readonly(array: np.ndarray) -> np.ndarray:
    """A view of ``array`` that cannot be written (what a task is given)."""
    view = array.view()
    view.flags.writeable = False
    return view


class PlatformBatch:
    """N platforms under one dynamics model, one plant, one task and one set of options.

    ``n`` rows; ``config`` the validated arguments (:class:`~stewart_env.envs.config.EnvConfig`).
    Public arrays (row i = platform i, frames and units of the environment card): position (n,3),
    rotation (n,3,3), velocity (n,3), angular_velocity (n,3), leg_forces (n,6), external_wrench
    (n,6), time (n,), leg_lengths (n,6), leg_rates (n,6), condition (n,), the reference (a
    :class:`~stewart_env.tasks.Reference` of (n, ...) arrays), error_integral (n,6) [m s; rad s]
    (None unless ``error_integral=True``) and observation (n, D), the latest observation of every
    row (scaled, noisy, delayed as configured).  ``model`` is the episode's closed-form dynamics
    model (one parameter row per platform with domain randomisation), ``plant`` what simulates
    the rows (:class:`~stewart_env.envs.plant.Plant`), ``observations`` the observation pipeline.
    """

    def __init__(self, n: int, config: EnvConfig):
        self.n = n
        self.config = config
        self._step_mode = "auto"
        self._init_physics(config)
        self._init_task(config)
        self._init_constraints(config, n)
        self._init_state(n)
        report = None
        if self.actuation is not None and self.actuation.report is not None:
            report = (*self.actuation.report, self.actuation.reported)
        self.observations = ObservationPipeline(
            config.observation, self.platform, self.task, config.actuator.actuator == "lag", self.control_dt, n, report
        )
        self._observation32 = np.zeros((n, self.observations.dim), dtype=np.float32)
        self._views()

    def _init_physics(self, config: EnvConfig) -> None:
        physics = config.physics
        self.platform: PlatformParams = physics.platform
        self.nominal_model: Dynamics = physics.dynamics
        self._model: Dynamics = self.nominal_model
        # whether :attr:`model` has handed the batch's model out: a reset then copies it first
        self._model_handed_out = False
        self.control_dt, self.physics_dt, self.substeps = physics.control_dt, physics.physics_dt, physics.substeps
        self.randomization = physics.randomization
        if self.randomization is not None:
            # One parameter row per platform, each set at its reset from the nominal packed row.
            self._model = self.nominal_model.with_params([self.platform] * self.n)
        # the action mode's inner loop and the actuator at the physics rate, or None: the forces
        # of the action (through the lag) held over the control step
        self.actuation: Actuation | None = None
        if config.actuator.physics_rate:
            # the MuJoCo plant carries the electric drive itself (its current loops at its steps)
            mujoco_drive = config.actuator.action_mode == "force" and config.actuator.actuator == "electric"
            if physics.plant != CLOSED_FORM and not mujoco_drive:
                raise UsageError.about(
                    "actuator" if config.actuator.action_mode == "force" else "action_mode",
                    f"the {physics.plant!r} plant takes leg forces only: action_mode='force' with an ideal or "
                    f"lag actuator (got action_mode={config.actuator.action_mode!r}, "
                    f"actuator={config.actuator.actuator!r})",
                )
            self.actuation = Actuation(config.actuator, self.platform, self.nominal_model, self.n)
        self.plant: Plant = make_plant(
            physics, self._model, self.n, actuator="ideal" if self.actuation is None else config.actuator.actuator
        )
        self.actuator_tau = config.actuator.actuator_tau
        self._lag = config.actuator.lag(self.control_dt)
        lo, hi = self.platform.limits.leg_force
        self._force_mid = 0.5 * (lo + hi)
        self._force_half = 0.5 * (hi - lo)

    def _init_task(self, config: EnvConfig) -> None:
        self.task = task = make_task(
            config.task.task, self.platform, self.control_dt, config.task.task_options, config.task.version
        )
        self.termination_reasons: tuple[str, ...] = (NOT_TERMINATED, *task.termination_reasons)
        self._reason_array = np.array(self.termination_reasons, dtype=str)
        self._moving_reference = task.moving_reference
        self._has_external_wrench = task.has_external_wrench

    def _init_constraints(self, config: EnvConfig, n: int) -> None:
        """The constraint costs and the constraints that end an episode (``terminate_on``), and
        the action delay (``action_delay``; None for none, today's step)."""
        chosen = config.constraints
        self.costs = BatchCosts(self.platform, self.control_dt, n, chosen.terminate_on)
        # before the step's task record is made (_views), which reads the task's limits
        self.task.disable_limit_reasons(self.costs.disabled_reasons)
        self.costs.set_first_code(len(self.termination_reasons))
        self.termination_reasons += self.costs.added_reasons
        self._reason_array = np.array(self.termination_reasons, dtype=str)
        # code -> whether it ends the episode with a failure (a task's success reasons do not)
        success = set(self.task.success_reasons)
        self._failure_codes = tuple(k > 0 and r not in success for k, r in enumerate(self.termination_reasons))
        self._failure_array = np.array(self._failure_codes)
        self._delay = ActionDelay(n, chosen.action_delay) if chosen.action_delay else None

    def _init_state(self, n: int) -> None:
        self.position = np.zeros((n, 3))
        self.rotation = np.zeros((n, 3, 3))
        self.velocity = np.zeros((n, 3))
        self.angular_velocity = np.zeros((n, 3))
        self.leg_forces = np.zeros((n, 6))
        self.external_wrench = np.zeros((n, 6))
        self.time = np.zeros(n)
        self.steps = np.zeros(n, dtype=np.int64)
        self.leg_lengths = np.zeros((n, 6))
        self.leg_rates = np.zeros((n, 6))
        self.condition = np.zeros(n)
        self.reference = zero_reference(n)
        self.episode = {k: np.zeros((n, *shape)) for k, shape in self.task.episode_fields().items()}
        self._backup = PlatformState(*(np.zeros((n, *shape)) for shape in ((3,), (3, 3), (3,), (3,))))
        # The tracking errors of every row after a step: the vectors and the norms of Errors.
        self._error_vectors, self._error_norms = np.zeros((4, n, 3)), np.zeros((4, n))
        self._action = np.zeros((n, 6))
        self._non_finite = np.zeros(n, dtype=bool)
        # the compiled step's outcome: termination codes, reward terms, reward, the rows it made
        # finite (and, made in __init__, the latest observation as float32), written by every step
        self._code, self._terms, self._reward = np.zeros(n, dtype=np.int64), np.zeros((5, n)), np.zeros(n)
        self._bad = np.zeros(n, dtype=bool)
        self._any_non_finite = False
        self._home_rotation = rpy_to_matrix(self.platform.home_rpy)
        # whether each row's episode meets the task's success criterion so far
        self._success = SuccessTracker(self.task.success_criterion, n)

    def _views(self) -> None:
        """The members that are views of others; made again in a copy (see :meth:`__setstate__`),
        since a copy of a view is no longer a view.  ``view`` is what the task sees of the batch."""
        self._state = PlatformState(self.position, self.rotation, self.velocity, self.angular_velocity)
        self._errors = errors_in(self._error_vectors, self._error_norms)
        errors = self._errors[0]
        self.view = StepView(
            PlatformState(*map(_readonly, self._state)),
            Reference(*map(_readonly, self.reference)),
            type(errors)(*map(_readonly, errors)),
            _readonly(self._action),
            _readonly(self.leg_forces),
            _readonly(self.leg_lengths),
            _readonly(self.leg_rates),
            _readonly(self.condition),
            _readonly(self.external_wrench),
            _readonly(self.time),
            _readonly(self._non_finite),
            MappingProxyType({k: _readonly(v) for k, v in self.episode.items()}),
        )
        # the compiled step's outcome: its reward terms by name, views of its (5, n) array
        self._term_views = dict(zip(REWARD_TERMS, self._terms))
        # the position and orientation errors (2, 3) of each row that track_success_of_row reads
        self._pose_errors = tuple(self._error_vectors[:2, i] for i in range(min(self.n, _ROW_BY_ROW)))
        self._actuation_record = None if self.actuation is None else self.actuation.record(self.physics_dt)
        self._step = self._make_step(self._step_mode)
        # the compiled step checks the action before it changes anything: nothing runs before it
        self.checks_action = self._step.checks_action and not (self._moving_reference or self._has_external_wrench)

    def _make_step(self, mode: str) -> FusedStep | StepOfParts:
        """The step object of ``mode``: the whole control step as one compiled call over the
        step's records (built here, once), or the step of parts, with ``mode`` "parts", or "auto"
        when the step needs Python between its parts (a plant with no compiled part, a task with
        its own termination or reward).  The compiled call makes the observation too unless the
        task observes terms of its own (then :meth:`ObservationPipeline.step` makes it after the
        call).  Raises ValueError for "fused" where the compiled step cannot run."""
        plant = self.plant.step_record(self.physics_dt, self.substeps)
        if mode == "parts":
            return StepOfParts(plant is not None)
        task = self.task.step_record()
        if plant is None or task is None:
            if mode == "fused":
                why = (
                    f"the plant {self.plant.name!r} has no compiled part"
                    if plant is None
                    else f"the task {self.task.name!r} has its own termination or reward"
                )
                raise ValueError(f"step_mode='fused': {why}; use 'auto' or 'parts'")
            return StepOfParts(plant is not None)
        state = _core.StateRecord(
            tuple(self._state),
            tuple(self._backup),
            self.external_wrench,
            self.steps,
            self.time,
            self._non_finite,
            self.leg_lengths,
            self.leg_rates,
            self.condition,
            tuple(getattr(self.reference, k) for k in PlatformState._fields),
            self._error_vectors,
            self._error_norms,
            self.nominal_model.packed,
            self.control_dt,
            self.platform.limits.max_condition,
        )
        actuator = _core.ActuatorRecord(self._force_half, self._force_mid, self._lag, self._action, self.leg_forces)
        outputs = _core.OutputRecord(self._code, self._terms, self._reward, self._bad, self._observation32)
        step = _core.BatchStep(
            state, plant, actuator, task, self.observations.step_record(), outputs, self._actuation_record
        )
        return FusedStep(step)

    @property
    def model(self) -> Dynamics:
        """The episode's closed-form dynamics model: one parameter row per platform with domain
        randomisation, else the nominal model.  A model read here never changes: the batch writes
        a reset's randomised rows into its own model in place until it has handed it out, and
        into a copy after."""
        self._model_handed_out = True
        return self._model

    @property
    def step_mode(self) -> str:
        """The step mode chosen (:meth:`set_step_mode`; "auto" unless chosen otherwise)."""
        return self._step_mode

    @property
    def fused(self) -> bool:
        """Whether a control step is the one compiled call (else the step of parts)."""
        return self._step.fused

    def set_step_mode(self, mode: str) -> None:
        """Choose how every following control step is made, the same numbers either way.

        Args:
            mode: "auto" (the default): the fused compiled step where the plant and the task allow
                it, else the step of parts; "fused": the fused step, or an error; "parts": the
                step of parts (the plant's step, then the task's termination and reward, then the
                observation pipeline), as for a plant or a task the fused step cannot run.

        Raises:
            ValueError: ``mode`` is not one of :data:`STEP_MODES`, or is "fused" where the fused
                step cannot run (the message says why).
        """
        if mode not in STEP_MODES:
            raise ValueError(f"step_mode: expected one of {', '.join(map(repr, STEP_MODES))}, got {mode!r}")
        self._make_step(mode)  # raises before anything changes
        self._step_mode = mode
        self._views()

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        del state["_state"], state["view"], state["_errors"], state["_step"], state["_term_views"]
        del state["_pose_errors"], state["_actuation_record"]
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        if "model" in state:  # pickled before the batch kept its model as _model
            state["_model"], state["_model_handed_out"] = state.pop("model"), True
        self.__dict__.update(state)
        self._views()

    # -- the observation, by the pipeline ----------------------------------------------------------

    @property
    def observation(self) -> np.ndarray:
        """The latest observation of every row (n, D): scaled, noisy and delayed as configured."""
        return self.observations.latest

    @property
    def obs_dim(self) -> int:
        """D, the length of an observation row."""
        return self.observations.dim

    @property
    def observation_layout(self) -> dict[str, slice]:
        """Each observation term's slice of an observation row, by name."""
        return self.observations.layout

    @property
    def error_integral(self) -> np.ndarray | None:
        """The integral of the pose errors (n,6) [m s; rad s] that the observation carries, or None when off."""
        return self.observations.error_integral

    def decode_observation(self, observation: np.ndarray) -> dict[str, np.ndarray]:
        """Observation(s) (..., D) back to physical units, by layout name.

        Args:
            observation: (..., D) observation rows, as the batch returns them.
        """
        return self.observations.decode(observation)

    @property
    def render_fps(self) -> float:
        """Frames per second of a rendered episode: one frame per control step, 1 / control_dt."""
        return 1.0 / self.control_dt

    # -- episode start ----------------------------------------------------------------------------------

    def reset_rows(
        self, rows: np.ndarray, rngs: Sequence[np.random.Generator], batch_infos: bool = False
    ) -> list[dict[str, Any]] | dict[str, Any]:
        """Start a new episode in each of ``rows`` (int array), row rows[j] drawing from rngs[j].

        Draw order within a row: randomisation factors, the task's episode, observation noise;
        rows with generators of their own draw all rows' factors, then all rows' episodes (the
        same numbers, row by row, as drawing one row after the other).  A randomised row's
        parameters are scaled in packed form and written into the rows of the batch's model in
        place (a model handed out by :attr:`model` is copied first, and never changes); its
        PlatformParams are built only when read (:meth:`episode_params`).  With the fused step,
        the rows' state, clock, leg sensors, reference and tracking errors are set in one
        compiled call (``BatchStep.reset``), the same numbers as the step of parts sets them.

        Args:
            rows: (m,) int, the rows to reset.
            rngs: one Generator per row of ``rows``.
            batch_infos: return one dict of the rows' infos instead of one dict per row.

        Returns:
            One info dict per row, which with randomisation holds ``randomization`` (the factors,
            name -> np.float64); with ``batch_infos``, one dict of the rows' infos instead, each
            value an (m,) array in the order of ``rows``.
        """
        rows = np.asarray(rows, dtype=np.int64)
        factors, start, episode, sensors = self._draw_episodes(rows, rngs)
        for k, v in episode.items():
            self.episode[k][rows] = v
        if factors is not None:
            self._set_parameters(rows, factors)
        forces = self._start_forces(rows, start, factors is not None)
        if self.actuation is not None and forces is not None:
            # the drives at equilibrium with the holding forces (the platform at rest)
            self.actuation.reset_rows(rows, forces)
            self.actuation.start_plant_drives(self.plant, rows)
        if self._step.observes:
            # the fused step makes the start observation in the same compiled call: no view of the rows
            state, errors = self._start_observed_rows(rows, start, forces, sensors, episode, rngs)
        else:
            view = self._start_rows(rows, start, forces, sensors, episode)
            state, errors = view.state, view.errors
        self.costs.reset_rows(rows, state)
        if self._delay is not None:
            self._delay.reset_rows(rows)  # the rows held no action before their start: zeros
        self._start_success(rows, errors)
        if not self._step.observes:
            self.observations.reset_rows(rows, view, rngs)
        keys = () if factors is None else tuple(self.randomization.ranges)
        if batch_infos:
            return {} if factors is None else {"randomization": dict(zip(keys, factors.T))}
        if factors is None:
            return [{} for _ in rows]
        return [{"randomization": {k: np.float64(v) for k, v in zip(keys, values)}} for values in factors.tolist()]

    def _draw_episodes(
        self, rows: np.ndarray, rngs: Sequence[np.random.Generator]
    ) -> tuple[np.ndarray | None, PlatformState, dict[str, np.ndarray], tuple | None]:
        """Draw each row's randomisation factors and the task's episode.  Returns the factors
        (m, k) in the order of the spec's keys (None without randomisation), the rows' start
        states (a PlatformState of (m, ...) arrays), their episode arrays by name, and the start
        states' leg sensors if the task measured them (None: not)."""
        rnd = self.randomization
        if len(rngs) == 1 or _shares_a_generator(rngs):
            # one row (the single environment), which numpy's overhead per call makes cheaper row by
            # row, or a generator shared by rows, whose draws must go row after row
            return self._draw_episodes_by_row(rows, rngs)
        draws = self.task.episode_draws
        if rnd is None or not draws:
            factors = None if rnd is None else rnd.sample_rows(rngs)
            return factors, *self.task.initialize_episodes_measured(rngs)
        # a row's factors and its episode's first draws are consecutive numbers of its generator:
        # the k + draws numbers of every row give both, the same numbers as two calls, all rows drawn in
        # one compiled call through their generators' bit generators (draw_unit_rows)
        k = len(rnd.ranges)
        unit = np.empty((len(rngs), k + draws))
        draw_unit_rows(rngs, unit)
        return rnd.factors_of(unit[:, :k]), *self.task.initialize_episodes_measured(rngs, unit[:, k:])

    def _draw_episodes_by_row(
        self, rows: np.ndarray, rngs: Sequence[np.random.Generator]
    ) -> tuple[np.ndarray | None, PlatformState, dict[str, np.ndarray], None]:
        """:meth:`_draw_episodes` one row after the other, every draw of a row before the next
        row's: for rows that share a generator (the leg sensors not measured: None)."""
        rnd, m = self.randomization, len(rows)
        factors = None if rnd is None else np.empty((m, len(rnd.ranges)))
        start = PlatformState(np.empty((m, 3)), np.empty((m, 3, 3)), np.empty((m, 3)), np.empty((m, 3)))
        episode = {k: np.empty((m, *shape)) for k, shape in self.task.episode_fields().items()}
        for j, rng in enumerate(rngs):
            if rnd is not None:
                factors[j] = list(rnd.sample(rng).values())
            state, values = self.task.initialize_episode(rng)
            for dst, src in zip(start, state):
                dst[j] = src
            for k, v in values.items():
                episode[k][j] = v
        return factors, start, episode, None

    def _set_parameters(self, rows: np.ndarray, factors: np.ndarray) -> None:
        """The randomised parameters of ``rows``: the nominal packed row scaled by each row's
        ``factors`` (m, k), written into those rows of the batch's model in place (the plant's
        record of the compiled step points at the model's array, so it sees them), or into a copy
        of a model that :attr:`model` has handed out, which the batch then goes on with."""
        rnd = self.randomization
        packed = np.empty((len(rows), self.nominal_model.packed.shape[1]))
        rnd.scale_packed_rows(self.nominal_model.packed[0], factors, packed)
        params = rnd.rows_params(self.platform, factors)
        if self._model_handed_out:
            self._model = self._model.with_packed_rows(rows, packed, params)
            self._model_handed_out = False
        else:
            # rows the compiled draws have checked (scale_packed_rows): written without a second check
            self._model._set_checked_rows(rows, packed, params)
        self.plant.set_model(self._model, rows)

    def _start_forces(self, rows: np.ndarray, start: PlatformState, randomised: bool) -> np.ndarray | None:
        """The leg forces at the start state of ``rows``: without actuator lag None (none; the
        first action sets them); with it, or with the actuation at the physics rate
        (:attr:`actuation`), the actuators hold the start state: the forces of zero
        acceleration of the rows' own model (their randomised parameters, or the nominal model),
        as far as the actuators reach."""
        if (not self._lag and self.actuation is None) or not len(rows):
            return None
        model = self._model.subset(rows) if randomised else self.nominal_model
        zero = np.zeros((len(rows), 3))
        lo, hi = self.platform.limits.leg_force
        return np.clip(model.inverse(*start, zero, zero), lo, hi)

    def _start_rows(
        self,
        rows: np.ndarray,
        start: PlatformState,
        forces: np.ndarray | None,
        sensors: tuple | None = None,
        drawn: dict[str, np.ndarray] | None = None,
    ) -> StepView:
        """Set the rows' start state, a zero clock, external wrench and applied action, their leg
        forces, the reference at t = 0, and their leg sensors and tracking errors at the start
        state: in one compiled call with the fused step, else by the batch's numpy arrays, the
        same numbers.  ``sensors``: the start states' leg lengths, rates and condition numbers if
        the task measured them (the fused step then reads them instead of measuring again).
        ``drawn``: the rows' episode arrays as drawn, which the view takes instead of copies of
        the batch's rows when they hold the same numbers (float64 of the rows' shape).
        Returns a view of those rows alone for the first observation."""
        m = len(rows)
        start = PlatformState(*(np.ascontiguousarray(x, dtype=np.float64) for x in start))
        episode, reference = self._start_reference(rows, drawn)
        if self._step.fused:
            (lengths, rates, condition), vectors, norms, _ = self._compiled_start(
                rows, start, forces, reference, sensors
            )
        else:
            lengths, rates, condition = np.empty((m, 6)), np.empty((m, 6)), np.empty(m)
            vectors, norms = np.empty((4, m, 3)), np.empty((4, m))
            leg_sensors_inplace(
                self.nominal_model, *start, self.platform.limits.max_condition, lengths, rates, condition
            )
            tracking_errors(start, reference, errors_in(vectors, norms))
            self.position[rows], self.rotation[rows], self.velocity[rows], self.angular_velocity[rows] = start
            self.steps[rows] = 0
            self.time[rows] = 0.0
            self.external_wrench[rows] = 0.0
            self._action[rows] = 0.0
            self.leg_forces[rows] = 0.0 if forces is None else forces
            for dst, src in zip(self.reference, reference):
                dst[rows] = src
            self.leg_lengths[rows], self.leg_rates[rows], self.condition[rows] = lengths, rates, condition
            self._error_vectors[:, rows], self._error_norms[:, rows] = vectors, norms
        zeros = np.zeros((m, 6))
        return StepView(
            start,
            reference,
            errors_in(vectors, norms)[0],
            zeros,
            zeros if forces is None else forces,
            lengths,
            rates,
            condition,
            zeros,
            np.zeros(m),
            np.zeros(m, dtype=bool),
            episode,
        )

    def _start_observed_rows(
        self,
        rows: np.ndarray,
        start: PlatformState,
        forces: np.ndarray | None,
        sensors: tuple | None,
        drawn: dict[str, np.ndarray] | None,
        rngs: Sequence[np.random.Generator],
    ) -> tuple[PlatformState, Errors]:
        """:meth:`_start_rows` with the fused step that makes the observation: the same compiled
        call also makes the rows' start observation (a zero error integral, the noise drawn from
        rngs[j] for row rows[j], every slot of the delay ring), the numbers of the observation
        pipeline's ``reset_rows``.  Returns the rows' start states and tracking errors, which is
        all the rest of the reset reads: no view of the rows is made."""
        start = PlatformState(*(np.ascontiguousarray(x, dtype=np.float64) for x in start))
        _, reference = self._start_reference(rows, drawn)
        observations = self.observations
        noise = observations.draw_start_noise(rngs)
        _, vectors, norms, made_finite = self._compiled_start(rows, start, forces, reference, sensors, True, noise)
        observations.after_compiled_reset(made_finite)
        return start, Errors(*vectors, *norms)

    def _compiled_start(
        self,
        rows: np.ndarray,
        start: PlatformState,
        forces: np.ndarray | None,
        reference: Reference,
        sensors: tuple | None,
        observe: bool = False,
        noise: np.ndarray | None = None,
    ) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], np.ndarray, np.ndarray, object]:
        """The fused step's compiled reset of ``rows`` (:meth:`_start_rows`' numbers), and with
        ``observe`` its start observation (``noise``: the observation pipeline's start noise of the
        rows, None without noise).
        Returns the rows' leg lengths, rates and condition numbers, their tracking-error vectors
        (4, m, 3) and norms (4, m), and what the compiled call returned (the observation's finite
        guard when it observes)."""
        m = len(rows)
        measured = sensors is not None
        if measured:
            lengths, rates, condition = (np.ascontiguousarray(x, dtype=np.float64) for x in sensors)
        else:
            lengths, rates, condition = np.empty((m, 6)), np.empty((m, 6)), np.empty(m)
        vectors, norms = np.empty((4, m, 3)), np.empty((4, m))
        pose_and_twist = tuple(reference[:4])
        observed = (True, noise) if observe else ()
        returned = self._step.compiled.reset(
            rows, tuple(start), forces, pose_and_twist, lengths, rates, condition, vectors, norms, measured, *observed
        )
        self._start_accelerations(rows, reference)
        return (lengths, rates, condition), vectors, norms, returned

    def _start_reference(
        self, rows: np.ndarray, drawn: dict[str, np.ndarray] | None
    ) -> tuple[MappingProxyType, Reference]:
        """The episode arrays of ``rows`` (a read-only mapping) and the task's reference at t = 0
        of those rows (m rows).  ``drawn``: as :meth:`_start_rows`."""
        m = len(rows)
        episode = {}
        for k, v in self.episode.items():
            d = None if drawn is None else drawn.get(k)
            # the drawn array is what the batch's rows now hold, bit for bit, if it is float64 of their
            # shape: no fancy-indexed copy
            same = type(d) is np.ndarray and d.dtype == np.float64 and d.shape == (m, *v.shape[1:])
            episode[k] = d if same else v[rows]
        episode = MappingProxyType(episode)
        reference = zero_reference(m)
        self.task.reference(episode, np.zeros(m), reference)
        return episode, reference

    def _start_accelerations(self, rows: np.ndarray, reference: Reference) -> None:
        """Write the reference's accelerations at t = 0 into ``rows`` of the batch's reference (the
        compiled reset writes the pose and twist; the step never reads the accelerations)."""
        for k in Reference._fields[4:]:
            getattr(self.reference, k)[rows] = getattr(reference, k)

    # -- control step -----------------------------------------------------------------------------------

    def step(
        self,
        action: np.ndarray,
        rngs: Sequence[np.random.Generator],
        skip: np.ndarray | None = None,
        reuse: bool = False,
    ) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray], np.ndarray] | None:
        """One control step of every row.

        Args:
            action: (n,6) float64, finite (see :func:`stewart_env.validation.check_action`); clipped
                to [-1, 1] here.  When :attr:`checks_action`, also an action not yet known to be
                finite, float64 or float32, C-contiguous, (n,6) or for one row (6,): the compiled
                step checks it before it changes anything and, if it is not finite, the step
                returns None having done nothing.
            rngs: one Generator per row (used only for observation noise).
            skip: optional (n,) bool of rows about to be reset by the caller: they are parked at
                home first (their outcome is thrown away) and draw no noise.
            reuse: write the outcome into arrays of the batch that the next step overwrites (for a
                caller that reads them at once).

        Returns:
            The tuple (reward (n,), termination code (n,) int, reward terms by name, each (n,),
            the latest observation (n, D) as float32), or None for a non-finite action as above;
            codes index :attr:`termination_reasons` (0: none).
        """
        if skip is not None:
            if self.checks_action and self._step.observes and skip.all():
                # every row is about to be reset, which sets all a step would: nothing to compute
                return self._nothing_stepped()
            self._park(skip)
        if self._delay is not None:
            # the actions reach the actuators delay steps late; a non-finite one is refused before
            # it enters the delay line, as the step refuses it before it changes anything
            action = np.asarray(action, dtype=np.float64).reshape(self.n, 6)
            if not np.isfinite(action).all():
                return None
            action = self._delay.push(action)
        driven = False
        if self._has_external_wrench:
            # the task's wrench sees the action and the leg forces of this step
            self._drive(action)
            driven = True
            self.task.external_wrench(self.view, self.control_dt, self.external_wrench)
        outcome = self._step.run(self, action, driven, rngs, skip, reuse)
        if outcome is not None:
            reward, code, terms, _ = outcome
            self.costs.after_step(self._state, self.leg_forces, code, terms, reward, self.task.weights.termination_cost)
        return outcome

    def _nothing_stepped(self) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray], np.ndarray]:
        """:meth:`step`'s outcome when every row is skipped: zeros, and the observation as it is."""
        n = self.n
        return (
            np.zeros(n),
            np.zeros(n, dtype=np.int64),
            dict(zip(REWARD_TERMS, np.zeros((5, n)))),
            self.observation.astype(np.float32),
        )

    def _end_non_finite(self, bad: np.ndarray, code: np.ndarray, terms: dict[str, np.ndarray]) -> np.ndarray:
        """End the rows ``bad`` whose observation or reward was not finite: no NaN or inf leaves the
        environment, the row ends as non-finite, its reward terms that are not finite count 0, and
        its termination term is the task's for the new code.  Returns the rows' reward."""
        code[bad] = NON_FINITE
        for term in terms.values():
            term[bad] = np.nan_to_num(term[bad], nan=0.0, posinf=0.0, neginf=0.0)
        terms["termination"] = self.task.termination_reward(code)
        return sum(terms.values())

    def _drive(self, action: np.ndarray) -> None:
        """The actuators: the action clipped to [-1, 1] (kept as the applied action) and mapped
        onto the force range, applied directly or through the first-order lag; at the physics rate,
        only clipped (the compiled step's actuation reads the applied action)."""
        if self.actuation is not None:
            np.clip(action, -1.0, 1.0, out=self._action)
            return
        _core.drive(action, self._force_half, self._force_mid, self._lag, self._action, self.leg_forces)

    # -- success -----------------------------------------------------------------------------------------

    def _start_success(self, rows: np.ndarray, errors) -> None:
        """Start the success tracker of ``rows`` with their errors at reset (:class:`Errors` of
        those rows): row by row in Python numbers for a few rows, as :meth:`track_success`."""
        if len(rows) <= _ROW_BY_ROW:
            for row, position, orientation in zip(rows.tolist(), errors.position.tolist(), errors.orientation.tolist()):
                self._success.start_row(row, error_norm(position), error_norm(orientation))
        else:
            # |e_p| as the compiled errors measured it, error_norm's numbers ((x^2 + y^2) + z^2, no
            # fused multiply-add); the orientation's is the norm of e_o, not the angle they hold
            self._success.start(rows, errors.position_norm, error_norm(errors.orientation))

    def track_success(self, code: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every row's outcome for the success criterion after a step; call once after each step.

        Args:
            code: (n,) the step's termination codes (as :meth:`step` returns them).

        Returns:
            The rows' position error |e_p| (n,) m, orientation error (the angle of e_o, at most
            pi) (n,) rad, both :func:`~stewart_env.tasks.base.error_norm` of the step's errors (the
            numbers the evaluation harness measures; a position error beyond the largest float64,
            that), and whether each episode, ended at this step, meets the task's success
            criterion (n,) bool.
        """
        if self.n <= _ROW_BY_ROW:
            rows = zip(*(self.track_success_of_row(i, code) for i in range(self.n)))
            return tuple(np.array(values) for values in rows)
        # both norms at once, of the (2, n, 3) position and orientation errors
        position, orientation = error_norm(self._error_vectors[:2])
        np.fmin(position, _LARGEST, out=position)
        return position, orientation, self._success.step(self.time, position, orientation, self._failure_array[code])

    def track_success_of_row(self, row: int, code: np.ndarray) -> tuple[float, float, bool]:
        """:meth:`track_success` of row ``row`` alone, as Python numbers: the same numbers at a
        fraction of the cost (the single environment's step, a batch of a few rows).  ``row`` is
        one of the first ``_ROW_BY_ROW`` rows, whose errors the batch keeps views of.

        Args:
            row: the row's index.
            code: (n,) the step's termination codes (as :meth:`step` returns them).

        Returns:
            The row's position error |e_p| (m), orientation error (rad) and whether its episode,
            ended at this step, succeeds.
        """
        p, o = self._pose_errors[row].tolist()
        position, orientation = error_norm(p), error_norm(o)
        if position > _LARGEST:
            position = _LARGEST
        return (
            position,
            orientation,
            self._success.step_row(
                row, self.time.item(row), position, orientation, self._failure_codes[code.item(row)]
            ),
        )

    def _park(self, rows: np.ndarray) -> None:
        """Put rows at home at rest: a safe state to step before the caller resets them."""
        self.position[rows] = self.platform.home_position
        self.rotation[rows] = self._home_rotation
        self.velocity[rows] = 0.0
        self.angular_velocity[rows] = 0.0

    # -- introspection ------------------------------------------------------------------------------------

    def episode_params(self, row: int) -> PlatformParams:
        """The PlatformParams of row ``row``'s episode: with domain randomisation the nominal ones
        scaled by the episode's factors (built on first read), else the nominal ones.

        Args:
            row: the row's index.
        """
        return self.platform if self.randomization is None else self._model.params_of(row)

    def reasons(self, code: np.ndarray) -> np.ndarray:
        """Termination reason names (str array; "" for code 0) of codes.

        Args:
            code: termination codes, an int array indexing :attr:`termination_reasons` (0: none).
        """
        return self._reason_array[code]


def _shares_a_generator(rngs: Sequence[Any]) -> bool:
    """Whether a generator appears more than once in ``rngs``.  A set of the generators themselves
    (numpy's hash and compare them by identity) is built without a Python int per row; generators
    that compare equal while distinct would only be drawn from row after row, the same numbers."""
    try:
        return len(set(rngs)) < len(rngs)
    except TypeError:  # unhashable generators of another kind: by identity
        return len(set(map(id, rngs))) < len(rngs)


# -- the step objects: one chosen when the batch makes its step (PlatformBatch._make_step) -------------


class FusedStep:
    """A control step of the batch as one compiled call, ``_core.BatchStep`` over the step's records.

    Before the call only the task's reference at the step's end (a moving reference) and the
    observation noise are drawn in Python; the call makes the actuators, the plant, the sensors,
    the errors, the termination, the reward and (unless the task observes terms of its own, then
    the observation pipeline after it) the observation, which it also gives as float32.

    Args:
        compiled: the compiled step over the batch's records.
    """

    #: Whether the step is the one compiled call (:attr:`PlatformBatch.fused`).
    fused = True
    #: The compiled call checks the action before it changes anything.
    checks_action = True

    def __init__(self, compiled: _core.BatchStep):
        self.compiled = compiled
        #: Whether the compiled call makes the observation too.
        self.observes: bool = compiled.observes

    def run(self, batch: PlatformBatch, action, driven: bool, rngs, skip, reuse: bool):
        """:meth:`PlatformBatch.step` of ``batch`` after its parked rows and the task's wrench.

        Args:
            batch: the batch whose records the compiled step holds.
            action: as :meth:`PlatformBatch.step` takes it.
            driven: whether the actuators were driven already (for the task's wrench).
            rngs: one Generator per row (observation noise).
            skip: (n,) bool of rows about to be reset, or None.
            reuse: return the batch's own outcome arrays, which the next step overwrites.

        Returns:
            :meth:`PlatformBatch.step`'s outcome, or None for a non-finite action.
        """
        obs = batch.observations
        if batch._moving_reference:
            # the reference at the end of the step, the time the call will set (it depends on no state)
            batch.task.reference(batch.view.episode, (batch.steps + 1) * batch.control_dt, batch.reference)
        observed = self.observes
        noise = obs.draw_noise(rngs, skip) if observed else None
        found = self.compiled.step(action, not driven, noise, skip)
        if found == _core.NOT_FINITE_ACTION:
            return None
        batch._any_non_finite = bool(found & _core.NON_FINITE_STATE)
        if reuse:
            code, terms, reward, observation = batch._code, batch._term_views, batch._reward, batch._observation32
        else:
            code, reward, observation = batch._code.copy(), batch._reward.copy(), batch._observation32.copy()
            terms = dict(zip(REWARD_TERMS, batch._terms.copy()))
        if observed:
            obs.after_compiled_step()
            bad = batch._bad if found & _core.BAD_ROWS else None
        else:
            bad = obs.step(batch.view, reward, rngs, skip)
            observation = batch.observation.astype(np.float32)
        if bad is not None:
            terms = dict(terms)  # _end_non_finite replaces a term: not in the batch's own views
            reward = batch._end_non_finite(bad, code, terms)
        return reward, code, terms, observation


class StepOfParts:
    """A control step of the batch made of its parts: the plant's step, then the task's termination
    and reward, then the observation pipeline; the numbers of :class:`FusedStep`.

    The plant's step is the closed-form plant's compiled control step where the plant has a
    compiled part, else the plant's ``step_inplace`` through the :class:`~stewart_env.envs.plant.Plant`
    interface between the actuators and the sensors, chosen here once.

    Args:
        compiled_plant: whether the plant has a compiled part (its ``step_record`` is not None).
    """

    #: Whether the step is the one compiled call (:attr:`PlatformBatch.fused`).
    fused = False
    #: The action is checked by the caller (:func:`stewart_env.validation.check_action`).
    checks_action = False
    #: The observation pipeline makes the observation after the task's reward.
    observes = False

    def __init__(self, compiled_plant: bool):
        self._physics = self._compiled_physics if compiled_plant else self._plant_physics

    def run(self, batch: PlatformBatch, action, driven: bool, rngs, skip, reuse: bool):
        """:meth:`PlatformBatch.step` of ``batch`` after its parked rows and the task's wrench.

        Args:
            batch: the batch to step.
            action: as :meth:`PlatformBatch.step` takes it, finite.
            driven: whether the actuators were driven already (for the task's wrench).
            rngs: one Generator per row (observation noise).
            skip: (n,) bool of rows about to be reset, or None.
            reuse: unused: the outcome of the step of parts is the step's own.

        Returns:
            :meth:`PlatformBatch.step`'s outcome.
        """
        self._physics(batch, action, driven)
        reward, code, terms = self._outcome(batch, rngs, skip)
        return reward, code, terms, batch.observation.astype(np.float32)

    @staticmethod
    def _compiled_physics(batch: PlatformBatch, action, driven: bool) -> None:
        """The actuators (unless ``driven`` already), the plant's substeps, the clock and the
        non-finite check, and the leg sensors of every row in one compiled call (the closed-form
        plant, the batch's own model).  A row whose state is no longer finite keeps its last
        finite state, so that observation, reward and rendering stay finite."""
        model = batch._model  # the batch's own (reading .model would hand it out)
        batch._any_non_finite = _core.control_step(
            model.packed,
            model.flags,
            batch.nominal_model.packed,
            batch._force_half,
            batch._force_mid,
            batch._lag,
            not driven,
            batch.physics_dt,
            batch.substeps,
            batch.control_dt,
            batch.platform.limits.max_condition,
            action,
            batch._action,
            batch.leg_forces,
            batch.external_wrench,
            *batch._state,
            *batch._backup,
            batch.steps,
            batch.time,
            batch._non_finite,
            batch.leg_lengths,
            batch.leg_rates,
            batch.condition,
            batch._actuation_record,
        )

    @staticmethod
    def _plant_physics(batch: PlatformBatch, action, driven: bool) -> None:
        """:meth:`_compiled_physics` with the plant's ``step_inplace`` (a plant with no compiled
        part, MuJoCo): the actuators, the plant, the clock and the non-finite check, the sensors."""
        if not driven:
            batch._drive(action)
        _core.copy_state(*batch._state, *batch._backup)
        actuation = batch.actuation
        batch.plant.step_inplace(
            batch.position,
            batch.rotation,
            batch.velocity,
            batch.angular_velocity,
            # the plant's electric drives take current set points
            batch.leg_forces if actuation is None else actuation.current_set_points(batch._action),
            batch.external_wrench,
            batch.physics_dt,
            batch.substeps,
        )
        if actuation is not None:
            actuation.take_plant_drives(batch.plant, batch.leg_forces)
        batch._any_non_finite = _core.after_physics(
            *batch._state, *batch._backup, batch.steps, batch.control_dt, batch.time, batch._non_finite
        )
        leg_sensors_inplace(
            batch.nominal_model,
            batch.position,
            batch.rotation,
            batch.velocity,
            batch.angular_velocity,
            batch.platform.limits.max_condition,
            batch.leg_lengths,
            batch.leg_rates,
            batch.condition,
        )

    @staticmethod
    def _outcome(batch: PlatformBatch, rngs, skip) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """Reference, then the task's termination and reward, and the observation after the
        physics of a step."""
        task, view = batch.task, batch.view
        if batch._moving_reference:
            task.reference(view.episode, batch.time, batch.reference)
        tracking_errors(batch._state, batch.reference, batch._errors)

        code = task.termination(view)
        if batch._any_non_finite:
            # The state stopped being finite: whatever the task says, the episode ends so.
            code[batch._non_finite] = NON_FINITE
        terms = task.reward_terms(view)
        terms["termination"] = task.termination_reward(code)
        reward = sum(terms.values())

        bad = batch.observations.step(view, reward, rngs, skip)
        if bad is not None:
            reward = batch._end_non_finite(bad, code, terms)
        return reward, code, terms
