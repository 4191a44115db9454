"""How close MuJoCo's twin comes to the exact ``improved`` model: the accuracy study.

Each function measures one thing on a platform config (an acceleration, a drift, a trajectory's
energy and loop closure, the effect of the omitted spherical friction); :func:`accuracy_report`
gathers them as the markdown table of ``python -m stewart_env.mujoco``.  With a platform's
electric drive (``actuator="electric"``), :func:`reflected_mass_error` and
:func:`electric_agreement` measure the twin's armature and drive against the closed form's
reflected masses (docs/physics.md section 10.2).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from stewart_env import _core
from stewart_env.actuators import ElectricActuator
from stewart_env.dynamics.model import make_dynamics
from stewart_env.kinematics import leg_kinematics
from stewart_env.mujoco.library import require_mujoco
from stewart_env.mujoco.mjcf import DEFAULT_SOLIMP, DEFAULT_SOLREF, home_rotation, number_list
from stewart_env.mujoco.plant import ACTUATORS, MujocoPlant
from stewart_env.mujoco.twin import Twin, joint_mass_matrix, model_and_data, platform_acceleration
from stewart_env.params import Damping, PlatformParams
from stewart_env.rotations import rotation_error, rpy_to_matrix

__all__ = [
    "MUJOCO_SOLIMP",
    "MUJOCO_SOLREF",
    "acceleration_error",
    "accuracy_report",
    "electric_agreement",
    "holding_drift",
    "plant_difference",
    "reflected_mass_error",
    "spherical_friction_effect",
    "trajectory_report",
]


def _test_state(params: PlatformParams, seed: int):
    """A valid moving state near home: P's origin within 2 % of the mean leg length, angles within
    0.1 rad, v up to 0.2 m/s, omega up to 0.3 rad/s; and the leg forces that hold that pose at rest."""
    rng = np.random.default_rng(seed)
    scale = float(np.mean(leg_kinematics(params, params.home_position, home_rotation(params)).lengths))
    t = params.home_position + rng.uniform(-0.02, 0.02, 3) * scale
    R = rpy_to_matrix(params.home_rpy + rng.uniform(-0.1, 0.1, 3))
    v, w = rng.uniform(-0.2, 0.2, 3), rng.uniform(-0.3, 0.3, 3)
    z = np.zeros(3)
    F = make_dynamics("improved", params).inverse(t, R, z, z, z, z)
    return t, R, v, w, F


def _without_spherical_friction(params: PlatformParams) -> PlatformParams:
    d = params.damping
    return params.replace(damping=Damping(d.universal, d.prismatic, 0.0))


def acceleration_error(
    params: PlatformParams,
    solref: Sequence[float] = DEFAULT_SOLREF,
    solimp: Sequence[float] = DEFAULT_SOLIMP,
    seed: int = 0,
    force_scale: float = 1.1,
) -> float:
    """Largest difference between MuJoCo's platform acceleration and the ``improved`` model's.

    The forward dynamics (docs/physics.md section 5.4) at a valid moving state near home with the
    legs set by inverse kinematics, under ``force_scale`` times the holding forces.  The model
    compared has C_s = 0, as the twin.

    Args:
        params: the platform's parameters.
        solref: the loop-closure constraints' (time constant s, damping ratio), as in
            :func:`~stewart_env.mujoco.to_mjcf`.
        solimp: the constraints' impedance, as in :func:`~stewart_env.mujoco.to_mjcf`.
        seed: the seed of the moving state near home.
        force_scale: the factor on the holding forces.

    Returns:
        One number over the six components, m/s^2 and rad/s^2.
    """
    mj = require_mujoco()
    t, R, v, w, F = _test_state(params, seed)
    F = F * force_scale
    m, d = model_and_data(params, t, R, v, w, F, solref=solref, solimp=solimp)
    mj.mj_forward(m, d)
    a, alpha = platform_acceleration(m, d)
    a0, alpha0 = make_dynamics("improved", _without_spherical_friction(params)).forward(t, R, v, w, F)
    return float(np.abs(np.concatenate([a - a0, alpha - alpha0])).max())


def spherical_friction_effect(params: PlatformParams, seed: int = 0) -> float:
    """What omitting the spherical joints' friction C_s changes.

    Args:
        params: the platform's parameters.
        seed: the seed of the moving state near home.

    Returns:
        The largest difference in the ``improved`` model's platform acceleration (m/s^2, rad/s^2)
        with and without C_s at the moving state of :func:`acceleration_error`.
    """
    t, R, v, w, F = _test_state(params, seed)
    a = make_dynamics("improved", params).forward(t, R, v, w, F)
    b = make_dynamics("improved", _without_spherical_friction(params)).forward(t, R, v, w, F)
    return float(np.abs(np.concatenate(a) - np.concatenate(b)).max())


def plant_difference(
    params: PlatformParams,
    seconds: float = 1.0,
    control_dt: float = 0.01,
    dt: float = 1e-3,
    spherical_friction: bool = True,
    seed: int = 0,
) -> tuple[float, float]:
    """How far :class:`MujocoPlant`'s platform ends from the ``improved`` model's.

    The ``improved`` model has every friction included, RK4 at ``dt``; both start from the moving
    state of :func:`acceleration_error` under its holding forces, stepped in calls of
    ``control_dt`` as an environment does.

    Args:
        params: the platform's parameters.
        seconds: the length of the motion, s.
        control_dt: the length of each call, s.
        dt: the step of both, s.
        spherical_friction: with the plant's held spherical friction.
        seed: the seed of the moving state near home.

    Returns:
        The pair (position m, rotation rad) of the differences at the end.
    """
    from stewart_env.integrate import rollout_inplace

    t, R, v, w, F = _test_state(params, seed)
    mine = [x[None].copy() for x in (t, R, v, w)]
    exact = [x.copy() for x in mine]
    F, W = F[None], np.zeros((1, 6))
    plant = MujocoPlant(params, dt, spherical_friction=spherical_friction)
    model = make_dynamics("improved", params)
    substeps = int(round(control_dt / dt))
    for _ in range(int(round(seconds / control_dt))):
        plant.step_inplace(*mine, F, W, dt, substeps)
        rollout_inplace(model, *exact, F, W, dt, substeps)
    return float(np.linalg.norm(mine[0][0] - exact[0][0])), float(rotation_error(mine[1][0], exact[1][0])[1])


def holding_drift(
    params: PlatformParams,
    seconds: float = 1.0,
    timestep: float = 1e-3,
    solref: Sequence[float] = DEFAULT_SOLREF,
    solimp: Sequence[float] = DEFAULT_SOLIMP,
    seed: int = 0,
) -> tuple[float, float]:
    """Drift of MuJoCo's platform under the forces that hold the exact mechanism at rest.

    The leg forces that ``inverse`` of the ``improved`` model says hold the platform at rest at
    the pose of :func:`acceleration_error`: the exact mechanism would not move at all.

    Args:
        params: the platform's parameters.
        seconds: the length of the motion, s.
        timestep: MuJoCo's step, s.
        solref: the loop-closure constraints' (time constant s, damping ratio), as in
            :func:`~stewart_env.mujoco.to_mjcf`.
        solimp: the constraints' impedance, as in :func:`~stewart_env.mujoco.to_mjcf`.
        seed: the seed of the moving state near home.

    Returns:
        The pair (position drift m, rotation drift rad) over ``seconds``.
    """
    t, R, _, _, F = _test_state(params, seed)
    plant = MujocoPlant(params, timestep, solref, solimp)
    state = [t[None].copy(), R[None].copy(), np.zeros((1, 3)), np.zeros((1, 3))]
    plant.step_inplace(*state, F[None], np.zeros((1, 6)), timestep, int(round(seconds / timestep)))
    return float(np.linalg.norm(state[0][0] - t)), float(rotation_error(state[1][0], R)[1])


def trajectory_report(
    params: PlatformParams,
    seconds: float = 1.0,
    timestep: float = 1e-3,
    solref: Sequence[float] = DEFAULT_SOLREF,
    solimp: Sequence[float] = DEFAULT_SOLIMP,
    seed: int = 0,
) -> dict:
    """Energy and loop closure of MuJoCo's twin over a free motion, beside the exact model.

    The platform starts at the moving state of :func:`acceleration_error` under constant holding
    forces, with every joint's friction set to zero, so the exact mechanism conserves
    E = kinetic + gravitational - sum_i F_i L_i (constant leg forces have the potential -F_i L_i).

    Args:
        params: the platform's parameters.
        seconds: the length of the motion, s.
        timestep: MuJoCo's step, s.
        solref: the loop-closure constraints' (time constant s, damping ratio), as in
            :func:`~stewart_env.mujoco.to_mjcf`.
        solimp: the constraints' impedance, as in :func:`~stewart_env.mujoco.to_mjcf`.
        seed: the seed of the moving state near home.

    Returns:
        A dict of ``energy_drift`` (J, largest |E - E(0)| along the way), ``kinetic_energy`` (J, at
        the start, the scale of the motion), ``closure_max`` (m, largest loop gap),
        ``position_difference`` (m, |t_MuJoCo - t_improved| at the end, the ``improved`` model
        integrated with RK4 at the same step), ``seconds`` and ``timestep``.
    """
    mj = require_mujoco()
    from stewart_env.integrate import rollout

    free = params.replace(damping=Damping(0.0, 0.0, 0.0))
    t, R, v, w, F = _test_state(free, seed)
    tw = Twin(free, timestep, solref, solimp)
    m = tw.model
    m.opt.enableflags |= mj.mjtEnableBit.mjENBL_ENERGY
    d = mj.MjData(m)
    tw.set_state(d, t, R, v, w)
    tw.set_wrench(d, t, R, F, np.zeros(6))

    def energy() -> float:
        mj.mj_energyPos(m, d)
        mj.mj_energyVel(m, d)
        return float(d.energy[0] + d.energy[1] - F @ d.qpos[tw.q_slide])

    e0 = energy()
    kinetic = float(d.energy[1])
    drift = closure = 0.0
    steps = int(round(seconds / timestep))
    for _ in range(steps):
        mj.mj_step(m, d)
        drift = max(drift, abs(energy() - e0))
        closure = max(closure, tw.closure_gap(d))
    t_ref = rollout(make_dynamics("improved", free), t, R, v, w, F, dt=timestep, steps=steps)[0]
    return {
        "energy_drift": drift,
        "kinetic_energy": kinetic,
        "closure_max": closure,
        "position_difference": float(np.linalg.norm(d.qpos[tw.q_free : tw.q_free + 3] - t_ref)),
        "seconds": seconds,
        "timestep": timestep,
    }


def _electric_drive(params: PlatformParams) -> ElectricActuator:
    """The drive of the config's ``actuators: electric:`` section; a ValueError naming it if none."""
    if params.actuators.electric is None:
        raise ValueError(
            f"actuator: 'electric' needs the platform config's actuators: electric: section, which {params.name!r} has not"
        )
    return ElectricActuator(params.actuators.electric)


