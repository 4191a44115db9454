"""Your own platform, the loop closed on a stand-in machine: excitation -> record -> identify from
the file -> computed torque on the identified model, measured on the tracking task.

The unknown machine is the MuJoCo twin of the platform with every inertial and friction parameter
perturbed (:func:`stewart_env.identification.experiment.perturbed`).  :func:`run` exports the
optimised excitation, records the machine following it (leg lengths and leg forces with sensor
noise, in the drive-log format), identifies the platform from that file alone (the forces read as
held by the drives on MuJoCo, the consistent fit's prior weight chosen among :data:`PRIOR_WEIGHTS` by
computed torque's tracking on validation episodes of the machine), and evaluates
computed torque built on the identified, the true and the nominal parameters on the tracking task
on the same machine; it writes every file of the path and ``summary.md`` / ``summary.json`` with
the RMS errors, the machine and the date into ``out``::

    python -m stewart_env.agents.studies.own_platform runs/own-platform

docs/guides/your-own-platform.md shows its numbers.
"""

from __future__ import annotations

import datetime
import json
import os
import platform as host
import sys
import time
from pathlib import Path

import yaml

from stewart_env import files
from stewart_env.agents import ComputedTorquePolicy, evaluate
from stewart_env.identification import experiment, logged, recording
from stewart_env.identification import log as logs
from stewart_env.params import PlatformParams, load_platform

#: The controllers compared, by the parameters their computed torque is built on.
BELIEFS = ("identified", "true", "nominal")
#: The consistent fit's prior weights the study chooses from, by the tracking error of computed
#: torque built on each identified platform on the machine over validation episodes.
PRIOR_WEIGHTS = (1e-4, 1e-3, 1e-2, 1e-1)
#: The validation episodes' seeds start here past the study's seed: none is an evaluation episode.
VALIDATION_SEED_OFFSET = 1000


def _processor() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return host.processor() or host.machine()


