r"""``stewart-env excitation``: the identification's excitation as set points for a machine.

    stewart-env excitation --platform dasgupta1998 --out excitation.csv --rate 200 --duration 60

writes the optimised (or, with ``--random``, random) Fourier excitation as time-stamped leg
lengths and poses (with their twist and acceleration) in the log format
(stewart_env.identification.log; docs/guides/log-format.md), checked along every sample against
the stroke, the workspace, the angle range, the singularity margin, the leg forces and
``--max-leg-speed`` (stewart_env.identification.recording).
"""

from __future__ import annotations

import argparse

from stewart_env.cli.arguments import PLATFORM_RULE, integer, platform_name, positive_int, real, seed, writable_file
from stewart_env.cli.common import error

VERB = "excitation"
#: Longest excitation, s.
MAX_DURATION = 3600.0
rate = real(1.0, 1000.0, doc="argparse type of --rate, Hz.")
leg_speed = real(1e-3, 100.0, doc="argparse type of --max-leg-speed, m/s.")
harmonics = integer(1, 50, doc="argparse type of --harmonics.")


def duration(text: str) -> float:
    """Argparse type of --duration: seconds of set points, two settling times and half a second at least.

    Args:
        text: the command-line text.
    """
    from stewart_env.identification.experiment import SETTLE

    return real(2 * SETTLE + 0.5, MAX_DURATION)(text)


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``excitation`` subcommand to ``subparsers``.

    Args:
        subparsers: the subcommands of the ``stewart-env`` parser (``add_subparsers``'s result).

    Returns:
        The command's parser.
    """
    p = subparsers.add_parser(
        VERB,
        help="write the identification's excitation as time-stamped leg-length and pose set points",
        description="Optimise a Fourier-series excitation for the condition number of the base regressor "
        "(or draw a random one), sample it at --rate as leg lengths and poses with their twist and "
        "acceleration, check every sample against the platform's stroke, workspace, angle range, "
        "singularity margin, leg forces and --max-leg-speed, and write it in the log format (CSV, or HDF5 "
        "for a .h5 file) with a header naming the platform, the rate and the series.",
    )
    p.add_argument(
        "--platform",
        type=platform_name,
        default="dasgupta1998",
        help=f"platform: shipped platform name or YAML config path ({PLATFORM_RULE}; default dasgupta1998)",
    )
    p.add_argument(
        "--out", type=writable_file, required=True, help="the log to write (.csv, or .h5 with the extra logs)"
    )
    p.add_argument(
        "--rate", type=rate, default=200.0, help="set points per second, Hz; a period of whole ms (default 200)"
    )
    p.add_argument("--duration", type=duration, default=60.0, help="seconds of set points (default 60)")
    p.add_argument("--period", type=real(0.1, MAX_DURATION), default=10.0, help="the series' period, s (default 10)")
    p.add_argument("--harmonics", type=harmonics, default=5, help="the series' harmonics (default 5)")
    p.add_argument("--iterations", type=positive_int, default=30, help="optimiser iterations (default 30)")
    p.add_argument(
        "--max-leg-speed",
        type=leg_speed,
        help="the legs' top speed the set points keep under, m/s (default 0.85 of the platform's "
        "limits.leg_velocity, or 1 where it has none)",
    )
    p.add_argument("--random", action="store_true", help="the random series, not optimised")
    p.add_argument("--seed", type=seed, default=0, help="random seed (default 0)")
    return p


def run(args: argparse.Namespace) -> int:
    """Run the ``excitation`` subcommand; 0 on success, 2 on an error the user can correct.

    Args:
        args: the parsed command line, with the options :func:`add_parser` declares.

    Returns:
        The exit status, 0 on success.
    """
    from stewart_env.identification import log, recording
    from stewart_env.params import load_platform

    if args.out.lower().endswith(log.HDF5_SUFFIXES):
        from stewart_env.extras import require

        require("logs", "--out (an HDF5 log)")
    try:
        recording.rate_samples(args.rate)
        nominal = load_platform(args.platform)
        excitation, checks = recording.excitation_log(
            nominal,
            args.platform,
            rate=args.rate,
            duration=args.duration,
            seed=args.seed,
            random=args.random,
            period=args.period,
            harmonics=args.harmonics,
            max_iterations=args.iterations,
            max_leg_speed=args.max_leg_speed,
        )
        log.write(args.out, excitation, nominal)
    except ValueError as err:  # IdentificationError, LogError, an unwritable --out: the message names the cause
        return error(VERB, err)
    share = ", ".join(f"{k} {m:.2f}" for k, m in checks.margins.items())
    print(
        f"{args.out}: {excitation.time.size} set points over {excitation.time[-1]:.6g} s at {args.rate:g} Hz; "
        f"condition number {checks.condition:.4g}; top leg speed {checks.max_leg_speed:.3g} m/s; "
        f"margins to the limits (0 at the excitation's share of each, 1 at its middle): {share}"
    )
    return 0