def reflected_mass_error(params: PlatformParams, seed: int = 0) -> tuple[float, float]:
    """How far the twin's mass matrix, the config's electric drive's reflected mass as the slides'
    armature, is from the closed form's M + J^T diag(m_r) J (docs/physics.md section 10.2).

    At the pose of :func:`acceleration_error`, at rest: MuJoCo's joint-space mass matrix M_q
    projected on the platform's twist [v; omega] ({B}) by G, the joint rates of each unit twist
    (inverse kinematics, the twin's ``set_state``), G^T M_q G; the closed form's matrix is column by
    column J^T (F(e_k) - F(0)), F the drive forces of ``inverse_reflected_batch`` at zero twist
    and no gravity's change (it cancels in the difference).

    Args:
        params: the platform's parameters, with an ``actuators: electric:`` section.
        seed: the seed of the pose near home.

    Returns:
        The pair (largest difference, largest entry of the closed form's matrix), kg, kg m, kg m^2.

    Raises:
        ValueError: the config has no electric drive (naming ``actuator``).
    """
    mj = require_mujoco()
    drive = _electric_drive(params)
    t, R, _, _, _ = _test_state(params, seed)
    tw = Twin(params, 1e-3, DEFAULT_SOLREF, DEFAULT_SOLIMP, electric=params.actuators.electric)
    d = mj.MjData(tw.model)
    G = np.zeros((tw.model.nv, 6))
    for k in range(6):
        twist = np.eye(6)[k]
        tw.set_state(d, t, R, twist[:3], twist[3:])
        G[:, k] = d.qvel
    tw.set_state(d, t, R, np.zeros(3), np.zeros(3))
    twin_matrix = G.T @ joint_mass_matrix(tw.model, d) @ G
    model = make_dynamics("improved", params)
    n = 7
    acc = np.zeros((n, 6))
    acc[1:] = np.eye(6)
    z = np.zeros((n, 3))
    forces = np.empty((n, 6))
    _core.inverse_reflected_batch(
        model.packed,
        model.flags,
        np.tile(t, (n, 1)),
        np.tile(R, (n, 1, 1)),
        z,
        z.copy(),
        acc,
        np.zeros((n, 6)),
        np.full((1, 6), drive.reflected_mass),
        forces,
    )
    closed = leg_kinematics(params, t, R).jacobian.T @ (forces[1:] - forces[0]).T
    return float(np.abs(twin_matrix - closed).max()), float(np.abs(closed).max())


