"""Evaluation harness: run a policy for seeded episodes of ``StewartPlatform-v1`` and score it.

:func:`evaluate` runs K episodes of one environment configuration (task, model, platform and
any other keyword of the environment) for one policy, as the K rows of the vector environment
(row i is the single environment reset with seed + i, step for step), and returns an
:class:`EvaluationResult`; :func:`write_report` writes the markdown table, the CSV and the plots
of one or more results.

Metrics of an episode (errors are the truth, target minus state, not the noisy observation;
samples at t = 0 and after every control step; see the functions of the same names):

* ``rms_position_error`` (m), ``rms_orientation_error`` (rad): root mean square over the samples
  of |e_p| and of the angle of the rotation R_target R^T.
* ``settling_time`` (s): the first sample time from which |e_p| <= position_tolerance and the
  angle <= orientation_tolerance hold to the end; NaN if the last sample is outside, or if the
  episode terminated early.
* ``position_overshoot``, ``orientation_overshoot`` (%): how far the error vector goes past zero
  along its initial direction, max_t -(e(t) . e(0)) / |e(0)|^2, times 100, zero if it never
  crosses; NaN when |e(0)| is within the tolerance (no step to overshoot, e.g. tracking).  For a
  scalar unit step response y(t) this is the classic max(y) - 1.
* ``steady_state_position_error`` (m), ``steady_state_orientation_error`` (rad): mean of |e_p|
  and of the angle over the final window (the last ``final_window`` fraction of the episode).
* ``peak_leg_force`` (N): max over steps and legs of |F_i|, the forces actually applied.
* ``control_energy`` (J): the actuators' absolute mechanical work,
  sum over steps k and legs i of |F_i,k (Ldot_i(t_k) + Ldot_i(t_k+1)) / 2| (t_k+1 - t_k),
  F held over each step (zero-order hold) and the leg rate averaged over it (trapezoid); energy
  that a leg absorbs counts as spent, as in an actuator without regeneration.
* ``success``: the episode ran to its time limit without termination and every sample of the
  final window is inside both tolerances (:class:`stewart_env.tasks.base.SuccessCriterion`, the
  criterion of the environment's ``info["is_success"]`` too).

The constraint costs of the environment's step infos (``info["cost"]``, ``info["cost_<name>"]``,
docs/physics.md, "Limits and constraint costs") give two more numbers per controller, beside the
metrics: the **cost rate**, the mean cost per control step over every step of every episode
(:meth:`EvaluationResult.cost_rate`; 0 inside every limit), and the **limit hits**, the steps
after which each constraint was violated, summed over the episodes
(:meth:`EvaluationResult.limit_hits`).  The tables, the CSV and ``results.json`` show both.

On the cueing task (``task="cueing"``) each episode also gets the cueing metrics of
:mod:`~stewart_env.agents.evaluation.cueing` (perceived errors, correlation, delay, false cues,
workspace and stroke use, limit hits), from the step infos; the CSV, ``results.json`` and
``results.md`` carry them.
"""

from __future__ import annotations

import csv
import json
import math
import re
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import gymnasium as gym
import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

import stewart_env as se
from stewart_env.agents.evaluation.cueing import (
    CUEING_INFO_KEYS,
    CUEING_METRICS,
    cueing_table,
    episode_cueing_metrics,
    is_cueing,
)
from stewart_env.files import lock_folder, publish, publishing
from stewart_env.progress import progress as progress_bar
from stewart_env.registration import ENV_ID
from stewart_env.rotations import rotation_error

# The defaults of settling and success (2 mm, 0.01 rad, the final tenth) and the criterion live with
# the tasks, whose environment reports the same verdict as info["is_success"].
from stewart_env.tasks.base import (
    FINAL_WINDOW,
    ORIENTATION_TOLERANCE,
    POSITION_TOLERANCE,
    SuccessCriterion,
    error_norm,
)
from stewart_env.validation import integer

#: The environment id with its module: ``gymnasium.make`` imports stewart_env first, so the id is
#: known in a fresh process too (a Ray worker, a subprocess) without importing stewart_env by hand.
QUALIFIED_ENV_ID = f"stewart_env:{ENV_ID}"


class Metric(NamedTuple):
    """One metric of an episode as the reports show it: ``key`` in ``Episode.metrics``,
    ``title`` of its table column, ``factor`` from SI to the display unit, ``spec`` its format."""

    key: str
    title: str
    factor: float
    spec: str


