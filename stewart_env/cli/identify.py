r"""``stewart-env identify``: dynamic parameter identification on a stand-in plant.

    stewart-env identify --plant improved --platform dasgupta1998 --excitation optimized \\
        --duration 60 --noise-force 1 --perturb 0.2 --out runs/ident

drives the plant along an excitation by computed torque, estimates the base parameters from the
noisy measurements and writes into ``--out``: ``platform.yaml``, the identified platform (a config
every command's ``--platform`` accepts as a path), ``truth.yaml`` (the plant's parameters),
``report.json`` and ``report.md``
(stewart_env.identification.experiment; docs/guides/identification.md).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from typing import TYPE_CHECKING

from stewart_env.cli.arguments import (
    PLATFORM_RULE,
    checked,
    directory_name,
    existing_file,
    model_name,
    plant_model_name,
    platform_name,
    positive_float,
    positive_int,
    quoted,
    real,
    seed,
)
from stewart_env.cli.common import error

if TYPE_CHECKING:
    from stewart_env.dynamics import ModelSpec

VERB = "identify"
#: Longest record, s.
MAX_DURATION = 3600.0
#: Noise standard deviations far beyond any sensor's, short of overflowing the estimate's sums of
#: squares: a workspace (1 m), a half turn (pi rad), a meganewton.
noise_position = real(0, 1.0, doc="argparse type of --noise-position, m.")
noise_angle = real(0, math.pi, doc="argparse type of --noise-angle, rad.")
noise_force = real(0, 1e6, doc="argparse type of --noise-force, N.")


def log_file(text: str) -> str:
    """Argparse type of --record: a non-blank path (the reader names a missing or unreadable file).

    Args:
        text: the command-line text.
    """
    if not text.strip():
        raise argparse.ArgumentTypeError("expected a log file, got ''")
    return text


held_out = checked(
    float, lambda v: 0 < v < 1, "a share in (0, 1)", "argparse type of --held-out: a share of the log in (0, 1)."
)
perturb = checked(
    float,
    lambda v: 0 <= v < 1,
    "a relative change in [0, 1)",
    "argparse type of --perturb: a relative change in [0, 1).",
)


def _model(text: str) -> ModelSpec:
    """Argparse type of --model: a closed-form model's name, parsed once into its spec."""
    if text.strip().lower() == "mujoco":
        raise argparse.ArgumentTypeError("the identified structure is a closed-form model (improved, classical, ...)")
    return model_name(text)


def duration(text: str) -> float:
    """Argparse type of --duration: seconds recorded, two settling times and half a second at least.

    Args:
        text: the command-line text.
    """
    from stewart_env.identification.experiment import SETTLE

    return real(2 * SETTLE + 0.5, MAX_DURATION)(text)


def period(text: str) -> float:
    """Argparse type of --period: the excitation's period, s, its highest harmonic at most at half
    the sampling rate (beyond it the samples cannot tell the harmonic apart).

    Args:
        text: the command-line text.
    """
    from stewart_env.identification.experiment import SAMPLE_DT, Settings

    return real(2 * Settings.harmonics * SAMPLE_DT, MAX_DURATION)(text)


