"""``python -m stewart_env.mujoco [PLATFORM ...] [--actuator electric]``: the accuracy report of MuJoCo's twin
(:func:`stewart_env.mujoco.accuracy_report`).  Not a verb of ``stewart-env``: the module's own
entry point, whose parser lives here with the others."""

from __future__ import annotations

import argparse
from collections.abc import Sequence

from stewart_env.cli.common import check_extras

PROG = "python -m stewart_env.mujoco"


def build_parser() -> argparse.ArgumentParser:
    """The parser of ``python -m stewart_env.mujoco``."""
    from stewart_env.mujoco import accuracy_report

    parser = argparse.ArgumentParser(prog=PROG, description=accuracy_report.__doc__.split("\n\n")[0])
    parser.add_argument(
        "platforms",
        nargs="*",
        default=["dasgupta1998", "motion_simulator"],
        help="platform config names or YAML paths (default: both shipped platforms)",
    )
    parser.add_argument(
        "--actuator",
        choices=["ideal", "electric"],
        default="ideal",
        help="the legs' actuator: the ideal force source (default) or the platform config's electric "
        "drive (actuators: electric:), compared with the closed form's reflected masses",
    )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``python -m stewart_env.mujoco``: the accuracy report of the MuJoCo twin.

    Args:
        argv: the command line without the program's name (default ``sys.argv[1:]``).

    Returns:
        The exit status, 0 on success.
    """
    from stewart_env.mujoco import accuracy_report
    from stewart_env.params import load_platform

    parser = build_parser()
    args = parser.parse_args(argv)
    problem = check_extras([("mujoco", PROG)])
    if problem is not None:
        parser.error(problem)
    platforms = []
    for name in args.platforms:
        try:
            platforms.append(load_platform(name))
        except (ValueError, OSError) as err:
            parser.error(f"argument platforms: {err}")
        if args.actuator == "electric" and platforms[-1].actuators.electric is None:
            parser.error(
                f"argument --actuator: 'electric' needs the platform config's actuators: electric: section, "
                f"which {name!r} has not"
            )
    for i, params in enumerate(platforms):
        print(("\n" if i else "") + accuracy_report(params, args.actuator))
    return 0