#: Metrics of an episode, in the order of the CSV columns.
METRICS = tuple(
    Metric(*m)
    for m in (
        ("success", "success", 1.0, ".0%"),
        ("rms_position_error", "RMS pos. err. (mm)", 1e3, ".3g"),
        ("rms_orientation_error", "RMS ori. err. (mrad)", 1e3, ".3g"),
        ("settling_time", "settling (s)", 1.0, ".3g"),
        ("position_overshoot", "overshoot pos. (%)", 1.0, ".3g"),
        ("orientation_overshoot", "overshoot ori. (%)", 1.0, ".3g"),
        ("steady_state_position_error", "steady-state pos. (mm)", 1e3, ".3g"),
        ("steady_state_orientation_error", "steady-state ori. (mrad)", 1e3, ".3g"),
        ("peak_leg_force", "peak leg force (N)", 1.0, ".4g"),
        ("control_energy", "energy (J)", 1.0, ".4g"),
    )
)


# -- metrics of one episode ------------------------------------------------------------------------


def rms(error) -> float:
    """Root mean square of the norm of error samples.

    Args:
        error: the samples, (T, k), or a scalar signal (T,).

    Returns:
        sqrt(mean_t |e(t)|^2), in the unit of ``error``.
    """
    e = np.asarray(error, dtype=float)
    e = e[:, None] if e.ndim == 1 else e
    return float(np.sqrt(np.mean(np.sum(e * e, axis=1))))


def settling_time(time, inside) -> float:
    """First sample time from which ``inside`` holds to the end; NaN if the last sample is outside.

    Args:
        time: the sample times (T,), s.
        inside: (T,) bool, whether each sample is within the tolerances.
    """
    inside = np.asarray(inside, dtype=bool)
    if not inside[-1]:
        return math.nan
    outside = np.flatnonzero(~inside)
    return float(time[0] if outside.size == 0 else time[outside[-1] + 1])


def overshoot(error, tolerance: float) -> float:
    """Percent overshoot of an error vector signal past zero along its initial direction:
    100 max(0, max_t -(e(t) . e(0)) / |e(0)|^2); NaN if |e(0)| <= tolerance (no step).

    Args:
        error: the error e(t), (T, k) (or (T,)).
        tolerance: the size of |e(0)| at or below which there is no step, in the unit of ``error``.
    """
    e = np.asarray(error, dtype=float)
    e = e[:, None] if e.ndim == 1 else e
    size2 = float(e[0] @ e[0])
    if math.sqrt(size2) <= tolerance:
        return math.nan
    return 100.0 * max(0.0, float(np.max(-(e @ e[0]) / size2)))


def final_window_mask(time, final_window: float) -> np.ndarray:
    """(T,) bool: the samples with t >= t_end - final_window (t_end - t_0); at least the last
    (:meth:`stewart_env.tasks.base.SuccessCriterion.final_window_mask`).

    Args:
        time: the sample times (T,), s.
        final_window: the window's length, a fraction of the episode in [0, 1].
    """
    return SuccessCriterion(final_window=final_window).final_window_mask(time)


def control_energy(time, leg_forces, leg_rates) -> float:
    """sum_k sum_i |F_i,k (Ldot_i(t_k) + Ldot_i(t_k+1)) / 2| (t_k+1 - t_k), J.

    Args:
        time: the sample times t_k (T+1,), s.
        leg_forces: the leg forces F (T, 6), N, each held over [t_k, t_k+1].
        leg_rates: the legs' extension rates Ldot (T+1, 6), m/s, at the sample times.
    """
    dt = np.diff(np.asarray(time, dtype=float))
    rates = np.asarray(leg_rates, dtype=float)
    mean_rate = 0.5 * (rates[:-1] + rates[1:])
    return float(np.sum(np.abs(np.asarray(leg_forces) * mean_rate) * dt[:, None]))


