"""Tracking: follow a multi-axis sinusoidal reference about the home pose."""

from __future__ import annotations

import itertools

import numpy as np

from stewart_env.params import PlatformParams
from stewart_env.rotations import rotation_error
from stewart_env.state import PlatformState, Reference
from stewart_env.tasks.base import (
    BASE_SCALE_OPTIONS,
    MAX_FREQUENCY,
    PRECISE_REWARD_SCALES,
    Scales,
    StepView,
    Task,
    motion_ranges,
    option,
    pose_margins,
    sinusoid_reference,
    zero_reference,
)
from stewart_env.validation import integer, interval, real

# Amplitudes that put a corner of the reference's range outside the limits are scaled down by this
# factor until every corner fits.
_SHRINK = 0.8
_MAX_SHRINKS = 50
#: Bounds of the options: frequencies in (0, MAX_FREQUENCY] Hz, at most MAX_PREVIEW samples, at
#: most MAX_PREVIEW_INTERVAL s apart.
MAX_PREVIEW = 100
MAX_PREVIEW_INTERVAL = 100.0


class TrackingTask(Task):
    """Follow a reference that moves every axis sinusoidally about home.

    Each episode draws, for each of x, y, z, roll, pitch, yaw (k = 1..6), an amplitude a_k
    uniformly in [0, max amplitude], a frequency f_k uniformly in frequency_range and a phase
    phi_k uniformly in [0, 2 pi); the reference pose is home + a_k sin(2 pi f_k t + phi_k) on each
    axis (angles as roll-pitch-yaw).  The episode's amplitudes are bounded to the limits: while
    any of the 64 corners of the range home +- a (every axis at an extreme at once) is not safely
    inside the workspace, the stroke and the condition bound (10 % margins), all amplitudes are
    scaled by 0.8.  The platform starts on the reference (pose and twist at t = 0).

    Observation terms beyond position and orientation error: velocity_error (3) m/s,
    angular_velocity_error (3) rad/s, and reference_preview (6 x preview): for each future
    sample j, the position of the reference minus the platform's position (3, m, {B}) and the
    rotation vector of R_ref(t + j dt) R^T (3, rad, {B}).

    The options are the environment's ``task_options``.

    Args:
        params: the platform's nominal parameters.
        control_dt: the control step, s.
        position_amplitude: (3,) m or one number: max amplitude on x, y, z, at most the
            workspace half-size; default 0.4 x the workspace half-size (dasgupta1998: 0.1, 0.1, 0.06).
        angle_amplitude: (3,) rad or one number: max amplitude on roll, pitch, yaw, at most
            limits.max_angle; default 0.4 x limits.max_angle (dasgupta1998: 0.2).
        frequency_range: (min, max) Hz, 0 < min <= max <= 1000, default (0.1, 0.5).
        preview: number of future reference samples observed (0-100), default 3.
        preview_interval: s between them (at most 100), default 0.1 (samples at t + 0.1, 0.2, 0.3 s).
        position_reward_scale, orientation_reward_scale: sharper than the other tasks' by
            default, 0.01 m and 0.02 rad (``PRECISE_REWARD_SCALES``), so that millimetre errors
            weigh in the reward; under the environment's version 0 (``StewartPlatform-v0``) the
            other tasks' 0.05 m and 0.1 rad (``version_defaults``).
        **weights: the other reward weights and scales of :class:`~stewart_env.tasks.RewardWeights`.

    Raises:
        ValueError: an unknown option or one out of its range (the message names it).
    """

    name = "tracking"
    version_defaults = {0: BASE_SCALE_OPTIONS}

    def __init__(
        self,
        params: PlatformParams,
        control_dt: float,
        *,
        position_amplitude=None,
        angle_amplitude=None,
        frequency_range=(0.1, 0.5),
        preview: int = 3,
        preview_interval: float = 0.1,
        position_reward_scale: float = PRECISE_REWARD_SCALES[0],
        orientation_reward_scale: float = PRECISE_REWARD_SCALES[1],
        **weights,
    ):
        super().__init__(
            params,
            control_dt,
            position_reward_scale=position_reward_scale,
            orientation_reward_scale=orientation_reward_scale,
            **weights,
        )
        self.position_amplitude, self.angle_amplitude = motion_ranges(
            params, position_amplitude, angle_amplitude, ("position_amplitude", "angle_amplitude")
        )
        self.frequency_range = interval(option("frequency_range"), frequency_range, 0.0, MAX_FREQUENCY, low_open=True)
        self.preview = integer(option("preview"), preview, 0, MAX_PREVIEW)
        self.preview_interval = real(
            option("preview_interval"), preview_interval, 0.0, MAX_PREVIEW_INTERVAL, low_open=True
        )
        self._corners = np.array(list(itertools.product((-1.0, 1.0), repeat=6)))

    def episode_fields(self):
        """The episode arrays (see :meth:`Task.episode_fields`): the sinusoids' amplitudes, angular frequencies and phases."""
        return {"amplitude": (6,), "omega": (6,), "phase": (6,)}

    def _bounded(self, amplitude: np.ndarray) -> np.ndarray:
        p = self.params
        for _ in range(_MAX_SHRINKS):
            offsets = self._corners * amplitude
            if np.all(pose_margins(self.kinematics, p.home_position + offsets[:, :3], p.home_rpy + offsets[:, 3:])):
                return amplitude
            amplitude = _SHRINK * amplitude
        raise RuntimeError(f"tracking: no amplitude fits the limits of platform {p.name!r}")

    def initialize_episode(self, rng):
        """Draw one row's episode (see :meth:`Task.initialize_episode`): sinusoids within the limits, the start on the reference at t = 0.

        Args:
            rng: the row's generator.
        """
        max_amplitude = np.concatenate([self.position_amplitude, self.angle_amplitude])
        amplitude = self._bounded(rng.uniform(0.0, 1.0, 6) * max_amplitude)
        omega = 2.0 * np.pi * rng.uniform(*self.frequency_range, 6)
        phase = rng.uniform(0.0, 2.0 * np.pi, 6)
        episode = {"amplitude": amplitude, "omega": omega, "phase": phase}
        ref = zero_reference(1)
        self.reference({k: v[None] for k, v in episode.items()}, np.zeros(1), ref)
        return PlatformState(ref.position[0], ref.rotation[0], ref.velocity[0], ref.angular_velocity[0]), episode

    def reference(self, episode, time, out: Reference) -> None:
        """Write the sinusoidal reference at ``time`` (see :func:`sinusoid_reference`).

        Args:
            episode: the episode arrays, name -> (N, ...).
            time: (N,) s, the rows' times.
            out: the :class:`Reference` (N rows) written into.
        """
        p = self.params
        sinusoid_reference(
            p.home_position, p.home_rpy, episode["amplitude"], episode["omega"], episode["phase"], time, out
        )

    def observation_terms(self, scales: Scales):
        """The pose errors, the velocity errors and, with a preview, the reference's future poses.

        Args:
            scales: the platform's :class:`Scales`.
        """
        angle = np.full(3, scales.angle)
        terms = super().observation_terms(scales)
        terms += [("velocity_error", scales.position.copy()), ("angular_velocity_error", angle.copy())]
        if self.preview:
            terms.append(("reference_preview", np.tile(np.concatenate([scales.position, angle]), self.preview)))
        return terms

    def observe(self, view: StepView, out) -> None:
        """Write the terms of :meth:`observation_terms` into ``out``.

        Args:
            view: the batch's :class:`StepView`.
            out: the terms' arrays, name -> (N, size).
        """
        super().observe(view, out)
        out["velocity_error"][:] = view.errors.velocity
        out["angular_velocity_error"][:] = view.errors.angular_velocity
        if not self.preview:
            return
        state, episode, time = view.state, view.episode, view.time
        n, k = time.shape[0], self.preview
        # All preview samples of all rows as one batch of n * k rows (row-major: row i, sample j).
        future = (time[:, None] + self.preview_interval * np.arange(1, k + 1)).reshape(n * k)
        ep = {name: np.repeat(v, k, axis=0) for name, v in episode.items()}
        ref = zero_reference(n * k)
        self.reference(ep, future, ref)
        preview = np.empty((n, k, 6))
        preview[:, :, :3] = ref.position.reshape(n, k, 3) - state.position[:, None, :]
        phi, _ = rotation_error(ref.rotation, np.repeat(state.rotation, k, axis=0))
        preview[:, :, 3:] = phi.reshape(n, k, 3)
        out["reference_preview"][:] = preview.reshape(n, 6 * k)
