"""Metrics of motion cueing: how well the motion felt on the platform matches the vehicle's, and
the whole chain's gain and phase over frequency in the manner of the objective motion cueing test.

Both motions, the vehicle's and the one the person on the platform is subjected to at the head
(specific force f, m/s², and angular velocity omega, rad/s, in the head frame {H}), go through the
vestibular models (:mod:`stewart_env.tasks.cueing.vestibular`: the otolith on the specific
force's deviation from rest f - (0, 0, g), the semicircular canal on omega, each started steady
under its first sample).  With p the vehicle's perceived signal and q the platform's, sampled
every dt over an episode (:func:`cueing_metrics`):

* ``rms_specific_force_error`` (m/s²), ``rms_angular_velocity_error`` (rad/s): the root mean
  square over the samples of |p - q| (the norm over the three axes).
* ``specific_force_correlation``, ``angular_velocity_correlation``: Pearson's correlation of p
  and q over the samples and axes together, each axis about its own mean,
  sum_i cov(p_i, q_i) / sqrt(sum_i var(p_i) sum_i var(q_i)) (1: the same shape up to a gain;
  NaN when either is constant).
* ``specific_force_delay``, ``angular_velocity_delay`` (s): the lag of q behind p that maximises
  their cross-correlation coefficient over the overlap (the same sums over axes) within
  ``max_delay``, refined between samples by a parabola through the peak and its neighbours;
  positive when the platform's cue comes late.
* ``false_specific_force_cues``, ``false_angular_velocity_cues``: the false cues, runs of
  consecutive samples on an axis where the platform's perceived motion is above that axis's
  perception threshold (:data:`~stewart_env.tasks.cueing.vestibular.THRESHOLDS`) and of the wrong
  sign (q_i p_i <= 0: opposite to the vehicle's, or felt where the vehicle's is exactly zero),
  counted over the axes; ``false_cue_time`` (s): the samples' time on any axis of either channel.
* ``workspace_use``: the largest excursion of the platform's pose from the workspace box's middle,
  as a fraction of its half-range, over the six coordinates (position of P in the box, roll,
  pitch, yaw about home within ``max_angle``); 1 is the box's edge.
* ``stroke_use``: the largest excursion of a leg's length from the middle of its stroke, as a
  fraction of the half-stroke; 1 is an end stop.
* ``limit_hits``: the steps after which any platform constraint was violated (the environment's
  ``info["cost_<name>"]``, as the harness's limit hits).

The gain and phase table (:func:`frequency_response_table`) drives a chain (a callable from a
vehicle motion to the platform's motion at the head) with one sine per channel and frequency, as
the objective motion cueing test (OMCT, ICAO 9625 ed. 4, after Advani and Hosman) does at its
frequencies (:data:`OMCT_FREQUENCIES`), and fits the output's first harmonic at the input's
frequency over whole periods after the transient: gain = |Y| / |U| and phase = arg(Y / U) in
degrees (negative: the cue lags).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from stewart_env.errors import UsageError
from stewart_env.rotations import rpy_to_matrix
from stewart_env.tasks.cueing.motion import STANDARD_GRAVITY, VehicleMotion
from stewart_env.tasks.cueing.vestibular import THRESHOLDS, Otolith, SemicircularCanal, false_cue_samples

__all__ = [
    "CUEING_METRICS",
    "CHANNELS",
    "CUEING_COLUMNS",
    "CUEING_INFO_KEYS",
    "OMCT_FREQUENCIES",
    "ScheduledEpisodes",
    "correlation",
    "cueing_metrics",
    "cueing_table",
    "environment_chain",
    "episode_cueing_metrics",
    "is_cueing",
    "delay",
    "false_cues",
    "fit_harmonic",
    "frequency_response_table",
    "kinematic_head_motion",
    "perceive",
    "perceive_batch",
    "perceived_cueing_metrics",
    "rms_error",
    "sine_motion",
    "table_markdown",
]

#: The cueing metrics of an episode, in the order of the CSV's columns (module docstring).
CUEING_METRICS = (
    "rms_specific_force_error",
    "rms_angular_velocity_error",
    "specific_force_correlation",
    "angular_velocity_correlation",
    "specific_force_delay",
    "angular_velocity_delay",
    "false_specific_force_cues",
    "false_angular_velocity_cues",
    "false_cue_time",
    "workspace_use",
    "stroke_use",
    "limit_hits",
)

#: The OMCT's test frequencies, rad/s (ICAO 9625 ed. 4: 0.1 to 15.8 rad/s, a fifth of a decade apart).
OMCT_FREQUENCIES = tuple(float(f) for f in np.round(10.0 ** (np.arange(-5, 7) / 5.0), 3))

#: The six channels of a motion: the specific force's x, y, z and the angular velocity's roll, pitch, yaw.
CHANNELS = ("f_x", "f_y", "f_z", "omega_x", "omega_y", "omega_z")


def perceive(specific_force, angular_velocity, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The perceived motion (module docstring): the otolith on f - (0, 0, g), the canal on omega.

    Args:
        specific_force: (T, 3) m/s², in {H}.
        angular_velocity: (T, 3) rad/s, in {H}.
        dt: the sample period, s.

    Returns:
        (perceived specific force's deviation from rest (T, 3), perceived angular velocity (T, 3)).
    """
    deviation = np.array(specific_force, dtype=float, copy=True)
    deviation[:, 2] -= STANDARD_GRAVITY
    return Otolith().perceive(deviation, dt), SemicircularCanal().perceive(angular_velocity, dt)


