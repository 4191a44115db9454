"""``stewart-env evaluate``: baselines and trained agents on every ``--model``, the same seeds."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from stewart_env.cli.arguments import (
    PLATFORM_RULE,
    TASKS,
    directory_name,
    episode_steps,
    model_name,
    plant_model_name,
    platform_count,
    platform_name,
    seed,
)
from stewart_env.cli.common import (
    CONTROLLERS,
    check_extras,
    check_out,
    controllers,
    error,
    plant_extras,
)

VERB = "evaluate"
#: The cueing task's baseline: classical washout with the shipped tuning, in pose mode.
WASHOUT = "washout"
#: The cueing task's episodes without --max-steps: they end with their motion, the longest shipped
#: evaluation motion lasting 120 s (the sweeps) at the 10 ms control step.
CUEING_MAX_STEPS = 12_001
#: Memory the evaluation keeps per episode and control step, bytes, rounded up: the position and
#: orientation errors, rates and six leg forces of every step, then stacked into one array each.
RECORD_BYTES_PER_STEP = 256


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``stewart-env evaluate`` command and its options.

    Args:
        subparsers: the subcommands of the ``stewart-env`` parser (``add_subparsers``'s result).

    Returns:
        The command's parser.
    """
    from stewart_env.agents.evaluation.cueing import CHANNELS
    from stewart_env.dynamics import ModelSpec

    p = subparsers.add_parser(
        VERB,
        help="evaluate baseline controllers and trained agents (--agent) on a task and dynamics model(s)",
        description="Run seeded episodes of the baseline controllers (--policy) and of agents trained by "
        "`stewart-env train` (--agent) and report RMS errors, settling time, overshoot, steady-state "
        "error, peak leg force, control energy, success rate, early terminations, the constraint cost rate "
        "and the steps each limit was hit (definitions: "
        "stewart_env.agents.evaluation).  Every controller runs on every model, with the same seeds.",
    )
    p.add_argument(
        "--policy",
        nargs="+",
        choices=(*CONTROLLERS, WASHOUT),
        help="pd: task-space PD (paper eq. 56, gains tuned for the control step); pd-gc: the same "
        "with gravity compensation (the improved model's holding forces); ct: computed "
        "torque with its own internal model; lqr: an LQR around home from the exact Jacobians of the "
        "control step; mpc: the linearised MPC with the leg force limits (needs the extra mpc); lqr "
        "and mpc are built on --internal-model too; washout: classical washout for --task cueing "
        "(configs/agents/washout.yaml, action_mode pose) (default pd, or washout on --task "
        "cueing, unless --agent is given)",
    )
    p.add_argument(
        "--agent",
        nargs="+",
        metavar="DIR",
        help="run directories of agents trained by `stewart-env train` (model.zip with its "
        "VecNormalize statistics); each is evaluated with its training environment "
        "settings, the plant model replaced by --model (needs the extra rl)",
    )
    p.add_argument(
        "--internal-model",
        type=model_name,
        default="improved",
        help="the dynamics model of computed torque, the LQR and the MPC, independent of the plant's "
        "(default improved)",
    )
    p.add_argument(
        "--model",
        nargs="+",
        type=plant_model_name,
        default=[ModelSpec("improved")],  # argparse converts a string default, not a list's items
        help="the plant's dynamics model(s): classical, improved, improved_centroidal, "
        "optionally with switches +c1..+c4, or mujoco (MuJoCo simulating the same "
        "mechanism, needs the extra mujoco) (default improved)",
    )
    p.add_argument("--task", choices=TASKS, help="default setpoint (for an --agent: the task it was trained on)")
    p.add_argument(
        "--platform",
        type=platform_name,
        help="shipped platform name or YAML config path "
        f"({PLATFORM_RULE}; default dasgupta1998; "
        "for an --agent: the platform it was trained on)",
    )
    p.add_argument("--episodes", type=platform_count, default=5, help="episodes per configuration (default 5)")
    p.add_argument("--seed", type=seed, default=0, help="episode i uses seed + i (default 0)")
    p.add_argument(
        "--max-steps",
        type=episode_steps,
        help=f"episode length in control steps (default the registered 500; on --task cueing {CUEING_MAX_STEPS}, "
        "the longest motion's, each episode ending with its motion)",
    )
    p.add_argument(
        "--out",
        type=directory_name,
        help="write the report (results.md, results.json, episodes.csv, PNG plots) into this directory",
    )
    p.add_argument(
        "--omct",
        nargs="*",
        choices=CHANNELS,
        metavar="CHANNEL",
        help="with --task cueing: instead of episodes, the objective motion cueing test of each controller "
        "and agent on each --model: one sine per channel and frequency through the whole chain, its gain and "
        f"phase at the head and perceived (omct.md, omct.csv in --out); the channels, of {', '.join(CHANNELS)} "
        "(default all six)",
    )
    p.add_argument(
        "--video",
        type=video_path,
        metavar="PATH",
        help="with --task cueing: instead of episodes, render the one controller or agent on the first "
        "held-out double lane change, from half a second before the track for 7 s, into PATH (.mp4 with "
        "the extra video, or .gif)",
    )
    p.add_argument(
        "--omct-frequencies",
        nargs="+",
        type=omct_frequency,
        metavar="W",
        help="with --omct: the frequencies, rad/s, 0.01 to 50 (default the OMCT's twelve, 0.1 to 15.8)",
    )
    return p


