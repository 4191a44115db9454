"""``stewart-env mismatch``: the model-mismatch study (:mod:`stewart_env.agents.studies.mismatch`) from
the command line.  :func:`add_parser` registers the verb with its options, :func:`run` runs it
and returns the exit code: 0 done, 1 stopped by a failed backend or write (what finished is
kept), 2 a bad request, 128 + N stopped by signal N."""

from __future__ import annotations

import argparse
import signal
import sys

from stewart_env.agents.evaluation.evaluation import ORIENTATION_TOLERANCE, POSITION_TOLERANCE
from stewart_env.agents.studies.mismatch import (
    AUTO_THREADS,
    BACKENDS,
    CONTROLLERS,
    DEFAULT_CONTROLLERS,
    FAILURE_THRESHOLD,
    QUICK_TIMESTEPS,
    SIMPLIFICATIONS,
    TRUE_MODEL,
    BackendError,
    run_mismatch,
)
from stewart_env.agents.training import ALGORITHMS, TrainingError, TrainingInterrupted, parse_env_kwargs
from stewart_env.cli.arguments import (
    PLATFORM_RULE,
    TASKS,
    agent_config,
    choice,
    directory_name,
    distinct_list,
    env_kwargs_token,
    episode_steps,
    integer,
    plant_list,
    plant_model_name,
    platform_count,
    platform_name,
    positive_float,
    positive_int,
    seed_list,
)
from stewart_env.cli.common import check_extras, check_out, error
from stewart_env.dynamics.threads import MAX_THREADS
from stewart_env.envs.config import ACTUATORS
from stewart_env.files import WriteError

__all__ = ["add_parser", "controller_platform", "physics_threads", "run", "simplification_list"]

VERB = "mismatch"


def simplification_list(text: str) -> list[str]:
    """Argparse type of --simplifications: comma-separated names of c1..c4, each once, or ``none``.

    Args:
        text: the command-line text.
    """
    if text.strip().lower() == "none":
        return []
    return distinct_list(choice(SIMPLIFICATIONS), "c1,c3")(text)


def controller_platform(text: str) -> str:
    """Argparse type of --controller-platform: ``[NAME=]PLATFORM`` whose platform loads (the study
    checks the name against its rows).

    Args:
        text: the command-line text.
    """
    from stewart_env.agents.studies.mismatch.settings import MismatchError, check_controller_platforms

    try:
        check_controller_platforms([text])  # the study's own rule for NAME and PLATFORM
    except MismatchError as err:
        raise argparse.ArgumentTypeError(err.problem) from None
    return text


def physics_threads(text: str) -> int | str:
    """Argparse type of --physics-threads: ``auto`` or a thread count from 1 to ``MAX_THREADS``.

    Args:
        text: the command-line text.

    Returns:
        ``"auto"`` or the count.
    """
    if text.strip().lower() == AUTO_THREADS:
        return AUTO_THREADS
    return thread_count(text)


