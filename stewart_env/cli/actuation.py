"""``stewart-env actuation``: what actuation costs each action mode's controllers
(:mod:`stewart_env.agents.studies.actuation`) from the command line.  :func:`add_parser` registers
the verb with its options, :func:`run` runs it and returns the exit code: 0 done, 1 stopped by a
failing write (the finished cells are kept), 2 a bad request, 130 interrupted (the finished cells
are kept; a training stopped by SIGINT or SIGTERM saves a checkpoint it continues from, 130 or 143)."""

from __future__ import annotations

import argparse
import sys

from stewart_env.cli.arguments import directory_name, existing_directory, positive_int, seed_list
from stewart_env.cli.common import check_extras, check_out, error
from stewart_env.envs.config import ACTION_MODES, ACTUATORS

__all__ = ["add_parser", "run"]

VERB = "actuation"
#: The tasks of the study (those of :data:`stewart_env.agents.studies.actuation.TASKS`).
TASKS = ("setpoint", "tracking")


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``actuation`` to an argparse subparsers object; its ``func`` is :func:`run`.

    Args:
        subparsers: the subcommands of the ``stewart-env`` parser (``add_subparsers``'s result).

    Returns:
        The command's parser.
    """
    p = subparsers.add_parser(
        VERB,
        help="what actuation costs: each action mode's controllers on ideal, lag, electric and hydraulic actuators",
        description="On the motion_simulator platform, per task, action mode and actuator level, evaluate "
        "the mode's controllers (force: PD with gravity compensation and computed torque; pose: the target "
        "commanded to the ik, pd_gravity or computed_torque inner loop; leg_length: the target's inverse "
        "kinematics commanded to the leg servos; and PPO with the mode's shipped config in the cells "
        "--ppo names) on the same seeded episodes: success, RMS errors, peak leg force, cost rate and limit "
        "hits with 95 %% intervals. Writes DIR/actuation.md, DIR/actuation.csv and DIR/results.json; a "
        "second run into DIR reuses the finished cells, and an interrupted run keeps them.",
    )
    p.add_argument("--out", type=directory_name, required=True, help="the study's folder (created)")
    p.add_argument("--tasks", nargs="+", choices=TASKS, default=list(TASKS), help="tasks (default: setpoint tracking)")
    p.add_argument(
        "--modes", nargs="+", choices=ACTION_MODES, default=list(ACTION_MODES), help="action modes (default: all)"
    )
    p.add_argument(
        "--actuators", nargs="+", choices=ACTUATORS, default=list(ACTUATORS), help="actuator levels (default: all)"
    )
    p.add_argument(
        "--episodes", type=positive_int, default=5, help="evaluation episodes per cell and PPO seed (default: 5)"
    )
    p.add_argument(
        "--ppo",
        nargs="*",
        default=[],
        metavar="MODE:ACTUATOR:TASK",
        help="the cells PPO runs in, e.g. pose:electric:setpoint, or all (every mode, actuator and task asked; "
        "default: none, the model-based controllers only)",
    )
    p.add_argument(
        "--seeds", type=seed_list, default=(0, 1, 2), help="PPO's training seeds, comma-separated (default: 0,1,2)"
    )
    p.add_argument(
        "--timesteps",
        type=positive_int,
        default=None,
        help="environment steps per PPO agent (default: the mode's config's n_timesteps)",
    )
    p.add_argument(
        "--agents",
        type=existing_directory,
        default=None,
        help="a folder of trained agents (MODE-ACTUATOR-TASK/seed_S, the layout of DIR/agents), read only: "
        "a missing agent leaves its seed out (default: DIR/agents, where the missing agents are trained)",
    )
    p.add_argument(
        "--max-steps", type=positive_int, default=None, help="episode length in control steps (default: 500)"
    )
    p.add_argument(
        "--ppo-trained-on",
        default=None,
        metavar="ACTUATOR",
        help="train every PPO agent on this actuator and run it on its cell's (e.g. ideal: what the drives cost "
        "one agent; default: each cell's own actuator)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    return p


def run(args: argparse.Namespace) -> int:
    """Run ``stewart-env actuation``.

    Args:
        args: the parsed command line, with the options :func:`add_parser` declares.

    Returns:
        The exit status, 0 on success.
    """
    needs = [("rl", "PPO (--ppo)")] if args.ppo else []
    problem = check_extras(needs) or check_out(args)
    if problem is not None:
        return error(VERB, problem)
    from stewart_env.agents.studies.actuation import ActuationError, ActuationSettings, run_actuation
    from stewart_env.files import WriteError

    try:
        settings = ActuationSettings(
            tasks=args.tasks,
            modes=args.modes,
            actuators=args.actuators,
            episodes=args.episodes,
            ppo_cells=args.ppo,
            seeds=args.seeds,
            timesteps=args.timesteps,
            agents=args.agents,
            max_steps=args.max_steps,
            ppo_trained_on=args.ppo_trained_on,
        )
    except ActuationError as err:
        return error(VERB, f"argument --{err.argument.replace('_cells', '').replace('_', '-')}: {err.problem}")
    kept = f"; the finished cells are kept in {args.out} (run the same command again to continue)"
    try:
        result = run_actuation(args.out, settings, progress=not args.no_progress)
    except WriteError as exc:
        print(f"stewart-env {VERB}: error: {exc}{kept}", file=sys.stderr)
        return 1
    except ValueError as exc:  # a training's error (another agent in the agents' folder), named
        return error(VERB, exc)
    except KeyboardInterrupt as stop:
        checkpoint = getattr(stop, "checkpoint", None)  # a training stopped by a signal saved one
        if checkpoint is not None:
            print(f"stewart-env {VERB}: stopped; checkpoint saved in {checkpoint}{kept}", file=sys.stderr)
            return stop.exit_code
        print(f"stewart-env {VERB}: interrupted{kept}", file=sys.stderr)
        return 130
    print(f"{len(result['cells'])} cells -> {result['files']['markdown']}")
    return 0
