"""``stewart-env reproduce``: the case study of He et al. (2018), figures 6-10 and a summary."""

from __future__ import annotations

import argparse
import sys
import time

from stewart_env.cli.arguments import PLATFORM_RULE, directory_name, platform_name, real
from stewart_env.cli.common import check_out, error

VERB = "reproduce"
#: Longest simulated time, s: the case settles within its first second.
MAX_DURATION = 60.0
#: The RK4 step's range, s: below MIN_DT rounding dominates; with the paper's gains RK4 diverges
#: on the shipped platforms at 0.01 s and holds at MAX_DT.
MIN_DT, MAX_DT = 1e-6, 5e-3
#: Most RK4 steps a run takes (--duration / --dt): every sample of three models is kept in memory.
MAX_CASE_STEPS = 10**6


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``stewart-env reproduce`` command and its options.

    Args:
        subparsers: the subcommands of the ``stewart-env`` parser (``add_subparsers``'s result).

    Returns:
        The command's parser.
    """
    p = subparsers.add_parser(
        VERB,
        help="reproduce the case study of He et al. (2018): figures 6-10 and a summary",
        description="Drive the platform from (0.1, 0, 0.395) m to (0.1, 0, 0.4) m, rpy (0, 0, -0.2), with the "
        "paper's task-space PD gains as a continuous controller (RK4, the law evaluated at every "
        "stage), on the classical, improved and improved_centroidal models; write the figures "
        "(PNG) and summary.md with the peak differences.  --out is locked while the command runs "
        "and every file is published whole.",
    )
    p.add_argument("--out", type=directory_name, required=True, help="output directory")
    p.add_argument(
        "--duration",
        type=real(0, MAX_DURATION, low_open=True),
        default=1.0,
        help=f"simulated time, s, at most {MAX_DURATION:g} (default 1.0)",
    )
    p.add_argument(
        "--dt",
        type=real(MIN_DT, MAX_DT),
        default=2e-4,
        help=f"RK4 step, s, in [{MIN_DT:g}, {MAX_DT:g}] and at most --duration (default 2e-4)",
    )
    p.add_argument(
        "--platform",
        type=platform_name,
        default="dasgupta1998",
        help=f"shipped platform name or YAML config path ({PLATFORM_RULE}; default dasgupta1998)",
    )
    p.add_argument(
        "--gravity-compensation",
        action="store_true",
        help="add the static holding forces to the PD law (the paper's law as we have it has none)",
    )
    return p


def run(args: argparse.Namespace) -> int:
    """Run ``stewart-env reproduce``.

    Args:
        args: the parsed command line, with the options :func:`add_parser` declares.

    Returns:
        The exit status, 0 on success.
    """
    from stewart_env.agents.studies.reproduce import reproduce

    if args.dt > args.duration:
        return error(VERB, f"argument --dt: the step {args.dt:g} s is longer than --duration {args.duration:g} s")
    if args.duration / args.dt > MAX_CASE_STEPS:
        return error(
            VERB,
            f"argument --dt: --duration / --dt is {args.duration / args.dt:.3g} steps, more than the "
            f"{MAX_CASE_STEPS:g} a run keeps in memory; take a longer --dt or a shorter --duration",
        )
    problem = check_out(args)
    if problem is not None:
        return error(VERB, problem)
    start = time.perf_counter()
    try:
        result = reproduce(
            args.out,
            duration=args.duration,
            dt=args.dt,
            platform=args.platform,
            gravity_compensation=args.gravity_compensation,
        )
    except ValueError as err:  # a platform whose leg stroke the case leaves, --out in use, a failed write
        return error(VERB, err)
    except FloatingPointError:  # the law's stiff gains beyond what this step resolves, on this platform
        return error(VERB, f"argument --dt: the simulation diverged with a step of {args.dt:g} s; take a shorter --dt")
    force = result["differences"]["leg_force"]
    print(f"wrote the figures and summary.md to {args.out}")
    print(
        f"leg force: peak-value difference classical vs improved {100 * force['peak_difference']:.2f} %, "
        f"pointwise {100 * force['pointwise_difference']:.2f} %; improved vs improved_centroidal "
        f"{result['centroidal_difference']:.1e}"
    )
    print(f"({time.perf_counter() - start:.1f} s)", file=sys.stderr)
    return 0
