"""The cueing task: move the platform so that a person on it feels what a person in the vehicle feels.

Each episode is one vehicle motion (:class:`~stewart_env.tasks.cueing.motion.VehicleMotion`): its
specific force and angular velocity at the head, drawn by name and seed. After every control step
the task measures what the person on the platform is subjected to at the head point
(:mod:`~stewart_env.tasks.cueing.head`), passes both the vehicle's and the platform's signals
through the vestibular models (:mod:`~stewart_env.tasks.cueing.vestibular`), and rewards the
agreement of the two perceptions, less the use of the workspace and of the legs' stroke.
"""

from __future__ import annotations

import math
import os
from collections import OrderedDict

import numpy as np

from stewart_env.errors import UsageError
from stewart_env.params import PlatformParams
from stewart_env.rotations import matrix_to_rpy, rpy_to_matrix
from stewart_env.state import PlatformState
from stewart_env.tasks.base import LIMIT_REASONS, Scales, StepView, SuccessCriterion, Task, option
from stewart_env.tasks.cueing.head import head_at_rest, head_motion
from stewart_env.tasks.cueing.motion import STANDARD_GRAVITY
from stewart_env.tasks.cueing.motions import (
    EVALUATION_MOTIONS,
    EVALUATION_SEEDS,
    MOTIONS,
    TRAINING_MOTIONS,
    TRAINING_SEED_BOUND,
    make_motion,
    read_motion,
)
from stewart_env.tasks.cueing.vestibular import THRESHOLDS, Otolith, SemicircularCanal, false_cue_samples
from stewart_env.validation import choice, integer, real, vector

__all__ = ["CueingTask", "DEFAULT_HEAD", "MAX_PREVIEW"]

#: The head point's default in {P} (m): 0.8 m above P's origin, about a seated person's eye height
#: above the cabin floor.
DEFAULT_HEAD = (0.0, 0.0, 0.8)
#: Bounds of the options: at most MAX_PREVIEW samples ahead, a head within MAX_HEAD m of P's origin.
MAX_PREVIEW = 100
MAX_HEAD = 10.0
#: How many vehicle motions the task keeps resampled, the most recently used first.
_CACHE_SIZE = 64
#: The largest sample period the motion generators take (s); a longer control step interpolates.
_MAX_MOTION_DT = 0.1