def episode_metrics(
    time,
    position_error,
    orientation_error,
    leg_forces,
    leg_rates,
    terminated: bool,
    position_tolerance: float = POSITION_TOLERANCE,
    orientation_tolerance: float = ORIENTATION_TOLERANCE,
    final_window: float = FINAL_WINDOW,
) -> dict[str, float]:
    """The metrics of one episode (module docstring).

    Args:
        time: the sample times (T+1,), s.
        position_error: target minus platform position at the samples (T+1, 3), m.
        orientation_error: the orientation error at the samples as a rotation vector (T+1, 3), rad.
        leg_forces: the leg forces over the steps (T, 6), N.
        leg_rates: the legs' extension rates at the samples (T+1, 6), m/s.
        terminated: whether the environment ended the episode early.
        position_tolerance: the settling and success tolerance of the position error's norm, m.
        orientation_tolerance: the settling and success tolerance of the orientation error's norm, rad.
        final_window: the final part of the episode whose errors give the steady-state metrics and
            success, a fraction of the episode.

    Returns:
        The metrics by key, the keys of ``METRICS``.
    """
    criterion = SuccessCriterion(position_tolerance, orientation_tolerance, final_window)
    p_norm = error_norm(np.asarray(position_error, dtype=float))
    o_norm = error_norm(np.asarray(orientation_error, dtype=float))
    inside = criterion.inside(p_norm, o_norm)
    window = criterion.final_window_mask(time)
    return {
        "success": float(criterion.succeeded(time, inside, terminated)),
        "rms_position_error": rms(position_error),
        "rms_orientation_error": rms(orientation_error),
        "settling_time": math.nan if terminated else settling_time(time, inside),
        "position_overshoot": overshoot(position_error, position_tolerance),
        "orientation_overshoot": overshoot(orientation_error, orientation_tolerance),
        "steady_state_position_error": float(p_norm[window].mean()),
        "steady_state_orientation_error": float(o_norm[window].mean()),
        "peak_leg_force": float(np.abs(leg_forces).max()) if len(leg_forces) else 0.0,
        "control_energy": control_energy(time, leg_forces, leg_rates),
    }


# -- running episodes ------------------------------------------------------------------------------


@dataclass
class Episode:
    """The recorded trajectory of one episode: time (T+1,) s; position_error (T+1,3) m and
    orientation_error (T+1,3) rad in {B}, target minus state; leg_forces (T,6) N applied over
    each step; leg_rates (T+1,6) m/s; termination: the environment's reason or None; reward:
    the episode's return; metrics (see the module docstring)."""

    seed: int
    time: np.ndarray
    position_error: np.ndarray
    orientation_error: np.ndarray
    leg_forces: np.ndarray
    leg_rates: np.ndarray
    termination: str | None
    reward: float
    metrics: dict[str, float] = field(default_factory=dict)
    #: the step infos' cost (T,), the sum over the constraints (none: not recorded)
    cost: np.ndarray | None = None
    #: the steps after which each constraint of the platform was violated, by name
    limit_hits: dict[str, int] = field(default_factory=dict)


@dataclass
class EvaluationResult:
    """The episodes of one policy on one environment configuration, and their metrics."""

    label: str
    env_kwargs: dict
    seed: int
    episodes: list[Episode]

    def summary(self) -> dict[str, float]:
        """Mean of every metric over the episodes (NaN-ignoring: settling time and overshoot are
        averaged over the episodes where they are defined; NaN if none)."""
        out = {}
        for key in [m.key for m in METRICS] + self.cueing_keys():
            values = np.array([ep.metrics[key] for ep in self.episodes], dtype=float)
            out[key] = float(np.mean(values[np.isfinite(values)])) if np.isfinite(values).any() else math.nan
        return out

    def cueing_keys(self) -> list[str]:
        """The cueing metrics the episodes carry (all of ``CUEING_METRICS`` on the cueing task, else none)."""
        return [key for key in CUEING_METRICS if self.episodes and all(key in ep.metrics for ep in self.episodes)]

    def cost_rate(self) -> float:
        """The mean constraint cost per control step over every step of every episode (the sum of
        the steps' ``info["cost"]`` over the number of steps); NaN when no cost was recorded."""
        costs = [ep.cost for ep in self.episodes if ep.cost is not None]
        steps = sum(len(c) for c in costs)
        return float(sum(float(c.sum()) for c in costs) / steps) if steps else math.nan

    def limit_hits(self) -> dict[str, int]:
        """The steps after which each constraint was violated, summed over the episodes, by
        constraint name (the platform's constraints, in the environment's order)."""
        hits: dict[str, int] = {}
        for ep in self.episodes:
            for name, count in ep.limit_hits.items():
                hits[name] = hits.get(name, 0) + count
        return hits

    @property
    def model(self) -> str:
        """The environment's dynamics model (``env_kwargs["model"]``, default ``"improved"``)."""
        return str(self.env_kwargs.get("model", "improved"))

    @property
    def task(self) -> str:
        """The environment's task (``env_kwargs["task"]``, default ``"setpoint"``)."""
        return str(self.env_kwargs.get("task", "setpoint"))


def _make_policy(policy, env_kwargs: dict):
    if hasattr(policy, "predict") and not isinstance(policy, type):
        return policy
    if callable(policy):
        made = policy(gym.make(QUALIFIED_ENV_ID, **env_kwargs))
        if not hasattr(made, "predict"):
            raise ValueError(f"policy: the factory returned {type(made).__name__}, which has no predict method")
        return made
    raise ValueError(
        f"policy: expected an object with predict(observation) or a callable env -> policy, got {type(policy).__name__}"
    )


