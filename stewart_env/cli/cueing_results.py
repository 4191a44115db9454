"""``stewart-env cueing-results``: PPO with the shipped cueing config against the tuned washout on
held-out manoeuvres (:mod:`stewart_env.agents.studies.cueing_results`) from the command line.
:func:`add_parser` registers the verb with its options, :func:`run` runs it and returns the exit
code: 0 done, 1 stopped by a failing write (the finished evaluations are kept), 2 a bad request,
130 interrupted (the finished evaluations are kept; a training stopped by SIGINT or SIGTERM saves
a checkpoint it continues from, 130 or 143)."""

from __future__ import annotations

import argparse
import sys

from stewart_env.cli.arguments import directory_name, existing_directory, positive_int, seed_list
from stewart_env.cli.common import check_extras, check_out, error

__all__ = ["add_parser", "run"]

VERB = "cueing-results"


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``cueing-results`` to an argparse subparsers object; its ``func`` is :func:`run`.

    Args:
        subparsers: the subcommands of the ``stewart-env`` parser (``add_subparsers``'s result).

    Returns:
        The command's parser.
    """
    p = subparsers.add_parser(
        VERB,
        help="the cueing results: PPO (configs/agents/ppo_cueing_residual.yml) against the tuned washout on "
        "held-out manoeuvres",
        description="Train one PPO agent per seed with a cueing config (default ppo_cueing_residual: PPO as a "
        "residual on the tuned washout) on task cueing (or read them from --agents), then run them and the tuned washout (configs/agents/washout.yaml) on the same "
        "held-out episodes of a lane change, braking, a coordinated turn and a lateral sweep: perceived "
        "specific-force RMS error, false cues, specific-force correlation and stroke use with 95 % intervals, "
        "and the goals against washout marked reached or not. Writes DIR/cueing.md, DIR/results.json and "
        "DIR/perceived_specific_force.png; a second run into DIR reuses the finished evaluations and agents.",
    )
    p.add_argument("--out", type=directory_name, required=True, help="the study's folder (created)")
    p.add_argument(
        "--seeds",
        type=seed_list,
        default=(0, 1, 2, 3, 4),
        help="PPO's training seeds, comma-separated (default: 0,1,2,3,4)",
    )
    p.add_argument(
        "--timesteps", type=positive_int, default=None, help="environment steps per agent (default: the config's)"
    )
    p.add_argument(
        "--episodes", type=positive_int, default=3, help="held-out seeds per manoeuvre, 1 to 10 (default: 3)"
    )
    p.add_argument(
        "--agents",
        type=existing_directory,
        default=None,
        help="a folder of trained agents (seed_S, the layout of DIR/agents), read only: a missing agent leaves "
        "its seed out; agents trained on another model (--agent-models) are read from its sibling agents_MODEL "
        "(default: DIR/agents, where the missing agents are trained)",
    )
    p.add_argument(
        "--config",
        default="ppo_cueing_residual",
        help="PPO's cueing config, a shipped name or a file's path: ppo_cueing_residual (PPO as a residual on "
        "the washout, its key residual_washout), ppo_cueing_mpc_residual (PPO as a residual on the cueing MPC, "
        "its key residual_mpc; extra mpc), ppo_cueing_mpc (PPO from an imitation of the cueing MPC, its key "
        "imitate_mpc; extra mpc) or ppo_cueing (PPO commands the pose itself) (default: ppo_cueing_residual)",
    )
    p.add_argument(
        "--agent-models",
        nargs="+",
        default=(),
        metavar="MODEL",
        help="what a model costs the cueing agent: also train each seed's agent on each of these dynamics "
        "models (e.g. classical, improved+c1) into DIR/agents_MODEL and run it on the improved plant beside "
        "the agents trained on the improved model; the table gains their rows and each model's cost with "
        "paired intervals (default: none)",
    )
    p.add_argument(
        "--mpc-preview",
        nargs="+",
        type=int,
        default=(),
        metavar="N",
        help="also run the model-predictive cueing baseline (CueingMPCPolicy, needs the extra mpc) on the "
        "held-out episodes, once per preview N (the task's preview option, 0 to 100 samples of the vehicle's "
        "coming motion), each its rows and goals against washout (default: none)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    return p


def run(args: argparse.Namespace) -> int:
    """Run ``stewart-env cueing-results``.

    Args:
        args: the parsed command line, with the options :func:`add_parser` declares.

    Returns:
        The exit status, 0 on success.
    """
    extras = [("rl", "PPO")] + ([("mpc", "the cueing MPC (--mpc-preview)")] if args.mpc_preview else [])
    problem = check_extras(extras) or check_out(args)
    if problem is not None:
        return error(VERB, problem)
    from stewart_env.agents.studies.cueing_results import CueingResultsSettings, run_cueing_results
    from stewart_env.errors import UsageError
    from stewart_env.files import WriteError

    try:
        settings = CueingResultsSettings(
            seeds=tuple(args.seeds),
            timesteps=args.timesteps,
            episodes=args.episodes,
            config=args.config,
            agent_models=tuple(args.agent_models),
            mpc_previews=tuple(args.mpc_preview),
        )
    except UsageError as err:
        option = {"mpc_previews": "mpc_preview"}.get(err.argument, err.argument)
        return error(VERB, f"argument --{option.replace('_', '-')}: {err.problem}")
    kept = f"; the finished evaluations are kept in {args.out} (run the same command again to continue)"
    try:
        results = run_cueing_results(args.out, settings, agents=args.agents, progress=not args.no_progress)
    except WriteError as exc:
        print(f"stewart-env {VERB}: error: {exc}{kept}", file=sys.stderr)
        return 1
    except ValueError as exc:  # a training's error (another agent in the agents' folder), named
        return error(VERB, exc)
    except KeyboardInterrupt as stop:
        checkpoint = getattr(stop, "checkpoint", None)
        if checkpoint is not None:
            print(f"stewart-env {VERB}: stopped; checkpoint saved in {checkpoint}{kept}", file=sys.stderr)
            return stop.exit_code
        print(f"stewart-env {VERB}: interrupted{kept}", file=sys.stderr)
        return 130
    print(f"PPO seeds {results['seeds']} against washout -> {args.out}/cueing.md")
    return 0
