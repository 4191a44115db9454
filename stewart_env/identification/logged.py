"""Identification from a machine's log (a ``record`` of :mod:`~stewart_env.identification.log`).

:func:`identify_log` turns the logged leg lengths into poses by the package's forward kinematics
(:func:`stewart_env.kinematics.forward_kinematics`, each sample from the previous one's pose) or
takes the logged poses; recovers velocities and accelerations by the Savitzky-Golay filter of
:func:`stewart_env.identification.estimate.derivatives` (or takes a logged twist and acceleration,
``derivatives="exact"``); turns motor currents into leg forces through the drive's
:class:`~stewart_env.actuators.transmission.BallScrew`; drops the samples whose force sits at the
drive's limit; fits the base parameters (OLS, WLS, physically consistent) on the log's first part
and measures the leg-force prediction error on its last, held-out part.  :func:`write` publishes
``platform.yaml``, ``report.json`` and ``report.md`` as ``stewart-env identify`` does.

Logs with jittered time stamps are resampled onto the grid of the header's rate before the filter
(cubic splines of the poses, linear interpolation of the forces): the filter assumes equal steps.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.interpolate
import scipy.linalg
import yaml

from stewart_env import files
from stewart_env.actuators.transmission import BallScrew
from stewart_env.dynamics.model import Dynamics
from stewart_env.dynamics.spec import ModelSpec
from stewart_env.errors import UsageError
from stewart_env.identification import base as base_mod
from stewart_env.identification import estimate as est
from stewart_env.identification import experiment
from stewart_env.identification import log as logs
from stewart_env.identification import regressor as reg
from stewart_env.identification.base import IdentificationError
from stewart_env.kinematics import ConvergenceError, forward_kinematics, jacobian
from stewart_env.params import PlatformParams
from stewart_env.rotations import rpy_to_matrix

#: Name of the drive constants' file looked for beside a log of motor currents.
DRIVE_FILE = "drive.yaml"
#: Largest drive constants' file, bytes.
MAX_DRIVE_BYTES = 1 << 16
#: Default share of the log, at its end, held out for validation.
HELD_OUT = 0.25
#: Leg-length residual of the forward kinematics, m: a few float64 roundings of a metre's length,
#: so that the poses are as exact as the logged lengths (the regressor's condition number, ~1e5,
#: turns a 1e-12 m pose error into 1e-7 of the parameters).
FK_TOLERANCE = 1e-14
#: How a log's forces (or currents) relate to their time stamps: ``sampled``, each the force at its
#: stamp (a load cell read at that instant); ``held``, each the force held from its stamp to the
#: next (a zero-order hold: a drive applying a digital controller's command at the log's rate), so
#: that the force acting around sample k, the one the filtered accelerations see, is the mean of
#: samples k - 1 and k.  Taken as sampled, held forces lead the motion by half a period, which the
#: fit reads as negative joint damping and a wrong model (docs/guides/your-own-platform.md).
FORCES = ("sampled", "held")
#: Relative jitter of the time stamps beyond which the log is resampled onto its rate's grid.
JITTER = 1e-9


@dataclass(frozen=True)
class LogSettings:
    """How :func:`identify_log` identifies: the identified structure (a model name), the
    derivatives (``filter``: Savitzky-Golay of the poses; ``exact``: the log's twist and
    acceleration), the share of the log held out at its end, the drive constants of a log of
    motor currents (None: looked for in ``drive.yaml`` beside the log), how the logged forces
    relate to their time stamps (:data:`FORCES`), and the consistent fit's prior weight, or
    several for :func:`identify_log` to choose from by a score."""

    model: str = "improved"
    derivatives: str = "filter"
    held_out: float = HELD_OUT
    drive: BallScrew | None = None
    forces: str = "sampled"
    prior_weight: float | tuple[float, ...] = est.PRIOR_WEIGHT


def read_drive(path: str | Path) -> BallScrew:
    """The drive constants of a YAML file whose keys are :class:`BallScrew`'s fields.

    Args:
        path: the YAML file.

    Returns:
        The drive.

    Raises:
        UsageError: the file cannot be read, or a key is unknown, missing or out of range
            (the message names the file and the key).
    """
    text = files.read_regular(path, MAX_DRIVE_BYTES, "drive constants file")
    doc = files.load_yaml(text)
    fields = tuple(BallScrew.__dataclass_fields__)
    if not isinstance(doc, dict):
        raise UsageError(f"{path}: expected a mapping of the drive constants {', '.join(fields)}")
    unknown = [k for k in doc if k not in fields]
    if unknown:
        raise UsageError(f"{path}: {unknown[0]}: not a drive constant (the keys are {', '.join(fields)})")
    if "lead" not in doc:
        raise UsageError(f"{path}: lead: missing (the screw's lead, m/rev)")
    try:
        return BallScrew(**doc)
    except (UsageError, TypeError, ValueError) as err:
        raise UsageError(f"{path}: {err}") from None


def drive_for(record: logs.Log, drive: BallScrew | None, nominal: PlatformParams | None = None) -> BallScrew:
    """The drive of a log of motor currents: ``drive``, or the ``drive.yaml`` beside the log, or
    the ball screw of the platform config's ``actuators.electric`` section.

    Args:
        record: the log.
        drive: the drive given, or None.
        nominal: the platform, whose electric actuator (if its config has one) is the last resort.

    Returns:
        The drive.

    Raises:
        UsageError: no drive given and no drive.yaml beside the log.
    """
    if drive is not None:
        return drive
    beside = Path(record.source).parent / DRIVE_FILE
    electric = None if nominal is None else nominal.actuators.electric
    if not beside.is_file() and electric is not None:
        return BallScrew.from_params(electric)
    if not beside.is_file():
        raise UsageError(
            f"{record.source}: motor currents need the drive constants: a {DRIVE_FILE} beside the log "
            f"(keys {', '.join(BallScrew.__dataclass_fields__)}), --drive FILE or the platform config's "
            "actuators.electric",
            argument="drive",
            problem="missing",
        )
    return read_drive(beside)


def poses(record: logs.Log, nominal: PlatformParams) -> tuple[np.ndarray, np.ndarray]:
    """The poses (t (T, 3), R (T, 3, 3)) of a log: its pose columns, or the forward kinematics of
    its leg lengths, each sample started from the previous one's pose (the first from home).

    Args:
        record: the log.
        nominal: the platform (its geometry).

    Returns:
        (positions, rotations).

    Raises:
        LogError: no pose fits a sample's leg lengths (naming its row).
    """
    if "pose" in record.data:
        q = record.data["pose"]
        return np.ascontiguousarray(q[:, :3]), rpy_to_matrix(q[:, 3:])
    lengths = record.data["leg_length"]
    n = lengths.shape[0]
    t, R = np.empty((n, 3)), np.empty((n, 3, 3))
    guess = (nominal.home_position, rpy_to_matrix(nominal.home_rpy))
    for k in range(n):
        try:
            try:
                guess = forward_kinematics(nominal, lengths[k], *guess, tol=FK_TOLERANCE)
            except ConvergenceError:  # rounding above FK_TOLERANCE: the default bound
                guess = forward_kinematics(nominal, lengths[k], *guess)
        except (ConvergenceError, ValueError) as err:
            raise logs.LogError(record.source, f"no pose has these leg lengths ({err})", row=k + 1) from None
        t[k], R[k] = guess
    return t, R


def _resampled(record: logs.Log, t, R, forces):
    """The poses and forces on the grid of the header's rate, when the stamps jitter."""
    time = record.time
    dt = 1.0 / record.rate
    grid = time[0] + dt * np.arange(int(np.floor((time[-1] - time[0]) / dt + 1e-9)) + 1)
    if grid.size == time.size and np.abs(grid - time).max() <= JITTER * max(1.0, abs(time[-1])):
        return time, t, R, forces, None
    pos = scipy.interpolate.CubicSpline(time, t, axis=0)(grid)
    rot = scipy.interpolate.CubicSpline(time, R.reshape(-1, 9), axis=0)(grid).reshape(-1, 3, 3)
    U, _, Vt = np.linalg.svd(rot)
    F = np.stack([np.interp(grid, time, forces[:, i]) for i in range(6)], axis=1)
    return grid, pos, U @ Vt, F, grid