def evaluate(
    policy,
    env_kwargs: Mapping | None = None,
    episodes: int = 5,
    seed: int = 0,
    label: str | None = None,
    max_steps: int | None = None,
    position_tolerance: float = POSITION_TOLERANCE,
    orientation_tolerance: float = ORIENTATION_TOLERANCE,
    final_window: float = FINAL_WINDOW,
    out=None,
    progress: bool = True,
) -> EvaluationResult:
    """Run ``episodes`` seeded episodes of a policy and measure them.

    Args:
        policy: anything with Stable-Baselines3's ``predict(observation, state, episode_start,
            deterministic) -> (action, state)`` that accepts a batch of observations (N, obs_dim), or
            a callable that builds one from an environment (e.g. :class:`~.pd.PDPolicy`); the callable
            gets ``gymnasium.make("StewartPlatform-v1", **env_kwargs)``.
        env_kwargs: keywords of the environment (model, platform, task, task_options, control_dt, ...).
        episodes: the number of episodes, run side by side in one vector environment.
        seed: episode i is the environment reset with seed + i; the run is deterministic given the
            seed (for a deterministic policy).
        label: the policy's name in tables and figures; default its class name.
        max_steps: episode length in control steps; default the registered time limit (500).
        position_tolerance: the settling and success tolerance of the position error, m (module docstring).
        orientation_tolerance: the settling and success tolerance of the orientation error, rad.
        final_window: the final part of the episode the steady-state metrics and success look at,
            a fraction of the episode.
        out: if given, a directory for :func:`write_report` of this result.
        progress: whether to show a progress bar of the steps.

    Returns:
        The episodes and their metrics.

    Raises:
        ValueError: an argument out of its range, named; a policy factory that returns no policy.
    """
    episodes = integer("episodes", episodes, 1, 2**31 - 1)  # the vector env's bound on its batch
    seed = integer("seed", seed, 0, 2**63 - 1)
    SuccessCriterion(position_tolerance, orientation_tolerance, final_window)  # checks them before any work
    env_kwargs = dict(env_kwargs or {})
    agent = _make_policy(policy, env_kwargs)
    label = label or type(agent).__name__
    vec_kwargs = {} if max_steps is None else {"max_episode_steps": int(max_steps)}
    env = gym.make_vec(
        QUALIFIED_ENV_ID, num_envs=int(episodes), vectorization_mode="vector_entry_point", **vec_kwargs, **env_kwargs
    )
    base = env.unwrapped
    n = base.num_envs
    dt = base.dt
    steps = base.max_episode_steps
    if steps is None:
        raise ValueError("max_steps: the environment has no time limit; give max_steps")
    obs, _ = env.reset(seed=int(seed))
    if callable(getattr(agent, "reset", None)):  # a policy with a state of its own (washout's filters) starts over
        agent.reset()
    cueing = is_cueing(env_kwargs)
    pos_err, ori_err, rates = _measure(base)
    record = {"p": [pos_err], "o": [ori_err], "r": [rates], "f": [], "c": [], "k": []}
    cues: dict[str, list[np.ndarray]] = {key: [] for key in CUEING_INFO_KEYS}
    constraints: list[str] = []  # the platform's, from the step infos' cost_<name> keys
    alive = np.ones(n, dtype=bool)
    length = np.full(n, steps)
    reasons: list[str | None] = [None] * n
    returns = np.zeros(n)
    with progress_bar(
        total=steps,
        desc=f"{label} on {env_kwargs.get('model', 'improved')}",
        unit="step",
        disable=not progress,
        leave=False,
    ) as bar:
        for k in range(steps):
            action, _ = agent.predict(obs, deterministic=True)
            obs, reward, terminated, truncated, info = env.step(np.asarray(action, dtype=np.float32))
            returns[alive] += reward[alive]
            record["f"].append(np.array(base.leg_forces))
            if k == 0:
                constraints = [key[len("cost_") :] for key in info if key.startswith("cost_")]
            record["c"].append(np.array(info["cost"], dtype=float))
            record["k"].append(np.stack([info[f"cost_{name}"] for name in constraints], axis=1) > 0)
            if cueing:
                for key in CUEING_INFO_KEYS:
                    if key in info:
                        cues[key].append(np.array(info[key], dtype=float))
            pos_err, ori_err, rates = _measure(base)
            record["p"].append(pos_err)
            record["o"].append(ori_err)
            record["r"].append(rates)
            for i in np.flatnonzero(alive & terminated):
                length[i] = k + 1
                reasons[i] = base.termination_reasons[info["termination"][i]]
            alive &= ~(terminated | truncated)
            bar.update()
            if not alive.any():
                break
    env.close()
    arrays = {key: np.stack(v, axis=1) for key, v in record.items()}  # (n, T(+1), ...)
    cue_arrays = {key: np.stack(v, axis=1) for key, v in cues.items() if v}
    results = []
    for i in range(n):
        t_end = int(length[i])
        ep = Episode(
            int(seed) + i,
            dt * np.arange(t_end + 1),
            arrays["p"][i, : t_end + 1],
            arrays["o"][i, : t_end + 1],
            arrays["f"][i, :t_end],
            arrays["r"][i, : t_end + 1],
            reasons[i],
            float(returns[i]),
            cost=arrays["c"][i, :t_end],
            limit_hits=dict(zip(constraints, arrays["k"][i, :t_end].sum(axis=0).tolist())),
        )
        ep.metrics = episode_metrics(
            ep.time,
            ep.position_error,
            ep.orientation_error,
            ep.leg_forces,
            ep.leg_rates,
            ep.termination is not None,
            position_tolerance,
            orientation_tolerance,
            final_window,
        )
        if cueing:
            steps = {key: value[i, :t_end] for key, value in cue_arrays.items()}
            hits = int(arrays["k"][i, :t_end].any(axis=1).sum()) if constraints else 0
            ep.metrics.update(episode_cueing_metrics(dt, steps, hits))
        results.append(ep)
    result = EvaluationResult(label, env_kwargs, int(seed), results)
    if out is not None:
        write_report([result], out)
    return result


