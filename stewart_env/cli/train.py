"""``stewart-env train``: a stable-baselines3 agent trained on ``StewartPlatform-v1``
(:func:`stewart_env.agents.training.train`)."""

from __future__ import annotations

import argparse
import signal
import sys

from stewart_env.agents.training import ALGORITHMS, DEFAULT_KEEP_CHECKPOINTS
from stewart_env.cli.arguments import (
    TASKS,
    agent_config,
    directory_name,
    env_kwargs_token,
    nonnegative_int,
    plant_model_name,
    platform_count,
    positive_int,
    seed,
)
from stewart_env.cli.common import check_extras, check_out, error, plant_extras

VERB = "train"


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``stewart-env train`` command and its options.

    Args:
        subparsers: the subcommands of the ``stewart-env`` parser (``add_subparsers``'s result).

    Returns:
        The command's parser.
    """
    p = subparsers.add_parser(
        VERB,
        help="train an RL agent (stable-baselines3) on StewartPlatform-v1",
        description="Train a stable-baselines3 agent with the hyperparameters of configs/agents/<algo>.yml "
        "(rl-baselines3-zoo format). Writes DIR/model.zip, DIR/vecnormalize.pkl, DIR/run.json, "
        "checkpoints and TensorBoard logs. SIGINT (Ctrl-C) or SIGTERM saves a checkpoint and exits "
        "with 130 or 143; a second signal exits at once. Needs the extra rl.",
    )
    p.add_argument("--algo", required=True, choices=ALGORITHMS, help=f"algorithm: {', '.join(ALGORITHMS)}")
    p.add_argument(
        "--model",
        type=plant_model_name,
        default=None,
        help="plant: a dynamics model, or mujoco for MuJoCo's simulation of the same mechanism "
        "(needs the mujoco extra) (default: improved; with --resume, the run's)",
    )
    p.add_argument("--task", choices=TASKS, default=None, help="task (default: setpoint; with --resume, the run's)")
    p.add_argument(
        "--timesteps",
        type=positive_int,
        default=None,
        help="environment steps of this call, at least: SB3 rounds up to whole rollouts of n_steps x "
        "n_envs (default: the config's n_timesteps; with --resume, steps added to those done)",
    )
    p.add_argument("--seed", type=seed, default=None, help="random seed (default: 0; with --resume, the run's)")
    p.add_argument("--out", type=directory_name, required=True, help="run directory (new or empty, unless --resume)")
    p.add_argument(
        "--resume",
        action="store_true",
        help="continue the run in --out from its newest complete checkpoint; a setting that differs from "
        "the run's is refused, except --timesteps",
    )
    p.add_argument(
        "--n-envs",
        type=platform_count,
        default=None,
        help="platforms in the training batch (default: the config's; with --resume, the run's)",
    )
    p.add_argument(
        "--checkpoint-freq",
        type=nonnegative_int,
        default=50_000,
        help="environment steps between checkpoints, 0 for none but the final (default: 50000)",
    )
    p.add_argument(
        "--keep-checkpoints",
        type=positive_int,
        default=DEFAULT_KEEP_CHECKPOINTS,
        metavar="K",
        help=f"keep the newest K checkpoints (default: {DEFAULT_KEEP_CHECKPOINTS})",
    )
    p.add_argument(
        "--config",
        type=agent_config,
        default=None,
        help="hyperparameter file: a path, or the name of a shipped config (e.g. ppo_6m) "
        "(default: configs/agents/<algo>.yml; with --resume, the run's)",
    )
    p.add_argument(
        "--env-kwargs",
        nargs="*",
        type=env_kwargs_token,
        default=None,
        metavar="KW",
        help="environment kwargs: a JSON object or key=value pairs (values parsed as JSON)",
    )
    p.add_argument(
        "--no-progress", action="store_true", help="no progress bar (there is none unless stderr is a terminal)"
    )
    return p


def run(args: argparse.Namespace) -> int:
    """Run ``stewart-env train``.

    Args:
        args: the parsed command line, with the options :func:`add_parser` declares.

    Returns:
        The exit status, 0 on success.
    """
    problem = check_extras([("rl", "training"), *plant_extras([args.model])]) or check_out(args)
    if problem is not None:
        return error(VERB, problem)
    from stewart_env.agents.training import TrainingInterrupted, parse_env_kwargs, train

    try:
        result = train(
            args.algo,
            args.out,
            model=args.model,  # parsed once by --model's type; run.json records its canonical name
            task=args.task,
            timesteps=args.timesteps,
            seed=args.seed,
            n_envs=args.n_envs,
            checkpoint_freq=args.checkpoint_freq,
            keep_checkpoints=args.keep_checkpoints,
            env_kwargs=parse_env_kwargs(args.env_kwargs),
            config=args.config,
            resume=args.resume,
            progress_bar=not args.no_progress,
        )
    except TrainingInterrupted as stop:
        print(
            f"stewart-env train: stopped by {signal.Signals(stop.signum).name}; checkpoint saved in "
            f"{stop.checkpoint} (continue with --resume)",
            file=sys.stderr,
        )
        return stop.exit_code
    except KeyboardInterrupt:
        again = (
            "its checkpoints are kept: run the same command to continue it"
            if args.resume
            else "run the same command to start it again"
        )
        print(f"stewart-env train: interrupted before training started; nothing saved ({again})", file=sys.stderr)
        return 130
    except ValueError as exc:  # TrainingError, a file error, an environment setting: named in the message
        return error(VERB, exc)
    print(
        f"trained {args.algo}: requested {result.requested} steps, ran {result.steps_this_run} (whole rollouts "
        f"of {result.rollout}); {result.num_timesteps} in total, in {result.wall_time:.0f} s -> {result.directory}"
    )
    return 0