def _weak_parameters(A: np.ndarray, base: base_mod.BaseParameters, source: str, duration: float) -> None:
    """IdentificationError naming the base parameters the log does not excite."""
    rows = A.reshape(-1, A.shape[-1])
    if rows.shape[0] <= rows.shape[1]:
        raise IdentificationError(
            f"{source}: {rows.shape[0]} equations for {rows.shape[1]} base parameters; the fitted part "
            f"({duration:.3g} s) needs at least {rows.shape[1] // 6 + 1} samples"
        )
    _, r, piv = scipy.linalg.qr(rows, mode="economic", pivoting=True)
    d = np.abs(np.diag(r))
    weak = piv[d < 1e-10 * d[0]]
    if weak.size:
        names = [base.names[k] for k in weak]
        shown = ", ".join(names[:4]) + (f" and {len(names) - 4} more" if len(names) > 4 else "")
        raise IdentificationError(
            f"{source}: the excitation does not excite {len(names)} of {base.rank} base parameters ({shown}): "
            "a longer record of the same motion does not help; a richer one does (stewart-env excitation, "
            "optimised, with more --harmonics)"
        )


def identify_log(
    record: logs.Log,
    nominal: PlatformParams,
    settings: LogSettings = LogSettings(),
    score: Callable[[PlatformParams], float] | None = None,
) -> dict:
    """Identify the base parameters from a record log (see the module docstring).

    With several prior weights (``settings.prior_weight`` a tuple) the consistent fit runs at
    each and keeps the identified platform of the lowest ``score``, e.g. the tracking error of a
    controller built on it on the machine (a held-out closed-loop test); the report lists every
    weight's score and held-out force error.

    Args:
        record: the checked record log.
        nominal: the nominal platform (geometry, the prior of the consistent fit).
        settings: the structure, derivatives, held-out share, drive, force timing and prior weight.
        score: the score of an identified platform, lower better (needed with several weights).

    Returns:
        ``{"identified": PlatformParams, "report": dict}``.

    Raises:
        IdentificationError: the log cannot identify the model (the message names why).
        LogError: the log does not fit (naming the file, row and column).
        UsageError: a setting out of range, or the drive constants missing.
    """
    if record.kind != "record":
        raise logs.LogError(record.source, f"a {record.kind} log, not a record")
    if settings.derivatives not in ("filter", "exact"):
        raise IdentificationError(f"--derivatives: expected filter or exact, got {settings.derivatives!r}")
    if not 0 < settings.held_out < 1:
        raise IdentificationError(f"--held-out: expected a share in (0, 1), got {settings.held_out!r}")
    if settings.forces not in FORCES:
        raise IdentificationError(f"--forces: expected {' or '.join(FORCES)}, got {settings.forces!r}")
    weights = settings.prior_weight if isinstance(settings.prior_weight, tuple) else (settings.prior_weight,)
    if not weights or not all(isinstance(x, (int, float)) and 0 < x < float("inf") for x in weights):
        raise IdentificationError(f"--prior-weight: expected positive numbers, got {settings.prior_weight!r}")
    if len(weights) > 1 and score is None:
        raise IdentificationError("prior_weight: several weights need a score to choose by")
    spec = ModelSpec.parse(settings.model, "model")
    source = record.source or "log"
    if "motor_current" in record.data:
        drive = drive_for(record, settings.drive, nominal)
        forces = drive.leg_force_from_current(record.data["motor_current"])
        force_source = "motor currents"
    else:
        drive, forces, force_source = None, record.data["leg_force"], "leg forces"
    t, R = poses(record, nominal)
    if settings.derivatives == "exact":
        missing = [g for g in ("twist", "acceleration") if g not in record.data]
        if missing:
            raise logs.LogError(source, f"--derivatives exact needs the log's {' and '.join(missing)} columns")
        tw, acc = record.data["twist"], record.data["acceleration"]
        time = record.time
        states = (t, R, tw[:, :3], tw[:, 3:], acc[:, :3], acc[:, 3:])
        keep = np.ones(time.size, bool)
        resampled = False
    else:
        time, t, R, forces, grid = _resampled(record, t, R, forces)
        resampled = grid is not None
        states = est.derivatives(1.0 / record.rate, t, R)
        keep = np.ones(time.size, bool)
        edge = est.SAVGOL_WINDOW // 2 + 1  # the filter's own extrapolation at both ends
        keep[:edge] = keep[-edge:] = False
    kept = logs.drop_clipped(source, forces, nominal.limits.leg_force)
    clipped = int((~kept).sum())
    keep &= kept
    if settings.forces == "held":
        # the hold's mean over the period centred on each stamp; a clipped sample spoils two means
        forces = np.concatenate([forces[:1], 0.5 * (forces[1:] + forces[:-1])])
        keep &= np.concatenate([[False], kept[:-1]])
    split = time[0] + (1 - settings.held_out) * (time[-1] - time[0])
    fit, held = keep & (time < split), keep & (time >= split)
    model = Dynamics(spec, nominal)
    base = base_mod.base_parameters(model)

    def rows(mask):
        sel = tuple(np.ascontiguousarray(x[mask]) for x in states)
        Y = reg.regressor_matrix(model, *sel)
        return est.leg_force_rows(base.columns(Y), jacobian(nominal, sel[0], sel[1]))

    if held.sum() < 1:
        raise logs.LogError(source, "no sample is left for the held-out part; a longer log is needed")
    A, F = rows(fit), forces[fit]
    fitted = float(fit.sum()) / record.rate
    _weak_parameters(A, base, source, fitted)
    o, w = est.ols(A, F), est.wls(A, F)
    on_drive = drive is not None  # motor currents: the drives' friction and reflected mass are in the forces
    nominal_theta = reg.theta_of(nominal, model.flags, drive=on_drive)
    A_held, F_held = rows(held), forces[held]

    def prediction_error(beta):
        return float(np.sqrt(np.mean((np.einsum("tir,r->ti", A_held, beta) - F_held) ** 2)))

    start = base.theta_from(w.beta, nominal_theta)
    candidates = []
    for weight in weights:
        theta = est.consistent(A, F, base, nominal_theta, start, prior_weight=weight, sigma=w.sigma)
        params = base_mod.params_from_theta(
            theta, nominal, model.flags, name=f"{nominal.name}_identified", drive=on_drive
        )
        candidates.append((weight, theta, params, None if score is None else float(score(params))))
    chosen = min(range(len(weights)), key=lambda k: candidates[k][3] if candidates[k][3] is not None else 0.0)
    prior_weight, theta_c, identified, _ = candidates[chosen]
    beta_c = base.of_theta(theta_c)

    beta_nominal = base.of_theta(nominal_theta)
    noise = float(np.sqrt(np.mean(w.sigma**2)))
    need = est.requirements(w.beta, w.std, fitted, noise)
    params_rows = [
        {
            "name": name,
            "ols": float(o.beta[k]),
            "ols_std": float(o.std[k]),
            "wls": float(w.beta[k]),
            "wls_std": float(w.std[k]),
            "rel_std": experiment._or_none(need.rel_std[k]),
            "duration_10pct": experiment._or_none(need.duration[k]),
            "noise_force_10pct": experiment._or_none(need.noise[k]),
            "near_zero": bool(need.near_zero[k]),
            "consistent": float(beta_c[k]),
            "nominal": float(beta_nominal[k]),
        }
        for k, name in enumerate(base.names)
    ]
    report = {
        "log": source,
        "log_header": dict(record.header),
        "platform": nominal.name,
        "settings": {
            "model": spec.name,
            "derivatives": settings.derivatives,
            "held_out": settings.held_out,
            "forces_from": force_source,
            "drive": None if drive is None else drive.__dict__.copy(),
            "forces": settings.forces,
            "prior_weight": prior_weight,
        },
        "prior_weights": [
            {"prior_weight": x, "score": sc, "held_out_force_error": prediction_error(base.of_theta(th))}
            for x, th, _, sc in candidates
        ],
        "samples": int(record.time.size),
        "resampled": resampled,
        "clipped_samples": clipped,
        "fitted_samples": int(fit.sum()),
        "held_out_samples": int(held.sum()),
        "fitted_duration": fitted,
        "rank": base.rank,
        "n_theta": reg.N_THETA,
        "residual_sigma_wls": w.sigma.tolist(),
        "base_parameters_under_10pct_rel_std": int(np.sum(need.rel_std < est.WELL_IDENTIFIED)),
        "held_out_rms_force": float(np.sqrt(np.mean(F_held**2))),
        "leg_friction_and_drive": {
            "viscous_Cp": float(theta_c[reg.OFF_DAMPING + 1]),
            "coulomb_friction": float(theta_c[reg.OFF_DRIVE]),
            "reflected_mass": float(theta_c[reg.OFF_DRIVE + 1]),
            "friction_speed": reg.friction_speed(nominal),
            "written_to": "actuators.electric"
            if on_drive and nominal.actuators.electric is not None
            else "report only",
        },
        "held_out_force_error": {
            "nominal": prediction_error(beta_nominal),
            "ols": prediction_error(o.beta),
            "wls": prediction_error(w.beta),
            "consistent": prediction_error(beta_c),
        },
        "base_parameters": params_rows,
    }
    return {"identified": identified, "report": report}