def omct_frequency(text: str) -> float:
    """A frequency of ``--omct-frequencies``, rad/s: a number from 0.01 to 50 (the control step's
    Nyquist frequency is 314 rad/s; 50 keeps twelve samples or more per period at the 10 ms step).

    Args:
        text: the command line's word.

    Returns:
        The frequency, rad/s.

    Raises:
        argparse.ArgumentTypeError: not a number from 0.01 to 50.
    """
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a frequency in rad/s, got {text!r}") from None
    if not 0.01 <= value <= 50.0:
        raise argparse.ArgumentTypeError(f"expected a frequency from 0.01 to 50 rad/s, got {text}")
    return value


def _runs(args: argparse.Namespace) -> list[tuple]:
    """(label, policy or factory, environment kwargs without the model) of every controller and agent."""
    runs = []
    baseline_kwargs = {"task": args.task or "setpoint", "platform": args.platform or "dasgupta1998"}
    if args.task == "cueing":  # the held-out motions and seeds
        baseline_kwargs["task_options"] = {"split": "evaluation"}
    names = args.policy or ([] if args.agent else [WASHOUT if args.task == "cueing" else "pd"])
    if WASHOUT in names:
        from stewart_env.agents.controllers.washout import WashoutPolicy

        runs.append(("washout", lambda env: WashoutPolicy(env, "washout"), {**baseline_kwargs, "action_mode": "pose"}))
    names = [name for name in names if name != WASHOUT]
    runs += [(label, policy, baseline_kwargs) for label, policy in controllers(names, args.internal_model).items()]
    if args.agent:
        from stewart_env.agents.training import load_agent

        agents = [load_agent(directory) for directory in args.agent]
        names = [agent.name for agent in agents]
        for directory, agent in zip(args.agent, agents):
            kwargs = dict(agent.env_kwargs)
            kwargs.update({k: v for k, v in (("task", args.task), ("platform", args.platform)) if v is not None})
            # agents of one algorithm and model are told apart by their run directory
            label = agent.name if names.count(agent.name) == 1 else f"{agent.name} {Path(directory).name}"
            runs.append((label, agent, kwargs))
    return runs


def _evaluate(args: argparse.Namespace) -> str:
    """The table of every controller and agent on every --model."""
    from stewart_env.agents.evaluation.evaluation import evaluate, markdown_table, write_report

    runs = _runs(args)
    results = [
        evaluate(policy, {**kwargs, "model": model}, args.episodes, args.seed, label=label, max_steps=_max_steps(args))
        for model in args.model
        for label, policy, kwargs in runs
    ]
    if args.out is not None:
        write_report(results, args.out)
    cueing = [r for r in results if r.cueing_keys()]
    if cueing:
        from stewart_env.agents.evaluation.cueing import cueing_table

        return markdown_table(results) + "\n\n" + cueing_table([(r.label, r.model, r.summary()) for r in cueing])
    return markdown_table(results)


def _omct(args: argparse.Namespace) -> str:
    """The OMCT of every controller and agent on every --model; each report in --out (a
    subfolder per controller and model when there are several)."""
    from stewart_env.agents.evaluation.cueing import CHANNELS, OMCT_FREQUENCIES
    from stewart_env.agents.evaluation.omct import omct_markdown, omct_rows, write_omct

    channels = tuple(args.omct) or CHANNELS
    frequencies = tuple(args.omct_frequencies or OMCT_FREQUENCIES)
    texts = []
    pairs = [(model, run) for model in args.model for run in _runs(args)]
    for model, (label, policy, kwargs) in pairs:
        env_kwargs = {k: v for k, v in kwargs.items() if k != "task"}
        env_kwargs["task_options"] = {k: v for k, v in env_kwargs.get("task_options", {}).items() if k != "split"}
        env_kwargs["model"] = model
        rows = omct_rows(
            policy,
            env_kwargs,
            channels,
            frequencies,
            progress=lambda c, w, name=f"{label} on {model}": print(f"  {name}: {c} at {w:g} rad/s", file=sys.stderr),
        )
        title = f"{label} on the {model} model, {kwargs.get('platform', 'dasgupta1998')}"
        if args.out is not None:
            out = Path(args.out) if len(pairs) == 1 else Path(args.out) / f"{label}-{model}".replace(" ", "_")
            write_omct(rows, out, title)
        texts.append(omct_markdown(rows, title))
    return "\n".join(texts)


