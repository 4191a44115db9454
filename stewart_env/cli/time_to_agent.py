"""``stewart-env time-to-agent``: the training wall time to a precise agent
(:mod:`stewart_env.agents.studies.time_to_agent`) from the command line.  :func:`add_parser` registers the
verb with its options, :func:`run` runs it and returns the exit code: 0 measured (whether or not
the target was reached: the table says), 1 stopped by a failing write (the points taken are kept),
2 a bad request, 130 interrupted (Ctrl-C; the points taken are kept)."""

from __future__ import annotations

import argparse
import sys

from stewart_env.agents.studies.time_to_agent import SeedResult, resolve_config, summary_table, time_to_agent
from stewart_env.agents.training import ALGORITHMS, TrainingError
from stewart_env.cli.arguments import (
    TASKS,
    directory_name,
    fraction,
    nonnegative_float,
    platform_count,
    real,
    seed_list,
)
from stewart_env.cli.common import error
from stewart_env.files import WriteError

__all__ = ["add_parser", "run"]

#: Longest training wall time per seed, s (a year): beyond it the clock's arithmetic, not the
#: measurement, would decide when to stop.
MAX_BUDGET = 365 * 24 * 3600.0
wall_time = real(0, MAX_BUDGET, low_open=True, doc="argparse type: a wall time in (0, MAX_BUDGET] seconds.")


VERB = "time-to-agent"


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``time-to-agent`` to an argparse subparsers object; its ``func`` is :func:`run`.

    Args:
        subparsers: the subcommands of the ``stewart-env`` parser (``add_subparsers``'s result).

    Returns:
        The command's parser.
    """
    p = subparsers.add_parser(
        VERB,
        help="training wall time to a precise agent, measured on held-out episodes",
        description="Train an agent per seed with a zoo config; every --interval seconds of training wall time "
        "pause and evaluate the policy on --episodes held-out episodes; stop at the first point with "
        "success >= --target-success and median steady-state position error <= --target-error-mm, or "
        "at --budget. Reports the time and steps to target and the steps/s of collection and of "
        "learning; writes DIR/time_to_agent.json, DIR/points.csv, DIR/summary.md and "
        "DIR/learning_curve.png.",
    )
    p.add_argument("--algo", required=True, choices=ALGORITHMS, help=f"algorithm: {', '.join(ALGORITHMS)}")
    p.add_argument(
        "--config",
        default=None,
        help="hyperparameters: a zoo config file or a shipped config's name, e.g. ppo_6m "
        "(default: configs/agents/<algo>.yml)",
    )
    p.add_argument("--task", choices=TASKS, default="setpoint", help="task (default: setpoint)")
    p.add_argument("--seeds", type=seed_list, default=[0], help="training seeds, comma-separated (default: 0)")
    p.add_argument(
        "--target-success",
        type=fraction,
        default=0.98,
        help="target success rate on the held-out episodes, in [0, 1] (default: 0.98)",
    )
    p.add_argument(
        "--target-error-mm",
        type=nonnegative_float,
        default=0.5,
        help="target median steady-state position error, mm (default: 0.5)",
    )
    p.add_argument("--budget", type=wall_time, default=300.0, help="training wall time per seed, s (default: 300)")
    p.add_argument(
        "--interval", type=wall_time, default=30.0, help="training wall time between two evaluations, s (default: 30)"
    )
    p.add_argument("--episodes", type=platform_count, default=50, help="held-out episodes per evaluation (default: 50)")
    p.add_argument("--out", type=directory_name, required=True, help="output directory (new or empty)")
    p.add_argument(
        "--no-progress", action="store_true", help="no progress bar (there is none unless stderr is a terminal)"
    )
    return p


def _seed_line(r: SeedResult) -> None:
    last = r.points[-1] if r.points else None
    state = f"target reached in {r.wall_time:.0f} s, {r.steps} steps" if r.reached else "target not reached"
    measured = "" if last is None else f"; last point: success {last.success:.0%}, {last.median_error_mm:.3g} mm"
    print(
        f"seed {r.seed}: {state}{measured}; collection {r.collection_rate:.0f} steps/s, learning "
        f"{r.learning_rate:.0f} steps/s",
        file=sys.stderr,
        flush=True,
    )


def run(args: argparse.Namespace) -> int:
    """Measure what the parsed ``args`` ask for; print the table or a one-line error; the exit code.

    Args:
        args: the parsed command line, with the options :func:`add_parser` declares.

    Returns:
        The exit status, 0 on success.
    """
    prog = "stewart-env time-to-agent"
    try:
        config = resolve_config(args.algo, args.config)
    except TrainingError as exc:  # a TimeToAgentError about "config": said of --config
        return error(VERB, exc)
    try:
        result = time_to_agent(
            args.algo,
            args.out,
            config=config,
            task=args.task,
            seeds=args.seeds,
            target_success=args.target_success,
            target_error_mm=args.target_error_mm,
            budget=args.budget,
            interval=args.interval,
            episodes=args.episodes,
            progress_bar=not args.no_progress,
            report=_seed_line,
        )
    except WriteError as exc:
        print(f"{prog}: error: {exc}; the points taken are kept in {args.out}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"{prog}: interrupted; the points taken are kept in {args.out}", file=sys.stderr)
        return 130
    except ValueError as exc:  # TrainingError, TimeToAgentError, FolderBusy, a bad environment keyword
        # a usage error about an argument a flag sets (out, config, model, ...) is said of that flag
        return error(VERB, exc)
    print(summary_table(result))
    print(f"\n{result.reached}/{len(result.seeds)} seeds reached the target -> {result.files['markdown'].parent}")
    return 0
