"""Sim-to-sim model mismatch: what a controller loses when it was designed or trained on a
simplified dynamics model of the Stewart platform.

The study is a matrix.  Rows are controllers, each tied to the dynamics model it was built on:

* ``CT [m]``: the computed-torque controller with internal model ``m`` (its inverse dynamics);
* ``<ALGO> [m]``: an RL agent trained on a plant simulated with model ``m``;
* ``<ALGO> [improved + DR]`` (optional): an agent trained on the improved model with domain
  randomisation of the inertial and friction parameters (:data:`DEFAULT_RANDOMIZATION`);
* ``PD + gravity comp.``: the task-space PD law with gravity compensation, a model-light
  reference row (its holding forces come from the improved model's statics).

Columns are test plants: the environment simulated with each test model (nominal parameters).
Every cell is :func:`stewart_env.agents.evaluation.evaluate` of the row's controller on the
column's plant over the same seeded episodes.  A per-simplification block adds the rows
``improved+c1`` ... ``improved+c4`` (the improved model with one of the classical model's
simplifications C1-C4 switched on) for the computed-torque controller and the RL agent, so the
study says which simplification costs most on the true (improved) plant.

Output in DIR: ``matrix.csv`` (one line per row and test plant, every metric, SI units),
``matrix.md`` (one table per metric, rows x test plants, and the ranking of the
simplifications, withheld with a warning where a ranked controller fails) and
``heatmap_<metric>.png`` per metric, failed cells hatched; trained agents in
``DIR/agents/<name>/`` (a second run with the same DIR loads them instead of training again).
"""

from __future__ import annotations

import argparse
import csv
import math
import signal
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from stewart_env.agents.training import (
    ALGORITHMS,
    MANIFEST,
    MODEL_FILE,
    TrainingError,
    TrainingInterrupted,
    check_writable,
    load_agent,
    newest_checkpoint,
    parse_env_kwargs,
    read_manifest,
    train,
)
from stewart_env.dynamics.model import SIMPLIFICATIONS as SIMPLIFICATION_TEXT
from stewart_env.progress import progress as progress_bar

#: Environment steps per RL agent of the quick default study: a smoke-scale budget (the whole
#: study in about a minute; such agents still lose the platform), --timesteps 1500000 or more for
#: agents that hold a set point.
QUICK_TIMESTEPS = 20_000
#: The classical model's simplifications, each a switch on the improved model.
SIMPLIFICATIONS = tuple(SIMPLIFICATION_TEXT)
#: Domain randomisation of the DR row: per-episode factors on the nominal parameters.  The legs'
#: inertial parameters get the widest ranges because three of the classical model's four
#: simplifications (C1-C3) concern the legs' dynamics.
DEFAULT_RANDOMIZATION: dict[str, tuple[float, float]] = {
    "platform.mass": (0.8, 1.2),
    "platform.inertia": (0.8, 1.2),
    "platform.com": (0.5, 1.5),
    "legs.mass": (0.5, 1.5),
    "legs.inertia": (0.5, 2.0),
    "legs.com": (0.5, 1.5),
    "damping": (0.0, 2.0),
}
#: Evaluation episodes use seeds seed + EVAL_SEED_OFFSET + i, away from the training rows' seeds.
EVAL_SEED_OFFSET = 100_000
#: The metrics that rank the simplifications, on the true plant: the static error (where the
#: set-point task shows a wrong model most), the transient error and the force peak.
RANKING_METRICS = ("steady_state_position_error", "steady_state_orientation_error", "rms_position_error",
                   "peak_leg_force")
TRUE_MODEL = "improved"
#: A cell whose controller succeeds in fewer than this share of the episodes is marked failed: its
#: heatmap cell is hatched grey, not coloured, and it ranks no simplification.
FAILURE_THRESHOLD = 0.5


@dataclass
class Row:
    """One controller of the study: its label, family ("PD", "CT" or the RL algorithm) and the
    model it was designed or trained on ("" for PD)."""

    label: str
    family: str
    model: str
    policy: Any = None
    info: str = ""


