"""The objective motion cueing test (OMCT) on the platform's whole chain: a cueing policy in the
cueing environment, the platform's dynamics and limits, the motion at the head and the vestibular
models, driven by one sine per channel and frequency.

The OMCT (ICAO 9625 ed. 4, after Advani and Hosman) drives a simulator's motion system with one
sine at a time on each of the six channels (specific force x, y, z; angular velocity roll, pitch,
yaw) at its test frequencies (:data:`~stewart_env.agents.evaluation.cueing.OMCT_FREQUENCIES`, 0.1
to 15.8 rad/s) and reports the gain and phase of the motion the pilot is subjected to against the
input.  :func:`omct_rows` runs each sine as a motion file through one cueing episode
(:func:`~stewart_env.agents.evaluation.cueing.environment_chain`) and fits the first harmonic
(:func:`~stewart_env.agents.evaluation.cueing.frequency_response_table`): ``gain`` and ``phase``
are the head's motion against the vehicle's; ``perceived_gain`` and ``perceived_phase`` the
platform's perceived motion against the vehicle's perceived motion (both through
:func:`~stewart_env.agents.evaluation.cueing.perceive`).  The vestibular models are linear and
the same on both sides, so where the chain is linear the two agree; where they differ the
platform's limits, rate limits or the tilt's nonlinearity shaped the cue.  ``played`` is the
share of the sine's steps the episode played: below 1, the platform's limits ended it and the
last sample is held.

:func:`write_omct` writes ``omct.csv`` (one line per channel and frequency) and ``omct.md`` (the
gain and phase table, the machine and date).  From a shell, ``stewart-env evaluate --task cueing
--omct`` (:mod:`stewart_env.cli.evaluate`) runs the tuned washout through it.
"""

from __future__ import annotations

import csv
import datetime
import math
from collections.abc import Sequence
from pathlib import Path

from stewart_env.agents.evaluation.cueing import (
    CHANNELS,
    OMCT_FREQUENCIES,
    environment_chain,
    fit_harmonic,
    frequency_response_table,
    perceive,
    table_markdown,
)

__all__ = ["OMCT_COLUMNS", "OMCT_PERIODS", "OMCT_SETTLE", "omct_markdown", "omct_rows", "write_omct"]

#: The whole periods of each sine the fit uses: two keep the lowest frequency's run at 146 s of motion.
OMCT_PERIODS = 2.0
#: The time left for the chain's transient before the fit, s.  With two periods after it, the tuned
#: washout's gains on the kinematic chain are within 0.01 of a fit of six periods after 150 s at
#: every OMCT frequency and channel (the slowest filter, yaw's high-pass at 0.11 rad/s, the worst).
OMCT_SETTLE = 20.0
#: The columns of ``omct.csv``.
OMCT_COLUMNS = ("channel", "frequency", "gain", "phase", "perceived_gain", "perceived_phase", "played")


def omct_rows(
    policy,
    env_kwargs: dict | None = None,
    channels: Sequence[str] = CHANNELS,
    frequencies: Sequence[float] = OMCT_FREQUENCIES,
    periods: float = OMCT_PERIODS,
    settle: float = OMCT_SETTLE,
    progress=None,
) -> list[dict]:
    """The gain and phase of the whole chain per channel and frequency (module docstring).

    Args:
        policy: an object with SB3's ``predict``, or a callable env -> such an object (e.g.
            ``lambda env: WashoutPolicy(env, "washout")``).
        env_kwargs: the environment's keywords besides the task (``{"action_mode": "pose"}`` for
            washout); its ``control_dt`` (default 0.01 s) is the sines' sample period.
        channels: the channels driven, of :data:`~stewart_env.agents.evaluation.cueing.CHANNELS`.
        frequencies: rad/s.
        periods: the whole periods fitted per sine.
        settle: the transient's time before the fit, s.
        progress: called with (channel, frequency) before each sine, or None.

    Returns:
        One dict per channel and frequency with the keys of :data:`OMCT_COLUMNS` (frequency in
        rad/s, phases in degrees).

    Raises:
        UsageError: an unknown channel, or a non-positive frequency, period count or settle time.
    """
    dt = float((env_kwargs or {}).get("control_dt", 0.01))
    chain = environment_chain(policy, env_kwargs)
    runs: dict[tuple[str, float], tuple] = {}

    def recorded(motion):
        channel, frequency = motion.meta["channel"], motion.meta["frequency"]
        if progress is not None:
            progress(channel, frequency)
        f, w = chain(motion)
        runs[(channel, frequency)] = (motion, f, w, chain.played / (motion.n_samples - 1))
        return f, w

    rows = frequency_response_table(recorded, channels, frequencies, dt=dt, periods=periods, settle=settle)
    for row in rows:
        motion, f, w, played = runs.pop((row["channel"], row["frequency"]))
        axis = CHANNELS.index(row["channel"])
        vehicle = perceive(motion.specific_force, motion.angular_velocity, dt)[axis // 3][:, axis % 3]
        platform = perceive(f, w, dt)[axis // 3][:, axis % 3]
        first = motion.meta["fit_from"]
        ratio = fit_harmonic(platform, dt, row["frequency"], first) / fit_harmonic(vehicle, dt, row["frequency"], first)
        row.update(
            perceived_gain=abs(ratio),
            perceived_phase=math.degrees(math.atan2(ratio.imag, ratio.real)),
            played=played,
        )
    return rows


def omct_markdown(rows: Sequence[dict], title: str, machine: str | None = None) -> str:
    """The OMCT report as Markdown: a title, the machine and date, then the gain and phase per
    channel (:func:`~stewart_env.agents.evaluation.cueing.table_markdown`), and the sines the
    platform's limits ended.

    Args:
        rows: the rows of :func:`omct_rows`.
        title: what ran (the policy and the environment).
        machine: the machine's one-line description (default
            :func:`stewart_env.benchmarks.measurements.machine`).

    Returns:
        The report's text.
    """
    if machine is None:
        from stewart_env.benchmarks.measurements import machine as describe

        machine = describe()
    date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d")
    lines = [f"# OMCT: {title}", "", f"Run on {machine}, {date}.", "", table_markdown(rows)]
    ended = [f"{r['channel']} at {r['frequency']:g} rad/s ({100 * r['played']:.0f} %)" for r in rows if r["played"] < 1]
    lines.append("Ended by the platform's limits: " + (", ".join(ended) if ended else "none") + ".\n")
    return "\n".join(lines)


def write_omct(rows: Sequence[dict], out, title: str, machine: str | None = None) -> tuple[Path, Path]:
    """Write ``omct.csv`` and ``omct.md`` (:func:`omct_markdown`) into ``out``, made if missing.

    Args:
        rows: the rows of :func:`omct_rows`.
        out: the folder.
        title: what ran.
        machine: the machine's description (default: this one's).

    Returns:
        The two files' paths.
    """
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    table = folder / "omct.csv"
    with open(table, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(OMCT_COLUMNS)
        for row in rows:
            writer.writerow([row["channel"]] + [f"{row[key]:.6g}" for key in OMCT_COLUMNS[1:]])
    report = folder / "omct.md"
    report.write_text(omct_markdown(rows, title, machine))
    return table, report