def run(
    out: str | Path,
    platform: str = "dasgupta1998",
    perturb: float = 0.2,
    seed: int = 0,
    duration: float = 60.0,
    period: float = 10.0,
    noise_length: float = 1e-6,
    noise_force: float = 1.0,
    episodes: int = 5,
    plant: str = "mujoco",
    random: bool = False,
    forces: str | None = None,
    prior_weights: tuple[float, ...] = PRIOR_WEIGHTS,
    validation_episodes: int = 3,
) -> dict:
    """The whole path on a stand-in machine (see the module docstring).

    Args:
        out: the folder of the files (excitation.csv, record.csv, truth.yaml, identified/,
            summary.md, summary.json), created if missing.
        platform: the nominal platform (a shipped name or a config path).
        perturb: the relative perturbation of the machine's parameters from the nominal.
        seed: the seed of the perturbation, the excitation's start, the noise and the episodes.
        duration: the excitation's length, s.
        period: the excitation's period, s.
        noise_length: the leg lengths' noise, standard deviation in m.
        noise_force: the leg forces' noise, standard deviation in N.
        episodes: the tracking episodes per controller.
        plant: the machine: ``mujoco`` (the twin) or a closed-form model's name.
        random: a random excitation instead of the optimised one (a quick check).
        forces: how the identification reads the log's forces (:data:`~stewart_env.identification.logged.FORCES`);
            None: ``held`` on MuJoCo, whose recorder holds each sample's force until the next as a
            digital controller does, ``sampled`` on a closed-form plant, whose recorder runs the law
            at every 1 ms step of the plant.
        prior_weights: the consistent fit's prior weights to choose from (one: no choice).
        validation_episodes: the tracking episodes on the machine that score each weight, with
            seeds from ``seed`` + :data:`VALIDATION_SEED_OFFSET`, apart from the evaluation's.

    Returns:
        The summary (what summary.json holds).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    if forces is None:
        forces = "held" if plant == "mujoco" else "sampled"
    nominal = load_platform(platform)
    excitation, checks = recording.excitation_log(
        nominal, platform, duration=duration, period=period, seed=seed, random=random
    )
    logs.write(out / "excitation.csv", excitation, nominal)
    settings = recording.RecordSettings(
        plant=plant, perturb=perturb, seed=seed, noise_length=noise_length, noise_force=noise_force
    )
    record, truth = recording.record_log(logs.read(out / "excitation.csv", nominal), nominal, settings)
    logs.write(out / "record.csv", record, nominal)
    files.publish(out / "truth.yaml", yaml.safe_dump(truth.to_dict(), sort_keys=False))
    env_kwargs = {"model": plant, "platform": truth, "task": "tracking", "observation_mode": "pose"}

    def tracking(believed: PlatformParams, n: int, first_seed: int, label: str) -> dict:
        return evaluate(
            lambda env: ComputedTorquePolicy(env, "improved", platform=believed),
            env_kwargs,
            episodes=n,
            seed=first_seed,
            label=label,
            progress=False,
        ).summary()

    def validation_error(candidate: PlatformParams) -> float:
        # the machine itself judges the candidate, on episodes the evaluation does not see
        return tracking(candidate, validation_episodes, seed + VALIDATION_SEED_OFFSET, "CT (candidate)")[
            "rms_position_error"
        ]

    # identification sees the file only, and the prior weight is chosen on the machine's validation episodes
    result = logged.identify_log(
        logs.read(out / "record.csv", nominal, min_duration=2 * experiment.SETTLE + 0.5),
        nominal,
        logged.LogSettings(forces=forces, prior_weight=tuple(prior_weights)),
        score=validation_error if len(prior_weights) > 1 else None,
    )
    logged.write(result, out / "identified")
    identified = result["identified"]
    believed = {"identified": identified, "true": truth, "nominal": nominal}
    rows = {}
    for name in BELIEFS:
        summary = tracking(believed[name], episodes, seed, f"CT ({name})")
        rows[name] = {
            "rms_position_error_mm": 1e3 * summary["rms_position_error"],
            "rms_orientation_error_mrad": 1e3 * summary["rms_orientation_error"],
            "success": summary["success"],
        }
    report = result["report"]
    summary = {
        "command": "python -m stewart_env.agents.studies.own_platform " + " ".join(sys.argv[1:]),
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": f"{_processor()}, {os.cpu_count()} logical CPUs, Python {host.python_version()}",
        "settings": {
            "platform": platform,
            "plant": plant,
            "perturb": perturb,
            "seed": seed,
            "duration": duration,
            "period": period,
            "noise_length": noise_length,
            "noise_force": noise_force,
            "episodes": episodes,
            "excitation": "random" if random else "optimized",
            "forces": forces,
            "validation_episodes": validation_episodes,
        },
        "prior_weights": [
            {
                "prior_weight": c["prior_weight"],
                "validation_rms_position_error_mm": None if c["score"] is None else 1e3 * c["score"],
                "held_out_force_error": c["held_out_force_error"],
            }
            for c in report["prior_weights"]
        ],
        "prior_weight": report["settings"]["prior_weight"],
        "excitation_condition_number": checks.condition,
        "held_out_force_error": report["held_out_force_error"],
        "held_out_rms_force": report["held_out_rms_force"],
        "base_parameters_under_10pct_rel_std": report["base_parameters_under_10pct_rel_std"],
        "rank": report["rank"],
        "tracking": rows,
        "ratio_identified_to_true": rows["identified"]["rms_position_error_mm"] / rows["true"]["rms_position_error_mm"],
        "wall_time_s": time.perf_counter() - start,
    }
    files.publish(out / "summary.json", json.dumps(experiment._strict(summary), indent=1) + "\n")
    files.publish(out / "summary.md", markdown(summary))
    return summary


def agents_on_machine(out: str | Path, agents: dict, episodes: int = 5, seed: int = 0) -> dict:
    """Agents trained by ``stewart-env train`` (on the identified and on the nominal platform, say)
    evaluated on the machine of a finished :func:`run` (its plant, ``truth.yaml``, the tracking
    task), each with its own training environment's settings but that plant and platform; writes
    ``agents.md`` and ``agents.json`` into ``out``.

    Args:
        out: the folder of a finished :func:`run`.
        agents: ``{name: run directory}`` of the trained agents.
        episodes: the tracking episodes per agent.
        seed: the episodes' seed.

    Returns:
        ``{name: {rms_position_error_mm, rms_orientation_error_mrad, success, timesteps, platform}}``.
    """
    from stewart_env.agents.training import load_agent  # the rl extra's, only for this step

    out = Path(out)
    run_summary = json.loads((out / "summary.json").read_text())
    truth = PlatformParams.from_dict(files.load_yaml((out / "truth.yaml").read_text()), "machine")
    rows = {}
    for name, directory in agents.items():
        agent = load_agent(directory)
        env_kwargs = {**agent.env_kwargs, "model": run_summary["settings"]["plant"], "platform": truth}
        summary = evaluate(agent, env_kwargs, episodes=episodes, seed=seed, label=name, progress=False).summary()
        trained_on = agent.env_kwargs.get("platform", "dasgupta1998")
        rows[name] = {
            "rms_position_error_mm": 1e3 * summary["rms_position_error"],
            "rms_orientation_error_mrad": 1e3 * summary["rms_orientation_error"],
            "success": summary["success"],
            "timesteps": int(agent.num_timesteps),
            "platform": trained_on if isinstance(trained_on, str) else getattr(trained_on, "name", "?"),
        }
    result = {
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": f"{_processor()}, {os.cpu_count()} logical CPUs, Python {host.python_version()}",
        "episodes": episodes,
        "agents": rows,
    }
    files.publish(out / "agents.json", json.dumps(experiment._strict(result), indent=1) + "\n")
    lines = [
        f"PPO agents on the machine ({run_summary['settings']['plant']}, truth.yaml), tracking task, "
        f"{episodes} episodes, {result['date']}, {result['machine']}:",
        "",
        "| agent | trained on | steps | RMS position error (mm) | RMS orientation error (mrad) | success |",
        "|---|---|---|---|---|---|",
    ]
    for name, row in rows.items():
        lines.append(
            f"| {name} | {row['platform']} | {row['timesteps']} | {row['rms_position_error_mm']:.4g} "
            f"| {row['rms_orientation_error_mrad']:.4g} | {100 * row['success']:.0f} % |"
        )
    files.publish(out / "agents.md", "\n".join(lines) + "\n")
    return result


def markdown(summary: dict) -> str:
    """summary.md: the settings, the identification's held-out error and the tracking table.

    Args:
        summary: what :func:`run` returns.

    Returns:
        The Markdown text.
    """
    s, e = summary["settings"], summary["held_out_force_error"]
    lines = [
        f"# Your own platform on a stand-in machine: {s['platform']}",
        "",
        f"`{summary['command']}`, {summary['date']}, {summary['machine']}, {summary['wall_time_s']:.0f} s",
        "",
        f"machine: {s['plant']} with the parameters perturbed by {s['perturb']:g} (seed {s['seed']}); excitation "
        f"{s['duration']:g} s of period {s['period']:g} s (condition number {summary['excitation_condition_number']:.4g}); "
        f"noise: leg length {s['noise_length']:g} m, leg force {s['noise_force']:g} N",
        "",
        f"identified from record.csv: {summary['base_parameters_under_10pct_rel_std']} of {summary['rank']} base "
        f"parameters under 10 % relative standard deviation; held-out leg-force RMS error (RMS force "
        f"{summary['held_out_rms_force']:.4g} N): nominal {e['nominal']:.4g} N, WLS {e['wls']:.4g} N, "
        f"consistent {e['consistent']:.4g} N; forces read as {s['forces']}",
        "",
        f"The consistent fit's prior weight, chosen by computed torque's RMS position error on "
        f"{s['validation_episodes']} validation episodes on the machine (seeds from {s['seed'] + VALIDATION_SEED_OFFSET}): "
        f"{summary['prior_weight']:g}",
        "",
        "| prior weight | validation RMS position error (mm) | held-out leg-force RMS error (N) |",
        "|---|---|---|",
        *(
            f"| {c['prior_weight']:g} | "
            + ("" if c["validation_rms_position_error_mm"] is None else f"{c['validation_rms_position_error_mm']:.4g}")
            + f" | {c['held_out_force_error']:.4g} |"
            for c in summary["prior_weights"]
        ),
        "",
        f"Computed torque on the tracking task on the machine, {s['episodes']} episodes:",
        "",
        "| built on | RMS position error (mm) | RMS orientation error (mrad) | success |",
        "|---|---|---|---|",
    ]
    for name, row in summary["tracking"].items():
        lines.append(
            f"| {name} | {row['rms_position_error_mm']:.4g} | {row['rms_orientation_error_mrad']:.4g} "
            f"| {100 * row['success']:.0f} % |"
        )
    lines += ["", f"identified / true RMS position error: {summary['ratio_identified_to_true']:.3g}"]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    """Run :func:`run` with its defaults into the folder the one argument names.

    Args:
        argv: the arguments, ``[OUT]``, or ``[OUT, "--agents", NAME=RUN_DIR, ...]`` to evaluate
            trained agents on that run's machine (:func:`agents_on_machine`) (default the
            process's).

    Returns:
        The exit status.
    """
    argv = sys.argv[1:] if argv is None else list(argv)
    usage = "usage: python -m stewart_env.agents.studies.own_platform OUT [--agents NAME=RUN_DIR ...]"
    if not argv or argv[0].startswith("-") or (len(argv) > 1 and argv[1] != "--agents"):
        print(usage, file=sys.stderr)
        return 2
    if len(argv) > 1:
        pairs = [a.split("=", 1) for a in argv[2:]]
        if not pairs or any(len(p) != 2 or not p[0] or not p[1] for p in pairs):
            print(f"own_platform: error: --agents: expected NAME=RUN_DIR pairs; {usage}", file=sys.stderr)
            return 2
        try:
            result = agents_on_machine(argv[0], dict(pairs))
        except (OSError, ValueError) as err:
            print(f"own_platform: error: --agents: {err}", file=sys.stderr)
            return 2
        print((Path(argv[0]) / "agents.md").read_text())
        return 0 if result["agents"] else 2
    try:
        summary = run(argv[0])
    except ValueError as err:  # a usage error: the message names the cause
        print(f"own_platform: error: {err}", file=sys.stderr)
        return 2
    print(markdown(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