@dataclass
class MismatchResult:
    """The study's numbers: ``summary[row label][test model]`` = {metric: mean over episodes};
    ``rows`` in table order; ``test_models`` the columns; ``files`` what was written."""

    rows: list[Row]
    test_models: list[str]
    summary: dict[str, dict[str, dict[str, float]]]
    episodes: int
    files: dict[str, Path] = field(default_factory=dict)

    def matrix(self, metric: str) -> np.ndarray:
        """(rows, test models) array of one metric's means."""
        return np.array([[self.summary[r.label][m][metric] for m in self.test_models] for r in self.rows])


def _check_models(names: Sequence[str], what: str) -> list[str]:
    import stewart_env as se

    params = se.load_platform("dasgupta1998")
    out = []
    for name in names:
        try:
            se.make_dynamics(name, params)
        except (ValueError, KeyError) as exc:
            raise TrainingError(f"{what}: {name!r} is not a dynamics model ({exc})") from None
        out.append(name)
    if not out:
        raise TrainingError(f"{what}: give at least one model")
    return out


def _agent(algo: str, directory: Path, env_kwargs: dict[str, Any], timesteps: int, seed: int,
           n_envs: int | None, progress: bool):
    """Load the agent in ``directory`` if it was trained for this row (same algorithm, seed and
    environment kwargs; its budget may differ and is reported), else train it there."""
    if (directory / MODEL_FILE).exists():
        manifest = read_manifest(directory)
        found = (manifest["algo"], manifest["seed"], manifest["env_kwargs"])
        if found != (algo, seed, env_kwargs):
            raise TrainingError(
                f"{directory} holds an agent trained differently (algorithm, seed, env kwargs: {found}) from "
                f"this study's row ({(algo, seed, env_kwargs)}); use another --out")
        return load_agent(directory)
    rest = {k: v for k, v in env_kwargs.items() if k not in ("model", "task")}
    row = dict(algo=algo, out=directory, model=env_kwargs["model"], task=env_kwargs["task"], seed=seed,
               n_envs=n_envs, checkpoint_freq=0, env_kwargs=rest, progress_bar=progress)
    resumable = None
    if (directory / MANIFEST).exists():
        resumable = newest_checkpoint(directory, algo, bool(read_manifest(directory).get("normalize")))
    if resumable:
        # A study stopped while training this row: continue the row's run for the rest of its budget;
        # given the row's settings, train() refuses a run trained with another seed or environment.
        steps, _ = resumable
        train(**row, timesteps=max(timesteps - steps, 1), resume=True)
    else:
        train(**row, timesteps=timesteps)
    return load_agent(directory)


def build_rows(out: Path, train_models: Sequence[str], task: str, algo: str | None, timesteps: int, seed: int,
               domain_randomization: bool, simplifications: Sequence[str], env_kwargs: Mapping[str, Any],
               n_envs: int | None, progress: bool) -> list[Row]:
    """The study's controllers, training the RL agents that ``out/agents`` does not hold yet."""
    from stewart_env.agents.computed_torque import ComputedTorquePolicy
    from stewart_env.agents.evaluation import slug
    from stewart_env.agents.pd import PDPolicy

    models = list(train_models) + [f"improved+{c}" for c in simplifications if f"improved+{c}" not in train_models]
    rows = [Row("PD + gravity comp.", "PD", "", lambda env: PDPolicy(env, gravity_compensation=True),
                "task-space PD, gravity compensation from the improved statics")]
    rows += [Row(f"CT [{m}]", "CT", m, lambda env, m=m: ComputedTorquePolicy(env, m)) for m in models]
    if algo is None:
        return rows
    trainings = [(m, None) for m in models]
    if domain_randomization:
        trainings.append(("improved", DEFAULT_RANDOMIZATION))
    for m, randomization in trainings:
        name = f"{m} + DR" if randomization else m
        kwargs = {**env_kwargs, "model": m, "task": task}
        if randomization:
            kwargs["randomization"] = {k: list(v) for k, v in randomization.items()}
        agent = _agent(algo, out / "agents" / slug(name), kwargs, timesteps, seed, n_envs, progress)
        info = f"{agent.num_timesteps} steps, seed {agent.manifest['seed']}"
        rows.append(Row(f"{algo.upper()} [{name}]", algo.upper(), m, agent, info))
    return rows


