"""The ``stewart-env`` command: demo, evaluate, reproduce, train, mismatch, bench, export-mjcf.

    stewart-env demo                       PD baseline on the classical and improved models
    stewart-env evaluate --policy pd ct --model classical improved --task tracking --out results/
    stewart-env evaluate --agent runs/ppo --model classical improved
    stewart-env reproduce --out figures/   the case study of He et al. (2018), Fig. 6-10
    stewart-env train ... / mismatch ...   stewart_env.agents.training, stewart_env.mismatch_cli
    stewart-env bench ...                  the benchmark (stewart_env.bench)
    stewart-env export-mjcf --platform dasgupta1998 --out stewart.xml   the MuJoCo twin as MJCF

Each subcommand has ``--help``.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

CONTROLLERS = ("pd", "pd-gc", "ct")
#: Commands that run the compiled kernels (bench announces its own compilation).
_SIMULATING = ("demo", "evaluate", "reproduce", "train", "mismatch")


def build_parser() -> argparse.ArgumentParser:
    # imported here, not at module top: stewart_env.agents loads the evaluation harness and
    # matplotlib, which `stewart-env bench` never needs; the training modules import
    # stable-baselines3 only inside the functions that need it
    from stewart_env import mismatch_cli, time_to_agent_cli
    from stewart_env.agents import training
    from stewart_env.agents.arguments import (
        TASKS,
        model_name,
        nonnegative_int,
        plant_model_name,
        platform_name,
        positive_float,
        positive_int,
    )

    parser = argparse.ArgumentParser(
        prog="stewart-env",
        description="The 6-UPS Stewart platform on closed-form Newton-Euler dynamics: baselines, "
                    "evaluation and the reproduction of He et al. (2018).",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    demo = sub.add_parser(
        "demo", help="evaluate the PD baseline on the classical and improved models and print the table",
        description="Evaluate the task-space PD baseline (gains tuned for the 10 ms control step), without and "
                    "with gravity compensation, on the set-point task of the default platform, once on the "
                    "classical and once on the improved dynamics model, with the same seeded episodes, and print "
                    "the comparison table.  No training; under a minute.",
    )
    demo.add_argument("--episodes", type=positive_int, default=3, help="episodes per model (default 3)")
    demo.add_argument("--seed", type=nonnegative_int, default=0, help="episode i uses seed + i (default 0)")
    demo.add_argument("--platform", type=platform_name, default="dasgupta1998", help="platform config name or YAML path "
                      "(default dasgupta1998)")
    demo.add_argument("--out", help="also write the report (table, CSV, plots) into this directory")

    ev = sub.add_parser(
        "evaluate", help="evaluate baseline controllers on a task and dynamics model(s)",
        description="Run seeded episodes of the baseline controllers and report RMS errors, settling time, "
                    "overshoot, steady-state error, peak leg force, control energy and success rate "
                    "(definitions: stewart_env.agents.evaluation).  Every controller runs on every model, "
                    "with the same seeds.",
    )
    ev.add_argument("--policy", nargs="+", choices=CONTROLLERS,
                    help="pd: task-space PD (paper eq. 56, gains tuned for the control step); pd-gc: the same "
                         "with gravity compensation (the improved model's holding forces); ct: computed "
                         "torque with its own internal model (default pd, unless --agent is given)")
    ev.add_argument("--agent", nargs="+", metavar="DIR",
                    help="run directories of agents trained by `stewart-env train` (model.zip with its "
                         "VecNormalize statistics); each is evaluated with its training environment "
                         "settings, the plant model replaced by --model")
    ev.add_argument("--internal-model", type=model_name, default="improved",
                    help="the computed-torque controller's dynamics model, independent of the plant's "
                         "(default improved)")
    ev.add_argument("--model", nargs="+", type=plant_model_name, default=["improved"],
                    help="the plant's dynamics model(s): classical, improved, improved_centroidal, "
                         "optionally with switches +c1..+c4, or mujoco (MuJoCo simulating the same "
                         "mechanism, needs the extra mujoco) (default improved)")
    ev.add_argument("--task", choices=TASKS,
                    help="default setpoint (for an --agent: the task it was trained on)")
    ev.add_argument("--platform", type=platform_name, help="platform config name or YAML path (default dasgupta1998; for an "
                    "--agent: the platform it was trained on)")
    ev.add_argument("--episodes", type=positive_int, default=5, help="episodes per configuration (default 5)")
    ev.add_argument("--seed", type=nonnegative_int, default=0, help="episode i uses seed + i (default 0)")
    ev.add_argument("--max-steps", type=positive_int, help="episode length in control steps "
                    "(default the registered 500)")
    ev.add_argument("--out", help="write the report (results.md, episodes.csv, PNG plots) into this directory")

    rep = sub.add_parser(
        "reproduce", help="reproduce the case study of He et al. (2018): figures 6-10 and a summary",
        description="Drive the platform from (0.1, 0, 0.395) m to (0.1, 0, 0.4) m, rpy (0, 0, -0.2), with the "
                    "paper's task-space PD gains as a continuous controller (RK4, the law evaluated at every "
                    "stage), on the classical, improved and improved_centroidal models; write the figures "
                    "(PNG) and summary.md with the peak differences.",
    )
    rep.add_argument("--out", required=True, help="output directory")
    rep.add_argument("--duration", type=positive_float, default=1.0, help="simulated time, s (default 1.0)")
    rep.add_argument("--dt", type=positive_float, default=2e-4, help="RK4 step, s (default 2e-4)")
    rep.add_argument("--platform", type=platform_name, default="dasgupta1998", help="platform config (default dasgupta1998)")
    rep.add_argument("--gravity-compensation", action="store_true",
                     help="add the static holding forces to the PD law (the paper's law as we have it has none)")

    training.add_cli(sub)
    mismatch_cli.add_parser(sub)
    time_to_agent_cli.add_parser(sub)
    sub.add_parser("bench", add_help=False, help="the benchmark (stewart_env.bench); see stewart-env bench --help")

    mjcf = sub.add_parser(
        "export-mjcf", help="write a platform's mechanism as a MuJoCo model (MJCF XML)",
        description="Write the mechanism of a platform config as MJCF for MuJoCo (stewart_env.mujoco.to_mjcf): "
                    "the platform a free body, each leg a universal joint, a slide and a loop-closure constraint, "
                    "masses, inertias, joint damping, force actuators, gravity, RK4.  An existing file is "
                    "overwritten.  Needs the extra: pip install -e \".[mujoco]\".",
    )
    mjcf.add_argument("--platform", type=platform_name, required=True, help="platform config name or YAML path")
    mjcf.add_argument("--out", required=True, help="the XML file to write")
    mjcf.add_argument("--timestep", type=positive_float, default=1e-3, help="MuJoCo's time step, s (default 1e-3)")
    mjcf.add_argument("--solref", type=float, nargs=2, metavar=("TIMECONST", "DAMPRATIO"),
                      help="softness of the loop-closure constraints (default: stewart_env.mujoco.DEFAULT_SOLREF)")
    mjcf.add_argument("--solimp", type=float, nargs=5, metavar=("DMIN", "DMAX", "WIDTH", "MID", "POWER"),
                      help="impedance of the loop-closure constraints (default: stewart_env.mujoco.DEFAULT_SOLIMP)")
    return parser


def _export_mjcf(args: argparse.Namespace) -> int:
    """The export-mjcf subcommand: the MJCF text of --platform into the file --out."""
    from stewart_env import mujoco as twin
    from stewart_env.files import check_writable
    from stewart_env.params import load_platform

    out = Path(args.out)

    def fail(message: str) -> int:
        print(f"stewart-env export-mjcf: error: {message}", file=sys.stderr)
        return 2

    if out.is_dir():
        return fail(f"argument --out: {str(out)!r} is a directory; give the XML file's name")
    try:
        check_writable(out.parent, create=False)
    except ValueError as err:  # stewart_env.files.NotWritable
        return fail(f"argument --out: {err}")
    kwargs = {k: getattr(args, k) for k in ("solref", "solimp") if getattr(args, k) is not None}
    try:
        xml = twin.to_mjcf(load_platform(args.platform), timestep=args.timestep, **kwargs)
    except ImportError as err:
        return fail(str(err))
    except ValueError as err:  # --solref or --solimp out of MuJoCo's range, named in the message
        name, _, problem = str(err).partition(": ")
        return fail(f"argument --{name}: {problem}")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(xml)
    except OSError as err:  # a full disk, a parent that is a file, no permission
        return fail(f"argument --out: cannot write {str(out)!r}: {err.strerror or err}")
    print(f"wrote {out} (MuJoCo model of {args.platform})")
    return 0


def _controllers(names: Sequence[str], internal_model: str) -> dict:
    from stewart_env.agents.computed_torque import ComputedTorquePolicy
    from stewart_env.agents.pd import PDPolicy

    out = {}
    for name in names:
        if name == "pd":
            out["PD"] = PDPolicy
        elif name == "pd-gc":
            out["PD + gravity comp."] = lambda env: PDPolicy(env, gravity_compensation=True)
        else:
            out[f"CT ({internal_model})"] = lambda env, m=internal_model: ComputedTorquePolicy(env, m)
    return out


def _run_demo(args: argparse.Namespace) -> str:
    from stewart_env.agents.evaluation import compare, markdown_table, write_report

    configs = [{"model": m, "task": "setpoint", "platform": args.platform} for m in ("classical", "improved")]
    results = compare(_controllers(["pd", "pd-gc"], "improved"), configs, episodes=args.episodes, seed=args.seed)
    if args.out is not None:
        write_report(results, args.out, title="Demo: PD baseline, classical vs improved dynamics")
    return markdown_table(results)


def _evaluate_command(args: argparse.Namespace) -> str:
    """The evaluate subcommand: baselines and trained agents on every --model, the same seeds."""
    from stewart_env.agents.evaluation import evaluate, markdown_table, write_report

    runs = []  # (label, policy or factory, environment kwargs without the model)
    baseline_kwargs = {"task": args.task or "setpoint", "platform": args.platform or "dasgupta1998"}
    names = args.policy or ([] if args.agent else ["pd"])
    runs += [(label, policy, baseline_kwargs) for label, policy in _controllers(names, args.internal_model).items()]
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
    results = [evaluate(policy, {**kwargs, "model": model}, args.episodes, args.seed, label=label,
                        max_steps=args.max_steps)
               for model in args.model for label, policy, kwargs in runs]
    if args.out is not None:
        write_report(results, args.out)
    return markdown_table(results)


def _preflight(args: argparse.Namespace) -> str | None:
    """What makes a command impossible before it does any work or writes anything: stable-baselines3
    missing for a command that trains or loads an agent, an --out that cannot be written."""
    from stewart_env.agents.training import TrainingError, check_rl_installed
    from stewart_env.files import check_writable

    needs_rl = (args.command == "train" or (args.command == "evaluate" and args.agent)
                or (args.command == "mismatch" and str(args.algo).lower() != "none"))
    if needs_rl:
        try:
            check_rl_installed()
        except TrainingError as err:
            return str(err)
    if getattr(args, "out", None) is not None:
        try:
            check_writable(args.out, create=False)
        except ValueError as err:  # stewart_env.files.NotWritable
            return f"argument --out: {err}"
    return None


def _announce_compilation(command: str | None = None) -> None:
    """One line before the kernels' first compilation, which takes tens of seconds: when no kernel
    is cached yet."""
    import stewart_env.envs  # noqa: F401  (numba compiles the environment's and the tasks' kernels)
    from stewart_env.numba_cache import is_warm

    if not is_warm():
        print("compiling kernels, first run only (~30 s)", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["bench"]:
        # bench parses its own arguments
        from stewart_env import bench

        return bench.main(argv[1:]) or 0
    args = build_parser().parse_args(argv)
    if args.command == "export-mjcf":
        return _export_mjcf(args)
    problem = _preflight(args)
    if problem is not None:
        print(f"stewart-env {args.command}: error: {problem}", file=sys.stderr)
        return 2
    if args.command in _SIMULATING:
        _announce_compilation(args.command)
    start = time.perf_counter()
    if args.command == "demo":
        try:
            table = _run_demo(args)
        except ValueError as err:  # --out in use by another command, or a write that failed (a full disk)
            print(f"stewart-env demo: error: {err}", file=sys.stderr)
            return 2
        print(f"PD baseline on the set-point task of {args.platform}, {args.episodes} seeded episodes per model "
              f"(seed {args.seed}):\n")
        print(table)
    elif args.command == "evaluate":
        try:
            print(_evaluate_command(args))
        except ValueError as err:  # a bad agent directory or environment setting, named in the message
            print(f"stewart-env evaluate: error: {err}", file=sys.stderr)
            return 2
    elif args.command in ("train", "mismatch", "time-to-agent"):
        return args.func(args)
    elif args.command == "reproduce":
        from stewart_env.agents.reproduce import reproduce

        try:
            result = reproduce(args.out, duration=args.duration, dt=args.dt, platform=args.platform,
                               gravity_compensation=args.gravity_compensation)
        except ValueError as err:  # a platform whose leg stroke the paper's case leaves, named in the message
            print(f"stewart-env reproduce: error: {err}", file=sys.stderr)
            return 2
        force = result["differences"]["leg_force"]
        print(f"wrote the figures and summary.md to {args.out}")
        print(f"leg force: peak-value difference classical vs improved {100 * force['peak_difference']:.2f} %, "
              f"pointwise {100 * force['pointwise_difference']:.2f} %; improved vs improved_centroidal "
              f"{result['centroidal_difference']:.1e}")
    if args.out is not None and args.command != "reproduce":
        print(f"\nreport written to {args.out}")
    print(f"({time.perf_counter() - start:.1f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
