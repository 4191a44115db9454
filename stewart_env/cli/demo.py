"""``stewart-env demo``: the PD baseline on the classical and improved models, one table."""

from __future__ import annotations

import argparse
import sys
import time

from stewart_env.cli.arguments import PLATFORM_RULE, directory_name, platform_count, platform_name, seed
from stewart_env.cli.common import check_out, controllers, error

VERB = "demo"


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``stewart-env demo`` command and its options.

    Args:
        subparsers: the subcommands of the ``stewart-env`` parser (``add_subparsers``'s result).

    Returns:
        The command's parser.
    """
    p = subparsers.add_parser(
        VERB,
        help="evaluate the PD baseline on the classical and improved models and print the table",
        description="Evaluate the task-space PD baseline (gains tuned for the 10 ms control step), without and "
        "with gravity compensation, on the set-point task of the default platform, once on the "
        "classical and once on the improved dynamics model, with the same seeded episodes, and print "
        "a compact comparison table (--out writes the table of every metric).  No training; under a "
        "minute.",
    )
    p.add_argument("--episodes", type=platform_count, default=3, help="episodes per model (default 3)")
    p.add_argument("--seed", type=seed, default=0, help="episode i uses seed + i (default 0)")
    p.add_argument(
        "--platform",
        type=platform_name,
        default="dasgupta1998",
        help=f"shipped platform name or YAML config path ({PLATFORM_RULE}; default dasgupta1998)",
    )
    p.add_argument(
        "--out",
        type=directory_name,
        help="also write the report (the table of every metric, CSV, plots) into this directory",
    )
    return p


def run(args: argparse.Namespace) -> int:
    """Run ``stewart-env demo``.

    Args:
        args: the parsed command line, with the options :func:`add_parser` declares.

    Returns:
        The exit status, 0 on success.
    """
    from stewart_env.agents.evaluation.evaluation import compact_table, compare, write_report

    problem = check_out(args)
    if problem is not None:
        return error(VERB, problem)
    start = time.perf_counter()
    from stewart_env.dynamics import ModelSpec

    models = [ModelSpec("classical"), ModelSpec("improved")]
    configs = [{"model": m, "task": "setpoint", "platform": args.platform} for m in models]
    try:
        results = compare(controllers(["pd", "pd-gc"], models[1]), configs, episodes=args.episodes, seed=args.seed)
        if args.out is not None:
            write_report(results, args.out, title="Demo: PD baseline, classical vs improved dynamics")
    except ValueError as err:  # --out in use by another command, or a write that failed (a full disk)
        return error(VERB, err)
    print(
        f"PD baseline on the set-point task of {args.platform}, {args.episodes} seeded episodes a model\n"
        f"(seed {args.seed}):\n"
    )
    print(compact_table(results))  # the few key metrics: the table of every metric is wider than a terminal
    print("(means over the episodes: success, RMS errors, peak leg force, control energy)")
    if args.out is not None:
        print(f"\nreport written to {args.out} (every metric: results.md)")
    else:
        print("\nevery metric (settling, overshoot, steady state): --out DIR writes DIR/results.md")
    print(f"({time.perf_counter() - start:.1f} s)", file=sys.stderr)
    return 0