def run_mismatch(out: str | Path, train_models: Sequence[str] = ("classical", "improved"),
                 test_models: Sequence[str] = ("classical", "improved", "improved_centroidal"),
                 task: str = "setpoint", algo: str | None = "ppo", timesteps: int = QUICK_TIMESTEPS,
                 episodes: int = 5, seed: int = 0, domain_randomization: bool = False,
                 simplifications: Sequence[str] = SIMPLIFICATIONS, env_kwargs: Mapping[str, Any] | None = None,
                 n_envs: int | None = None, max_steps: int | None = None, progress: bool = True) -> MismatchResult:
    """Run the mismatch study and write it to ``out`` (see the module docstring).

    train_models: models to build controllers on (CT internal models, RL training plants).
    test_models: the plants every controller is evaluated on (the columns).
    algo: the RL algorithm ("ppo", "sac", "td3"), or None for the model-based rows only.
    timesteps: environment steps per RL agent; seed: training seed of every agent (evaluation
        episodes use seed + EVAL_SEED_OFFSET + i, the same for every cell).
    episodes: evaluation episodes per cell.
    simplifications: which of c1..c4 get an ``improved+cK`` row ([] for none).
    env_kwargs: further environment kwargs shared by training and test plants.
    n_envs: platforms per training batch (default the algorithm config's).
    max_steps: evaluation episode length in control steps (default the registered 500).
    """
    from stewart_env.agents.evaluation import METRICS, evaluate

    if algo is not None and algo not in ALGORITHMS:
        raise TrainingError(f"unknown algorithm {algo!r}; choose one of {', '.join(ALGORITHMS)}")
    unknown = [c for c in simplifications if c not in SIMPLIFICATIONS]
    if unknown:
        raise TrainingError(f"simplifications: unknown {', '.join(unknown)}; choose from {', '.join(SIMPLIFICATIONS)}")
    train_models = _check_models(train_models, "train models")
    test_models = _check_models(test_models, "test models")
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise TrainingError(f"episodes must be a positive integer, got {episodes!r}")
    env_kwargs = dict(env_kwargs or {})
    clash = [k for k in ("model", "task", "randomization") if k in env_kwargs]
    if clash:
        raise TrainingError(f"env kwargs: {', '.join(clash)} are set by the study itself "
                            "(--train-models/--test-models, --task, --domain-randomization)")
    out = check_writable(out)

    start = time.perf_counter()
    rows = build_rows(out, train_models, task, algo, timesteps, seed, domain_randomization, simplifications,
                      env_kwargs, n_envs, progress)
    summary: dict[str, dict[str, dict[str, float]]] = {r.label: {} for r in rows}
    cells = [(r, m) for r in rows for m in test_models]
    for row, model in progress_bar(cells, desc="mismatch matrix", unit="cell", disable=not progress):
        result = evaluate(row.policy, {**env_kwargs, "model": model, "task": task}, episodes=episodes,
                          seed=seed + EVAL_SEED_OFFSET, label=row.label, max_steps=max_steps, progress=False)
        summary[row.label][model] = result.summary()
    result = MismatchResult(rows, list(test_models), summary, episodes)
    header = {"task": task, "episodes": episodes, "eval_seed": seed + EVAL_SEED_OFFSET, "algo": algo,
              "wall_time": time.perf_counter() - start}
    result.files = write_outputs(result, out, METRICS, header)
    return result


# -- outputs ---------------------------------------------------------------------------------------


def _fmt(value: float, factor: float, spec: str) -> str:
    return "-" if not np.isfinite(value) else format(value * factor, spec)


