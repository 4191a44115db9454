"""A machine's side of identification, on paper and on a stand-in: the excitation exported as
set points, and a record of a plant following them written as its drives would log it.

:func:`excitation_log` samples the optimised (or random) Fourier excitation of
:mod:`~stewart_env.identification.excitation` at a chosen rate as time-stamped leg lengths and
poses (with their twist and acceleration), checked along every sample against the stroke, the
workspace, the angle range, the singularity margin (the Jacobian's condition number), the leg
forces and the leg speed; the series itself rides in the header (``series``), so that
:func:`record_log` can track it by the experiment's compiled computed-torque law on a plant
(:func:`stewart_env.identification.experiment.simulate`), and write leg lengths and leg forces or
motor currents (through :class:`~stewart_env.actuators.transmission.BallScrew`) with sensor
noise and delay, in the format of :mod:`~stewart_env.identification.log`.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np

from stewart_env.actuators.transmission import BallScrew
from stewart_env.dynamics.model import Dynamics
from stewart_env.dynamics.spec import ModelSpec
from stewart_env.identification import base as base_mod
from stewart_env.identification import excitation as exc
from stewart_env.identification import experiment
from stewart_env.identification import log as logs
from stewart_env.identification import regressor as reg
from stewart_env.identification.base import IdentificationError
from stewart_env.kinematics import inverse_kinematics, jacobian
from stewart_env.params import PlatformParams

#: Default bound on the legs' speed along the excitation, m/s: a ball-screw leg's usual top speed.
MAX_LEG_SPEED = 1.0
#: The structure the excitation is optimised for and the recording controller's model.
MODEL = "improved"


def rate_samples(rate: float, argument: str = "rate") -> int:
    """The plant steps (of PLANT_DT) in one sample at ``rate`` Hz.

    Args:
        rate: the sampling rate, Hz.
        argument: the argument named in the error.

    Returns:
        The whole number of plant steps per sample.

    Raises:
        IdentificationError: a rate whose period is not a whole number of PLANT_DT steps.
    """
    steps = 1.0 / (rate * experiment.PLANT_DT)
    if not (math.isfinite(steps) and steps >= 1 and abs(steps - round(steps)) < 1e-9):
        problem = (
            f"{rate:g} Hz: its period must be a whole number of the plant's {experiment.PLANT_DT:g} s steps "
            f"(e.g. 1000, 500, 250, 200, 100 Hz)"
        )
        raise IdentificationError(f"--{argument.replace('_', '-')}: {problem}", argument=argument, problem=problem)
    return int(round(steps))


@dataclass(frozen=True)
class ExcitationChecks:
    """The excitation's smallest margins to its limits along every exported sample (>= 0 inside
    :data:`~stewart_env.identification.excitation.LIMIT_SHARE` of each), its largest leg speed
    (m/s) and the condition number of its stacked base regressor."""

    margins: dict
    max_leg_speed: float
    condition: float


def excitation_log(
    nominal: PlatformParams,
    platform: str,
    rate: float = 1 / experiment.SAMPLE_DT,
    duration: float = 60.0,
    seed: int = 0,
    random: bool = False,
    period: float = 10.0,
    harmonics: int = 5,
    max_iterations: int = 30,
    max_leg_speed: float | None = None,
) -> tuple[logs.Log, ExcitationChecks]:
    """The excitation as a log of kind ``excitation``.

    Args:
        nominal: the platform.
        platform: how the platform was named (a shipped name or a config path), for the header.
        rate: the set points' rate, Hz (a period of whole plant steps).
        duration: the set points' span, s.
        seed: the random generator's seed (the random start of the optimisation).
        random: the random series, not optimised.
        period: the series' period, s.
        harmonics: its number of harmonics.
        max_iterations: the optimiser's iteration limit.
        max_leg_speed: the legs' top speed, m/s; None: the excitation's share
            (:data:`~stewart_env.identification.excitation.LIMIT_SHARE`) of the platform's
            ``limits.leg_velocity`` where it has one, else :data:`MAX_LEG_SPEED`.

    Returns:
        (the log, the checks along its samples).

    Raises:
        IdentificationError: a setting out of range, or set points outside a limit (naming it).
    """
    rate_samples(rate)
    model = Dynamics(ModelSpec.parse(MODEL), nominal)
    base = base_mod.base_parameters(model)
    rng = np.random.default_rng(seed)
    series = exc.random_excitation(nominal, model, rng, period=min(period, duration), harmonics=harmonics)
    if not random:
        series, _ = exc.optimized_excitation(series, model, base, max_iterations=max_iterations)
    times = np.arange(int(math.floor(duration * rate + 1e-9)) + 1) / rate
    kinds = ("leg stroke", "workspace", "angle range", "singularity margin (Jacobian condition)", "leg force")
    margins = dict(zip(kinds, (float(m) for m in exc.margins(series, model, times))))
    for kind, margin in margins.items():
        if margin < 0:
            raise IdentificationError(
                f"excitation: the set points leave the {kind} limit (margin {margin:.3g}; "
                f"{exc.LIMIT_SHARE:g} of each limit is the excitation's)"
            )
    q, qd, qdd = series.sample(times)
    t, R, v, w, a, alpha = exc.task_states(q, qd, qdd)
    lengths, _ = inverse_kinematics(nominal, t, R)
    speed = np.abs(np.einsum("nij,nj->ni", jacobian(nominal, t, R), np.concatenate([v, w], axis=1)))
    bound, source = max_leg_speed, "--max-leg-speed"
    if max_leg_speed is None:
        limit = nominal.limits.max_leg_velocity
        finite = math.isfinite(limit)
        bound = exc.LIMIT_SHARE * limit if finite else MAX_LEG_SPEED
        source = f"{exc.LIMIT_SHARE:g} of the platform's leg_velocity" if finite else "the default --max-leg-speed"
    if speed.max() > bound:
        problem = f"the set points' legs reach {speed.max():.3g} m/s, above {bound:g} m/s ({source})"
        raise IdentificationError(
            f"--max-leg-speed: {problem}; a longer --period slows them",
            argument="max_leg_speed",
            problem=problem,
        )
    header = {
        "format": logs.FORMAT,
        "kind": "excitation",
        "platform": platform,
        "rate_hz": repr(float(rate)),
        "what": f"{'random' if random else 'optimised'} Fourier excitation, {harmonics} harmonics of period "
        f"{series.period:.6g} s, seed {seed}",
        "condition_number": f"{exc.condition_number(series, model, base, times[times < series.period]):.6g}",
        "series": json.dumps(series.to_dict(), separators=(",", ":")),
    }
    data = {
        "time": times,
        "leg_length": lengths,
        "pose": q,
        "twist": np.concatenate([v, w], axis=1),
        "acceleration": np.concatenate([a, alpha], axis=1),
    }
    checks = ExcitationChecks(margins, float(speed.max()), float(header["condition_number"]))
    return logs.check(logs.Log(header, data), nominal), checks


def series_of(trajectory: logs.Log) -> exc.Excitation:
    """The Fourier series an excitation log carries in its header.

    Args:
        trajectory: the excitation log.

    Returns:
        The series.

    Raises:
        LogError: the log has no series, or one that does not read.
    """
    text = trajectory.header.get("series")
    if text is None:
        raise logs.LogError(
            trajectory.source,
            "the header has no 'series' entry: record follows the excitations stewart-env excitation writes",
        )
    try:
        d = json.loads(text)
        q0, a, b = (np.asarray(d[k], dtype=float) for k in ("q0", "a", "b"))
        wf = float(d["wf"])
        ok = q0.shape == (6,) and a.ndim == 2 and a.shape[0] == 6 and a.shape == b.shape and wf > 0
        ok = ok and bool(np.isfinite(q0).all() and np.isfinite(a).all() and np.isfinite(b).all() and math.isfinite(wf))
    except (ValueError, KeyError, TypeError):
        ok = False
    if not ok:
        raise logs.LogError(trajectory.source, "the header's 'series' is not a Fourier series (q0, a, b, wf)")
    return exc.Excitation(q0, a, b, wf)


@dataclass(frozen=True)
class RecordSettings:
    """How :func:`record_log` records: the plant (a model name or ``mujoco``), the relative
    perturbation of the plant's parameters from the nominal and its seed, the noise of the leg
    lengths (m) and leg forces (N), the delay (s, whole samples) of the leg lengths behind the
    forces, the drive whose motor currents are logged instead of forces (None: forces), and
    whether the plant's own twist and acceleration are logged too (``exact``, a closed-form
    plant's, a simulation-only check)."""

    plant: str | ModelSpec = "improved"
    perturb: float = 0.0
    seed: int = 0
    noise_length: float = 0.0
    noise_force: float = 0.0
    delay: float = 0.0
    drive: BallScrew | None = None
    exact: bool = False