def _measure(base) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """True errors (target minus state, (N,3) m and rad) and leg rates (N,6) m/s of a vector env."""
    state, target = base.state, base.target
    legs = se.leg_kinematics(base.model, state.position, state.rotation, state.velocity, state.angular_velocity)
    return target.position - state.position, rotation_error(target.rotation, state.rotation)[0], legs.rates


# -- reports ---------------------------------------------------------------------------------------


def _fmt(value: float, factor: float, spec: str) -> str:
    return "-" if not np.isfinite(value) else format(value * factor, spec)


#: The column of :func:`markdown_table` that counts the episodes ended before their time limit.
ENDED_EARLY = "ended early"
#: The columns of :func:`markdown_table` after the metrics: the cost rate and the limit hits.
COST_RATE, LIMIT_HITS = "cost rate", "limit hits (steps)"


def limit_hits_cell(result: EvaluationResult) -> str:
    """The limit hits of ``result`` as a table shows them: each violated constraint with its
    steps, e.g. ``"leg_velocity 12, force_rate 3"``, or ``"0"`` when no limit was hit.

    Args:
        result: the evaluated episodes.
    """
    hits = [f"{name} {count}" for name, count in result.limit_hits().items() if count]
    return ", ".join(hits) if hits else "0"


def ended_early(result: EvaluationResult) -> str:
    """The episodes of ``result`` that the environment terminated before their time limit, and
    the most common reason: ``"0"``, or e.g. ``"3 (leg_limit)"`` (the reason met first among
    equally common ones).

    Args:
        result: the evaluated episodes.
    """
    reasons = Counter(ep.termination for ep in result.episodes if ep.termination is not None)
    if not reasons:
        return "0"
    return f"{sum(reasons.values())} ({reasons.most_common(1)[0][0]})"


def markdown_table(results: Sequence[EvaluationResult]) -> str:
    """A markdown table of the mean metrics of each result (one row per result), with the count
    of episodes ended early and their most common reason (``ended_early``) after the success
    rate: a controller that loses the platform at once has no overshoot to show, but shows here;
    the cost rate and the limit hits (the columns "cost rate" and "limit hits (steps)") end the row.

    Args:
        results: the evaluations, one row each.
    """
    titles = [m.title for m in METRICS]
    at = [m.key for m in METRICS].index("success") + 1
    head = ["controller", "model", "task", "episodes"] + titles[:at] + [ENDED_EARLY] + titles[at:]
    head += [COST_RATE, LIMIT_HITS]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in results:
        s = r.summary()
        metrics = [_fmt(s[m.key], m.factor, m.spec) for m in METRICS]
        cells = [r.label, r.model, r.task, str(len(r.episodes))] + metrics[:at] + [ended_early(r)] + metrics[at:]
        cells += [_fmt(r.cost_rate(), 1.0, ".3g"), limit_hits_cell(r)]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