def video_path(text: str) -> Path:
    """The file of ``--video``: a path ending in .mp4 or .gif.

    Args:
        text: the command line's word.

    Returns:
        The path.

    Raises:
        argparse.ArgumentTypeError: another suffix.
    """
    path = Path(text)
    if path.suffix.lower() not in (".mp4", ".gif"):
        raise argparse.ArgumentTypeError(f"expected a .mp4 or .gif file, got {text!r}")
    return path


def _video(args: argparse.Namespace) -> str:
    """The video of the one controller or agent on the first model."""
    from stewart_env.agents.evaluation.video import write_cueing_video

    ((label, policy, kwargs),) = _runs(args)
    env_kwargs = {k: v for k, v in kwargs.items() if k != "task"}
    env_kwargs["task_options"] = {k: v for k, v in env_kwargs.get("task_options", {}).items() if k != "split"}
    env_kwargs["model"] = args.model[0]
    path, frames, start = write_cueing_video(policy, env_kwargs, args.video)
    return f"{label}: {frames} frames from t = {start:.2f} s written to {path} ({path.stat().st_size / 1e3:.0f} kB)"


def _max_steps(args: argparse.Namespace) -> int | None:
    """--max-steps, or on the cueing task enough steps for its longest motion."""
    return CUEING_MAX_STEPS if args.max_steps is None and args.task == "cueing" else args.max_steps


def _problem(args: argparse.Namespace) -> str | None:
    """What the parsed options ask that cannot run (a value given twice, a record too large for
    this machine's memory), naming the flag; None if nothing."""
    from stewart_env.envs.vector import BYTES_PER_PLATFORM, check_batch_memory
    from stewart_env.registration import MAX_EPISODE_STEPS

    for flag, values in (("--policy", args.policy), ("--agent", args.agent), ("--model", args.model)):
        twice = sorted({str(v) for v in values or () if values.count(v) > 1})
        if twice:
            return f"argument {flag}: {', '.join(twice)} given twice"
    if WASHOUT in (args.policy or ()) and args.task != "cueing":
        return f"argument --policy: {WASHOUT} cues vehicle motion: give --task cueing"
    if args.omct is not None and args.task != "cueing":
        return "argument --omct: the objective motion cueing test drives the cueing task: give --task cueing"
    if args.video is not None and args.task != "cueing":
        return "argument --video: the video shows a cueing episode: give --task cueing"
    if args.video is not None and args.omct is not None:
        return "argument --video: give --video or --omct, not both"
    if args.video is not None and len(args.policy or ()) + len(args.agent or ()) > 1:
        return "argument --video: give one --policy or --agent"
    if args.video is not None and len(args.model) > 1:
        return "argument --video: give one --model"
    if args.video is not None:
        from stewart_env.files import check_writable

        try:  # before the episode runs, not after
            check_writable(args.video.parent, create=False)
        except ValueError as err:  # stewart_env.files.FileError
            return f"argument --video: {err}"
    if args.omct_frequencies is not None and args.omct is None:
        return "argument --omct-frequencies: give --omct too"
    twice = sorted({c for c in args.omct or () if args.omct.count(c) > 1})
    if twice:
        return f"argument --omct: {', '.join(twice)} given twice"
    missing = [d for d in args.agent or () if not Path(d).is_dir()]
    if missing:
        return f"argument --agent: no such directory: {missing[0]!r}"
    steps = _max_steps(args) or MAX_EPISODE_STEPS
    try:  # every episode runs in one batch, each step of each episode kept
        check_batch_memory("--episodes", args.episodes, BYTES_PER_PLATFORM + RECORD_BYTES_PER_STEP * steps)
    except ValueError as err:
        return f"argument {err} (at --max-steps {steps})"
    return None


def run(args: argparse.Namespace) -> int:
    """Run ``stewart-env evaluate``.

    Args:
        args: the parsed command line, with the options :func:`add_parser` declares.

    Returns:
        The exit status, 0 on success.
    """
    needs = ([("rl", "--agent")] if args.agent else []) + plant_extras(args.model)
    needs += [("mpc", "--policy mpc")] if args.policy and "mpc" in args.policy else []
    problem = check_extras(needs) or _problem(args) or check_out(args)
    if problem is not None:
        return error(VERB, problem)
    start = time.perf_counter()
    try:
        if args.video is not None:
            print(_video(args))
        else:
            print(_omct(args) if args.omct is not None else _evaluate(args))
    except ValueError as err:  # a bad agent directory or environment setting, named in the message
        return error(VERB, err)
    if args.out is not None:
        print(f"\nreport written to {args.out}")
    print(f"({time.perf_counter() - start:.1f} s)", file=sys.stderr)
    return 0