def markdown(report: dict) -> str:
    """report.md of an identification from a log.

    Args:
        report: the report of :func:`identify_log`.

    Returns:
        The Markdown text.
    """
    s, e = report["settings"], report["held_out_force_error"]
    lines = [
        f"# Identification of {report['platform']} from {report['log']}",
        "",
        f"model `{s['model']}`, derivatives `{s['derivatives']}`, forces from {s['forces_from']} "
        f"({s.get('forces', 'sampled')}), prior weight {s.get('prior_weight', est.PRIOR_WEIGHT):g}; "
        f"{report['samples']} samples{' (resampled onto the rate grid)' if report['resampled'] else ''}, "
        f"{report['clipped_samples']} clipped and dropped; fitted on {report['fitted_samples']} "
        f"({report['fitted_duration']:.4g} s), {report['held_out_samples']} held out "
        f"(the last {100 * s['held_out']:g} %)",
        "",
        f"- base parameters: {report['rank']} of {report['n_theta']}",
        f"- base parameters under 10 % relative standard deviation (WLS): "
        f"{report['base_parameters_under_10pct_rel_std']} of {report['rank']}",
        f"- held-out leg-force RMS error (N; RMS force {report['held_out_rms_force']:.4g} N): nominal "
        f"{e['nominal']:.4g}, OLS {e['ols']:.4g}, WLS {e['wls']:.4g}, consistent {e['consistent']:.4g}",
        *experiment._by_body(report),
        "",
        _friction_line(report["leg_friction_and_drive"]),
        "",
        "| base parameter | WLS | std | rel. std | consistent | nominal |",
        "|---|---|---|---|---|---|",
    ]
    for p in report["base_parameters"]:
        rel = "inf" if p["rel_std"] is None else f"{p['rel_std']:.3g}"
        lines.append(
            f"| `{p['name']}` | {p['wls']:.6g} | {p['wls_std']:.3g} | {rel} | {p['consistent']:.6g} | {p['nominal']:.6g} |"
        )
    return "\n".join(lines) + "\n"


