"""How close MuJoCo's twin comes to the exact ``improved`` model: the accuracy study.

Each function measures one thing on a platform config (an acceleration, a drift, a trajectory's
energy and loop closure, the effect of the omitted spherical friction); :func:`accuracy_report`
gathers them as the markdown table of ``python -m stewart_env.mujoco``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from stewart_env.dynamics.model import make_dynamics
from stewart_env.kinematics import leg_kinematics
from stewart_env.mujoco.library import require_mujoco
from stewart_env.mujoco.mjcf import DEFAULT_SOLIMP, DEFAULT_SOLREF, home_rotation, number_list
from stewart_env.mujoco.plant import MujocoPlant
from stewart_env.mujoco.twin import Twin, model_and_data, platform_acceleration
from stewart_env.params import Damping, PlatformParams
from stewart_env.rotations import rotation_error, rpy_to_matrix

__all__ = [
    "MUJOCO_SOLIMP",
    "MUJOCO_SOLREF",
    "acceleration_error",
    "accuracy_report",
    "holding_drift",
    "plant_difference",
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


#: MuJoCo's own defaults for constraint softness, for comparison in :func:`accuracy_report`.
MUJOCO_SOLREF = (0.02, 1.0)
MUJOCO_SOLIMP = (0.9, 0.95, 0.001, 0.5, 2.0)


def accuracy_report(params: PlatformParams) -> str:
    """How close the MuJoCo twin comes to the exact model on a platform, as markdown.

    :func:`acceleration_error` at three softnesses, :func:`holding_drift`,
    :func:`trajectory_report` with the twin's and MuJoCo's default softness, and
    :func:`spherical_friction_effect`; ``python -m stewart_env.mujoco NAME`` prints it.

    Args:
        params: the platform's parameters.

    Returns:
        The report's markdown.
    """
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
    return "\n".join(lines)