def perceive_batch(specific_force, angular_velocity, lengths, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`perceive` of episodes side by side, in one pass over the samples: the same numbers,
    episode by episode (the vestibular filters give each element of a batch its own numbers, bit
    for bit).

    Args:
        specific_force: (N, T, 3) m/s², in {H}; episode i's samples are its first ``lengths[i]``.
        angular_velocity: (N, T, 3) rad/s.
        lengths: (N,) each episode's samples, 1 to T.
        dt: the sample period, s.

    Returns:
        (perceived specific force's deviation from rest (N, T, 3), perceived angular velocity
        (N, T, 3)); past an episode's length, its last sample held.
    """
    f = np.array(specific_force, dtype=float, copy=True)
    w = np.array(angular_velocity, dtype=float, copy=True)
    n, t = f.shape[:2]
    for i, length in enumerate(np.asarray(lengths, dtype=np.int64).tolist()):
        f[i, length:] = f[i, length - 1]
        w[i, length:] = w[i, length - 1]
    f[..., 2] -= STANDARD_GRAVITY
    otolith, canal = Otolith().discretize(dt), SemicircularCanal().discretize(dt)
    otolith.reset(f[:, 0])
    canal.reset(w[:, 0])
    out_f, out_w = np.empty_like(f), np.empty_like(w)
    for k in range(t):
        out_f[:, k] = otolith.step(f[:, k])
        out_w[:, k] = canal.step(w[:, k])
    return out_f, out_w


def rms_error(reference, signal) -> float:
    """The root mean square over the samples of the error vector's norm |reference - signal|.

    Args:
        reference: (T, 3).
        signal: (T, 3).

    Returns:
        The RMS, in the signals' unit.
    """
    error = np.asarray(reference, dtype=float) - np.asarray(signal, dtype=float)
    return float(np.sqrt(np.mean(np.sum(error * error, axis=1))))


def _centred(x) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    x = x[:, None] if x.ndim == 1 else x
    return x - x.mean(axis=0)


def correlation(reference, signal) -> float:
    """Pearson's correlation of two signals over the samples and axes, each axis about its mean.

    Args:
        reference: (T,) or (T, k).
        signal: the same shape.

    Returns:
        sum_i cov_i / sqrt(sum_i var(reference_i) sum_i var(signal_i)); NaN when either is constant.
    """
    a, b = _centred(reference), _centred(signal)
    scale = math.sqrt(float(np.sum(a * a)) * float(np.sum(b * b)))
    return float(np.sum(a * b)) / scale if scale > 0.0 else math.nan


def delay(reference, signal, dt: float, max_delay: float = 1.0) -> float:
    """The lag of ``signal`` behind ``reference`` that maximises their cross-correlation, s.

    Args:
        reference: (T,) or (T, k), the leading signal.
        signal: the same shape, the one that may lag.
        dt: the sample period, s.
        max_delay: the largest lag searched either way, s.

    Returns:
        The lag (s), refined between samples by a parabola through the peak; positive when
        ``signal`` comes after ``reference``; NaN when either is constant.
    """
    a, b = _centred(reference), _centred(signal)
    if not np.any(a) or not np.any(b):
        return math.nan
    n = len(a)
    most = max(1, min(n - 1, int(round(max_delay / dt))))
    lags = np.arange(-most, most + 1)
    # c(k): the correlation coefficient of a(t) and b(t + k) over their overlap, which Cauchy-Schwarz
    # bounds by 1, reached at the lag of an exact delay however the signals' power varies in time
    c = np.array([_overlap_correlation(a[max(0, -k) : n - max(0, k)], b[max(0, k) : n - max(0, -k)]) for k in lags])
    j = int(np.argmax(c))
    shift = 0.0
    if 0 < j < len(c) - 1:
        denominator = c[j - 1] - 2.0 * c[j] + c[j + 1]
        if denominator < 0.0:
            shift = 0.5 * (c[j - 1] - c[j + 1]) / denominator
    return float((lags[j] + shift) * dt)


def _overlap_correlation(a: np.ndarray, b: np.ndarray) -> float:
    scale = math.sqrt(float(np.sum(a * a)) * float(np.sum(b * b)))
    return float(np.sum(a * b)) / scale if scale > 0.0 else -math.inf


def false_cues(reference, signal, threshold) -> tuple[int, np.ndarray]:
    """False cues: runs of samples where ``signal`` is above the threshold with the wrong sign.

    Args:
        reference: (T, k), the vehicle's perceived signal.
        signal: (T, k), the platform's perceived signal.
        threshold: (k,) the perception thresholds per axis.

    Returns:
        (the number of runs of consecutive false samples, summed over the axes; the (T, k) mask
        of the false samples).
    """
    false = false_cue_samples(reference, signal, threshold)
    starts = false & ~np.vstack([np.zeros((1, false.shape[1]), dtype=bool), false[:-1]])
    return int(starts.sum()), false


def cueing_metrics(
    dt: float,
    vehicle_specific_force,
    vehicle_angular_velocity,
    head_specific_force,
    head_angular_velocity,
    pose_fraction=None,
    leg_fraction=None,
    limit_hits: int = 0,
    max_delay: float = 1.0,
) -> dict[str, float]:
    """The cueing metrics of one episode (module docstring).

    Args:
        dt: the sample period, s.
        vehicle_specific_force: (T, 3) the vehicle's specific force at the head, m/s².
        vehicle_angular_velocity: (T, 3) its angular velocity, rad/s.
        head_specific_force: (T, 3) the platform's specific force at the head point, m/s².
        head_angular_velocity: (T, 3) its angular velocity, rad/s.
        pose_fraction: (T', 6) the pose's excursions as fractions of the workspace's half-ranges,
            or None (workspace_use NaN).
        leg_fraction: (T', 6) the legs' excursions as fractions of the half-stroke, or None.
        limit_hits: the steps after which a constraint was violated.
        max_delay: the largest delay searched, s.

    Returns:
        The metrics by name, the names of :data:`CUEING_METRICS`.
    """
    vf, vw = perceive(vehicle_specific_force, vehicle_angular_velocity, dt)
    hf, hw = perceive(head_specific_force, head_angular_velocity, dt)
    return perceived_cueing_metrics(dt, vf, vw, hf, hw, pose_fraction, leg_fraction, limit_hits, max_delay)


def perceived_cueing_metrics(
    dt: float, vf, vw, hf, hw, pose_fraction=None, leg_fraction=None, limit_hits: int = 0, max_delay: float = 1.0
) -> dict[str, float]:
    """:func:`cueing_metrics` of the perceived signals (:func:`perceive`'s outputs, computed once
    for a batch of episodes by :func:`perceive_batch`).

    Args:
        dt: the sample period, s.
        vf: (T, 3) the vehicle's perceived specific force's deviation from rest, m/s².
        vw: (T, 3) its perceived angular velocity, rad/s.
        hf: (T, 3) the platform's perceived specific force's deviation from rest, m/s².
        hw: (T, 3) its perceived angular velocity, rad/s.
        pose_fraction: as :func:`cueing_metrics`.
        leg_fraction: as :func:`cueing_metrics`.
        limit_hits: as :func:`cueing_metrics`.
        max_delay: as :func:`cueing_metrics`.

    Returns:
        The metrics by name, the names of :data:`CUEING_METRICS`.
    """
    f_cues, f_mask = false_cues(vf, hf, THRESHOLDS["specific_force"])
    w_cues, w_mask = false_cues(vw, hw, THRESHOLDS["angular_velocity"])
    return {
        "rms_specific_force_error": rms_error(vf, hf),
        "rms_angular_velocity_error": rms_error(vw, hw),
        "specific_force_correlation": correlation(vf, hf),
        "angular_velocity_correlation": correlation(vw, hw),
        "specific_force_delay": delay(vf, hf, dt, max_delay),
        "angular_velocity_delay": delay(vw, hw, dt, max_delay),
        "false_specific_force_cues": float(f_cues),
        "false_angular_velocity_cues": float(w_cues),
        "false_cue_time": float((f_mask.any(axis=1) | w_mask.any(axis=1)).sum() * dt),
        "workspace_use": _largest(pose_fraction),
        "stroke_use": _largest(leg_fraction),
        "limit_hits": float(limit_hits),
    }


def _largest(fraction) -> float:
    if fraction is None:
        return math.nan
    values = np.abs(np.asarray(fraction, dtype=float))
    return float(values.max()) if values.size else math.nan


#: The step infos of the cueing task that the metrics read (each (N, 3) or (N,) per step).
CUEING_INFO_KEYS = (
    "vehicle_specific_force",
    "vehicle_angular_velocity",
    "head_specific_force",
    "head_angular_velocity",
    "workspace_use",
    "stroke_use",
)


def is_cueing(env_kwargs) -> bool:
    """Whether an environment configuration runs the cueing task.

    Args:
        env_kwargs: the environment's keywords.

    Returns:
        True for ``task="cueing"``.
    """
    return str(dict(env_kwargs or {}).get("task", "")) == "cueing"


def episode_cueing_metrics(dt: float, steps: dict, limit_hits: int) -> dict[str, float]:
    """The cueing metrics of one episode from its step infos (:data:`CUEING_INFO_KEYS`).

    Args:
        dt: the control step, s.
        steps: info key -> the episode's values over its steps, (T, 3) or (T,); the workspace and
            stroke use, when present, are the task's fractions of the limits.
        limit_hits: the steps after which a constraint was violated.

    Returns:
        The metrics of :data:`CUEING_METRICS`.
    """
    fraction = {
        k: None if steps.get(k) is None else np.asarray(steps[k])[:, None] for k in ("workspace_use", "stroke_use")
    }
    return cueing_metrics(
        dt,
        steps["vehicle_specific_force"],
        steps["vehicle_angular_velocity"],
        steps["head_specific_force"],
        steps["head_angular_velocity"],
        pose_fraction=fraction["workspace_use"],
        leg_fraction=fraction["stroke_use"],
        limit_hits=limit_hits,
    )


#: The cueing metrics as the reports show them: title, factor from SI, format.
CUEING_COLUMNS = {
    "rms_specific_force_error": ("RMS f err. (m/s²)", 1.0, ".3g"),
    "rms_angular_velocity_error": ("RMS ω err. (deg/s)", 180.0 / math.pi, ".3g"),
    "specific_force_correlation": ("corr. f", 1.0, ".3f"),
    "angular_velocity_correlation": ("corr. ω", 1.0, ".3f"),
    "specific_force_delay": ("delay f (ms)", 1e3, ".3g"),
    "angular_velocity_delay": ("delay ω (ms)", 1e3, ".3g"),
    "false_specific_force_cues": ("false cues f", 1.0, ".3g"),
    "false_angular_velocity_cues": ("false cues ω", 1.0, ".3g"),
    "false_cue_time": ("false cue time (s)", 1.0, ".3g"),
    "workspace_use": ("workspace use", 1.0, ".2f"),
    "stroke_use": ("stroke use", 1.0, ".2f"),
    "limit_hits": ("limit hits (steps)", 1.0, ".3g"),
}


def cueing_table(rows: Sequence[tuple[str, str, dict[str, float]]]) -> str:
    """A Markdown table of the mean cueing metrics, one row per controller.

    Args:
        rows: (controller, model, {metric: mean}) per result.

    Returns:
        The table's text.
    """
    head = ["controller", "model"] + [title for title, _, _ in CUEING_COLUMNS.values()]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for label, model, means in rows:
        cells = [label, model]
        for key, (_, factor, spec) in CUEING_COLUMNS.items():
            value = means.get(key, math.nan)
            cells.append("-" if not math.isfinite(value) else format(value * factor, spec))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


# -- the whole chain over frequency ----------------------------------------------------------------


def sine_motion(
    channel: str, frequency: float, amplitude: float, dt: float, periods: float = 6.0, settle: float = 20.0
) -> VehicleMotion:
    """A vehicle motion with one sine on one channel, at rest otherwise (f = (0, 0, g)).

    Args:
        channel: one of :data:`CHANNELS`.
        frequency: rad/s.
        amplitude: m/s² for the specific force's channels, rad/s for the angular velocity's.
        dt: the sample period, s.
        periods: the periods after ``settle`` that the fit uses.
        settle: the time left for the chain's transient, s.

    Returns:
        The motion, ``meta`` holding the channel, frequency, amplitude and the fit's first sample.

    Raises:
        UsageError: an unknown channel or a non-positive frequency, amplitude or dt.
    """
    if channel not in CHANNELS:
        raise UsageError.about("channel", f"must be one of {list(CHANNELS)}, got {channel!r}")
    for name, value in (("frequency", frequency), ("amplitude", amplitude), ("dt", dt)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise UsageError.about(name, f"must be a finite positive number, got {value!r}")
    period = 2.0 * math.pi / frequency
    first = int(math.ceil(settle / dt))
    n = first + int(math.ceil(periods * period / dt)) + 1
    t = np.arange(n) * dt
    f = np.zeros((n, 3))
    f[:, 2] = STANDARD_GRAVITY
    w = np.zeros((n, 3))
    axis = CHANNELS.index(channel)
    # a sine from zero, so that the start is continuous
    (f if axis < 3 else w)[:, axis % 3] += amplitude * np.sin(frequency * t)
    meta = {"channel": channel, "frequency": frequency, "amplitude": amplitude, "fit_from": first}
    return VehicleMotion(f"sine_{channel}", dt, f, w, source="sine_motion", meta=meta)


def fit_harmonic(signal, dt: float, frequency: float, first: int = 0) -> complex:
    """The complex amplitude Y of the first harmonic, signal ~ Re(Y e^{j w t}) + mean, by least squares.

    Args:
        signal: (T,) samples at t = k dt.
        dt: the sample period, s.
        frequency: w, rad/s.
        first: the first sample used; the fit takes whole periods from there when it can.

    Returns:
        Y, with |Y| the amplitude and arg(Y) the phase relative to cos(w t).
    """
    y = np.asarray(signal, dtype=float)[first:]
    t = (first + np.arange(len(y))) * dt
    whole = int(math.floor(len(y) * dt * frequency / (2.0 * math.pi)) * 2.0 * math.pi / frequency / dt)
    if whole >= 3:
        y, t = y[: whole + 1], t[: whole + 1]
    basis = np.stack([np.cos(frequency * t), -np.sin(frequency * t), np.ones_like(t)], axis=1)
    c = np.linalg.lstsq(basis, y, rcond=None)[0]
    return complex(c[0], c[1])


def frequency_response_table(
    chain: Callable[[VehicleMotion], tuple[np.ndarray, np.ndarray]],
    channels: Sequence[str] = CHANNELS,
    frequencies: Sequence[float] = OMCT_FREQUENCIES,
    amplitudes: dict[str, float] | None = None,
    dt: float = 0.01,
    periods: float = 6.0,
    settle: float = 20.0,
) -> list[dict]:
    """The whole chain's gain and phase per channel and frequency (module docstring).

    Args:
        chain: vehicle motion -> the platform's (specific force (T, 3), angular velocity (T, 3))
            at the head, sampled as the motion (e.g. an environment run of a cueing policy, or
            :func:`kinematic_head_motion` of a washout).
        channels: the channels driven, of :data:`CHANNELS`.
        frequencies: rad/s.
        amplitudes: per channel, the input's amplitude (default 1 m/s² and 0.1 rad/s: inside a
            small platform's reach at the OMCT's middle frequencies).
        dt: the sample period, s.
        periods: the whole periods the fit uses, after ``settle`` (:func:`sine_motion`).
        settle: the time left for the chain's transient before the fit, s.

    Returns:
        One row per channel and frequency: channel, frequency (rad/s), gain, phase (deg).
    """
    rows = []
    for channel in channels:
        axis = CHANNELS.index(channel) if channel in CHANNELS else None
        if axis is None:
            raise UsageError.about("channels", f"unknown channel {channel!r}; known: {list(CHANNELS)}")
        default = 1.0 if axis < 3 else 0.1
        amplitude = float((amplitudes or {}).get(channel, default))
        for frequency in frequencies:
            motion = sine_motion(channel, float(frequency), amplitude, dt, periods, settle)
            head_f, head_w = chain(motion)
            output = np.asarray(head_f if axis < 3 else head_w, dtype=float)[:, axis % 3]
            source = (motion.specific_force if axis < 3 else motion.angular_velocity)[:, axis % 3]
            first = motion.meta["fit_from"]
            ratio = fit_harmonic(output, dt, frequency, first) / fit_harmonic(source, dt, frequency, first)
            rows.append(
                {
                    "channel": channel,
                    "frequency": float(frequency),
                    "gain": abs(ratio),
                    "phase": math.degrees(math.atan2(ratio.imag, ratio.real)),
                }
            )
    return rows


def table_markdown(rows: Sequence[dict]) -> str:
    """The gain and phase table as Markdown: one row per frequency, gain and phase per channel.

    Args:
        rows: the rows of :func:`frequency_response_table`.

    Returns:
        The table's text.
    """
    channels = list(dict.fromkeys(r["channel"] for r in rows))
    frequencies = sorted({r["frequency"] for r in rows})
    cell = {(r["channel"], r["frequency"]): r for r in rows}
    head = "| w (rad/s) | " + " | ".join(f"{c} gain | {c} phase (deg)" for c in channels) + " |"
    rule = "|---:|" + "---:|---:|" * len(channels)
    lines = [head, rule]
    for w in frequencies:
        values = []
        for c in channels:
            r = cell.get((c, w))
            values += [f"{r['gain']:.3g}", f"{r['phase']:.1f}"] if r else ["", ""]
        lines.append(f"| {w:g} | " + " | ".join(values) + " |")
    return "\n".join(lines) + "\n"


def kinematic_head_motion(displacement, rpy, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The specific force and angular velocity at the head of a cabin that follows a pose exactly.

    The head is at ``displacement`` (in {H} at home) and the cabin at the roll-pitch-yaw ``rpy``
    relative to home: f = R^T (a + (0, 0, g)) with a the displacement's second derivative, and
    omega from R^T dR/dt, both by central differences (one-sided at the ends): what the cueing
    algorithm alone renders, before the platform's dynamics and limits.

    Args:
        displacement: (T, 3) m.
        rpy: (T, 3) rad.
        dt: the sample period, s.

    Returns:
        (specific force (T, 3) m/s², angular velocity (T, 3) rad/s) in the cabin's frame.
    """
    p = np.asarray(displacement, dtype=float)
    rotation = rpy_to_matrix(np.asarray(rpy, dtype=float))
    velocity = np.gradient(p, dt, axis=0)
    acceleration = np.gradient(velocity, dt, axis=0)
    acceleration[:, 2] += STANDARD_GRAVITY
    f = np.einsum("tji,tj->ti", rotation, acceleration)
    rate = np.gradient(rotation, dt, axis=0)
    skew = np.einsum("tji,tjk->tik", rotation, rate)  # R^T dR/dt = [omega]x in the cabin's frame
    w = np.stack([skew[:, 2, 1] - skew[:, 1, 2], skew[:, 0, 2] - skew[:, 2, 0], skew[:, 1, 0] - skew[:, 0, 1]], axis=1)
    return f, 0.5 * w


def environment_chain(policy, env_kwargs: dict | None = None, folder=None):
    """The whole chain as a callable for :func:`frequency_response_table`: the motion written as a
    motion file, one episode of the cueing task on it with ``policy``, the platform's motion at
    the head read from the step infos.

    Args:
        policy: an object with SB3's ``predict`` (and optionally ``reset``), or a callable env ->
            such an object, as :func:`~stewart_env.agents.evaluation.evaluation.evaluate` takes.
        env_kwargs: the environment's keywords besides the task and its ``motions`` option
            (e.g. ``{"action_mode": "pose"}`` for washout).
        folder: where the motion files go (default a temporary folder per call).

    Returns:
        motion -> (head specific force (T, 3), head angular velocity (T, 3)), the first sample at
        rest, then one per control step (the motion's sample period must be the control step);
        after an episode the platform's limits ended, the last sample held to T.  The callable's
        attribute ``played`` is the control steps its last call played (T - 1 unless the limits
        ended the episode).
    """
    import tempfile
    from pathlib import Path

    import gymnasium as gym

    from stewart_env.registration import ENV_ID
    from stewart_env.tasks.cueing.motions import write_motion

    def chain(motion: VehicleMotion) -> tuple[np.ndarray, np.ndarray]:
        with tempfile.TemporaryDirectory(dir=folder) as tmp:
            path = write_motion(motion, Path(tmp) / f"{motion.name}.csv")
            kwargs = dict(env_kwargs or {})
            options = {**kwargs.pop("task_options", {}), "motions": str(path)}
            env = gym.make(
                ENV_ID, task="cueing", task_options=options, max_episode_steps=motion.n_samples - 1, **kwargs
            )
            agent = policy(env) if callable(policy) and not hasattr(policy, "predict") else policy
            if callable(getattr(agent, "reset", None)):
                agent.reset()
            obs, _ = env.reset(seed=0)
            rest = np.array([0.0, 0.0, STANDARD_GRAVITY])
            head_f, head_w = [rest], [np.zeros(3)]
            for _ in range(motion.n_samples - 1):
                action, _ = agent.predict(obs, deterministic=True)
                obs, _, terminated, truncated, info = env.step(action)
                head_f.append(np.asarray(info["head_specific_force"], dtype=float))
                head_w.append(np.asarray(info["head_angular_velocity"], dtype=float))
                if terminated or truncated:
                    break
            env.close()
        chain.played = len(head_f) - 1
        n = motion.n_samples
        f = np.tile(head_f[-1], (n, 1))
        w = np.tile(head_w[-1], (n, 1))
        f[: len(head_f)], w[: len(head_w)] = head_f, head_w
        return f, w

    chain.played = 0
    return chain


class ScheduledEpisodes:
    """Given cueing episodes side by side, one row each of the native vector environment (the
    task's :meth:`~stewart_env.tasks.cueing.task.CueingTask.schedule`), each run until its motion
    ends or the platform's limits end it, scored by :func:`episode_cueing_metrics`: what a washout's
    tuning and a comparison of cueing agents on given manoeuvres run.

    Args:
        episodes: the (motion name, seed) pairs of built-in motions, one row each.
        env_kwargs: the environment's keywords besides ``task`` (``task_options`` without ``motions``).

    Raises:
        UsageError: no episodes, an unknown motion or a bad seed (the message names ``episodes``).
    """

    def __init__(self, episodes: Sequence[tuple[str, int]], env_kwargs: dict | None = None):
        from stewart_env.envs.vector import StewartPlatformVectorEnv

        self.episodes = [(str(name), seed) for name, seed in episodes]
        if not self.episodes:
            raise UsageError.about("episodes", "give at least one (motion, seed) pair")
        kwargs = dict(env_kwargs or {})
        names = tuple(dict.fromkeys(name for name, _ in self.episodes))
        # training_seeds=1: a row that ends before the others restarts on one motion, generated once
        # (its steps are not scored)
        options = {**kwargs.pop("task_options", {}), "motions": names, "training_seeds": 1}
        self.env = StewartPlatformVectorEnv(num_envs=len(self.episodes), task="cueing", task_options=options, **kwargs)
        task = self.env.task
        task.schedule(self.episodes)  # checks the pairs before a run
        self.steps = np.array([len(task.motion_of(task.motion_names.index(m), s)) - 1 for m, s in self.episodes])
        self.dt = self.env.dt

    def run(self, policy, traces: bool = False) -> list[dict]:
        """Every episode once, side by side, the environment reset with seed 0.

        Args:
            policy: an object with SB3's ``predict`` (and optionally ``reset``), or a callable
                env -> such an object.
            traces: also return each episode's step signals (the :data:`CUEING_INFO_KEYS`).

        Returns:
            Per episode, the cueing metrics, ``failed`` (1.0 when the platform's limits ended it
            before its motion's end, else 0.0), ``played`` (the share of the motion's steps
            played) and, with ``traces``, ``traces``: key -> (T, 3) or (T,) values over its steps.
        """
        env, n = self.env, len(self.episodes)
        env.task.schedule(self.episodes)
        agent = policy(env) if callable(policy) and not hasattr(policy, "predict") else policy
        obs, _ = env.reset(seed=0)
        if callable(getattr(agent, "reset", None)):
            agent.reset()
        alive = np.ones(n, dtype=bool)
        length = self.steps.copy()
        failed = np.zeros(n)
        record: dict[str, list[np.ndarray]] = {key: [] for key in CUEING_INFO_KEYS}
        hits: list[np.ndarray] = []
        k = 0
        while alive.any():
            action, _ = agent.predict(obs, deterministic=True)
            obs, _, terminated, truncated, info = env.step(np.asarray(action, dtype=np.float32))
            for key in CUEING_INFO_KEYS:
                record[key].append(np.array(info[key], dtype=float))
            costs = [np.asarray(info[key]) > 0 for key in info if key.startswith("cost_")]
            hits.append(np.any(costs, axis=0) if costs else np.zeros(n, dtype=bool))
            k += 1
            for i in np.flatnonzero(alive & (terminated | truncated)):
                length[i] = k
                failed[i] = float(env.termination_reasons[int(info["termination"][i])] != "motion_end")
            alive &= ~(terminated | truncated)
        arrays = {key: np.stack(v, axis=1) for key, v in record.items()}
        limit_hits = np.stack(hits, axis=1)
        # both motions of every episode perceived in one pass over the steps
        perceived_f, perceived_w = perceive_batch(
            np.concatenate([arrays["vehicle_specific_force"], arrays["head_specific_force"]]),
            np.concatenate([arrays["vehicle_angular_velocity"], arrays["head_angular_velocity"]]),
            np.concatenate([length, length]),
            self.dt,
        )
        rows = []
        for i in range(n):
            t = int(length[i])
            steps = {key: value[i, :t] for key, value in arrays.items()}
            metrics: dict = perceived_cueing_metrics(
                self.dt,
                perceived_f[i, :t],
                perceived_w[i, :t],
                perceived_f[n + i, :t],
                perceived_w[n + i, :t],
                pose_fraction=steps["workspace_use"][:, None],
                leg_fraction=steps["stroke_use"][:, None],
                limit_hits=int(limit_hits[i, :t].sum()),
            )
            metrics.update(failed=float(failed[i]), played=t / max(int(self.steps[i]), 1))
            if traces:
                metrics["traces"] = steps
            rows.append(metrics)
        return rows

    def close(self) -> None:
        """Close the environment."""
        self.env.close()
