"""The batched core of the environments: N platforms, a task, and one compiled rollout per step.

:class:`PlatformBatch` holds the state of N platforms in preallocated arrays and does everything
of a control step for all of them at once: action to leg forces, actuator lag, the task's
external wrench, one call of :func:`~stewart_env.integrate.rollout_inplace` (or of the MuJoCo
plant with ``model="mujoco"``), leg sensors and the observation (noise and delay included); the
task, given a read-only :class:`~stewart_env.tasks.StepView` of the batch, decides termination
and reward.  The single environment is a batch of one, the vector environment a batch of N; both
give a platform the same arithmetic, so a vector row reproduces a single environment bit for bit.
Per-row Python loops run only at episode start and for observation noise (each row draws from its
own Generator).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from types import MappingProxyType
from typing import Any

import numpy as np
from gymnasium.error import ResetNeeded
from numba import njit

from stewart_env.dynamics import Dynamics
from stewart_env.envs.config import MUJOCO, EnvConfig, defaults
from stewart_env.integrate import rollout_inplace
from stewart_env.kinematics import leg_sensors_inplace
from stewart_env.params import PlatformParams
from stewart_env.rotations import rpy_to_matrix
from stewart_env.state import PlatformState, Reference
from stewart_env.tasks import LIMIT_REASONS, Scales, StepView, make_task, tracking_errors
from stewart_env.tasks.base import errors_in, zero_reference
from stewart_env.validation import check_action

__all__ = ["DEFAULTS", "TERMINATION_REASONS", "BatchAttributes", "PlatformBatch", "check_action"]

#: Every keyword argument of the environments and its default (the arguments table of the card).
DEFAULTS: dict[str, Any] = defaults()
#: The platform's limits as termination reasons, by priority: every task's reasons begin with them.
TERMINATION_REASONS = LIMIT_REASONS
#: The name of termination code 0, a step that does not terminate (``info["termination"]`` is
#: the code, an index into an environment's ``termination_reasons``).
NOT_TERMINATED = ""
#: The code of "non_finite", the first of every task's reasons.
NON_FINITE = 1
# The largest float32: an observation entry beyond it would become inf in the returned float32 array.
_FLOAT32_MAX = float(np.finfo(np.float32).max)


@njit(cache=True)
def _within_float32(raw, reward, largest):
    """Whether every entry of raw (rows, D) is within +-largest (so finite) and every reward finite."""
    for v in raw.flat:
        if not abs(v) <= largest:
            return False
    for r in reward:
        if not abs(r) < np.inf:
            return False
    return True


# The per-step arithmetic of the batch in a few compiled passes (each row as numpy would compute it,
# operation for operation), so that a step's Python overhead stays small next to the physics.

@njit(cache=True)
def _drive(action, half, mid, lag, clipped, forces):
    """Clip the action to [-1, 1] into ``clipped`` and map it onto the force range: the command
    mid + a half, applied directly (lag 0) or through the exact first-order lag."""
    for b in range(action.shape[0]):
        for i in range(6):
            a = min(max(action[b, i], -1.0), 1.0)
            clipped[b, i] = a
            command = a * half + mid
            if lag:
                forces[b, i] += lag * (command - forces[b, i])
            else:
                forces[b, i] = command


@njit(cache=True)
def _copy_state(t, R, v, w, t_to, R_to, v_to, w_to):
    """Copy a batch state into another's arrays."""
    t_to[:] = t
    R_to[:] = R
    v_to[:] = v
    w_to[:] = w


@njit(cache=True)
def _after_physics(t, R, v, w, t0, R0, v0, w0, steps, dt, time, non_finite):
    """Advance every row's clock one control step (time = steps dt) and find the rows whose
    state is no longer finite, putting them back to the state they started the step from (t0,
    R0, v0, w0).  Returns whether any row was."""
    found = False
    for b in range(t.shape[0]):
        steps[b] += 1
        time[b] = steps[b] * dt
        ok = True
        for j in range(3):
            ok &= np.isfinite(t[b, j]) and np.isfinite(v[b, j]) and np.isfinite(w[b, j])
            for k in range(3):
                ok &= np.isfinite(R[b, j, k])
        non_finite[b] = not ok
        if not ok:
            found = True
            t[b] = t0[b]
            R[b] = R0[b]
            v[b] = v0[b]
            w[b] = w0[b]
    return found