#: The metrics of :func:`compact_table` with their short headings: what a terminal of 80 columns
#: shows of a result.
COMPACT_COLUMNS = {
    "success": "success",
    "rms_position_error": "pos. mm",
    "rms_orientation_error": "ori. mrad",
    "peak_leg_force": "force N",
    "control_energy": "energy J",
}


def compact_table(results: Sequence[EvaluationResult], columns: Mapping[str, str] | None = None) -> str:
    """A plain-text table of a few mean metrics of each result, aligned, for a terminal: controller,
    model and the metrics ``columns`` ({metric key: heading}, default :data:`COMPACT_COLUMNS`:
    success, RMS position and orientation errors, peak leg force, control energy, in 80 columns
    for the demo's labels).  :func:`markdown_table` has every metric.

    Args:
        results: the results, one row each.
        columns: {metric key of :data:`METRICS`: its heading}.

    Returns:
        The table, one line a row under a heading line.

    Raises:
        KeyError: a key of ``columns`` that is no metric.
    """
    columns = dict(COMPACT_COLUMNS if columns is None else columns)
    metrics = {m.key: m for m in METRICS}
    chosen = [metrics[key] for key in columns]
    rows = [["controller", "model", *columns.values()]]
    for r in results:
        s = r.summary()
        rows.append([r.label, r.model, *(_fmt(s[m.key], m.factor, m.spec) for m in chosen)])
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    # names flush left, numbers flush right
    return "\n".join(
        "  ".join(cell.ljust(w) if i < 2 else cell.rjust(w) for i, (cell, w) in enumerate(zip(row, widths))).rstrip()
        for row in rows
    )


def slug(text: str) -> str:
    """``text`` as a file or directory name: lower case, each run of other characters than a-z and 0-9
    one underscore, e.g. ``"PPO [improved + DR]"`` -> ``"ppo_improved_dr"``.

    Args:
        text: a label.
    """
    return re.sub(r"[^a-z0-9]+", "_", text.lower()).strip("_")


def write_report(results: Sequence[EvaluationResult], out, title: str = "Controller evaluation") -> dict[str, Path]:
    """Write ``results.md`` (the table and the definitions' source), ``episodes.csv`` (one row per
    episode, SI units, with its cost rate and limit hits), ``results.json`` (each result's mean
    metrics, cost rate and limit hits), ``error_norms.png`` (every result's error norms over time) and one
    ``trajectory_<label>_<model>.png`` per result (error components and leg forces of its first
    episode) into the directory ``out``.

    The directory's lock is held while writing; each file is published atomically.

    Args:
        results: the evaluations to report.
        out: the directory, made if missing.
        title: the heading of ``results.md``.

    Returns:
        The paths of the files written, by name.

    Raises:
        stewart_env.files.FolderBusy: another report is being written into ``out``.
        stewart_env.files.WriteError: a write failed (a full disk); the message names the file.
    """
    with lock_folder(out) as out:
        return _write_report(results, out, title)


def _write_report(results: Sequence[EvaluationResult], out: Path, title: str) -> dict[str, Path]:
    paths = {
        "markdown": out / "results.md",
        "csv": out / "episodes.csv",
        "json": out / "results.json",
        "error_norms": out / "error_norms.png",
    }
    constraints = list(dict.fromkeys(name for r in results for ep in r.episodes for name in ep.limit_hits))
    cue_keys = [key for key in CUEING_METRICS if any(key in r.cueing_keys() for r in results)]
    publish(
        paths["markdown"],
        f"# {title}\n\n" + markdown_table(results) + "\n\n"
        "Means over the episodes (settling time and overshoot over the episodes where they are defined; "
        "'-' where none); the cost rate is the mean constraint cost per step, the limit hits the steps "
        "with each constraint violated, summed over the episodes. Metric definitions: "
        "`stewart_env.agents.evaluation`.\n" + _cueing_section(results),
    )
    with publishing(paths["csv"]) as tmp, tmp.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(
            ["controller", "model", "task", "platform", "seed", "termination", "return"]
            + [m.key for m in METRICS]
            + ["cost_rate"]
            + [f"hits_{name}" for name in constraints]
            + cue_keys
        )
        for r in results:
            platform = _platform_name(r)
            for ep in r.episodes:
                rate = float(ep.cost.mean()) if ep.cost is not None and len(ep.cost) else math.nan
                writer.writerow(
                    [r.label, r.model, r.task, platform, ep.seed, ep.termination or "", f"{ep.reward:.6g}"]
                    + [f"{ep.metrics[m.key]:.9g}" for m in METRICS]
                    + [f"{rate:.9g}"]
                    + [ep.limit_hits.get(name, "") for name in constraints]
                    + [f"{ep.metrics[key]:.9g}" if key in ep.metrics else "" for key in cue_keys]
                )
    publish(paths["json"], json.dumps([_result_record(r) for r in results], indent=2) + "\n")
    with publishing(paths["error_norms"]) as tmp:
        error_norms_figure(results).savefig(tmp, dpi=110)
    for r in results:
        path = out / f"trajectory_{slug(r.label)}_{slug(r.model)}.png"
        _plot_trajectory(r, path)
        paths[f"trajectory {r.label} {r.model}"] = path
    return paths


