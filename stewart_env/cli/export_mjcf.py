"""``stewart-env export-mjcf``: a platform's mechanism as a MuJoCo model (MJCF XML)."""

from __future__ import annotations

import argparse
from pathlib import Path

from stewart_env.cli.arguments import PLATFORM_RULE, finite_float, platform_name, positive_float
from stewart_env.cli.common import check_extras, error

VERB = "export-mjcf"


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``stewart-env export-mjcf`` command and its options.

    Args:
        subparsers: the subcommands of the ``stewart-env`` parser (``add_subparsers``'s result).

    Returns:
        The command's parser.
    """
    p = subparsers.add_parser(
        VERB,
        help="write a platform's mechanism as a MuJoCo model (MJCF XML)",
        description="Write the mechanism of a platform config as MJCF for MuJoCo (stewart_env.mujoco.to_mjcf): "
        "the platform a free body, each leg a universal joint, a slide and a loop-closure constraint, "
        "masses, inertias, joint damping, force actuators, gravity, RK4.  An existing file is "
        'overwritten.  Needs the extra: pip install -e ".[mujoco]".',
    )
    p.add_argument(
        "--platform",
        type=platform_name,
        required=True,
        help=f"shipped platform name or YAML config path ({PLATFORM_RULE})",
    )
    p.add_argument("--out", required=True, help="the XML file to write")
    p.add_argument("--timestep", type=positive_float, default=1e-3, help="MuJoCo's time step, s (default 1e-3)")
    p.add_argument(
        "--solref",
        type=finite_float,
        nargs=2,
        metavar=("TIMECONST", "DAMPRATIO"),
        help="softness of the loop-closure constraints (default: stewart_env.mujoco.DEFAULT_SOLREF)",
    )
    p.add_argument(
        "--solimp",
        type=finite_float,
        nargs=5,
        metavar=("DMIN", "DMAX", "WIDTH", "MID", "POWER"),
        help="impedance of the loop-closure constraints (default: stewart_env.mujoco.DEFAULT_SOLIMP)",
    )
    return p


def run(args: argparse.Namespace) -> int:
    """The MJCF text of --platform into the file --out.

    Args:
        args: the parsed command line, with the options :func:`add_parser` declares.

    Returns:
        The exit status, 0 on success.
    """
    from stewart_env import mujoco as twin
    from stewart_env.errors import UsageError
    from stewart_env.files import check_writable
    from stewart_env.params import load_platform

    out = Path(args.out)
    if out.is_dir():
        return error(VERB, f"argument --out: {str(out)!r} is a directory; give the XML file's name")
    try:
        check_writable(out.parent, create=False)
    except ValueError as err:  # stewart_env.files.NotWritable
        return error(VERB, f"argument --out: {err}")
    problem = check_extras([("mujoco", "export-mjcf")])
    if problem is not None:
        return error(VERB, problem)
    kwargs = {k: getattr(args, k) for k in ("solref", "solimp") if getattr(args, k) is not None}
    try:
        xml = twin.to_mjcf(load_platform(args.platform), timestep=args.timestep, **kwargs)
    except (ImportError, UsageError) as err:  # --timestep, --solref or --solimp out of range: said of its flag
        return error(VERB, err)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(xml)
    except OSError as err:  # a full disk, a parent that is a file, no permission
        return error(VERB, f"argument --out: cannot write {str(out)!r}: {err.strerror or err}")
    print(f"wrote {out} (MuJoCo model of {args.platform})")
    return 0
