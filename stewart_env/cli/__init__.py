"""The ``stewart-env`` command: demo, evaluate, reproduce, train, time-to-agent, mismatch, actuation,
cueing-results, identify, bench, export-mjcf, excitation, record.

    stewart-env demo                       PD baseline on the classical and improved models
    stewart-env evaluate --policy pd ct --model classical improved --task tracking --out results/
    stewart-env evaluate --agent runs/ppo --model classical improved
    stewart-env reproduce --out figures/   the case study of He et al. (2018), Fig. 6-10
    stewart-env train ... / mismatch ...   stewart_env.agents.training and .mismatch
    stewart-env actuation --out results/actuation   each action mode's controllers on each actuator level
    stewart-env cueing-results --out results/cueing   PPO against the tuned washout on held-out manoeuvres
    stewart-env identify --platform dasgupta1998 --out runs/ident   identification on a stand-in plant
    stewart-env bench ...                  the benchmark (stewart_env.benchmarks)
    stewart-env export-mjcf --platform dasgupta1998 --out stewart.xml   the MuJoCo twin as MJCF
    stewart-env excitation --platform dasgupta1998 --out exc.csv   the excitation as set points
    stewart-env record --trajectory exc.csv --out log.csv   a stand-in machine's drive log

Each subcommand has ``--help``.  One module per verb in this package, each with
``add_parser(subparsers)`` and ``run(args) -> int``; :data:`VERBS` is the table :func:`main`
dispatches on.  The argparse types live in :mod:`stewart_env.cli.arguments`; no module that does
the work imports argparse.  Every error a user can correct
(:class:`stewart_env.errors.UsageError`), and every missing optional extra, is one line
``stewart-env <verb>: error: ...`` with exit status 2; an error about an argument a flag sets
names the flag (:data:`stewart_env.cli.common.FLAGS`).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from types import ModuleType

from stewart_env.cli import (
    actuation,
    bench,
    cueing_results,
    demo,
    evaluate,
    excitation,
    export_mjcf,
    identify,
    mismatch,
    record,
    reproduce,
    time_to_agent,
    train,
)
from stewart_env.cli.common import error
from stewart_env.errors import UsageError
from stewart_env.extras import extra_of, install_hint
from stewart_env.registration import ENV_ID

__all__ = ["VERBS", "build_parser", "main"]

#: Each verb's module, in the order ``--help`` lists them.
VERBS: dict[str, ModuleType] = {
    module.VERB: module
    for module in (
        demo,
        evaluate,
        reproduce,
        train,
        time_to_agent,
        mismatch,
        actuation,
        cueing_results,
        identify,
        bench,
        export_mjcf,
        excitation,
        record,
    )
}


def _version() -> str:
    import stewart_env

    return f"stewart-env {stewart_env.__version__}"


def build_parser() -> argparse.ArgumentParser:
    """The parser of ``stewart-env``, every verb a subparser (the site's command reference is
    generated from it)."""
    parser = argparse.ArgumentParser(
        prog="stewart-env",
        description="The 6-UPS Stewart platform on closed-form Newton-Euler dynamics: baselines, "
        "evaluation and the reproduction of He et al. (2018).  The Gymnasium environment's id is "
        f"{ENV_ID}.",
        epilog=f"Quick start: `stewart-env demo` compares the PD baseline on the classical and improved models "
        f"(under a minute); in Python, `import stewart_env` registers the environment: "
        f'`gym.make("{ENV_ID}")`.  Each command has --help.',
    )
    parser.add_argument("--version", action="version", version=_version())
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for module in VERBS.values():
        module.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``stewart-env`` with ``argv`` (default the process's arguments); the exit status.

    Args:
        argv: the command line without the program's name (default ``sys.argv[1:]``).
    """
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv:  # no command: what there is to run, not argparse's complaint that a command is missing
        parser.print_help()
        return 0
    args = parser.parse_args(argv)
    try:
        return VERBS[args.command].run(args)
    except UsageError as err:
        return error(args.command, err)
    except ImportError as err:
        extra = extra_of(err)
        if extra is None:
            raise
        # the extra is known from the module that failed to import, never from the message's words
        return error(args.command, f"{err}; {install_hint(extra)}")