def _cueing_section(results: Sequence[EvaluationResult]) -> str:
    """The cueing metrics' table of the results on the cueing task, with a heading; "" if none."""
    cueing = [r for r in results if r.cueing_keys()]
    if not cueing:
        return ""
    table = cueing_table([(r.label, r.model, r.summary()) for r in cueing])
    return (
        "\n## Cueing\n\n" + table + "\n\nMeans over the episodes; definitions: "
        "`stewart_env.agents.evaluation.cueing`.\n"
    )


def _platform_name(result: EvaluationResult) -> str:
    """The name of the platform ``result`` ran on."""
    platform = result.env_kwargs.get("platform", "dasgupta1998")
    return platform.name if isinstance(platform, se.PlatformParams) else str(platform)


def _result_record(result: EvaluationResult) -> dict:
    """A result as ``results.json`` holds it: its configuration, mean metrics (SI units), cost rate
    and limit hits; a number that is not finite (an undefined metric) as null."""

    def number(value: float) -> float | None:
        return value if math.isfinite(value) else None

    return {
        "controller": result.label,
        "model": result.model,
        "task": result.task,
        "platform": _platform_name(result),
        "episodes": len(result.episodes),
        "seed": result.seed,
        "ended_early": ended_early(result),
        "metrics": {key: number(value) for key, value in result.summary().items()},
        "cost_rate": number(result.cost_rate()),
        "limit_hits": result.limit_hits(),
    }


#: Error norms below this (mm, mrad) are drawn at it: a log axis would otherwise spread rounding
#: noise over decades, or drop exact zeros.
ERROR_FLOOR = 1e-6
#: Styles of the results in one plot, in drawing order: each later one narrower and on top, so a
#: curve lying on an earlier one leaves that one showing around it.
_STYLES = (
    dict(ls="-", lw=3.2),
    dict(ls="--", lw=2.2, marker="o", ms=4),
    dict(ls=":", lw=1.8, marker="s", ms=3.5),
    dict(ls="-.", lw=1.4, marker="^", ms=3.5),
    dict(ls=(0, (5, 1, 1, 1)), lw=1.0, marker="D", ms=3),
)


def new_figure(**kwargs) -> Figure:
    """A matplotlib Figure on its own Agg canvas: figures are made without pyplot, so writing
    them neither needs a display nor changes the user's backend.

    Args:
        **kwargs: the keywords of matplotlib's ``Figure`` (figsize, layout, ...).
    """
    fig = Figure(**kwargs)
    FigureCanvasAgg(fig)
    return fig


def curve_style(j: int) -> dict:
    """Line style of the j-th overlaid curve (see :data:`_STYLES`); markers at even distances
    on the screen (on log axes too), offset from the other curves' markers.

    Args:
        j: the curve's index among the overlaid ones, from 0.

    Returns:
        Keywords of ``Axes.plot``.
    """
    style = dict(_STYLES[j % len(_STYLES)], zorder=2 + j)
    if "marker" in style:
        style["markevery"] = (0.02 * (j % len(_STYLES)), 0.1)
    return style


def draw_floor(ax, floor: float, unit: str) -> None:
    """Mark a log axis's clip floor as one: a dotted rule, a label and nothing drawn below it.

    Args:
        ax: the matplotlib Axes.
        floor: the value below which the curves are drawn at it, in the axis's unit.
        unit: the axis's unit, for the label.
    """
    ax.axhline(floor, color="0.35", ls=":", lw=1.0, zorder=1)
    mantissa, exponent = f"{floor:.0e}".split("e")
    ax.annotate(
        f"below {mantissa}e{int(exponent)} {unit}: rounding floor",
        (0.01, floor),
        xycoords=("axes fraction", "data"),
        xytext=(0, 2),
        textcoords="offset points",
        fontsize=8,
        color="0.3",
        va="bottom",
    )
    ax.set_ylim(bottom=floor / 2)