def electric_agreement(
    params: PlatformParams,
    seconds: float = 0.5,
    dt: float = 1e-3,
    amplitude: float = 0.8,
    frequency: float = 2.0,
    solref: Sequence[float] = DEFAULT_SOLREF,
    solimp: Sequence[float] = DEFAULT_SOLIMP,
) -> dict:
    """The twin driven by the config's electric drives, against the closed form with reflected masses.

    :class:`MujocoPlant` (``actuator="electric"``, C_s left out as in :func:`acceleration_error`)
    starts at home with the holding currents and is driven by the current profile
    i_j(t) = i_hold,j + ``amplitude`` i_max sin(2 pi ``frequency`` t + 2 pi j / 6), which reaches
    past the current limit.  At every MuJoCo step the motion (pose, twist and MuJoCo's
    acceleration at the step's start) and the leg forces F the drive produced for the step are
    recorded; then the closed form's ``inverse_reflected_batch`` of that motion (the ``improved``
    model, the drive's m_r) gives forces F_cf and its ``forward_reflected_batch`` of the forces F
    an acceleration: both must agree with the twin to the loops' softness.

    Args:
        params: the platform's parameters, with an ``actuators: electric:`` section.
        seconds: the length of the motion, s.
        dt: MuJoCo's step, s.
        amplitude: the profile's amplitude over the current limit.
        frequency: the profile's frequency, Hz.
        solref: the loop-closure constraints' (time constant s, damping ratio), as in
            :func:`~stewart_env.mujoco.to_mjcf`.
        solimp: the constraints' impedance, as in :func:`~stewart_env.mujoco.to_mjcf`.

    Returns:
        A dict of ``force_error`` (N, largest |F - F_cf|), ``force_scale`` (N, largest |F|),
        ``acceleration_error`` (m/s^2 and rad/s^2, largest difference of the accelerations),
        ``peak_current`` (A, largest |i|), ``current_limit`` (A), ``peak_leg_speed`` (m/s, largest
        |dL/dt|), ``no_load_speed`` (m/s), ``reflected_mass`` (kg), ``steps``.

    Raises:
        ValueError: the config has no electric drive (naming ``actuator``).
    """
    mj = require_mujoco()
    drive = _electric_drive(params)
    free = _without_spherical_friction(params)
    model = make_dynamics("improved", free)
    z = np.zeros((1, 3))
    home = [params.home_position[None].copy(), home_rotation(params)[None].copy(), z.copy(), z.copy()]
    per_ampere = drive.stall_force / drive.params.current_limit  # eta k K_t, N/A
    holding = model.inverse(*home, z, z) / per_ampere
    plant = MujocoPlant(free, dt, solref, solimp, nthread=0, spherical_friction=False, actuator="electric")
    plant.reset_currents(None, holding)
    plant.step_inplace(*home, holding, np.zeros((1, 6)), dt, 0)  # sets MuJoCo's state, no step
    tw = plant.twins[0]
    scratch = mj.MjData(tw.model)
    steps = int(round(seconds / dt))
    phase = 2 * np.pi * np.arange(6) / 6
    state = home
    records = {
        name: np.empty((steps,) + shape)
        for name, shape in (("t", (3,)), ("R", (3, 3)), ("v", (3,)), ("w", (3,)), ("acc", (6,)), ("F", (6,)))
    }
    peak_current = peak_speed = 0.0
    wrench = np.zeros((1, 6))
    for k in range(steps):
        command = holding + amplitude * drive.params.current_limit * np.sin(2 * np.pi * frequency * k * dt + phase)
        for name, x in zip("tRvw", state):
            records[name][k] = x[0]
        start = plant._states[0].copy()  # MuJoCo's full state at the step's start
        plant.step_inplace(*state, command, wrench, dt, 1)
        records["F"][k] = plant.drive_force[0]
        mj.mj_setState(tw.model, scratch, start, plant._spec)
        scratch.ctrl[:] = plant.drive_force[0]
        mj.mj_forward(tw.model, scratch)
        a, alpha = platform_acceleration(tw.model, scratch)
        records["acc"][k] = np.concatenate([a, alpha])
        peak_current = max(peak_current, float(np.abs(plant.current).max()))
        peak_speed = max(peak_speed, float(np.abs(scratch.qvel[tw.v_slide]).max()))
    m_r = np.full((1, 6), drive.reflected_mass)
    motion = [np.ascontiguousarray(records[name]) for name in "tRvw"]
    W = np.zeros((steps, 6))
    forces = np.empty((steps, 6))
    _core.inverse_reflected_batch(model.packed, model.flags, *motion, records["acc"], W, m_r, forces)
    acc = np.empty((steps, 6))
    _core.forward_reflected_batch(model.packed, model.flags, *motion, records["F"], W, m_r, acc)
    return {
        "force_error": float(np.abs(forces - records["F"]).max()),
        "force_scale": float(np.abs(records["F"]).max()),
        "acceleration_error": float(np.abs(acc - records["acc"]).max()),
        "peak_current": peak_current,
        "current_limit": float(drive.params.current_limit),
        "peak_leg_speed": peak_speed,
        "no_load_speed": drive.no_load_speed,
        "reflected_mass": drive.reflected_mass,
        "steps": steps,
    }