def _friction_line(d: dict) -> str:
    """report.md's line of the leg friction and the drive's reflected mass (consistent fit)."""
    where = (
        "written to platform.yaml's actuators.electric"
        if d["written_to"] == "actuators.electric"
        else "in this report only (platform.yaml keeps C_p; it has no drive section for the rest)"
    )
    return (
        f"- leg friction (consistent fit): viscous C_p {d['viscous_Cp']:.4g} N s/m, Coulomb "
        f"{d['coulomb_friction']:.4g} N (as f_c tanh(Ldot / {d['friction_speed']:g} m/s)), reflected mass "
        f"{d['reflected_mass']:.4g} kg; {where}"
    )


def write(result: dict, out: str | Path) -> Path:
    """Publish ``platform.yaml``, ``report.json`` and ``report.md`` into the folder ``out``, locked
    while written, each file whole or not at all.

    Args:
        result: what :func:`identify_log` returns.
        out: the folder, created if missing.

    Returns:
        The folder.
    """
    with files.lock_folder(out) as folder:
        text = yaml.safe_dump(result["identified"].to_dict(), sort_keys=False)
        PlatformParams.from_dict(files.load_yaml(text), result["identified"].name)  # it loads back
        files.publish(folder / "platform.yaml", "# identified by stewart-env identify --record; see report.md\n" + text)
        report = experiment._strict(result["report"])
        files.publish(folder / "report.json", json.dumps(report, indent=1, allow_nan=False) + "\n")
        files.publish(folder / "report.md", markdown(result["report"]))
    return Path(folder)