def simplification_costs(result: MismatchResult, family: str, plant: str = TRUE_MODEL) -> list[tuple[str, str]]:
    """(simplification, row label) of the ``family``'s improved+cK rows, for the ranking on
    ``plant``; [] if ``plant`` is not a column or the family has no exact (improved) row."""
    if plant not in result.test_models:
        return []
    labels = {r.model: r.label for r in result.rows if r.family == family and "DR" not in r.label}
    if TRUE_MODEL not in labels:
        return []
    return [(c, labels[f"improved+{c}"]) for c in SIMPLIFICATIONS if f"improved+{c}" in labels]


def _ranking_lines(result: MismatchResult, family: str, metrics) -> list[str]:
    """The markdown block saying which simplification costs the ``family`` most on the true plant:
    each simplification's metrics and their ratios to the exact-model row, and per metric the
    simplifications ordered by that ratio; only a warning line if any of these rows fails on the
    true plant (success below :data:`FAILURE_THRESHOLD`)."""
    rows = simplification_costs(result, family)
    if not rows:
        return []
    meta = {m[0]: m for m in metrics}
    exact_label = f"{family} [{TRUE_MODEL}]"
    exact = result.summary[exact_label][TRUE_MODEL]
    heading = [f"## Which simplification costs most: {family} on the {TRUE_MODEL} plant", ""]
    failed = [label for label in [exact_label] + [label for _, label in rows]
              if result.summary[label][TRUE_MODEL]["success"] < FAILURE_THRESHOLD]
    if failed:
        return heading + [
            f"**Warning: no ranking.** {', '.join(failed)} succeed{'s' if len(failed) == 1 else ''} in fewer than "
            f"{FAILURE_THRESHOLD:.0%} of the episodes on the {TRUE_MODEL} plant; their errors measure the failure, "
            "not the simplification.", ""]
    lines = heading + [
        f"Each entry: the metric of {family} [improved+cK] on the {TRUE_MODEL} plant, and in brackets its "
        f"ratio to {family} [{TRUE_MODEL}] (the controller built on the exact model).", "",
        "| simplification | " + " | ".join(meta[k][1] for k in RANKING_METRICS) + " |",
        "|---|" + "---|" * len(RANKING_METRICS)]
    ratios = {}
    for c, label in rows:
        cells = []
        for key in RANKING_METRICS:
            value, base = result.summary[label][TRUE_MODEL][key], exact[key]
            ratios[c, key] = value / base if base > 0 else math.nan
            cells.append(f"{_fmt(value, meta[key][2], meta[key][3])} ({ratios[c, key]:.3g})")
        lines.append(f"| {c.upper()}: {SIMPLIFICATION_TEXT[c]} | " + " | ".join(cells) + " |")
    lines.append("")
    for key in RANKING_METRICS:
        order = sorted((c for c, _ in rows), key=lambda c: -ratios[c, key] if np.isfinite(ratios[c, key]) else math.inf)
        lines.append(f"- {meta[key][1]}, costliest first: "
                     + ", ".join(f"{c.upper()} x{ratios[c, key]:.3g}" for c in order) + ".")
    return lines + [""]


def write_outputs(result: MismatchResult, out: Path, metrics, header: Mapping[str, Any]) -> dict[str, Path]:
    """matrix.csv, matrix.md and one heatmap PNG per metric into ``out``; returns {name: path}."""
    files = {"csv": out / "matrix.csv", "markdown": out / "matrix.md"}
    with files["csv"].open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["controller", "family", "design_model", "test_model", "episodes"] + [m[0] for m in metrics])
        for r in result.rows:
            for m in result.test_models:
                s = result.summary[r.label][m]
                writer.writerow([r.label, r.family, r.model, m, result.episodes] + [f"{s[k[0]]:.9g}" for k in metrics])

    lines = [f"# Model mismatch on the {header['task']} task", "",
             f"Rows: controllers and the dynamics model they were designed or trained on; columns: the plant "
             f"they run on. Each cell: mean over {result.episodes} episodes (evaluation seeds "
             f"{header['eval_seed']}..{header['eval_seed'] + result.episodes - 1}, the same for every cell; "
             "settling time and overshoot over the episodes where they are defined, '-' where none).", ""]
    notes = [f"- {r.label}: {r.info}" for r in result.rows if r.info]
    if notes:
        lines += ["Controllers:", "", *notes, ""]
    for key, title, factor, spec in metrics:
        lines += [f"## {title}", "", "| controller | " + " | ".join(result.test_models) + " |",
                  "|---|" + "---|" * len(result.test_models)]
        for r in result.rows:
            cells = [_fmt(result.summary[r.label][m][key], factor, spec) for m in result.test_models]
            lines.append(f"| {r.label} | " + " | ".join(cells) + " |")
        lines.append("")
    for family in dict.fromkeys(r.family for r in result.rows):
        lines += _ranking_lines(result, family, metrics)
    lines.append(f"Wall time of the study: {header['wall_time']:.0f} s.")
    files["markdown"].write_text("\n".join(lines) + "\n")

    for key, title, factor, spec in metrics:
        path = out / f"heatmap_{key}.png"
        heatmap(result, key, title, factor, spec, path)
        files[f"heatmap {key}"] = path
    return files


