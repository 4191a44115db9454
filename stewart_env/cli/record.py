r"""``stewart-env record``: a stand-in machine follows set points and logs what its drives report.

    stewart-env record --plant mujoco --platform dasgupta1998 --perturb 0.2 \\
        --trajectory excitation.csv --out record.csv --noise-length 1e-6 --noise-force 1

tracks the excitation that ``stewart-env excitation`` wrote by the identification's computed-torque
law on a plant whose parameters are the platform's perturbed (the unknown truth), and writes leg
lengths and leg forces (or, with ``--currents --drive FILE``, motor currents) with sensor noise and
delay, in the log format (stewart_env.identification.recording; docs/guides/log-format.md).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from stewart_env.cli.arguments import (
    PLATFORM_RULE,
    existing_file,
    plant_model_name,
    platform_name,
    real,
    seed,
    writable_file,
)
from stewart_env.cli.common import error
from stewart_env.cli.identify import delay, noise_force, perturb

VERB = "record"
noise_length = real(0, 0.1, doc="argparse type of --noise-length, m.")


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``record`` subcommand to ``subparsers``.

    Args:
        subparsers: the subcommands of the ``stewart-env`` parser (``add_subparsers``'s result).

    Returns:
        The command's parser.
    """
    p = subparsers.add_parser(
        VERB,
        help="run set points on a stand-in plant and write the log its drives would",
        description="Track an excitation written by `stewart-env excitation` by computed torque on a plant "
        "(a closed-form model or the MuJoCo twin) whose parameters are the platform's perturbed, and write "
        "time stamps, leg lengths and leg forces or motor currents, with sensor noise and the leg lengths' "
        "delay, in the log format.",
    )
    p.add_argument(
        "--plant",
        type=plant_model_name,
        default="improved",
        help="the plant: a dynamics model (improved, classical or a name with switches) or mujoco (needs the "
        "extra mujoco; default improved)",
    )
    p.add_argument(
        "--platform",
        type=platform_name,
        default="dasgupta1998",
        help=f"nominal platform: shipped platform name or YAML config path ({PLATFORM_RULE}; default dasgupta1998)",
    )
    p.add_argument("--trajectory", type=existing_file, required=True, help="the excitation log to follow")
    p.add_argument(
        "--out", type=writable_file, required=True, help="the log to write (.csv, or .h5 with the extra logs)"
    )
    p.add_argument(
        "--perturb",
        type=perturb,
        default=0.2,
        help="relative random change of the plant's inertial and friction parameters (default 0.2)",
    )
    p.add_argument(
        "--noise-length", type=noise_length, default=0.0, help="leg length noise, standard deviation in m (default 0)"
    )
    p.add_argument(
        "--noise-force", type=noise_force, default=0.0, help="leg force noise, standard deviation in N (default 0)"
    )
    p.add_argument(
        "--delay", type=delay, default=0.0, help="seconds the leg lengths lag the forces, whole samples (default 0)"
    )
    p.add_argument(
        "--currents",
        action="store_true",
        help="log motor currents through the drive constants of --drive (written beside the log as drive.yaml)",
    )
    p.add_argument(
        "--drive", type=existing_file, help="YAML of the drive constants (BallScrew's fields), with --currents"
    )
    p.add_argument(
        "--derivatives",
        choices=("none", "exact"),
        default="none",
        help="exact: log the plant's own twist and acceleration too (a closed-form plant; a simulation-only "
        "check; default none)",
    )
    p.add_argument("--truth", type=writable_file, help="write the plant's true parameters to this platform YAML")
    p.add_argument("--seed", type=seed, default=0, help="random seed of the perturbation and the noise (default 0)")
    return p


def run(args: argparse.Namespace) -> int:
    """Run the ``record`` subcommand; 0 on success, 2 on an error the user can correct.

    Args:
        args: the parsed command line, with the options :func:`add_parser` declares.

    Returns:
        The exit status, 0 on success.
    """
    import yaml

    from stewart_env import files
    from stewart_env.identification import log, logged, recording
    from stewart_env.params import load_platform

    if args.currents != (args.drive is not None):
        return error(VERB, "--currents and --drive go together: motor currents need the drive constants")
    if args.out.lower().endswith(log.HDF5_SUFFIXES):
        from stewart_env.extras import require

        require("logs", "--out (an HDF5 log)")
    if args.plant == "mujoco":
        from stewart_env.extras import require

        require("mujoco", "--plant mujoco")
    try:
        drive = None if args.drive is None else logged.read_drive(args.drive)
        beside = Path(args.out).parent / logged.DRIVE_FILE
        if drive is not None and beside.is_file() and logged.read_drive(beside) != drive:
            return error(
                VERB, f"{beside}: holds other drive constants than --drive {args.drive}; choose another folder"
            )
        nominal = load_platform(args.platform)
        trajectory = log.read(args.trajectory, nominal)
        settings = recording.RecordSettings(
            plant=args.plant,
            perturb=args.perturb,
            seed=args.seed,
            noise_length=args.noise_length,
            noise_force=args.noise_force,
            delay=args.delay,
            drive=drive,
            exact=args.derivatives == "exact",
        )
        record, truth = recording.record_log(trajectory, nominal, settings)
        log.write(args.out, record, nominal)
        if drive is not None:
            files.publish(beside, yaml.safe_dump(drive.__dict__.copy(), sort_keys=False))
        if args.truth is not None:
            files.publish(args.truth, yaml.safe_dump(truth.to_dict(), sort_keys=False))
    except ValueError as err:  # IdentificationError, LogError, an unwritable file: the message names the cause
        return error(VERB, err)
    forces = "motor currents" if drive is not None else "leg forces"
    print(
        f"{args.out}: {record.time.size} samples of leg lengths and {forces} on the plant {getattr(args.plant, 'name', args.plant)}"
    )
    return 0