def drive_forces(plant: Dynamics | None, truth: PlatformParams, drive: BallScrew, traj) -> np.ndarray:
    """The force (T, 6) each drive spends on itself along a recorded trajectory, beyond the leg
    force it delivers: m_r Lddot + b Ldot + f_c tanh(Ldot / v_s), with the screw's reflected mass
    m_r and the truth's electric friction (b, f_c, v_s; zeros without an ``actuators.electric``
    section), taken from the regressor's own columns (so a log of motor currents holds exactly
    the drive terms identification fits).  The plant moves under the leg forces, as if its
    controller made up for the drives' losses.

    Args:
        plant: the closed-form plant, whose forward dynamics give the accelerations; None (MuJoCo):
            the truth's closed-form model gives them.
        truth: the plant's true platform.
        drive: the drive's screw (its reflected mass).
        traj: the recorded trajectory of :func:`~stewart_env.identification.experiment.simulate`.

    Returns:
        The drive forces (T, 6), N.
    """
    model = plant if plant is not None else Dynamics(ModelSpec.parse(MODEL), truth)
    t, R, v, w = traj.position, traj.rotation, traj.velocity, traj.angular_velocity
    a, alpha = model.forward(t, R, v, w, traj.leg_forces)
    b, fc, _ = reg.drive_terms(truth)
    Y = reg.regressor_matrix(model, t, R, v, w, a, alpha, speed_scale=reg.friction_speed(truth))
    # C_p's column is J^T Ldot: the drive's viscous b acts through it
    columns = Y[..., [reg.OFF_DAMPING + 1, reg.OFF_DRIVE, reg.OFF_DRIVE + 1]]
    wrench = columns @ np.array([b, fc, drive.reflected_mass])
    return np.linalg.solve(np.swapaxes(jacobian(truth, t, R), 1, 2), wrench[..., None])[..., 0]