def delay(text: str) -> float:
    """Argparse type of --delay: seconds in [0, MAX_DELAY], a whole number of SAMPLE_DT samples.

    Args:
        text: the command-line text.
    """
    from stewart_env.identification.experiment import MAX_DELAY, SAMPLE_DT

    value = real(0, MAX_DELAY)(text)
    if abs(value - round(value / SAMPLE_DT) * SAMPLE_DT) > 1e-9:
        raise argparse.ArgumentTypeError(f"expected a whole number of samples of {SAMPLE_DT:g} s, got {quoted(text)}")
    return value


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``identify`` subcommand to ``subparsers``.

    Args:
        subparsers: the subcommands of the ``stewart-env`` parser (``add_subparsers``'s result).

    Returns:
        The command's parser.
    """
    from stewart_env.identification import estimate as est
    from stewart_env.identification import logged

    p = subparsers.add_parser(
        VERB,
        help="identify a platform's inertial and friction parameters on a stand-in plant",
        description="Drive a plant along an excitation trajectory (a finite Fourier series in task space, "
        "optimised for the condition number of the base regressor, or random) by computed torque, "
        "add sensor noise, recover velocities and accelerations by a Savitzky-Golay filter, and "
        "estimate the base parameters by OLS, WLS and a physically consistent least squares.  Writes "
        "platform.yaml (the identified platform), truth.yaml (the plant's), report.json and report.md "
        "into --out.",
    )
    p.add_argument(
        "--plant",
        type=plant_model_name,
        default="improved",
        help="the plant: a dynamics model (improved, classical or a name with switches) or mujoco, the MuJoCo "
        "twin (needs the extra mujoco; default improved)",
    )
    p.add_argument("--model", type=_model, default="improved", help="the model structure identified (default improved)")
    p.add_argument(
        "--platform",
        type=platform_name,
        default="dasgupta1998",
        help=f"nominal platform: shipped platform name or YAML config path ({PLATFORM_RULE}; default dasgupta1998)",
    )
    p.add_argument(
        "--excitation",
        choices=("optimized", "random"),
        default="optimized",
        help="excitation trajectory (default optimized)",
    )
    p.add_argument("--duration", type=duration, default=60.0, help="seconds recorded (default 60)")
    p.add_argument("--period", type=period, default=10.0, help="period of the Fourier series, s (default 10)")
    p.add_argument(
        "--noise-position",
        type=noise_position,
        default=1e-5,
        help="position noise, standard deviation in m (default 1e-5)",
    )
    p.add_argument(
        "--noise-angle",
        type=noise_angle,
        default=1e-5,
        help="orientation noise, standard deviation in rad (default 1e-5)",
    )
    p.add_argument(
        "--noise-force", type=noise_force, default=1.0, help="leg force noise, standard deviation in N (default 1)"
    )
    p.add_argument(
        "--delay",
        type=delay,
        default=0.0,
        help="seconds the pose measurements lag the leg-force measurements, a whole number of the "
        "0.005 s samples, at most 0.25 (default 0)",
    )
    p.add_argument(
        "--perturb",
        type=perturb,
        default=0.2,
        help="relative random change of the plant's inertial and friction parameters from the nominal "
        "(the unknown truth; default 0.2)",
    )
    p.add_argument(
        "--derivatives",
        choices=("filter", "exact"),
        default="filter",
        help="velocities and accelerations by the Savitzky-Golay filter of the noisy poses, or the "
        "plant's exact ones (default filter)",
    )
    p.add_argument("--iterations", type=positive_int, default=30, help="optimiser iterations (default 30)")
    p.add_argument(
        "--predicted-by",
        metavar="REPORT",
        help="report.json of an earlier run of the same platform and model: the report compares the "
        "standard deviations it predicts for this record and force noise with this run's",
    )
    p.add_argument("--seed", type=seed, default=0, help="random seed (default 0)")
    p.add_argument("--out", type=directory_name, required=True, help="output directory (locked while written)")
    p.add_argument(
        "--record",
        type=log_file,
        metavar="LOG",
        help="identify from a machine's log (docs/guides/log-format.md) instead of a stand-in plant: leg lengths "
        "to poses by forward kinematics, --derivatives, the forces or the motor currents; the plant, noise, "
        "delay, perturbation and excitation options do not apply",
    )
    p.add_argument(
        "--drive",
        type=existing_file,
        help="with --record of motor currents: YAML of the drive constants (default drive.yaml beside the log)",
    )
    p.add_argument(
        "--held-out",
        type=held_out,
        default=0.25,
        help="with --record: the share of the log, at its end, held out for validation (default 0.25)",
    )
    p.add_argument(
        "--forces",
        choices=logged.FORCES,
        default="sampled",
        help="with --record: how the logged forces or currents relate to their time stamps: sampled, each the "
        "value at its stamp, or held, each held from its stamp to the next (a drive's zero-order hold; read as "
        "the mean of two samples) (default sampled; docs/guides/log-format.md)",
    )
    p.add_argument(
        "--prior-weight",
        type=positive_float,
        default=est.PRIOR_WEIGHT,
        help=f"with --record: the physically consistent fit's pull towards the nominal parameters "
        f"(default {est.PRIOR_WEIGHT:g}; docs/guides/your-own-platform.md chooses it by tracking)",
    )
    return p


def _run_record(args: argparse.Namespace) -> int:
    """``identify --record``: identification from a log (stewart_env.identification.logged)."""
    from stewart_env.files import check_writable
    from stewart_env.identification import log, logged
    from stewart_env.identification.experiment import SETTLE
    from stewart_env.params import load_platform

    if args.record.lower().endswith(log.HDF5_SUFFIXES):
        from stewart_env.extras import require

        require("logs", "--record (an HDF5 log)")
    try:
        check_writable(args.out, create=False)
        nominal = load_platform(args.platform)
        drive = None if args.drive is None else logged.read_drive(args.drive)
        record = log.read(args.record, nominal, min_duration=2 * SETTLE + 0.5)
        settings = logged.LogSettings(
            model=args.model,
            derivatives=args.derivatives,
            held_out=args.held_out,
            drive=drive,
            forces=args.forces,
            prior_weight=args.prior_weight,
        )
        folder = logged.write(logged.identify_log(record, nominal, settings), args.out)
    except ValueError as err:  # LogError, IdentificationError, a busy or unwritable --out: the message names it
        return error(VERB, err)
    print((folder / "report.md").read_text().split("\n| base parameter")[0].rstrip())
    print(f"\nidentified platform: {folder / 'platform.yaml'}")
    return 0


def run(args: argparse.Namespace) -> int:
    """Run the ``identify`` subcommand; 0 on success, 2 on an error the user can correct.

    Args:
        args: the parsed command line, with the options :func:`add_parser` declares.

    Returns:
        The exit status, 0 on success.
    """
    from stewart_env.files import check_writable
    from stewart_env.identification import experiment
    from stewart_env.params import load_platform

    if args.record is not None:
        return _run_record(args)
    start = time.perf_counter()
    try:
        settings = experiment.Settings(
            plant=args.plant,
            model=args.model,
            excitation=args.excitation,
            duration=args.duration,
            noise_position=args.noise_position,
            noise_angle=args.noise_angle,
            noise_force=args.noise_force,
            delay=args.delay,
            perturb=args.perturb,
            derivatives=args.derivatives,
            seed=args.seed,
            period=args.period,
            max_iterations=args.iterations,
        )
        check_writable(args.out, create=False)
        reference = None
        if args.predicted_by is not None:
            try:
                reference = experiment.read_report(args.predicted_by)
            except ValueError as err:
                return error(VERB, f"--predicted-by: {err}")
        result = experiment.run(settings, load_platform(args.platform), predicted_by=reference)
        folder = experiment.write(result, args.out)
    except ValueError as err:  # IdentificationError, a busy or unwritable --out: the message names the cause
        return error(VERB, err)
    print((folder / "report.md").read_text().split("\n| base parameter")[0].rstrip())
    print(f"\nidentified platform: {folder / 'platform.yaml'}")
    print(f"({time.perf_counter() - start:.1f} s)", file=sys.stderr)
    return 0
