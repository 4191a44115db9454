"""``stewart-env bench``: the benchmark of the compiled core (:mod:`stewart_env.benchmarks`)."""

from __future__ import annotations

import argparse

from stewart_env.cli.arguments import PLATFORM_RULE, distinct_list, model_name, platform_name, writable_file
from stewart_env.cli.common import check_extras, error

VERB = "bench"


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``stewart-env bench`` command and its options.

    Args:
        subparsers: the subcommands of the ``stewart-env`` parser (``add_subparsers``'s result).

    Returns:
        The command's parser.
    """
    from stewart_env.benchmarks import MODEL_NAMES
    from stewart_env.benchmarks import __doc__ as description

    p = subparsers.add_parser(
        VERB,
        help="the benchmark of the compiled core (stewart_env.benchmarks)",
        description=description.split("\n\n")[0].replace("``", ""),
    )
    p.add_argument(
        "--platform",
        type=platform_name,
        default="dasgupta1998",
        help=f"shipped platform name or YAML config path ({PLATFORM_RULE})",
    )
    p.add_argument(
        "--models",
        type=distinct_list(model_name, "classical,improved"),
        default=",".join(MODEL_NAMES),
        help="comma-separated model names",
    )
    p.add_argument("--env", action="store_true", help="also benchmark the single and vector environments")
    p.add_argument("--plot", type=writable_file, metavar="PATH", help="also draw the scaling table to this PNG file")
    p.add_argument(
        "--mujoco",
        action="store_true",
        help="also time MuJoCo on the same mechanism beside the kernels, the env and the vector env "
        '(needs the extra: pip install -e ".[mujoco]")',
    )
    p.add_argument(
        "--derivatives",
        action="store_true",
        help="also time the exact derivatives of the dynamics and of a control step beside the values "
        "(and beside MuJoCo's mjd_transitionFD when the mujoco extra is installed)",
    )
    return p


def run(args: argparse.Namespace) -> int:
    """Run ``stewart-env bench``.

    Args:
        args: the parsed command line, with the options :func:`add_parser` declares.

    Returns:
        The exit status, 0 on success.
    """
    from stewart_env.benchmarks import run_bench

    problem = check_extras([("mujoco", "--mujoco")] if args.mujoco else [])
    if problem is not None:
        return error(VERB, f"argument --mujoco: {problem}")
    try:
        run_bench(
            args.platform, args.models, env=args.env, mujoco=args.mujoco, plot=args.plot, derivatives=args.derivatives
        )
    except ImportError as err:  # the MuJoCo library present but failing to load
        return error(VERB, f"argument --mujoco: {err}")
    return 0