#: A thread count (:func:`stewart_env.set_num_threads`'s range).
thread_count = integer(1, MAX_THREADS, f"'auto' or an integer from 1 to {MAX_THREADS}")


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``mismatch`` to an argparse subparsers object; its ``func`` is :func:`run`.

    Args:
        subparsers: the subcommands of the ``stewart-env`` parser (``add_subparsers``'s result).

    Returns:
        The command's parser.
    """
    p = subparsers.add_parser(
        VERB,
        help="model-mismatch study: controllers built on one model, run on another",
        description="Train (or load) RL agents per training model and seed, build the model-based "
        "controllers (--controllers: PD and computed torque, or also the LQR and the MPC) on the same "
        "models and on the improved model with each of C1..C4 switched on, "
        "evaluate every controller on every test plant, and write DIR/matrix.md, DIR/matrix.csv "
        "(95 % intervals), DIR/differences.csv, DIR/forest.png and DIR/heatmap_<metric>.png.",
    )
    p.add_argument(
        "--train-models",
        type=plant_list,
        default="classical,improved",
        help="comma-separated models to train agents on / build PD and CT on (default: classical,improved)",
    )
    p.add_argument(
        "--test-models",
        type=plant_list,
        default="classical,improved,improved_centroidal",
        help="comma-separated plant models (default: classical,improved,improved_centroidal)",
    )
    p.add_argument("--task", default="setpoint", choices=TASKS, help="task (default: setpoint)")
    p.add_argument(
        "--platform",
        default="dasgupta1998",
        type=platform_name,
        help=f"shipped platform name or YAML config path ({PLATFORM_RULE}): the plants' (the truth), and "
        "the controllers' but those of "
        "--controller-platform (default: dasgupta1998)",
    )
    p.add_argument(
        "--controller-platform",
        type=controller_platform,
        action="append",
        default=[],
        metavar="[NAME=]PLATFORM",
        help="a further platform the controllers are built on (e.g. an identified platform.yaml), "
        "its rows labelled [model @ NAME] (default NAME: the config's name or file stem), run on "
        "--platform's plants; repeat for several",
    )
    p.add_argument(
        "--controllers",
        nargs="+",
        choices=CONTROLLERS,
        default=list(DEFAULT_CONTROLLERS),
        help="the model-based controllers built on each model: pd (task-space PD with the model's holding "
        "forces), ct (computed torque), lqr (an LQR around home from the model's control step Jacobians), "
        "mpc (the linearised MPC with the leg force limits, needs the extra mpc) (default: pd ct)",
    )
    p.add_argument("--out", type=directory_name, required=True, help="study directory")
    p.add_argument(
        "--algo",
        default="ppo",
        choices=(*ALGORITHMS, "none"),
        help="RL algorithm, or 'none' for the model-based rows only (default: ppo)",
    )
    p.add_argument(
        "--timesteps",
        type=positive_int,
        default=QUICK_TIMESTEPS,
        help=f"environment steps per agent (default: {QUICK_TIMESTEPS}, a quick smoke-scale study)",
    )
    p.add_argument(
        "--n-envs", type=platform_count, default=None, help="platforms per training batch (default: the config's)"
    )
    p.add_argument("--episodes", type=platform_count, default=5, help="evaluation episodes per cell (default: 5)")
    p.add_argument(
        "--max-steps",
        type=episode_steps,
        default=None,
        help="evaluation episode length in control steps (default: the registered 500)",
    )
    p.add_argument(
        "--position-tolerance",
        type=positive_float,
        default=POSITION_TOLERANCE,
        help=f"success band, m (default: {POSITION_TOLERANCE}); a cell succeeding in fewer than "
        f"{100 * FAILURE_THRESHOLD:g}%% of its episodes is marked failed",
    )
    p.add_argument(
        "--orientation-tolerance",
        type=positive_float,
        default=ORIENTATION_TOLERANCE,
        help=f"success band, rad (default: {ORIENTATION_TOLERANCE})",
    )
    p.add_argument(
        "--cost-plant",
        type=plant_model_name,
        default=TRUE_MODEL,
        help=f"the test plant the simplifications' costs are measured on (default: {TRUE_MODEL})",
    )
    p.add_argument(
        "--seeds",
        type=seed_list,
        default=[0],
        help="training seeds, comma-separated: one agent per seed and learned row (default: 0)",
    )
    p.add_argument(
        "--agent-models",
        type=plant_list,
        default=None,
        help="comma-separated models to train agents on (default: every model of the study, improved+cK included)",
    )
    p.add_argument(
        "--config",
        type=agent_config,
        default=None,
        help="the agents' hyperparameters: a zoo config file, or the name of a shipped config (e.g. "
        "ppo_6m) (default: configs/agents/<algo>.yml)",
    )
    p.add_argument(
        "--domain-randomization",
        action="store_true",
        help="add agents trained on the improved model with domain randomisation",
    )
    p.add_argument(
        "--simplifications",
        type=simplification_list,
        default=",".join(SIMPLIFICATIONS),
        help="which of c1..c4 get an improved+cK row, comma-separated, or 'none' (default: all)",
    )
    p.add_argument(
        "--env-kwargs",
        nargs="*",
        type=env_kwargs_token,
        default=None,
        metavar="KW",
        help="further environment kwargs for training and testing: JSON or key=value",
    )
    p.add_argument(
        "--backend",
        default="local",
        choices=BACKENDS,
        help="local: in this process (default); ray: every training run and evaluation a Ray task",
    )
    p.add_argument(
        "--ray-address",
        default=None,
        help="with --backend ray: an existing cluster, 'auto' or HOST:PORT (default: a local Ray instance)",
    )
    p.add_argument(
        "--physics-threads",
        type=physics_threads,
        default=AUTO_THREADS,
        metavar="auto|N",
        help="each job's physics threads: auto, the CPUs a Ray job was given (one) or this process's "
        "count with --backend local; or N for every job (default: auto)",
    )
    p.add_argument(
        "--plant-actuator",
        choices=ACTUATORS,
        default=None,
        help="the test plants' actuator, when it is not the one the controllers are built on (that of "
        "--env-kwargs, ideal by default): e.g. electric runs controllers built on ideal force sources on "
        "electric drives (drives need --platform motion_simulator; lag needs actuator_tau in --env-kwargs)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(func=run)
    return p


def _problem(args: argparse.Namespace) -> str | None:
    """What the parsed options ask that cannot run, naming the flag, before the study writes
    anything; None if nothing."""
    twice = sorted({c for c in args.controllers if args.controllers.count(c) > 1})
    if twice:
        return f"argument --controllers: {', '.join(twice)} given twice"
    if args.ray_address is not None and (args.backend != "ray" or not args.ray_address.strip()):
        return (
            "argument --ray-address: only with --backend ray"
            if args.backend != "ray"
            else "argument --ray-address: expected 'auto' or HOST:PORT, got ''"
        )
    if args.env_kwargs:
        from stewart_env.envs import StewartPlatformEnv

        try:  # an unknown keyword or a bad value, named by the environment
            StewartPlatformEnv(**parse_env_kwargs(args.env_kwargs)).close()
        except (ValueError, TypeError) as err:
            return f"argument --env-kwargs: {err}"
    return None


def run(args: argparse.Namespace) -> int:
    """Run the study the parsed ``args`` ask for; print one line of result or error; the exit code.

    Args:
        args: the parsed command line, with the options :func:`add_parser` declares.

    Returns:
        The exit status, 0 on success.
    """
    needs = [("rl", "training agents (--algo none runs the model-based rows only)")] if args.algo != "none" else []
    if args.backend == "ray":
        needs.append(("distributed", "--backend ray"))
    if "mpc" in args.controllers:
        needs.append(("mpc", "--controllers mpc"))
    problem = check_extras(needs) or _problem(args) or check_out(args)
    if problem is not None:
        return error(VERB, problem)
    kept = f"; finished agents and cells are kept in {args.out} (run the same command again to continue)"
    try:
        result = run_mismatch(
            args.out,
            args.train_models,
            args.test_models,
            task=args.task,
            algo=None if args.algo == "none" else args.algo,
            timesteps=args.timesteps,
            episodes=args.episodes,
            seeds=args.seeds,
            domain_randomization=args.domain_randomization,
            simplifications=args.simplifications,
            env_kwargs=parse_env_kwargs(args.env_kwargs),
            n_envs=args.n_envs,
            max_steps=args.max_steps,
            platform=args.platform,
            backend=args.backend,
            ray_address=args.ray_address,
            agent_models=args.agent_models,
            config=args.config,
            position_tolerance=args.position_tolerance,
            orientation_tolerance=args.orientation_tolerance,
            cost_plant=args.cost_plant,
            controller_platforms=args.controller_platform,
            physics_threads=args.physics_threads,
            plant_actuator=args.plant_actuator,
            progress=not args.no_progress,
            controllers=args.controllers,
        )
    except (BackendError, WriteError) as exc:
        print(f"stewart-env mismatch: error: {exc}{kept}", file=sys.stderr)
        return 1
    except (TrainingError, ValueError) as exc:
        print(f"stewart-env mismatch: error: {exc}", file=sys.stderr)
        return 2
    except TrainingInterrupted as stop:
        print(
            f"stewart-env mismatch: stopped by {signal.Signals(stop.signum).name}; checkpoint saved in "
            f"{stop.checkpoint}{kept}",
            file=sys.stderr,
        )
        return stop.exit_code
    except KeyboardInterrupt:
        print(f"stewart-env mismatch: interrupted{kept}", file=sys.stderr)
        return 130
    print(f"{len(result.rows)} controllers x {len(result.test_models)} plants -> {result.files['markdown']}")
    return 0
