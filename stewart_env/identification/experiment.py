"""The identification experiment on a stand-in plant: excite, measure, estimate, report.

:func:`run` drives a plant (a closed-form model, optionally with perturbed parameters as the
unknown truth) along an excitation by the compiled computed-torque law, adds sensor noise to the
recorded poses and leg forces (the poses optionally delayed against the forces), recovers
velocities and accelerations by a Savitzky-Golay filter, estimates the base parameters (OLS, WLS,
physically consistent) and, per base parameter, the record and force noise that would identify
it to 10 %, and measures the leg-force prediction error on a second, held-out trajectory.
:func:`write` publishes the identified platform config and the report (strict JSON: a number
that is not finite is written as null); :func:`read_report` reads a report back, checked, for
a later run's ``predicted_by``.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from stewart_env import files
from stewart_env.dynamics.model import Dynamics
from stewart_env.dynamics.rk4 import law_forces
from stewart_env.dynamics.spec import ModelSpec
from stewart_env.errors import UsageError
from stewart_env.identification import base as base_mod
from stewart_env.identification import estimate as est
from stewart_env.identification import excitation as exc
from stewart_env.identification import regressor as reg
from stewart_env.identification.base import IdentificationError
from stewart_env.integrate import Trajectory, rollout
from stewart_env.kinematics import inverse_kinematics, jacobian
from stewart_env.params import Damping, PlatformParams, RigidBody
from stewart_env.params.checks import short
from stewart_env.rotations import rotvec_to_matrix

#: Integration step of the plant (s) and sampling period of the measurements (s).
PLANT_DT = 1e-3
SAMPLE_DT = 5e-3
#: The start of each record the filter and the controller's transient spoil (s).
SETTLE = 0.5
#: Largest report.json read back (``--predicted-by``), bytes: a report is tens of kilobytes.
MAX_REPORT_BYTES = 16 << 20
#: Longest measurement delay (s): sensor pipelines lag by milliseconds to tens of milliseconds;
#: a quarter second is far beyond them and keeps the shift inside the record's dropped start.
MAX_DELAY = 0.25


def _refuse(setting: str, problem: str) -> IdentificationError:
    """The error of a setting: ``--<option>: <problem>``, the setting's name as its ``argument``."""
    return IdentificationError(f"--{setting.replace('_', '-')}: {problem}", argument=setting, problem=problem)