@njit(cache=True)
def _pose_block(t, R, v, w, raw):
    """The pose observation's first 15 entries of every row: P, the first two columns of R, the
    velocity and the angular velocity."""
    for b in range(t.shape[0]):
        for j in range(3):
            raw[b, j] = t[b, j]
            raw[b, 3 + j] = R[b, j, 0]
            raw[b, 6 + j] = R[b, j, 1]
            raw[b, 9 + j] = v[b, j]
            raw[b, 12 + j] = w[b, j]


@njit(cache=True)
def _normalize(raw, offset, inv_scale):
    """raw = (raw - offset) * inv_scale, in place."""
    for b in range(raw.shape[0]):
        for k in range(raw.shape[1]):
            raw[b, k] = (raw[b, k] - offset[k]) * inv_scale[k]


def _readonly(array: np.ndarray) -> np.ndarray:
    """A view of ``array`` that cannot be written (what a task is given)."""
    view = array.view()
    view.flags.writeable = False
    return view


class PlatformBatch:
    """N platforms under one dynamics model, one task and one set of options.

    ``n`` rows; ``config`` the validated arguments (:class:`~stewart_env.envs.config.EnvConfig`).
    Public arrays (row i = platform i, frames and units of the environment card): position (n,3),
    rotation (n,3,3), velocity (n,3), angular_velocity (n,3), leg_forces (n,6), external_wrench
    (n,6), time (n,), leg_lengths (n,6), leg_rates (n,6), condition (n,), the reference (a
    :class:`~stewart_env.tasks.Reference` of (n, ...) arrays), error_integral (n,6) [m s; rad s]
    (None unless ``error_integral=True``) and observation (n, D), the latest observation of every
    row (scaled, noisy, delayed as configured).
    """

    def __init__(self, n: int, config: EnvConfig):
        self.n = n
        self.config = config
        self._init_physics(config)
        self._init_task(config)
        self._init_state(n)
        self._init_observation(config.observation, n)
        self._views()

    def _init_physics(self, config: EnvConfig) -> None:
        physics = config.physics
        self.platform: PlatformParams = physics.platform
        self.nominal_model: Dynamics = physics.dynamics
        self.model: Dynamics = self.nominal_model
        self.control_dt, self.physics_dt, self.substeps = physics.control_dt, physics.physics_dt, physics.substeps
        self.randomization = physics.randomization
        #: MuJoCo simulating the rows (model="mujoco"), else None: the compiled rollout does.
        self.plant = self._mujoco_plant(self.n) if physics.mujoco else None
        if self.randomization is not None:
            # One parameter row per platform, each set at its reset from the nominal packed row.
            self.model = self.nominal_model.with_params([self.platform] * self.n)
        self.actuator_tau = config.actuator.actuator_tau
        self._lag = config.actuator.lag(self.control_dt)
        lo, hi = self.platform.limits.leg_force
        self._force_mid = 0.5 * (lo + hi)
        self._force_half = 0.5 * (hi - lo)

    def _mujoco_plant(self, n: int):
        """A MuJoCo plant of n rows of the nominal platform, stepped at physics_dt."""
        from stewart_env.mujoco import MujocoPlant  # imports without MuJoCo; the plant names the extra

        try:
            return MujocoPlant([self.platform] * n, timestep=self.physics_dt)
        except ImportError as error:
            raise ImportError(f"model={MUJOCO!r}: {error}") from error

    def _init_task(self, config: EnvConfig) -> None:
        self.task = task = make_task(config.task.task, self.platform, self.control_dt, config.task.task_options)
        self.termination_reasons: tuple[str, ...] = (NOT_TERMINATED, *task.termination_reasons)
        self._reason_array = np.array(self.termination_reasons, dtype=str)
        self._moving_reference = task.moving_reference
        self._has_external_wrench = task.has_external_wrench

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
        self._any_non_finite = False
        # Rows whose start observation was not finite: their first step terminates ("non_finite").
        self._pending = np.zeros(n, dtype=bool)
        self._any_pending = False
        self._home_rotation = rpy_to_matrix(self.platform.home_rpy)

    def _init_observation(self, obs, n: int) -> None:
        """The observation's layout, scaling, noise, delay and error integral (see the card)."""
        lim = self.platform.limits
        self.observation_mode = obs.observation_mode
        scales = Scales.of(self.platform)
        box_centre = 0.5 * (lim.position_min + lim.position_max)
        stroke_mid = 0.5 * (lim.leg_length[0] + lim.leg_length[1])
        ang = np.full(3, scales.angle)
        # (name, scale, offset): observed value = (physical - offset) / scale when normalised.
        terms: list[tuple[str, np.ndarray, np.ndarray]] = []
        if self.observation_mode == "pose":
            terms += [("position", scales.position, box_centre), ("orientation", np.ones(6), np.zeros(6)),
                      ("velocity", scales.position, np.zeros(3)), ("angular_velocity", ang, np.zeros(3))]
        else:
            terms += [("leg_lengths", np.full(6, scales.leg_length), np.full(6, stroke_mid)),
                      ("leg_rates", np.full(6, scales.leg_length), np.zeros(6))]
        if self.actuator_tau > 0:
            terms.append(("leg_forces", np.full(6, scales.leg_force), np.full(6, self._force_mid)))
        terms += [(name, scale, np.zeros(scale.size)) for name, scale in self.task.observation_terms(scales)]
        self.error_integral_limit = obs.error_integral_limit
        # Anti-windup bound (6,) [m s; rad s]: error_integral_limit seconds of an error of one
        # observation scale (h, A); the normalised integral is the integral over this bound.
        self.error_integral_bound = self.error_integral_limit * np.concatenate([scales.position, ang])
        band = obs.error_integral_band
        # Conditional integration (6,) [m; rad]: an error component adds to the integral only
        # while within band x its observation scale, so that approaching the target (large
        # errors) does not wind the integral up and it holds mostly the steady-state bias.
        self.error_integral_band = None if band is None else band * np.concatenate([scales.position, ang])
        # The time integral (n,6) [m s; rad s] of (position_error, orientation_error); None when off.
        self.error_integral = np.zeros((n, 6)) if obs.error_integral else None
        self._integral_step = np.zeros((n, 6))
        if obs.error_integral:
            terms.append(("error_integral", self.error_integral_bound, np.zeros(6)))
        self.normalize_observation = obs.normalize_observation
        self.observation_layout: dict[str, slice] = {}
        start = 0
        for name, scale, _ in terms:
            self.observation_layout[name] = slice(start, start + scale.size)
            start += scale.size
        self.obs_dim = start
        if self.normalize_observation:
            self.observation_scale = np.concatenate([t[1] for t in terms])
            self.observation_offset = np.concatenate([t[2] for t in terms])
        else:
            self.observation_scale = np.ones(start)
            self.observation_offset = np.zeros(start)
        self._inv_scale = 1.0 / self.observation_scale
        self._raw = np.zeros((n, start))
        self.noise_std = self._noise(obs.observation_noise)
        self.observation_delay = obs.observation_delay
        # A ring of the last observation_delay + 1 observations; the slot _head + 1 is the oldest.
        self._history = np.zeros((self.observation_delay + 1, n, start))
        self._head = 0

    def _views(self) -> None:
        """The members that are views of others; made again in a copy (see :meth:`__setstate__`),
        since a copy of a view is no longer a view.  ``view`` is what the task sees of the batch."""
        self._state = PlatformState(self.position, self.rotation, self.velocity, self.angular_velocity)
        self._raw_views = self._views_of(self._raw)
        self._errors = errors_in(self._error_vectors, self._error_norms)
        errors = self._errors[0]
        self.view = StepView(
            PlatformState(*map(_readonly, self._state)), Reference(*map(_readonly, self.reference)),
            type(errors)(*map(_readonly, errors)), _readonly(self._action), _readonly(self.leg_forces),
            _readonly(self.leg_lengths), _readonly(self.leg_rates), _readonly(self.condition),
            _readonly(self.external_wrench), _readonly(self.time), _readonly(self._non_finite),
            MappingProxyType({k: _readonly(v) for k, v in self.episode.items()}))

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        del state["_state"], state["_raw_views"], state["view"], state["_errors"]
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._views()

    @property
    def observation(self) -> np.ndarray:
        """The latest observation of every row (n, D): scaled, noisy and delayed as configured."""
        return self._history[(self._head + 1) % (self.observation_delay + 1)]

    # -- configuration -----------------------------------------------------------------------------

    def _views_of(self, raw: np.ndarray) -> dict[str, np.ndarray]:
        return {name: raw[:, sl] for name, sl in self.observation_layout.items()}

    def _noise(self, value: Any) -> np.ndarray | None:
        """Per-entry noise std (D,) in observation units, or None for no noise; ``value`` is the
        checked number or dict of :class:`~stewart_env.envs.config.ObservationConfig`."""
        std = np.zeros(self.obs_dim)
        if isinstance(value, dict):
            unknown = [k for k in value if k not in self.observation_layout]
            if unknown:
                raise ValueError(f"observation_noise: unknown observation term(s) {', '.join(map(repr, unknown))}; "
                                 f"terms: {', '.join(self.observation_layout)}")
            for name, s in value.items():
                std[self.observation_layout[name]] = s
        else:
            std[:] = value
        return std if std.any() else None

    @property
    def render_fps(self) -> float:
        return 1.0 / self.control_dt

    def decode_observation(self, observation: np.ndarray) -> dict[str, np.ndarray]:
        """Observation(s) (..., D) back to physical units, by layout name."""
        physical = np.asarray(observation, dtype=np.float64) * self.observation_scale + self.observation_offset
        return {name: physical[..., sl] for name, sl in self.observation_layout.items()}

    # -- episode start ----------------------------------------------------------------------------------

    def reset_rows(self, rows: np.ndarray, rngs: Sequence[np.random.Generator]) -> list[dict[str, Any]]:
        """Start a new episode in each of ``rows`` (int array), row rows[j] drawing from rngs[j].

        Draw order within a row: randomisation factors, the task's episode, observation noise.
        Returns one info dict per row: with randomisation, ``randomization`` (the factors, name ->
        np.float64).  A randomised row's parameters are scaled in packed form; its PlatformParams
        are built only when read (:meth:`episode_params`).
        """
        infos = []
        rnd = self.randomization
        m = len(rows)
        if rnd is not None:
            nominal = self.nominal_model.packed[0]
            packed = np.empty((m, nominal.shape[0]))
            sources = []
        for j, i in enumerate(rows):
            rng = rngs[j]
            info: dict[str, Any] = {}
            if rnd is not None:
                factors = rnd.sample(rng)
                rnd.scale_packed(nominal, factors, packed[j])
                sources.append(functools.partial(rnd.apply, self.platform, factors))
                info["randomization"] = {k: np.float64(v) for k, v in factors.items()}
            start, episode = self.task.initialize_episode(rng)
            self.position[i], self.rotation[i], self.velocity[i], self.angular_velocity[i] = start
            for k, v in episode.items():
                self.episode[k][i] = v
            infos.append(info)
        if rnd is not None:
            self.model = self.model.with_packed_rows(rows, packed, sources)
            if self.plant is not None:
                self.plant.set_params(rows, [self.model.params_of(i) for i in rows])
        self.steps[rows] = 0
        self.time[rows] = 0.0
        if self.error_integral is not None:
            self.error_integral[rows] = 0.0
        self.external_wrench[rows] = 0.0
        self._action[rows] = 0.0
        state = PlatformState(*(x[rows] for x in self._state))
        lengths, rates, cond = np.empty((m, 6)), np.empty((m, 6)), np.empty(m)
        if self._lag:
            # The actuators start holding the start state: the forces of zero acceleration, as far
            # as the actuators reach.
            model = (self.nominal_model if rnd is None
                     else self.nominal_model.with_params([self.platform] * m).with_packed_rows(range(m), packed,
                                                                                             sources))
            zero = np.zeros((m, 3))
            lo, hi = self.platform.limits.leg_force
            self.leg_forces[rows] = np.clip(model.inverse(*state, zero, zero), lo, hi)
        else:
            self.leg_forces[rows] = 0.0
        leg_sensors_inplace(self.nominal_model, *state, self.platform.limits.max_condition, lengths, rates, cond)
        self.leg_lengths[rows], self.leg_rates[rows], self.condition[rows] = lengths, rates, cond
        episode = MappingProxyType({k: v[rows] for k, v in self.episode.items()})
        ref = zero_reference(m)
        self.task.reference(episode, self.time[rows], ref)
        for dst, src in zip(self.reference, ref):
            dst[rows] = src
        view = StepView(state, ref, tracking_errors(state, ref), self._action[rows], self.leg_forces[rows],
                        lengths, rates, cond, self.external_wrench[rows], self.time[rows], np.zeros(m, dtype=bool),
                        episode)
        raw = np.empty((m, self.obs_dim))
        integral = None if self.error_integral is None else self.error_integral[rows]
        self._measure(view, integral, raw)
        if self.noise_std is not None:
            for j in range(m):
                raw[j] += rngs[j].normal(size=self.obs_dim) * self.noise_std
        bad = self._finite_or_marked(raw, np.zeros(m))
        self._pending[rows] = False if bad is None else bad
        self._any_pending = bool(self._pending.any())
        # A delayed sensor has seen only the start: every slot of the history holds it.
        self._history[:, rows] = raw
        return infos

    # -- control step -----------------------------------------------------------------------------------

    def step(self, action: np.ndarray, rngs: Sequence[np.random.Generator],
             skip: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """One control step of every row.

        action (n,6) float64, finite (see :func:`check_action`); clipped to [-1, 1] here.  rngs:
        one Generator per row (used only for observation noise).  skip: optional (n,) bool of rows
        about to be reset by the caller: they are parked at home first (their outcome is thrown
        away) and draw no noise.  Returns (reward (n,), termination code (n,) int, reward terms
        by name, each (n,)); codes index :attr:`termination_reasons` (0: none).
        """
        _drive(action, self._force_half, self._force_mid, self._lag, self._action, self.leg_forces)
        if skip is not None:
            self._park(skip)
        if self._has_external_wrench:
            self.task.external_wrench(self.view, self.control_dt, self.external_wrench)
        _copy_state(*self._state, *self._backup)
        self._physics()
        return self._outcome(rngs, skip)

    def _physics(self) -> None:
        """The rollout of every row, the non-finite check and the leg sensors."""
        if self.plant is None:
            rollout_inplace(self.model, self.position, self.rotation, self.velocity, self.angular_velocity,
                            self.leg_forces, self.external_wrench, self.physics_dt, self.substeps)
        else:
            self.plant.step_inplace(self.position, self.rotation, self.velocity, self.angular_velocity,
                                    self.leg_forces, self.external_wrench, self.physics_dt, self.substeps)
        # A row whose state is no longer finite keeps its last finite state, so that observation,
        # reward and rendering stay finite.
        self._any_non_finite = _after_physics(*self._state, *self._backup, self.steps, self.control_dt, self.time,
                                              self._non_finite)
        leg_sensors_inplace(self.nominal_model, self.position, self.rotation, self.velocity,
                            self.angular_velocity, self.platform.limits.max_condition, self.leg_lengths,
                            self.leg_rates, self.condition)

    def _outcome(self, rngs, skip) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """Reference, then the task's termination and reward, and the observation after the
        physics of a step."""
        task, view = self.task, self.view
        if self._moving_reference:
            task.reference(view.episode, self.time, self.reference)
        tracking_errors(self._state, self.reference, self._errors)

        code = task.termination(view)
        if self._any_non_finite:
            # The state stopped being finite: whatever the task says, the episode ends so.
            code[self._non_finite] = NON_FINITE
        terms = task.reward_terms(view)
        terms["termination"] = task.termination_reward(code)
        reward = sum(terms.values())

        if self.error_integral is not None:
            self._integrate(view.errors)
        raw = self._raw
        self._measure(view, self.error_integral, raw)
        if self.noise_std is not None:
            for i in range(self.n):
                if skip is None or not skip[i]:
                    raw[i] += rngs[i].normal(size=self.obs_dim) * self.noise_std
        bad = self._finite_or_marked(raw, reward)
        if self._any_pending:
            bad = self._pending.copy() if bad is None else bad | self._pending
            self._pending[:] = False
            self._any_pending = False
        if bad is not None:
            # No NaN or inf leaves the environment: the row ends as non-finite, its reward terms
            # that are not finite count 0, and its termination term is the task's for the new code.
            code[bad] = NON_FINITE
            for term in terms.values():
                term[bad] = np.nan_to_num(term[bad], nan=0.0, posinf=0.0, neginf=0.0)
            terms["termination"] = task.termination_reward(code)
            reward = sum(terms.values())
        self._head = (self._head + 1) % (self.observation_delay + 1)
        self._history[self._head] = raw
        return reward, code, terms

    @staticmethod
    def _finite_or_marked(raw: np.ndarray, reward: np.ndarray) -> np.ndarray | None:
        """The rows (bool (rows,)) of an observation batch or its reward with an entry that is
        not finite or beyond the float32 range, their observation entries made finite in place
        (NaN 0, the rest clipped to the float32 range); None when every row is fine (one
        compiled pass)."""
        if _within_float32(raw, reward, _FLOAT32_MAX):
            return None
        bad = ~((np.abs(raw) <= _FLOAT32_MAX).all(axis=1) & np.isfinite(reward))
        raw[bad] = np.clip(np.nan_to_num(raw[bad], nan=0.0), -_FLOAT32_MAX, _FLOAT32_MAX)
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

    def _park(self, rows: np.ndarray) -> None:
        """Put rows at home at rest: a safe state to step before the caller resets them."""
        self.position[rows] = self.platform.home_position
        self.rotation[rows] = self._home_rotation
        self.velocity[rows] = 0.0
        self.angular_velocity[rows] = 0.0

    def _measure(self, view: StepView, integral, raw: np.ndarray) -> None:
        """Write the clean observation of a batch (any number of rows) seen through ``view`` into
        ``raw``; integral is the batch's error integral (rows, 6), or None when it is not observed."""
        views = self._raw_views if raw is self._raw else self._views_of(raw)
        if self.observation_mode == "pose":
            _pose_block(*view.state, raw)
        else:
            views["leg_lengths"][:] = view.leg_lengths
            views["leg_rates"][:] = view.leg_rates
        if "leg_forces" in views:
            views["leg_forces"][:] = view.leg_forces
        self.task.observe(view, views)
        if integral is not None:
            views["error_integral"][:] = integral
        if self.normalize_observation:
            _normalize(raw, self.observation_offset, self._inv_scale)

    # -- introspection ------------------------------------------------------------------------------------

    def episode_params(self, row: int) -> PlatformParams:
        """The PlatformParams of row ``row``'s episode: with domain randomisation the nominal ones
        scaled by the episode's factors (built on first read), else the nominal ones."""
        return self.platform if self.randomization is None else self.model.params_of(row)

    def reasons(self, code: np.ndarray) -> np.ndarray:
        """Termination reason names (str array; "" for code 0) of codes."""
        return self._reason_array[code]


class BatchAttributes:
    """What both environments show of their :class:`PlatformBatch`.

    ``_rows`` picks row 0 (the single environment: arrays without the batch axis) or every row
    (the vector environment: a leading N).  Arrays are copies.
    """

    _core: PlatformBatch
    _rows: int | slice
    _renderer = None  # made on first render
    _reset_done = False  # set by the first reset()

    def _rows_of(self, array: np.ndarray) -> np.ndarray:
        return array[self._rows].copy()

    def __getstate__(self) -> dict[str, Any]:
        # A copy draws with a renderer of its own, made on its first render().
        state = self.__dict__.copy()
        state.pop("_renderer", None)
        return state

    def _check_reset(self) -> None:
        """Refuse a step before the first reset(), which draws the episode (the state would be zeros)."""
        if not self._reset_done:
            raise ResetNeeded(f"{type(self).__name__}: call reset() before step(); the first reset() "
                              "draws the episode's start state")

    @property
    def observation_layout(self) -> dict[str, slice]:
        """Observation term name -> slice of a (row's) observation vector."""
        return dict(self._core.observation_layout)

    def decode_observation(self, observation) -> dict[str, np.ndarray]:
        """An observation, or a batch of them, in physical units by term name (undoes the scaling)."""
        return self._core.decode_observation(observation)

    @property
    def state(self) -> PlatformState:
        """The platform's current state, {B}: position, rotation, velocity, angular velocity."""
        return PlatformState(*(self._rows_of(x) for x in self._core._state))

    @property
    def target(self) -> Reference:
        """The task's current reference: position, rotation, velocity, angular velocity, {B}."""
        return Reference(*(self._rows_of(x) for x in self._core.reference))

    @property
    def model(self) -> Dynamics:
        """The dynamics model of the current episode: one parameter set, or one per row with
        domain randomisation."""
        return self._core.model

    @property
    def platform(self) -> PlatformParams:
        """The nominal PlatformParams."""
        return self._core.platform

    @property
    def termination_reasons(self) -> tuple[str, ...]:
        """The names of the termination codes of ``info["termination"]``: "" (code 0, the episode
        goes on), then the environment's reasons by priority, then the task's."""
        return self._core.termination_reasons

    @property
    def episode_params(self):
        """The PlatformParams of the current episode (with domain randomisation, the nominal ones
        scaled by the episode's factors; else the nominal ones); a tuple of one per row in the
        vector environment."""
        core = self._core
        if isinstance(self._rows, slice):
            return tuple(core.episode_params(i) for i in range(core.n))
        return core.episode_params(self._rows)

    @property
    def task(self):
        """The task object (see stewart_env.tasks)."""
        return self._core.task

    @property
    def leg_forces(self) -> np.ndarray:
        """The leg forces (6,) N applied over the last control step (after clipping and lag)."""
        return self._rows_of(self._core.leg_forces)

    @property
    def external_wrench(self) -> np.ndarray:
        """The external wrench (6,) [N; N m] in {B} applied over the last control step."""
        return self._rows_of(self._core.external_wrench)

    @property
    def leg_lengths(self) -> np.ndarray:
        """Leg lengths (6,) m now."""
        return self._rows_of(self._core.leg_lengths)

    @property
    def dt(self) -> float:
        """The control period, s."""
        return self._core.control_dt

    def _scene(self) -> tuple[np.ndarray, ...]:
        """What a frame shows of every row: position, rotation, leg forces, target position and
        rotation, time (the batch's own arrays, not copies)."""
        core = self._core
        ref = core.reference
        return core.position, core.rotation, core.leg_forces, ref.position, ref.rotation, core.time

    def _draw(self, row: int = 0, label: str = "", scene: tuple[np.ndarray, ...] | None = None):
        """Row ``row`` of ``scene`` (default: now, see :meth:`_scene`) drawn by a PlatformRenderer
        made on first use (the target pose as a ghost): an RGB frame, or None in human mode."""
        core = self._core
        if self._renderer is None:
            from stewart_env.envs.render import PlatformRenderer  # matplotlib only when rendering

            p = core.platform
            size = core.config.render
            self._renderer = PlatformRenderer(p.base_joints, p.platform_joints, p.home_position,
                                              p.limits.leg_force, size.width, size.height, self.render_mode)
        position, rotation, forces, target_position, target_rotation, time = scene or self._scene()
        return self._renderer.render(position[row], rotation[row], forces[row], target_position=target_position[row],
                                     target_rotation=target_rotation[row], text=f"{label}t = {time[row]:.2f} s")

    def _close_renderer(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