def error_norms_figure(results: Sequence[EvaluationResult]) -> Figure:
    """Position and orientation error norms against time, log scale: each episode faint, the
    median over episodes bold; one colour and one line style per result; norms below
    :data:`ERROR_FLOOR` drawn at the floor, which is marked when reached.

    Args:
        results: the evaluations, one colour each (the task of the first titles the figure).
    """
    fig = new_figure(figsize=(9, 6.5), layout="constrained")
    axes = fig.subplots(2, 1, sharex=True)
    colours = colormaps["tab10"].colors
    panels = ((axes[0], "position_error", "mm"), (axes[1], "orientation_error", "mrad"))
    floored = [False, False]
    for j, r in enumerate(results):
        colour = colours[j % len(colours)]
        for p, (ax, key, _) in enumerate(panels):
            raw = [np.linalg.norm(getattr(ep, key), axis=1) * 1e3 for ep in r.episodes]
            floored[p] |= any(np.any(x < ERROR_FLOOR) for x in raw)
            norms = [np.maximum(x, ERROR_FLOOR) for x in raw]
            style = curve_style(j)
            for ep, nrm in zip(r.episodes, norms):
                ax.plot(ep.time, nrm, color=colour, ls=style["ls"], lw=0.6, alpha=0.35, zorder=1)
            shortest = min(len(x) for x in norms)
            ax.plot(
                r.episodes[0].time[:shortest],
                np.median([x[:shortest] for x in norms], axis=0),
                color=colour,
                label=f"{r.label} on {r.model}",
                **style,
            )
    axes[0].set_ylabel("|position error| (mm)")
    axes[1].set_ylabel("orientation error (mrad)")
    axes[1].set_xlabel("time (s)")
    for p, (ax, _, unit) in enumerate(panels):
        ax.set_yscale("log")
        ax.grid(alpha=0.3, which="both")
        if floored[p]:
            draw_floor(ax, ERROR_FLOOR, unit)
    axes[0].legend(fontsize=9)
    task = results[0].task
    fig.suptitle(f"Errors on the {task} task (median over episodes bold, episodes faint)", fontsize=11)
    return fig


def _plot_trajectory(result: EvaluationResult, path: Path) -> None:
    """Error components and leg forces of the result's first episode."""
    ep = result.episodes[0]
    fig = new_figure(figsize=(9, 8), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    for k, name in enumerate("xyz"):
        axes[0].plot(ep.time, ep.position_error[:, k] * 1e3, label=name)
    for k, name in enumerate(("about x", "about y", "about z")):
        axes[1].plot(ep.time, ep.orientation_error[:, k] * 1e3, label=name)
    for i in range(6):
        axes[2].step(ep.time[:-1], ep.leg_forces[:, i], where="post", lw=1.0, label=f"leg {i + 1}")
    axes[0].set_ylabel("position error (mm)")
    axes[1].set_ylabel("orientation error,\nrotation vector (mrad)")
    axes[2].set_ylabel("leg force (N)")
    axes[2].set_xlabel("time (s)")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, ncol=6 if ax is axes[2] else 3, loc="upper right")
    end = f", terminated: {ep.termination}" if ep.termination else ""
    fig.suptitle(f"{result.label} on the {result.model} model, {result.task} task, seed {ep.seed}{end}", fontsize=11)
    with publishing(path) as tmp:
        fig.savefig(tmp, dpi=110)


def compare(
    policies: Mapping[str, object],
    env_kwargs_list: Sequence[Mapping],
    episodes: int = 5,
    seed: int = 0,
    out=None,
    progress: bool = True,
    **kwargs,
) -> list[EvaluationResult]:
    """:func:`evaluate` every policy (label -> policy or factory) on every environment
    configuration, with the same seeds; writes one report of all of them into ``out`` if given.

    Args:
        policies: {label: policy or factory}, as :func:`evaluate` takes them.
        env_kwargs_list: the environment configurations, each a mapping of keywords.
        episodes: episodes of each policy on each configuration.
        seed: the first episode's seed, the same for every policy.
        out: if given, the directory of :func:`write_report`.
        progress: whether to show progress bars.
        **kwargs: further keywords of :func:`evaluate` (max_steps, the tolerances, final_window).

    Returns:
        The results, configuration by configuration, policy by policy.
    """
    results = [
        evaluate(policy, env_kwargs, episodes, seed, label=label, progress=progress, **kwargs)
        for env_kwargs in env_kwargs_list
        for label, policy in policies.items()
    ]
    if out is not None:
        write_report(results, out)
    return results