def record_log(
    trajectory: logs.Log, nominal: PlatformParams, settings: RecordSettings
) -> tuple[logs.Log, PlatformParams]:
    """Follow an excitation log on a plant and log it as its drives would.

    Args:
        trajectory: the excitation log (its header's series is tracked).
        nominal: the nominal platform (the controller's model and, perturbed, the plant's truth).
        settings: the plant, noise, delay, forces or currents.

    Returns:
        (the record log, the plant's true platform).

    Raises:
        IdentificationError: a setting out of range, or the plant leaving the stroke.
        LogError: the trajectory is not an excitation with a series.
    """
    if trajectory.kind != "excitation":
        raise logs.LogError(trajectory.source, f"a {trajectory.kind} log, not an excitation")
    series = series_of(trajectory)
    every = rate_samples(trajectory.rate, "trajectory")
    sample_dt = every * experiment.PLANT_DT
    delay = int(round(settings.delay / sample_dt))
    if not (0 <= settings.delay <= experiment.MAX_DELAY and abs(delay * sample_dt - settings.delay) < 1e-9):
        problem = f"expected whole samples of {sample_dt:g} s in [0, {experiment.MAX_DELAY}], got {settings.delay!r}"
        raise IdentificationError(f"--delay: {problem}", argument="delay", problem=problem)
    plant_spec = None if settings.plant == "mujoco" else ModelSpec.parse(settings.plant, "plant")
    plant_name = "mujoco" if plant_spec is None else plant_spec.name
    if settings.exact and plant_spec is None:
        problem = "the MuJoCo plant gives no accelerations"
        raise IdentificationError(f"--derivatives exact: {problem}", argument="derivatives", problem=problem)
    rng = np.random.default_rng(settings.seed)
    truth = experiment.perturbed(nominal, settings.perturb, rng)
    plant = "mujoco" if plant_spec is None else Dynamics(plant_spec, truth)
    controller = Dynamics(ModelSpec.parse(MODEL), nominal)
    duration = float(trajectory.time[-1] - trajectory.time[0])
    traj = experiment.simulate(plant, truth, controller, series, duration + 0.5 * sample_dt, sample_dt=sample_dt)
    n = traj.time.size
    lengths, _ = inverse_kinematics(truth, traj.position, traj.rotation)
    lengths = experiment.delayed(lengths, delay) + rng.normal(scale=settings.noise_length, size=(n, 6))
    forces = traj.leg_forces + rng.normal(scale=settings.noise_force, size=(n, 6))
    data = {"time": traj.time + trajectory.time[0], "leg_length": lengths}
    if settings.drive is None:
        data["leg_force"] = forces
    else:
        forces = forces + drive_forces(plant if plant_spec is not None else None, truth, settings.drive, traj)
        data["motor_current"] = settings.drive.current_from_leg_force(forces)
    if settings.exact:
        a, alpha = plant.forward(traj.position, traj.rotation, traj.velocity, traj.angular_velocity, traj.leg_forces)
        data["twist"] = experiment.delayed(np.concatenate([traj.velocity, traj.angular_velocity], axis=1), delay)
        data["acceleration"] = experiment.delayed(np.concatenate([a, alpha], axis=1), delay)
    header = {
        "format": logs.FORMAT,
        "kind": "record",
        "platform": trajectory.header["platform"],
        "rate_hz": trajectory.header["rate_hz"],
        "what": f"the excitation followed on the plant {plant_name} (parameters perturbed by "
        f"{settings.perturb:g}, seed {settings.seed}); noise: leg length {settings.noise_length:g} m, "
        f"leg force {settings.noise_force:g} N; leg lengths {settings.delay:g} s late",
    }
    return logs.check(logs.Log(header, data), nominal), truth