class CueingTask(Task):
    """Reproduce a vehicle's motion as a person perceives it, within the platform's limits.

    Each episode draws a motion from ``motions`` (uniformly) and a seed (training: below 2**30;
    ``split="evaluation"``: one of the held-out evaluation seeds, at or above 2**30); the platform
    starts at rest at home and the episode lasts the motion's duration, ending then with the
    reason ``"motion_end"`` (a success: no termination cost), or earlier at the platform's limits
    (failures, as in every task). The motion is resampled onto the control steps (linear
    interpolation).

    After each step, with ``f_v, w_v`` the vehicle's specific force (m/s²) and angular velocity
    (rad/s) at the step's time, ``f_p, w_p`` the platform's at the head point (both in {H}) and
    a hat what the otolith and semicircular-canal models make of them (each started adapted to its
    signal at rest)::

        r = specific_force_weight    exp(-(|f_hat_v - f_hat_p| / specific_force_scale)^2)
          + angular_velocity_weight  exp(-(|w_hat_v - w_hat_p| / angular_velocity_scale)^2)
          - workspace_weight u_w^2 - stroke_weight u_s^2 - ctrl_cost_weight mean(a^2)
          - false_cue_weight n_false
          - termination_cost on a failure,

    ``u_w`` the workspace use (the largest of |p - box centre| / half-box on x, y, z and
    |rpy - home rpy| / max_angle, at most 1), ``u_s`` the stroke use (the largest
    |L_i - mid-stroke| / half-stroke, at most 1), ``n_false`` the axes of the two channels (0 to
    6) on which the platform's perceived motion is a false cue at the step (above the perception
    threshold with the sign opposite to the vehicle's perceived motion, the specific forces taken
    as deviations from rest: the samples the evaluation's false cues count). The perception terms
    are one less their bounded perceived errors, so that a step inside the motion is always worth
    more than an early end (with ``false_cue_weight`` 0, the default).

    Observation terms: ``vehicle_specific_force`` (3, m/s², scale |g|), ``vehicle_angular_velocity``
    (3, rad/s, scale 1), with ``preview`` > 0 ``preview`` (6 x preview: the vehicle's f and w
    at the next ``preview`` control steps, the last sample held past the end), and
    ``motion_time_left`` (1, s, scale 10), besides the platform's state the environment observes.

    Args:
        params: the platform's nominal parameters.
        control_dt: the control step, s.
        motions: the motions' names (a tuple) or a motion file's path (a ``str`` or path),
            default: the split's motions.
        split: ``"train"`` or ``"evaluation"``, which seeds episodes draw.
        training_seeds: None (training seeds uniform in [0, 2**30)) or n, 1 to 2**30: training
            seeds uniform in [0, n), so that a few motions per name recur and the task generates
            each once (it keeps the last 64); default None.
        preview: samples ahead observed, 0-100, default 0.
        head: (3,) m in {P}, the head point, default (0, 0, 0.8).
        specific_force_weight: default 1.0.
        specific_force_scale: m/s², default 1.0 (about six otolith thresholds).
        angular_velocity_weight: default 1.0.
        angular_velocity_scale: rad/s, default 0.1 (about two canal thresholds).
        workspace_weight: default 0.2.
        stroke_weight: default 0.2.
        ctrl_cost_weight: default 0.0.
        false_cue_weight: the penalty per false-cue axis and step, default 0.0.
        termination_cost: default 10.0.

    Raises:
        UsageError: an option out of its range, an unknown motion or an unreadable motion file
            (the message names the option).
    """

    name = "cueing"
    termination_reasons = (*LIMIT_REASONS, "motion_end")
    success_reasons = ("motion_end",)
    #: An episode succeeds when it runs to the motion's end (no pose band: every pose error passes).
    success_criterion = SuccessCriterion(math.inf, math.inf, 0.0)

    def __init__(
        self,
        params: PlatformParams,
        control_dt: float,
        *,
        motions=None,
        split: str = "train",
        training_seeds: int | None = None,
        preview: int = 0,
        head=DEFAULT_HEAD,
        specific_force_weight: float = 1.0,
        specific_force_scale: float = 1.0,
        angular_velocity_weight: float = 1.0,
        angular_velocity_scale: float = 0.1,
        workspace_weight: float = 0.2,
        stroke_weight: float = 0.2,
        ctrl_cost_weight: float = 0.0,
        false_cue_weight: float = 0.0,
        termination_cost: float = 10.0,
    ):
        self.split = choice(option("split"), split, ("train", "evaluation"))
        self.preview = integer(option("preview"), preview, 0, MAX_PREVIEW)
        self.training_seeds = (
            TRAINING_SEED_BOUND
            if training_seeds is None
            else integer(option("training_seeds"), training_seeds, 1, TRAINING_SEED_BOUND)
        )
        self.head = vector(option("head"), head, 3, -MAX_HEAD, MAX_HEAD)
        self.cue_weights = {
            "specific_force_weight": real(option("specific_force_weight"), specific_force_weight, 0.0, 1e6),
            "specific_force_scale": real(option("specific_force_scale"), specific_force_scale, 0.0, 1e6, low_open=True),
            "angular_velocity_weight": real(option("angular_velocity_weight"), angular_velocity_weight, 0.0, 1e6),
            "angular_velocity_scale": real(
                option("angular_velocity_scale"), angular_velocity_scale, 0.0, 1e6, low_open=True
            ),
            "workspace_weight": real(option("workspace_weight"), workspace_weight, 0.0, 1e6),
            "stroke_weight": real(option("stroke_weight"), stroke_weight, 0.0, 1e6),
            "false_cue_weight": real(option("false_cue_weight"), false_cue_weight, 0.0, 1e6),
        }
        self._file_motion = None
        self.motion_names = self._motion_names(motions)
        super().__init__(
            params,
            control_dt,
            position_reward_weight=0.0,
            orientation_reward_weight=0.0,
            velocity_cost_weight=0.0,
            ctrl_cost_weight=ctrl_cost_weight,
            termination_cost=termination_cost,
        )
        self._home_rotation = rpy_to_matrix(params.home_rpy)
        self._gravity = np.array(params.gravity, dtype=np.float64)
        self._rest = head_at_rest(self._gravity)
        lim = params.limits
        self._box_centre = 0.5 * (lim.position_min + lim.position_max)
        self._box_half = 0.5 * (lim.position_max - lim.position_min)
        self._stroke_mid = 0.5 * (lim.leg_length[0] + lim.leg_length[1])
        self._stroke_half = 0.5 * (lim.leg_length[1] - lim.leg_length[0])
        self._otolith = Otolith()
        # the otolith's output at rest (its gain at rest times |g| along z, as the evaluation takes it):
        # the false cues are counted on the deviations from it
        self._perceived_rest_specific_force = self._otolith.gain * np.array([0.0, 0.0, STANDARD_GRAVITY])
        self._canal = SemicircularCanal()
        self._motions: OrderedDict[tuple[int, int], np.ndarray] = OrderedDict()
        self._batch: dict[str, np.ndarray] | None = None
        self._scheduled: list[tuple[int, int]] = []

    # -- options ----------------------------------------------------------------------------------

    def _motion_names(self, motions) -> tuple[str, ...]:
        if motions is None:
            return tuple(TRAINING_MOTIONS if self.split == "train" else EVALUATION_MOTIONS)
        if isinstance(motions, (str, os.PathLike)):
            self._file_motion = read_motion(motions)
            return (self._file_motion.name,)
        if not isinstance(motions, (tuple, list)) or not motions or not all(isinstance(m, str) for m in motions):
            raise UsageError.about(
                option("motions"), f"expected a tuple of motion names or a motion file's path, got {motions!r}"
            )
        names = tuple(motions)
        unknown = [name for name in names if name not in MOTIONS]
        if unknown:
            raise UsageError.about(
                option("motions"),
                f"unknown motion(s) {', '.join(map(repr, unknown))}; choose from {', '.join(MOTIONS)}",
            )
        return names

    # -- episodes ---------------------------------------------------------------------------------

    def episode_fields(self):
        """The episode arrays (see :meth:`Task.episode_fields`): the home target, the motion's index and seed, its steps."""
        return {"target_position": (3,), "target_rotation": (3, 3), "motion": (), "seed": (), "motion_steps": ()}

    def motion_of(self, index: int, seed: int) -> np.ndarray:
        """The motion ``motion_names[index]`` of ``seed`` on the control steps: (K + 1, 6) [f (m/s²), w (rad/s)] in {H}.

        Args:
            index: the motion's index in :attr:`motion_names`.
            seed: its seed.

        Returns:
            The samples at t = k control_dt, k = 0..K, K control_dt at most the motion's duration.
        """
        key = (int(index), int(seed))
        samples = self._motions.get(key)
        if samples is not None:
            self._motions.move_to_end(key)
            return samples
        motion = self._file_motion
        if motion is None:
            motion = make_motion(self.motion_names[key[0]], key[1], min(self.control_dt, _MAX_MOTION_DT))
        steps = int(math.floor(motion.duration / self.control_dt + 1e-9))
        if steps < 1:
            raise UsageError.about(
                option("motions"),
                f"motion {motion.name!r} lasts {motion.duration} s, less than one control step ({self.control_dt} s)",
            )
        time = np.arange(steps + 1) * self.control_dt
        values = np.concatenate([motion.specific_force, motion.angular_velocity], axis=1)
        samples = np.stack([np.interp(time, motion.time, values[:, c]) for c in range(6)], axis=1)
        samples.setflags(write=False)
        self._motions[key] = samples
        while len(self._motions) > _CACHE_SIZE:
            self._motions.popitem(last=False)
        return samples

    def schedule(self, episodes) -> None:
        """Play these episodes at the next row resets, in order (a reset of all rows: row i the i-th), then draw again.

        A batch that scores given motions side by side (a washout's tuning in the environment, an
        evaluation of given manoeuvres) schedules one per row and resets every row; the scheduled
        episodes draw no random numbers, and the draws resume when the schedule is used up.

        Args:
            episodes: a sequence of (motion name, seed) pairs, each name one of :attr:`motion_names`
                and each seed an integer in [0, 2**63).

        Raises:
            UsageError: a motion not among the task's, or a bad seed (the message names ``episodes``).
        """
        pairs = []
        for k, pair in enumerate(episodes):
            if not isinstance(pair, (tuple, list)) or len(pair) != 2 or pair[0] not in self.motion_names:
                raise UsageError.about(
                    "episodes",
                    f"entry {k} must be a (motion, seed) pair with a motion of {', '.join(self.motion_names)}, got {pair!r}",
                )
            seed = integer(f"episodes[{k}] seed", pair[1], 0, 2**63 - 1)
            pairs.append((self.motion_names.index(pair[0]), seed))
        self._scheduled = pairs

    def initialize_episode(self, rng):
        """Draw one row's episode (see :meth:`Task.initialize_episode`): a motion and its seed (the
        next scheduled one, :meth:`schedule`, if any); the start at rest at home.

        Args:
            rng: the row's generator.
        """
        if self._scheduled:
            index, seed = self._scheduled.pop(0)
            return self._episode(index, seed)
        index = int(rng.integers(len(self.motion_names)))
        if self._file_motion is not None:
            seed = 0
        elif self.split == "train":
            seed = int(rng.integers(self.training_seeds))
        else:
            seed = int(EVALUATION_SEEDS[int(rng.integers(len(EVALUATION_SEEDS)))])
        return self._episode(index, seed)

    def _episode(self, index: int, seed: int):
        """The start at rest at home and the episode arrays of motion ``index`` drawn with ``seed``."""
        samples = self.motion_of(index, seed)
        p = self.params
        home = rpy_to_matrix(p.home_rpy)
        episode = {
            "target_position": p.home_position.copy(),
            "target_rotation": home,
            "motion": float(index),
            "seed": float(seed),
            "motion_steps": float(len(samples) - 1),
        }
        return PlatformState(p.home_position.copy(), home, np.zeros(3), np.zeros(3)), episode

    def _samples(self, episode, steps: np.ndarray, ahead: int = 0) -> np.ndarray:
        """The vehicle's samples (N, 1 + ahead, 6) at each row's step index and the ``ahead`` next (the last held past the end)."""
        offsets = np.arange(ahead + 1)
        out = np.empty((steps.shape[0], ahead + 1, 6))
        for i, (index, seed, k) in enumerate(zip(episode["motion"].tolist(), episode["seed"].tolist(), steps.tolist())):
            samples = self.motion_of(int(index), int(seed))
            out[i] = samples[np.minimum(k + offsets, len(samples) - 1)]
        return out

    def _steps(self, time: np.ndarray) -> np.ndarray:
        return np.rint(time / self.control_dt).astype(np.int64)

    # -- observation ------------------------------------------------------------------------------

    def observation_terms(self, scales: Scales):
        """The vehicle's signals now, the preview, the motion's time left.

        Args:
            scales: the platform's :class:`Scales` (unused: the vehicle's scales are |g| and 1 rad/s).
        """
        signal = np.array([STANDARD_GRAVITY] * 3 + [1.0] * 3)
        terms = [("vehicle_specific_force", signal[:3].copy()), ("vehicle_angular_velocity", signal[3:].copy())]
        if self.preview:
            terms.append(("preview", np.tile(signal, self.preview)))
        terms.append(("motion_time_left", np.array([10.0])))
        return terms

    def observe(self, view: StepView, out) -> None:
        """Write the terms of :meth:`observation_terms` into ``out``.

        Args:
            view: the batch's :class:`StepView`.
            out: the terms' arrays, name -> (N, size).
        """
        steps = self._steps(view.time)
        samples = self._samples(view.episode, steps, self.preview)
        out["vehicle_specific_force"][:] = samples[:, 0, :3]
        out["vehicle_angular_velocity"][:] = samples[:, 0, 3:]
        if self.preview:
            out["preview"][:] = samples[:, 1:].reshape(steps.shape[0], 6 * self.preview)
        out["motion_time_left"][:, 0] = (view.episode["motion_steps"] - steps) * self.control_dt

    # -- perception, reward and termination --------------------------------------------------------

    def _perceive(self, view: StepView) -> dict[str, np.ndarray]:
        """Advance every row's vestibular filters by the step just made; returns the step's signals.

        A row's filters start at its first step (its step index 1), adapted to its signals at
        rest: the vehicle's first sample and the platform at rest at home.
        """
        n = view.time.shape[0]
        steps = self._steps(view.time)
        vehicle = self._samples(view.episode, steps)[:, 0]
        batch = self._batch
        if batch is None or batch["previous_velocity"].shape[0] != n:
            batch = self._batch = {
                "previous_velocity": np.zeros((n, 3)),
                "previous_angular_velocity": np.zeros((n, 3)),
                "otolith": self._otolith.discretize(self.control_dt),
                "canal": self._canal.discretize(self.control_dt),
            }
            batch["otolith"].reset(np.zeros((n, 2, 3)))
            batch["canal"].reset(np.zeros((n, 2, 3)))
        first = steps == 1
        if first.any():
            rows = np.flatnonzero(first)
            start = self._samples({k: v[rows] for k, v in view.episode.items()}, np.zeros(len(rows), dtype=np.int64))[
                :, 0
            ]
            rest_f, rest_w = self._rest
            batch["otolith"].start_rows(rows, np.stack([start[:, :3], np.broadcast_to(rest_f, (len(rows), 3))], axis=1))
            batch["canal"].start_rows(rows, np.stack([start[:, 3:], np.broadcast_to(rest_w, (len(rows), 3))], axis=1))
            batch["previous_velocity"][rows] = 0.0
            batch["previous_angular_velocity"][rows] = 0.0
        state = view.state
        head_f, head_w = head_motion(
            state.rotation,
            state.velocity,
            state.angular_velocity,
            batch["previous_velocity"],
            batch["previous_angular_velocity"],
            self.control_dt,
            self.head,
            self._gravity,
            self._home_rotation,
        )
        batch["previous_velocity"][:] = state.velocity
        batch["previous_angular_velocity"][:] = state.angular_velocity
        perceived_f = batch["otolith"].step(np.stack([vehicle[:, :3], head_f], axis=1))
        perceived_w = batch["canal"].step(np.stack([vehicle[:, 3:], head_w], axis=1))
        signals = {
            "vehicle_specific_force": vehicle[:, :3],
            "vehicle_angular_velocity": vehicle[:, 3:],
            "head_specific_force": head_f,
            "head_angular_velocity": head_w,
            "perceived_vehicle_specific_force": perceived_f[:, 0],
            "perceived_vehicle_angular_velocity": perceived_w[:, 0],
            "perceived_head_specific_force": perceived_f[:, 1],
            "perceived_head_angular_velocity": perceived_w[:, 1],
        }
        signals["perceived_specific_force_error"] = _norm(perceived_f[:, 1] - perceived_f[:, 0])
        signals["perceived_angular_velocity_error"] = _norm(perceived_w[:, 1] - perceived_w[:, 0])
        batch["info"] = signals
        return signals

    def reward_terms(self, view: StepView) -> dict[str, np.ndarray]:
        """The reward terms (N,) each of a step (see the class docstring): ``specific_force``,
        ``angular_velocity``, ``workspace``, ``stroke``, ``control``, ``false_cues``.  Advances the perception.

        Args:
            view: the batch's :class:`StepView` after the step.
        """
        w = self.cue_weights
        signals = self._perceive(view)
        e_f = signals["perceived_specific_force_error"] / w["specific_force_scale"]
        e_w = signals["perceived_angular_velocity_error"] / w["angular_velocity_scale"]
        state = view.state
        offset = np.abs(state.position - self._box_centre) / self._box_half
        angles = np.abs(matrix_to_rpy(state.rotation) - self.params.home_rpy) / self.params.limits.max_angle
        workspace = np.minimum(np.maximum(offset.max(axis=1), angles.max(axis=1)), 1.0)
        stroke = np.minimum((np.abs(view.leg_lengths - self._stroke_mid) / self._stroke_half).max(axis=1), 1.0)
        signals["workspace_use"], signals["stroke_use"] = workspace, stroke
        action = view.action
        false_cues = np.zeros(len(workspace))
        if w["false_cue_weight"] > 0.0:
            rest = self._perceived_rest_specific_force
            false_cues = false_cue_samples(
                signals["perceived_vehicle_specific_force"] - rest,
                signals["perceived_head_specific_force"] - rest,
                THRESHOLDS["specific_force"],
            ).sum(axis=1) + false_cue_samples(
                signals["perceived_vehicle_angular_velocity"],
                signals["perceived_head_angular_velocity"],
                THRESHOLDS["angular_velocity"],
            ).sum(axis=1)
        return {
            "specific_force": w["specific_force_weight"] * np.exp(-(e_f * e_f)),
            "angular_velocity": w["angular_velocity_weight"] * np.exp(-(e_w * e_w)),
            "workspace": -w["workspace_weight"] * workspace * workspace,
            "stroke": -w["stroke_weight"] * stroke * stroke,
            "control": -self.weights.ctrl_cost_weight * np.mean(action * action, axis=1),
            "false_cues": -w["false_cue_weight"] * false_cues,
        }

    def termination(self, view: StepView) -> np.ndarray:
        """The platform's limits, then ``"motion_end"`` at the motion's last sample.

        Args:
            view: the batch's :class:`StepView` after the step.
        """
        code = super().termination(view)
        self.end(code, self._steps(view.time) >= view.episode["motion_steps"], "motion_end")
        return code

    def step_info(self) -> dict[str, np.ndarray]:
        """The last step's signals by name, (N, 3) or (N,) arrays of their own: what the environment adds to ``info``.

        ``vehicle_specific_force``, ``vehicle_angular_velocity``, ``head_specific_force``,
        ``head_angular_velocity`` (m/s², rad/s, {H}), their perceptions
        ``perceived_vehicle_*`` and ``perceived_head_*``, the perceived errors' norms
        ``perceived_specific_force_error`` (m/s²) and ``perceived_angular_velocity_error`` (rad/s),
        ``workspace_use`` and ``stroke_use`` (fractions).
        """
        if self._batch is None or "info" not in self._batch:
            return {}
        return {k: v.copy() for k, v in self._batch["info"].items()}


def _norm(vectors: np.ndarray) -> np.ndarray:
    squares = vectors * vectors
    return np.sqrt(squares[:, 0] + squares[:, 1] + squares[:, 2])
