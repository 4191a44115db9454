"""``python -m stewart_env.mujoco [PLATFORM ...]``: the accuracy report of MuJoCo's twin."""

from __future__ import annotations

from collections.abc import Sequence

from stewart_env.mujoco.accuracy import accuracy_report

__all__ = ["main"]


def main(argv: Sequence[str] | None = None) -> int:
    import argparse

    from stewart_env.params import load_platform

    parser = argparse.ArgumentParser(prog="python -m stewart_env.mujoco", description=accuracy_report.__doc__.split("\n\n")[0])
    parser.add_argument("platforms", nargs="*", default=["dasgupta1998", "motion_simulator"],
                        help="platform config names or YAML paths (default: both shipped platforms)")
    args = parser.parse_args(argv)
    for i, name in enumerate(args.platforms):
        try:
            params = load_platform(name)
        except (ValueError, OSError) as err:
            parser.error(f"argument platforms: {err}")
        print(("\n" if i else "") + accuracy_report(params))
    return 0
