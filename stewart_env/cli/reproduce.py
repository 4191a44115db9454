"""``stewart-env reproduce``: the case study of He et al. (2018), figures 6-10 and a summary."""

from __future__ import annotations

import argparse
import sys
import time

from stewart_env.cli.arguments import PLATFORM_RULE, platform_name, positive_float
from stewart_env.cli.common import check_out, error

VERB = "reproduce"


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        VERB, help="reproduce the case study of He et al. (2018): figures 6-10 and a summary",
        description="Drive the platform from (0.1, 0, 0.395) m to (0.1, 0, 0.4) m, rpy (0, 0, -0.2), with the "
                    "paper's task-space PD gains as a continuous controller (RK4, the law evaluated at every "
                    "stage), on the classical, improved and improved_centroidal models; write the figures "
                    "(PNG) and summary.md with the peak differences.  --out is locked while the command runs "
                    "and every file is published whole.",
    )
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--duration", type=positive_float, default=1.0, help="simulated time, s (default 1.0)")
    p.add_argument("--dt", type=positive_float, default=2e-4, help="RK4 step, s (default 2e-4)")
    p.add_argument("--platform", type=platform_name, default="dasgupta1998",
                   help=f"shipped platform name or YAML config path ({PLATFORM_RULE}; default dasgupta1998)")
    p.add_argument("--gravity-compensation", action="store_true",
                   help="add the static holding forces to the PD law (the paper's law as we have it has none)")
    return p


def run(args: argparse.Namespace) -> int:
    from stewart_env.agents.reproduce import reproduce

    problem = check_out(args)
    if problem is not None:
        return error(VERB, problem)
    start = time.perf_counter()
    try:
        result = reproduce(args.out, duration=args.duration, dt=args.dt, platform=args.platform,
                           gravity_compensation=args.gravity_compensation)
    except ValueError as err:  # a platform whose leg stroke the case leaves, --out in use, a failed write
        return error(VERB, err)
    force = result["differences"]["leg_force"]
    print(f"wrote the figures and summary.md to {args.out}")
    print(f"leg force: peak-value difference classical vs improved {100 * force['peak_difference']:.2f} %, "
          f"pointwise {100 * force['pointwise_difference']:.2f} %; improved vs improved_centroidal "
          f"{result['centroidal_difference']:.1e}")
    print(f"({time.perf_counter() - start:.1f} s)", file=sys.stderr)
    return 0