@dataclass
class Settings:
    """One experiment.  plant: a model name (``improved``, ``classical``, ``improved+c2``...) or
    ``mujoco``, the MuJoCo twin of the truth (stewart_env.mujoco);
    model: the structure identified (a model name); excitation: ``optimized`` or ``random``;
    duration (s) of the identification record; noise: standard deviations of the position (m),
    angle (rad) and leg force (N) measurements; delay (s, whole samples of SAMPLE_DT): how long
    the pose measurements lag the leg-force measurements; perturb: relative size of the random
    change of every inertial and friction parameter that makes the plant's truth differ from the
    nominal platform (0: the truth is the nominal); derivatives: ``filter`` (Savitzky-Golay of the
    noisy poses) or ``exact`` (the plant's own, a simulation-only check); seed."""

    plant: str = "improved"
    model: str = "improved"
    excitation: str = "optimized"
    duration: float = 20.0
    noise_position: float = 0.0
    noise_angle: float = 0.0
    noise_force: float = 0.0
    delay: float = 0.0
    perturb: float = 0.0
    derivatives: str = "filter"
    seed: int = 0
    period: float = 10.0
    harmonics: int = 5
    max_iterations: int = 30

    def check(self) -> tuple[ModelSpec | None, ModelSpec]:
        """Check every setting and parse the plant's and the model's names once.

        ``plant`` and ``model`` (names or :class:`~stewart_env.ModelSpec`) become their canonical
        names (what the report records).

        Returns:
            The pair (plant's spec, None for ``mujoco``; the identified model's spec).

        Raises:
            IdentificationError: a setting out of its range, naming its option (``err.argument``
                is the setting's name).
        """
        specs: dict[str, ModelSpec | None] = {"plant": None}
        for name in ("plant", "model"):
            if name == "plant" and self.plant == "mujoco":
                if self.derivatives == "exact":
                    problem = "the MuJoCo plant gives no accelerations; use filter"
                    raise IdentificationError(
                        f"--derivatives exact: {problem}", argument="derivatives", problem=f"exact: {problem}"
                    )
                from stewart_env.mujoco.library import require_mujoco

                try:
                    require_mujoco()
                except ImportError as err:
                    raise IdentificationError(f"--plant mujoco: {err}", argument="plant", problem=str(err)) from None
                continue
            try:
                specs[name] = ModelSpec.parse(getattr(self, name), name)
            except UsageError as err:
                raise _refuse(name, err.problem) from None
            setattr(self, name, specs[name].name)
        if self.excitation not in ("optimized", "random"):
            raise _refuse("excitation", f"expected optimized or random, got {self.excitation!r}")
        if self.derivatives not in ("filter", "exact"):
            raise _refuse("derivatives", f"expected filter or exact, got {self.derivatives!r}")
        for name in ("duration", "period"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise _refuse(name, f"expected a positive number of seconds, got {value!r}")
        if self.duration > 3600:
            raise _refuse("duration", f"at most 3600 s, got {self.duration}")
        if self.duration < 2 * SETTLE + 0.5:
            raise _refuse("duration", f"{self.duration} s is too short; at least {2 * SETTLE + 0.5} s")
        for name in ("noise_position", "noise_angle", "noise_force", "perturb"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise _refuse(name, f"expected a number >= 0, got {value!r}")
        delay = self.delay
        if not (isinstance(delay, (int, float)) and math.isfinite(delay) and 0 <= delay <= MAX_DELAY):
            raise _refuse("delay", f"expected seconds in [0, {MAX_DELAY}], got {delay!r}")
        if abs(delay - self.delay_samples * SAMPLE_DT) > 1e-9:
            raise _refuse("delay", f"expected a whole number of samples of {SAMPLE_DT} s, got {delay!r}")
        if self.perturb >= 1:
            raise _refuse("perturb", f"expected a relative change below 1, got {self.perturb}")
        return specs["plant"], specs["model"]

    @property
    def delay_samples(self) -> int:
        """The delay in whole samples of SAMPLE_DT."""
        return int(round(self.delay / SAMPLE_DT))


@dataclass
class Record:
    """Measured samples: time (T,), pose, leg forces, and the derivatives used."""

    time: np.ndarray
    states: tuple  # (t, R, v, w, a, alpha), each (T, ...)
    forces: np.ndarray  # (T, 6) measured
    true_forces: np.ndarray  # (T, 6) applied


@dataclass
class Result:
    """What :func:`run` returns: its settings, the plant's true platform, the identified platform
    and the report (the content of report.json)."""

    settings: Settings
    truth: PlatformParams
    identified: PlatformParams
    report: dict = field(default_factory=dict)


def perturbed(params: PlatformParams, size: float, rng: np.random.Generator) -> PlatformParams:
    """``params`` with every body's mass, CoM and inertia and every friction coefficient changed
    by a random relative amount up to ``size`` (each leg part on its own).

    Args:
        params: the nominal platform.
        size: the largest relative change (0: ``params`` unchanged).
        rng: the random generator.
    """
    if size == 0:
        return params

    def body(b: RigidBody) -> RigidBody:
        if b.mass == 0:
            return b
        f = 1 + rng.uniform(-size, size, 3)
        com = b.com + rng.uniform(-size, size, 3) * max(np.abs(b.com).max(), 0.01)
        return RigidBody(mass=b.mass * f[0], com=com, inertia=b.inertia * f[2])

    d = params.damping
    fd = 1 + rng.uniform(-size, size, 3)
    return params.replace(
        platform=body(params.platform),
        upper_leg=tuple(body(b) for b in params.upper_leg),
        lower_leg=tuple(body(b) for b in params.lower_leg),
        damping=Damping(d.universal * fd[0], d.prismatic * fd[1], d.spherical * fd[2]),
    )


def _simulate_mujoco(truth: PlatformParams, row: np.ndarray, start: tuple, steps: int, every: int) -> Trajectory:
    """MuJoCo stepping the truth, the law's forces held over each sampling period (zero-order
    hold, as a digital controller applies them).  The recorded force of sample k is the mean of
    the forces held before and after its stamp (``forces="held"`` of a log, logged.FORCES): the
    force around the stamp, where the filtered accelerations are centred; the force applied from
    the stamp on would lead the motion by half a period."""
    from stewart_env.mujoco import MujocoPlant

    plant = MujocoPlant(truth, timestep=PLANT_DT, nthread=0)
    t, R, v, w = (np.ascontiguousarray(x.copy()) for x in start)
    n = steps // every + 1
    rec = Trajectory(
        np.arange(n) * every * PLANT_DT,
        np.empty((n, 3)),
        np.empty((n, 3, 3)),
        np.empty((n, 3)),
        np.empty((n, 3)),
        np.empty((n, 6)),
    )
    wrench = np.zeros((1, 6))
    for k in range(n):
        F = law_forces(exc.FOURIER_COMPUTED_TORQUE, row[None], t, R, v, w, time=float(rec.time[k]))
        for arr, x in zip(rec[1:], (t[0], R[0], v[0], w[0], F[0])):
            arr[k] = x
        if not np.isfinite(F).all():
            raise IdentificationError("plant: the MuJoCo simulation diverged along the excitation")
        if k < n - 1:
            plant.step_inplace(t, R, v, w, F, wrench, PLANT_DT, every)
    applied = rec.leg_forces.copy()
    rec.leg_forces[1:] = 0.5 * (applied[:-1] + applied[1:])
    return rec


def simulate(
    plant: Dynamics | str,
    truth: PlatformParams,
    controller: Dynamics,
    series: exc.Excitation,
    duration: float,
    sample_dt: float = SAMPLE_DT,
):
    """Drive the plant (a closed-form model, or ``"mujoco"`` on the truth) along the series by
    the compiled computed-torque law; returns the recorded Trajectory.  IdentificationError
    when the plant diverges or leaves the stroke.

    Args:
        plant: the plant: a closed-form model, or ``"mujoco"``.
        truth: the plant's true platform (MuJoCo's; a closed-form plant has its own).
        controller: the computed-torque controller's dynamics model.
        series: the excitation to follow.
        duration: the record's length, s.
        sample_dt: the sampling period of the record, s, a whole number of PLANT_DT steps.
    """
    q, qd, qdd = series.sample([0.0])
    t0, R0, v0, w0, _, _ = exc.task_states(q, qd, qdd)
    steps = int(round(duration / PLANT_DT))
    every = int(round(sample_dt / PLANT_DT))
    steps -= steps % every
    row = series.law_row(controller)
    if isinstance(plant, str):
        traj = _simulate_mujoco(truth, row, (t0, R0, v0, w0), steps, every)
    else:
        try:
            traj = rollout(
                plant,
                t0[0],
                R0[0],
                v0[0],
                w0[0],
                dt=PLANT_DT,
                steps=steps,
                control_law=exc.FOURIER_COMPUTED_TORQUE,
                control_params=row,
                record_every=every,
            )
        except FloatingPointError:
            raise IdentificationError(
                "plant: the simulation diverged along the excitation (state no longer finite)"
            ) from None
    if not (np.isfinite(traj.position).all() and np.isfinite(traj.rotation).all()):
        raise IdentificationError("plant: the simulation diverged along the excitation (state no longer finite)")
    lim = truth.limits
    L, _ = inverse_kinematics(truth, traj.position, traj.rotation)
    if L.min() < lim.leg_length[0] or L.max() > lim.leg_length[1]:
        raise IdentificationError(
            f"excitation: the plant's legs leave the stroke {list(lim.leg_length)} m "
            f"(lengths {L.min():.4f}-{L.max():.4f} m)"
        )
    return traj


def delayed(x: np.ndarray, samples: int) -> np.ndarray:
    """X (T, ...) seen ``samples`` samples late: entry n is x[n - samples]; the first entries,
    before anything arrived, repeat x[0] (callers drop them).

    Args:
        x: the samples (T, ...).
        samples: the delay in samples (0: ``x`` itself).
    """
    if samples == 0:
        return x
    return np.concatenate([np.repeat(x[:1], samples, axis=0), x[:-samples]])


def measure(plant: Dynamics, traj, settings: Settings, rng: np.random.Generator) -> Record:
    """Noisy measurements of a recorded trajectory and the motion derivatives the estimators use.
    The poses (and with exact derivatives every motion quantity) lag the leg forces by
    ``settings.delay``.

    Args:
        plant: the plant's closed-form model, whose forward dynamics give the exact accelerations
            (``settings.derivatives`` ``"exact"``).
        traj: the recorded trajectory of :func:`simulate`.
        settings: the experiment's settings (noise levels, delay, derivative method).
        rng: the random generator of the noise.
    """
    n, k = traj.time.size, settings.delay_samples
    pos = delayed(traj.position, k) + rng.normal(scale=settings.noise_position, size=(n, 3))
    rot = rotvec_to_matrix(rng.normal(scale=settings.noise_angle, size=(n, 3))) @ delayed(traj.rotation, k)
    forces = traj.leg_forces + rng.normal(scale=settings.noise_force, size=(n, 6))
    if not (np.isfinite(pos).all() and np.isfinite(rot).all() and np.isfinite(forces).all()):
        raise IdentificationError("measurements: non-finite poses or leg forces")
    if settings.derivatives == "exact":
        t, R, v, w = traj.position, traj.rotation, traj.velocity, traj.angular_velocity
        a, alpha = plant.forward(t, R, v, w, traj.leg_forces)
        states = tuple(delayed(x, k) for x in (t, R, v, w, a, alpha))
    else:
        states = est.derivatives(SAMPLE_DT, pos, rot)
    keep = traj.time >= SETTLE
    keep[: k + est.SAVGOL_WINDOW // 2 + 1] = False  # poses not yet arrived, and the filter's start on them
    keep[-(est.SAVGOL_WINDOW // 2 + 1) :] = False
    return Record(
        traj.time[keep], tuple(np.ascontiguousarray(x[keep]) for x in states), forces[keep], traj.leg_forces[keep]
    )


def rows_of(model: Dynamics, base: base_mod.BaseParameters, record: Record) -> np.ndarray:
    """Leg-force rows A (T, 6, r) of a record.

    Args:
        model: the identified model's dynamics.
        base: its base parameters.
        record: the measured record.
    """
    Y = reg.regressor_matrix(model, *record.states)
    J = jacobian(model.params[0], record.states[0], record.states[1])
    return est.leg_force_rows(base.columns(Y), J)


def read_report(path: str | Path) -> dict:
    """The report.json of an earlier run, read to predict this run's standard deviations.

    Read through :func:`stewart_env.files.read_json` (a regular file of at most
    :data:`MAX_REPORT_BYTES`) and checked by :func:`check_report`.

    Args:
        path: the report.json.

    Returns:
        The report.

    Raises:
        IdentificationError: not a readable JSON file, or a field a prediction reads is missing
            or not what it should be (the message names the file and the key).
    """
    try:
        report = files.read_json(path, MAX_REPORT_BYTES, "report.json")
    except files.FileError as err:
        raise IdentificationError(str(err)) from None
    return check_report(report, str(path))


def check_report(report: object, source: str) -> dict:
    """``report`` if every field a prediction reads from an identify report holds what
    :func:`run` writes: ``platform`` and ``settings.model`` text, ``settings.noise_force`` and
    ``fitted_duration`` positive numbers, ``base_parameters`` a list of objects with a ``name``,
    a finite ``wls`` and a positive ``wls_std`` (a report someone edited may hold anything).

    Args:
        report: the decoded report.json.
        source: where it came from, named in messages.

    Returns:
        ``report``.

    Raises:
        IdentificationError: naming ``source`` and the key (``base_parameters[3].wls_std``).
    """

    def field(mapping: object, name: str, key: str) -> object:
        if not isinstance(mapping, dict):
            raise IdentificationError(
                f"{source}: not a report.json of stewart-env identify ({key or 'the document'} "
                f"is {short(mapping)}, not an object)"
            )
        if name not in mapping:
            raise IdentificationError(
                f"{source}: not a report.json of stewart-env identify (no {key + '.' if key else ''}{name})"
            )
        return mapping[name]

    def text(mapping: object, name: str, key: str = "") -> None:
        value = field(mapping, name, key)
        if not isinstance(value, str):
            raise IdentificationError(f"{source}: {key + '.' if key else ''}{name}: expected text, got {short(value)}")

    def number(mapping: object, name: str, key: str = "", positive: bool = True) -> None:
        value = field(mapping, name, key)
        usable = (
            isinstance(value, (int, float))
            and not isinstance(value, bool)
            and math.isfinite(value)
            and (value > 0 or not positive)
        )
        if not usable:
            kind = "a number > 0" if positive else "a finite number"
            raise IdentificationError(
                f"{source}: {key + '.' if key else ''}{name}: expected {kind}, got {short(value)}"
            )

    text(report, "platform")
    text(field(report, "settings", ""), "model", "settings")
    number(report["settings"], "noise_force", "settings")
    number(report, "fitted_duration")
    rows = field(report, "base_parameters", "")
    if not isinstance(rows, list) or not rows:
        raise IdentificationError(f"{source}: base_parameters: expected a list of base parameters, got {short(rows)}")
    for k, row in enumerate(rows):
        key = f"base_parameters[{k}]"
        text(row, "name", key)
        number(row, "wls", key, positive=False)
        number(row, "wls_std", key)
    return report


def _check_reference(
    reference: dict, settings: Settings, nominal: PlatformParams, base: base_mod.BaseParameters, model: ModelSpec
) -> None:
    """IdentificationError unless ``reference`` is an identify report of the same platform's and
    model's base parameters, recorded with force noise, and this experiment has force noise."""
    check_report(reference, "--predicted-by")
    names = [p["name"] for p in reference["base_parameters"]]
    try:  # a report of an older version may spell the same model otherwise ("classical+c1")
        same_model = ModelSpec.parse(reference["settings"]["model"]) == model
    except UsageError:
        same_model = False
    ok = reference["platform"] == nominal.name and same_model
    if not ok or names != base.names:
        raise IdentificationError(
            f"--predicted-by: a report of {nominal.name}'s {settings.model} base parameters with force noise is needed"
        )
    if settings.noise_force <= 0:
        raise IdentificationError("--predicted-by: needs --noise-force > 0 (the law scales with the force noise)")


def _prediction(reference: dict, fitted: float, noise: float, std_now: np.ndarray, need: est.Requirement) -> dict:
    """The reference's standard deviations scaled to this record and noise, against this record's."""
    ref = reference["base_parameters"]
    std = est.predicted_std(
        np.array([p["wls_std"] for p in ref]),
        reference["fitted_duration"],
        reference["settings"]["noise_force"],
        fitted,
        noise,
    )
    ref_beta = np.array([p["wls"] for p in ref])
    ref_zero = np.abs(ref_beta) <= est.NEAR_ZERO_STD * np.array([p["wls_std"] for p in ref])
    both = ~(need.near_zero | ref_zero)
    rel_predicted = std / np.abs(ref_beta)

    def spread(x):
        return {
            "median": float(np.median(x)),
            "p10": float(np.percentile(x, 10)),
            "p90": float(np.percentile(x, 90)),
            "count": int(x.size),
        }

    return {
        "fitted_duration": float(reference["fitted_duration"]),
        "noise_force": float(reference["settings"]["noise_force"]),
        "std_ratio": spread(std_now / std),
        "rel_std_ratio": spread(need.rel_std[both] / rel_predicted[both]),
        "predicted_std": std.tolist(),
        "predicted_rel_std": rel_predicted.tolist(),
    }


def run(settings: Settings, nominal: PlatformParams, predicted_by: dict | None = None) -> Result:
    """The whole experiment (see the module docstring).  ``predicted_by``: the report of an
    earlier run of the same platform and model, whose standard deviations, scaled to this
    record's length and force noise (:func:`estimate.predicted_std`), the report compares with
    this run's (its ``predicted_by`` entry).

    Args:
        settings: the experiment's settings.
        nominal: the nominal platform, which the plant's truth perturbs and the identification starts from.
        predicted_by: the report of an earlier run to compare the standard deviations with, or None.
    """
    plant_spec, model_spec = settings.check()
    rng = np.random.default_rng(settings.seed)
    truth = perturbed(nominal, settings.perturb, rng)
    plant = "mujoco" if plant_spec is None else Dynamics(plant_spec, truth)
    model = Dynamics(model_spec, nominal)
    base = base_mod.base_parameters(model)
    if predicted_by is not None:
        _check_reference(predicted_by, settings, nominal, base, model_spec)
    period = min(settings.period, settings.duration)
    start = exc.random_excitation(nominal, model, rng, period=period, harmonics=settings.harmonics)
    times = np.linspace(0, period, 100, endpoint=False)
    info = {"condition_start": exc.condition_number(start, model, base, times)}
    series = start
    if settings.excitation == "optimized":
        series, info = exc.optimized_excitation(start, model, base, max_iterations=settings.max_iterations)
    info["condition"] = info.get("condition", info["condition_start"])

    record = measure(plant, simulate(plant, truth, model, series, settings.duration), settings, rng)
    A = rows_of(model, base, record)
    est.check_rank(A, base)
    o = est.ols(A, record.forces)
    w = est.wls(A, record.forces)
    nominal_theta = reg.theta_of(nominal, model.flags)
    theta_wls = base.theta_from(w.beta, nominal_theta)
    theta_c = est.consistent(A, record.forces, base, nominal_theta, theta_wls, sigma=w.sigma)
    beta_c = base.of_theta(theta_c)
    identified = base_mod.params_from_theta(theta_c, nominal, model.flags, name=f"{nominal.name}_identified")

    # held out: a second, random series on the same plant, its forces predicted by each model
    held_series = exc.random_excitation(nominal, model, rng, period=period, harmonics=settings.harmonics)
    held = measure(plant, simulate(plant, truth, model, held_series, min(settings.duration, 2 * period)), settings, rng)
    A_held = rows_of(model, base, held)

    def prediction_error(beta):
        F = np.einsum("tir,r->ti", A_held, beta)
        return float(np.sqrt(np.mean((F - held.true_forces) ** 2)))

    beta_nominal = base.of_theta(nominal_theta)
    truth_beta = base.of_theta(reg.theta_of(truth, model.flags))
    plant_flags = 0 if plant_spec is None else plant_spec.flags  # MuJoCo: exact
    exact_structure = plant_flags == model.flags
    rms_force = float(np.sqrt(np.mean(held.true_forces**2)))
    names = base.names
    fitted = record.time.size * SAMPLE_DT
    need = est.requirements(w.beta, w.std, fitted, settings.noise_force)
    dropped = settings.duration - fitted  # the record's start and end the fit does not use
    params_rows = []
    for k in range(base.rank):
        row = {
            "name": names[k],
            "ols": float(o.beta[k]),
            "ols_std": float(o.std[k]),
            "wls": float(w.beta[k]),
            "wls_std": float(w.std[k]),
            "rel_std": _or_none(need.rel_std[k]),
            "duration_10pct": _or_none(need.duration[k] + dropped),
            "noise_force_10pct": _or_none(need.noise[k]),
            "near_zero": bool(need.near_zero[k]),
            "consistent": float(beta_c[k]),
            "nominal": float(beta_nominal[k]),
        }
        if exact_structure:
            row["truth"] = float(truth_beta[k])
        params_rows.append(row)
    rel_std = need.rel_std
    prediction = None if predicted_by is None else _prediction(predicted_by, fitted, settings.noise_force, w.std, need)
    if prediction is not None:
        for row, std, rel in zip(params_rows, prediction["predicted_std"], prediction["predicted_rel_std"]):
            row["predicted_std"], row["predicted_rel_std"] = _or_none(std), _or_none(rel)
    report = {
        "settings": settings.__dict__.copy(),
        "platform": nominal.name,
        "samples": int(record.time.size),
        "delay_samples": settings.delay_samples,
        "fitted_duration": fitted,
        "rank": base.rank,
        "n_theta": reg.N_THETA,
        "rank_tolerance": base_mod.RANK_TOLERANCE,
        "condition_number": float(info["condition"]),
        "condition_number_start": float(info["condition_start"]),
        "residual_sigma_wls": w.sigma.tolist(),
        "base_parameters_under_10pct_rel_std": int(np.sum(rel_std < 0.1)),
        "held_out_rms_force": rms_force,
        "held_out_force_error": {
            "nominal": prediction_error(beta_nominal),
            "ols": prediction_error(o.beta),
            "wls": prediction_error(w.beta),
            "consistent": prediction_error(beta_c),
        },
        "excitation": series.to_dict(),
        "base_parameters": params_rows,
    }
    if prediction is not None:
        report["predicted_by"] = {k: v for k, v in prediction.items() if not k.startswith("predicted_")}
    if exact_structure:
        err = np.abs(w.beta - truth_beta)
        rel = err / np.maximum(np.abs(truth_beta), 1e-12)
        report["truth_error"] = {
            "max_rel_wls": float(np.max(rel)),
            "median_rel_wls": float(np.median(rel)),
            "within_10pct_wls": int(np.sum(rel < 0.1)),
            "within_3_std_wls": float(np.mean(err <= 3 * w.std)),
        }
    return Result(settings, truth, identified, report)


def _strict(value):
    """``value`` with every number that is not finite replaced by None, JSON's null: strict JSON
    has no NaN or Infinity (Python's json would write them, other readers refuse the file)."""
    if isinstance(value, dict):
        return {k: _strict(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_strict(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _or_none(x: float) -> float | None:
    """x, or None (JSON's null) where it is infinite."""
    return float(x) if math.isfinite(x) else None


def _figure(x: float | None, none: str) -> str:
    return none if x is None else f"{x:.3g}"


def body_of(name: str) -> str:
    """The body a base parameter belongs to, by its leading entry of theta: ``platform``,
    ``leg i`` (its upper and lower part turn together) or ``friction`` (the joints' and the drives').

    Args:
        name: the base parameter's name, as :attr:`~stewart_env.identification.base.BaseParameters.names` gives
            it.
    """
    head = name.split(" ")[0].split(".")[0]
    if head.startswith(("upper_leg[", "lower_leg[")):
        return "leg " + head.split("[")[1].rstrip("]")
    return "friction" if head in ("damping", "drive") else head


def _by_body(report: dict) -> list[str]:
    """The per-body summary of the per-parameter answers (report.md)."""
    groups: dict[str, list[dict]] = {}
    for p in report["base_parameters"]:
        groups.setdefault(body_of(p["name"]), []).append(p)
    target = f"{100 * est.WELL_IDENTIFIED:g} %"
    lines = [
        "",
        f"By body: how many base parameters are under {target} and how many ~0; of the others, the "
        f"`--duration` (s) for {target} at this force noise and the force noise (N) for {target} in this "
        "recording, median and worst.",
        "",
        f"| body | base parameters | rel. std < {target} | ~0 | --duration, median | --duration, longest "
        "| force noise, median | force noise, smallest |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for body, rows in groups.items():
        rest = [p for p in rows if not p["near_zero"]]
        time = np.array([np.inf if p["duration_10pct"] is None else p["duration_10pct"] for p in rest])
        noise = np.array([np.inf if p["noise_force_10pct"] is None else p["noise_force_10pct"] for p in rest])
        under = sum(p["rel_std"] is not None and p["rel_std"] < est.WELL_IDENTIFIED for p in rows)
        figures = (
            f"{np.median(time):.3g} | {time.max():.3g} | {np.median(noise):.3g} | {noise.min():.3g}"
            if rest
            else "| | |"
        )
        lines.append(f"| {body} | {len(rows)} | {under} | {len(rows) - len(rest)} | {figures} |")
    return lines


def _markdown(report: dict) -> str:
    s = report["settings"]
    e = report["held_out_force_error"]
    lines = [
        f"# Identification of {report['platform']}",
        "",
        f"plant `{s['plant']}`, model `{s['model']}`, excitation `{s['excitation']}`, {s['duration']} s, "
        f"noise: position {s['noise_position']} m, angle {s['noise_angle']} rad, force {s['noise_force']} N; "
        f"poses delayed by {s['delay']} s ({report['delay_samples']} samples); "
        f"truth perturbed by {s['perturb']}; seed {s['seed']}",
        "",
        f"- base parameters: {report['rank']} of {report['n_theta']} (QR tolerance {report['rank_tolerance']:g})",
        f"- condition number of the stacked base regressor: {report['condition_number']:.4g} "
        f"(random start {report['condition_number_start']:.4g})",
        f"- base parameters under 10 % relative standard deviation (WLS): "
        f"{report['base_parameters_under_10pct_rel_std']} of {report['rank']}",
        f"- held-out leg-force RMS error (N; RMS force {report['held_out_rms_force']:.4g} N): nominal "
        f"{e['nominal']:.4g}, OLS {e['ols']:.4g}, WLS {e['wls']:.4g}, consistent {e['consistent']:.4g}",
    ]
    if "truth_error" in report:
        t = report["truth_error"]
        lines.append(
            f"- WLS against the truth: {t['within_10pct_wls']} of {report['rank']} base parameters within "
            f"10 %, median relative error {t['median_rel_wls']:.3g}, largest {t['max_rel_wls']:.3g} (a "
            f"combination near zero); {100 * t['within_3_std_wls']:.1f} % within 3 standard deviations"
        )
    if "predicted_by" in report:
        q = report["predicted_by"]
        a, b = q["std_ratio"], q["rel_std_ratio"]
        lines.append(
            f"- against what a run of {q['fitted_duration']:.4g} s at {q['noise_force']:g} N predicts "
            f"(std ~ sigma / sqrt(T)), measured / predicted: std median {a['median']:.3g} (10-90 %: "
            f"{a['p10']:.3g}-{a['p90']:.3g}, {a['count']} parameters), rel. std median {b['median']:.3g} "
            f"({b['p10']:.3g}-{b['p90']:.3g}, the {b['count']} not ~0 in either run)"
        )
    lines += _by_body(report)
    truth = "truth_error" in report
    predicted = "predicted_by" in report
    target = f"{100 * est.WELL_IDENTIFIED:g} %"
    lines += [
        "",
        f"Per base parameter: the WLS estimate, its standard deviation and relative standard deviation; "
        f"the `--duration` (s) that brings it to {target} at this force noise, and the force noise (N) that "
        f"does in this recording (standard deviation as sigma / sqrt(T)); `~0`: the estimate is within "
        f"{est.NEAR_ZERO_STD:g} standard deviations of zero, so its relative deviation tells nothing.",
        "",
        f"| base parameter | WLS | std | rel. std | --duration for {target}, s | force noise for {target}, N "
        + ("| predicted rel. std " if predicted else "")
        + "| consistent | nominal |"
        + (" truth |" if truth else ""),
        "|---|---|---|---|---|---|---|---|" + ("---|" if truth else "") + ("---|" if predicted else ""),
    ]
    for p in report["base_parameters"]:
        if p["near_zero"]:
            time, noise = "~0", "~0"
        else:
            time, noise = _figure(p["duration_10pct"], "never"), _figure(p["noise_force_10pct"], "n/a")
        row = (
            f"| `{p['name']}` | {p['wls']:.6g} | {p['wls_std']:.3g} | {_figure(p['rel_std'], 'inf')} | {time} "
            f"| {noise} "
            + (f"| {_figure(p['predicted_rel_std'], 'inf')} " if predicted else "")
            + f"| {p['consistent']:.6g} | {p['nominal']:.6g} |"
        )
        if truth:
            row += f" {p['truth']:.6g} |"
        lines.append(row)
    return "\n".join(lines) + "\n"


def write(result: Result, out: str | Path) -> Path:
    """Publish ``platform.yaml`` (the identified platform, a config every command accepts as
    ``--platform``), ``truth.yaml`` (the plant's), ``report.json`` and ``report.md`` into the folder ``out``, which is locked
    while it is written; each file appears whole or not at all.  report.json is strict JSON: a
    number that is not finite (an infinite relative deviation or condition number, a NaN) is
    written as null; report.md shows it as ``inf`` or ``nan``.

    Args:
        result: the experiment's result.
        out: the folder, created if missing.
    """
    with files.lock_folder(out) as folder:
        text = yaml.safe_dump(result.identified.to_dict(), sort_keys=False)
        PlatformParams.from_dict(files.load_yaml(text), result.identified.name)  # it loads back
        files.publish(folder / "platform.yaml", "# identified by stewart-env identify; see report.md\n" + text)
        truth = yaml.safe_dump(result.truth.to_dict(), sort_keys=False)
        files.publish(
            folder / "truth.yaml", "# the plant's parameters (the unknown truth) of this experiment\n" + truth
        )
        files.publish(folder / "report.json", json.dumps(_strict(result.report), indent=1, allow_nan=False) + "\n")
        files.publish(folder / "report.md", _markdown(result.report))
    return Path(folder)