def heatmap(result: MismatchResult, key: str, title: str, factor: float, spec: str, path: Path) -> None:
    """Write :func:`heatmap_figure` of one metric to ``path`` (PNG)."""
    heatmap_figure(result, key, title, factor, spec).savefig(path, dpi=110)


def heatmap_figure(result: MismatchResult, key: str, title: str, factor: float, spec: str):
    """One metric as a rows x test-plants heatmap with the values written in the cells; a log
    colour scale when the values span more than two decades (model errors do).  Failed cells
    (success below :data:`FAILURE_THRESHOLD`) are hatched grey and say so, outside the colour
    scale, so that a controller that loses the platform is never coloured as the best."""
    from matplotlib import colormaps
    from matplotlib.colors import LogNorm, Normalize
    from matplotlib.patches import Rectangle
    from matplotlib.ticker import PercentFormatter

    from stewart_env.agents.evaluation import new_figure

    values = result.matrix(key) * factor
    failed = result.matrix("success") < FAILURE_THRESHOLD
    finite = values[np.isfinite(values) & ~failed]
    positive = finite[finite > 0]
    if key == "success":  # a share of the episodes: one fixed scale for every study
        norm = Normalize(0.0, 1.0)
    elif positive.size and positive.size == finite.size and positive.max() > 100 * positive.min():
        norm = LogNorm(positive.min(), positive.max())
    else:
        norm = Normalize(*(finite.min(), finite.max()) if finite.size else (0, 1))
    cmap = colormaps["viridis" if key == "success" else "viridis_r"].with_extremes(bad="white")
    n_rows, n_cols = values.shape
    fig = new_figure(figsize=(2.0 + 1.6 * n_cols, 1.6 + 0.42 * n_rows), layout="constrained")
    ax = fig.subplots()
    image = ax.imshow(np.ma.masked_where(~np.isfinite(values) | failed, values), cmap=cmap, norm=norm, aspect="auto")
    for i, j in zip(*np.nonzero(failed)):
        ax.add_patch(Rectangle((j - 0.5, i - 0.5), 1.0, 1.0, facecolor="0.82", edgecolor="0.55", hatch="///",
                               lw=0.0))
    for i in range(n_rows):
        for j in range(n_cols):
            v = values[i, j]
            text = "-" if not np.isfinite(v) else format(v, spec)
            if failed[i, j]:
                ax.text(j, i, f"failed ({text})", ha="center", va="center", fontsize=8, color="black",
                        bbox=dict(boxstyle="round,pad=0.15", facecolor="0.82", edgecolor="none"))
                continue
            # viridis is dark at its low end, viridis_r at its high end
            dark = np.isfinite(v) and (norm(v) < 0.5 if key == "success" else norm(v) > 0.5)
            ax.text(j, i, text, ha="center", va="center", fontsize=8, color="white" if dark else "black")
    for i in range(1, n_rows):  # a white rule between controller families
        if result.rows[i].family != result.rows[i - 1].family:
            ax.axhline(i - 0.5, color="white", lw=2.5)
    ax.set_xticks(range(n_cols), result.test_models)
    ax.set_yticks(range(n_rows), [r.label for r in result.rows])
    ax.set_xlabel("test plant (dynamics model simulated)")
    ax.set_ylabel("controller [design / training model]")
    note = f"\nhatched: failed (success < {FAILURE_THRESHOLD:.0%}), value in brackets" if failed.any() else ""
    ax.set_title(title + note, fontsize=11 if not note else 10)
    fig.colorbar(image, ax=ax, shrink=0.9, format=PercentFormatter(1.0) if key == "success" else None)
    return fig


