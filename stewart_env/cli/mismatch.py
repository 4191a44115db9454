"""``stewart-env mismatch``: the model-mismatch study (:mod:`stewart_env.agents.mismatch`), whose
parser and run function the study's module provides."""

from __future__ import annotations

import argparse

from stewart_env.cli.arguments import agent_config
from stewart_env.cli.common import announce_compilation, check_extras, check_out, error

VERB = "mismatch"


def add_parser(subparsers) -> argparse.ArgumentParser:
    from stewart_env.agents import mismatch

    p = mismatch.add_cli(subparsers)
    # a description is not %-formatted by argparse (help strings are): one percent sign, as printed
    p.description = p.description.replace("%%", "%")
    config = next(action for action in p._actions if action.dest == "config")
    config.type = agent_config
    config.help = ("the agents' hyperparameters: a zoo config file, or the name of a shipped config (e.g. "
                   "ppo_integral) (default: configs/agents/<algo>.yml)")
    return p


def run(args: argparse.Namespace) -> int:
    needs = [("rl", "training agents (--algo none runs the model-based rows only)")] if args.algo != "none" else []
    if args.backend == "ray":
        needs.append(("distributed", "--backend ray"))
    problem = check_extras(needs) or check_out(args)
    if problem is not None:
        return error(VERB, problem)
    announce_compilation()
    return args.func(args)