#: MuJoCo's own defaults for constraint softness, for comparison in :func:`accuracy_report`.
MUJOCO_SOLREF = (0.02, 1.0)
MUJOCO_SOLIMP = (0.9, 0.95, 0.001, 0.5, 2.0)


def accuracy_report(params: PlatformParams, actuator: str = "ideal") -> str:
    """How close the MuJoCo twin comes to the exact model on a platform, as markdown.

    :func:`acceleration_error` at three softnesses, :func:`holding_drift`,
    :func:`trajectory_report` with the twin's and MuJoCo's default softness, and
    :func:`spherical_friction_effect`; with ``actuator="electric"`` also the config's electric
    drive against the closed form's reflected masses (:func:`reflected_mass_error`,
    :func:`electric_agreement`).  ``python -m stewart_env.mujoco NAME [--actuator electric]``
    prints it.

    Args:
        params: the platform's parameters.
        actuator: ``"ideal"`` or ``"electric"`` (the config's ``actuators: electric:`` drive).

    Returns:
        The report's markdown.

    Raises:
        ValueError: an unknown ``actuator``, or ``"electric"`` on a config without an electric
            drive (naming ``actuator``).
    """
    if actuator not in ACTUATORS:
        raise ValueError(f"actuator: expected one of {', '.join(map(repr, ACTUATORS))}, got {actuator!r}")
    if actuator == "electric":
        _electric_drive(params)  # refused before the minutes of the ideal part
    loose = (0.99, 0.99) + DEFAULT_SOLIMP[2:]
    lines = [
        f"MuJoCo twin of {params.name} (stewart_env.mujoco), against the improved model:",
        "",
        "| loop softness (solref; solimp d) | platform acceleration error | closure, 1 s free motion "
        "| energy drift / kinetic energy | position vs improved after 1 s |",
        "|---|---|---|---|---|",
    ]
    for label, solref, solimp in (
        ("twin default", DEFAULT_SOLREF, DEFAULT_SOLIMP),
        ("d = 0.99", DEFAULT_SOLREF, loose),
        ("MuJoCo default", MUJOCO_SOLREF, MUJOCO_SOLIMP),
    ):
        acc = acceleration_error(params, solref, solimp)
        r = trajectory_report(params, solref=solref, solimp=solimp)
        lines.append(
            f"| {label} ({number_list(solref)}; {solimp[0]:g}) | {acc:.2e} | {r['closure_max']:.2e} m "
            f"| {r['energy_drift']:.2e} J / {r['kinetic_energy']:.3g} J | {r['position_difference']:.2e} m |"
        )
    position, angle = holding_drift(params)
    held, omitted = plant_difference(params), plant_difference(params, spherical_friction=False)
    lines += [
        "",
        f"holding forces of `inverse`, 1 s: platform drifts {position:.2e} m and {angle:.2e} rad",
        f"spherical-joint friction C_s (not in the MJCF model) changes the improved model's acceleration by "
        f"{spherical_friction_effect(params):.2e} (m/s^2, rad/s^2) at the same state",
        f"MujocoPlant vs improved after 1 s of motion in 10 ms steps: {held[0]:.2e} m, {held[1]:.2e} rad with "
        f"C_s held over each step; {omitted[0]:.2e} m, {omitted[1]:.2e} rad without",
    ]
    if actuator == "electric":
        lines += ["", *_electric_lines(params)]
    return "\n".join(lines)


def _electric_lines(params: PlatformParams) -> list[str]:
    """The electric drive's part of :func:`accuracy_report`."""
    mass, scale = reflected_mass_error(params)
    lines = [
        f"electric drive (actuators.electric, m_r = {_electric_drive(params).reflected_mass:.4g} kg per leg as the "
        f"slides' armature): mass matrix G^T M_q G vs M + J^T diag(m_r) J differs by {mass:.2e} "
        f"(largest entry {scale:.3g})",
        "",
        "| loop softness (solimp d) | force error / largest force | acceleration error "
        "| peak current / limit | peak leg speed / no-load speed |",
        "|---|---|---|---|---|",
    ]
    for d in (DEFAULT_SOLIMP[0], 0.999):
        r = electric_agreement(params, solimp=(d, d) + DEFAULT_SOLIMP[2:])
        lines.append(
            f"| {d:g} | {r['force_error']:.3g} N / {r['force_scale']:.4g} N | {r['acceleration_error']:.2e} "
            f"| {r['peak_current']:.3g} A / {r['current_limit']:.3g} A "
            f"| {r['peak_leg_speed']:.3g} m/s / {r['no_load_speed']:.3g} m/s |"
        )
    return lines