# -- command line ---------------------------------------------------------------------------------


def _names(text: str) -> list[str]:
    return [t.strip() for t in text.split(",") if t.strip()]


def add_cli(subparsers) -> argparse.ArgumentParser:
    """Add ``mismatch`` to an argparse subparsers object; its ``func`` returns an exit code."""
    p = subparsers.add_parser(
        "mismatch", help="model-mismatch study: controllers built on one model, run on another",
        description="Train (or load) an RL agent per training model, build computed-torque controllers on "
                    "the same models and on the improved model with each of C1..C4 switched on, evaluate "
                    "every controller on every test plant, and write DIR/matrix.md, DIR/matrix.csv and "
                    "DIR/heatmap_<metric>.png.")
    p.add_argument("--train-models", default="classical,improved",
                   help="comma-separated models to train agents on / use as CT internal models "
                        "(default: classical,improved)")
    p.add_argument("--test-models", default="classical,improved,improved_centroidal",
                   help="comma-separated plant models (default: classical,improved,improved_centroidal)")
    p.add_argument("--task", default="setpoint", help="task (default: setpoint)")
    p.add_argument("--out", required=True, help="study directory")
    p.add_argument("--algo", default="ppo", help=f"RL algorithm: {', '.join(ALGORITHMS)}, or 'none' for "
                                                 "the model-based rows only (default: ppo)")
    p.add_argument("--timesteps", type=int, default=QUICK_TIMESTEPS,
                   help=f"environment steps per agent (default: {QUICK_TIMESTEPS}, a quick smoke-scale study)")
    p.add_argument("--n-envs", type=int, default=None, help="platforms per training batch (default: the config's)")
    p.add_argument("--episodes", type=int, default=5, help="evaluation episodes per cell (default: 5)")
    p.add_argument("--seed", type=int, default=0, help="seed of the training runs and of the evaluation (default: 0)")
    p.add_argument("--domain-randomization", action="store_true",
                   help="add an agent trained on the improved model with domain randomisation")
    p.add_argument("--simplifications", default=",".join(SIMPLIFICATIONS),
                   help="which of c1..c4 get an improved+cK row, comma-separated, or 'none' (default: all)")
    p.add_argument("--env-kwargs", nargs="*", default=None, metavar="KW",
                   help="further environment kwargs for training and testing: JSON or key=value")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(func=_cli_mismatch)
    return p


def _cli_mismatch(args: argparse.Namespace) -> int:
    simplifications = [] if args.simplifications.strip().lower() == "none" else _names(args.simplifications)
    try:
        result = run_mismatch(args.out, _names(args.train_models), _names(args.test_models), task=args.task,
                              algo=None if args.algo.lower() == "none" else args.algo, timesteps=args.timesteps,
                              episodes=args.episodes, seed=args.seed, domain_randomization=args.domain_randomization,
                              simplifications=simplifications, env_kwargs=parse_env_kwargs(args.env_kwargs),
                              n_envs=args.n_envs, progress=not args.no_progress)
    except (TrainingError, ValueError) as exc:
        print(f"stewart-env mismatch: error: {exc}", file=sys.stderr)
        return 2
    except TrainingInterrupted as stop:
        print(f"stewart-env mismatch: stopped by {signal.Signals(stop.signum).name}; checkpoint saved in "
              f"{stop.checkpoint} (run the same command again to continue)", file=sys.stderr)
        return stop.exit_code
    print(f"{len(result.rows)} controllers x {len(result.test_models)} plants -> {result.files['markdown']}")
    return 0
