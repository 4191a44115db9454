"""Disturbance rejection: hold the home pose while a random external wrench acts on the platform."""

from __future__ import annotations

import numpy as np

from stewart_env.params import PlatformParams
from stewart_env.rotations import rpy_to_matrix
from stewart_env.state import PlatformState
from stewart_env.tasks.base import BASE_SCALE_OPTIONS, MAX_FREQUENCY, PRECISE_REWARD_SCALES, Task, option
from stewart_env.validation import integer, interval, real, vector

#: Bounds of the options: forces at most MAX_LOAD platform weights W (moments MAX_LOAD W r),
#: frequencies in (0, MAX_FREQUENCY] Hz, at most MAX_IMPULSES pulses, a horizon of at most
#: MAX_HORIZON s.  Beyond, the wrench throws any platform out of its workspace at once.
MAX_LOAD = 100.0
MAX_IMPULSES = 1000
MAX_HORIZON = 1e6


class DisturbanceTask(Task):
    """Hold the home pose, starting there at rest, against a random external wrench.

    The wrench [F_ext at P's origin; M_ext] in {B} is the sum of
      * sinusoids on each of its six axes k: A_k sin(omega_k t + phi_k), A_k uniform in
        [0, sine_force] (forces) or [0, sine_moment] (moments), omega_k = 2 pi f_k with f_k uniform
        in frequency_range, phi_k uniform in [0, 2 pi);
      * n_impulses rectangular pulses of impulse_duration, starting at times uniform in
        [0, horizon - impulse_duration], each a force of uniform magnitude in [0, impulse_force]
        along a uniformly random direction and a moment of uniform magnitude in
        [0, impulse_moment] about a uniformly random axis.
    All of it is drawn once per episode.  The environment holds the wrench constant over each
    control step (as it holds the leg forces) at its average over that step, computed exactly, so
    a pulse shorter than a control step still delivers its full impulse.

    The options are the environment's ``task_options``.  Below, W = platform.mass |g| is the
    platform's weight and r the mean distance of the platform joints from P's origin in the {P}
    x-y plane (dasgupta1998: W = 392 N, r = 0.62 m); forces are at most 100 W, moments at most
    100 W r.

    Args:
        params: the platform's nominal parameters.
        control_dt: the control step, s.
        sine_force: (3,) N or one number, default 0.2 W.
        sine_moment: (3,) N m or one number, default 0.2 W r.
        frequency_range: (min, max) Hz, 0 < min <= max <= 1000, default (0.2, 2.0).
        n_impulses: 0-1000, default 2.
        impulse_force: N, default W.
        impulse_moment: N m, default 0.5 W r.
        impulse_duration: s, > 0, default 0.05.
        horizon: s, the span the pulses are placed in, from impulse_duration to 1e6, default 5.0
            (the default episode length).
        position_reward_scale, orientation_reward_scale: sharper than the other tasks' by
            default, 0.01 m and 0.02 rad (``PRECISE_REWARD_SCALES``), so that millimetre errors
            weigh in the reward; under the environment's version 0 (``StewartPlatform-v0``) the
            other tasks' 0.05 m and 0.1 rad (``version_defaults``).
        **weights: the other reward weights and scales of :class:`~stewart_env.tasks.RewardWeights`.

    Raises:
        ValueError: an unknown option or one out of its range (the message names it).
    """

    name = "disturbance"
    version_defaults = {0: BASE_SCALE_OPTIONS}

    def __init__(
        self,
        params: PlatformParams,
        control_dt: float,
        *,
        sine_force=None,
        sine_moment=None,
        frequency_range=(0.2, 2.0),
        n_impulses: int = 2,
        impulse_force=None,
        impulse_moment=None,
        impulse_duration: float = 0.05,
        horizon: float = 5.0,
        position_reward_scale: float = PRECISE_REWARD_SCALES[0],
        orientation_reward_scale: float = PRECISE_REWARD_SCALES[1],
        **weights,
    ):
        weight = params.platform.mass * (float(np.linalg.norm(params.gravity)) or 9.81)
        radius = float(np.mean(np.linalg.norm(params.platform_joints[:, :2], axis=1)))
        max_force, max_moment = MAX_LOAD * weight, MAX_LOAD * weight * radius
        self.sine_force = (
            np.full(3, 0.2 * weight)
            if sine_force is None
            else vector(option("sine_force"), sine_force, 3, 0.0, max_force)
        )
        self.sine_moment = (
            np.full(3, 0.2 * weight * radius)
            if sine_moment is None
            else vector(option("sine_moment"), sine_moment, 3, 0.0, max_moment)
        )
        self.frequency_range = interval(option("frequency_range"), frequency_range, 0.0, MAX_FREQUENCY, low_open=True)
        self.n_impulses = integer(option("n_impulses"), n_impulses, 0, MAX_IMPULSES)
        self.impulse_force = (
            weight if impulse_force is None else real(option("impulse_force"), impulse_force, 0.0, max_force)
        )
        self.impulse_moment = (
            0.5 * weight * radius
            if impulse_moment is None
            else real(option("impulse_moment"), impulse_moment, 0.0, max_moment)
        )
        self.impulse_duration = real(option("impulse_duration"), impulse_duration, 0.0, MAX_HORIZON, low_open=True)
        self.horizon = real(option("horizon"), horizon, self.impulse_duration, MAX_HORIZON)
        self._home_rotation = rpy_to_matrix(params.home_rpy)
        super().__init__(
            params,
            control_dt,
            position_reward_scale=position_reward_scale,
            orientation_reward_scale=orientation_reward_scale,
            **weights,
        )

    def episode_fields(self):
        """The episode arrays (see :meth:`Task.episode_fields`): the target pose, the sinusoids' amplitudes, angular frequencies and phases, and the impulses' times and wrenches."""
        return {
            "target_position": (3,),
            "target_rotation": (3, 3),
            "sine_amplitude": (6,),
            "sine_omega": (6,),
            "sine_phase": (6,),
            "impulse_time": (self.n_impulses,),
            "impulse_wrench": (self.n_impulses, 6),
        }

    def initialize_episode(self, rng):
        """Draw one row's episode (see :meth:`Task.initialize_episode`): the start and target at home, the sinusoids and the impulses.

        Args:
            rng: the row's generator.
        """
        amplitude = rng.uniform(0.0, 1.0, 6) * np.concatenate([self.sine_force, self.sine_moment])
        omega = 2.0 * np.pi * rng.uniform(*self.frequency_range, 6)
        phase = rng.uniform(0.0, 2.0 * np.pi, 6)
        n = self.n_impulses
        times = rng.uniform(0.0, self.horizon - self.impulse_duration, n)
        directions = rng.normal(size=(n, 2, 3))
        directions /= np.linalg.norm(directions, axis=2, keepdims=True)
        magnitudes = rng.uniform(0.0, 1.0, (n, 2)) * (self.impulse_force, self.impulse_moment)
        wrench = (directions * magnitudes[:, :, None]).reshape(n, 6)
        p = self.params
        start = PlatformState(p.home_position.copy(), self._home_rotation.copy(), np.zeros(3), np.zeros(3))
        return start, {
            "target_position": p.home_position,
            "target_rotation": self._home_rotation,
            "sine_amplitude": amplitude,
            "sine_omega": omega,
            "sine_phase": phase,
            "impulse_time": times,
            "impulse_wrench": wrench,
        }

    def external_wrench(self, view, dt, out) -> None:
        """Write the wrench held over the step (see :meth:`Task.external_wrench`): the sinusoids averaged over the step plus the impulses' share of it.

        Args:
            view: the batch's :class:`StepView` at the step's start.
            dt: the step's length, s.
            out: (N,6) the wrench [F_ext at P, N; M_ext, N m] in {B}, written into.
        """
        episode, time = view.episode, view.time
        omega, phase = episode["sine_omega"], episode["sine_phase"]
        t0 = omega * time[:, None] + phase
        # Average of A sin(omega t + phi) over [t, t + dt].
        out[:] = episode["sine_amplitude"] * (np.cos(t0) - np.cos(t0 + omega * dt)) / (omega * dt)
        start = episode["impulse_time"]
        overlap = (
            np.minimum(time[:, None] + dt, start + self.impulse_duration) - np.maximum(time[:, None], start)
        ).clip(min=0.0) / dt
        for k in range(self.n_impulses):
            out += overlap[:, k : k + 1] * episode["impulse_wrench"][:, k]
