"""The mechanism of a platform config as MJCF: MuJoCo's model of the same mechanism.

The mechanism (docs/physics.md sections 1-2).  The platform is a free body whose frame is {P}
(origin P, axes the columns of R).  Leg i is two bodies: the lower leg (cylinder) hangs on a
universal joint at the base joint b_i, written as two hinges, the first along the config's
fixed Hooke axis k_i, the second along the moving axis y_i (perpendicular to k_i and to the leg
at the home pose); the upper leg (piston) is its child on a slide joint along the leg.  Both
leg bodies carry the leg frame {D_i} of the home pose as their own frame, so the config's leg
CoMs and inertias (given in {D_i}) are written unchanged, and the bodies turn with {D_i} as the
closed-form models assume.  MuJoCo simulates trees, so the six loops are closed at the platform
joints P_i by ``connect`` equality constraints (a ball joint outside the tree) between a site at
the upper leg's tip and a site at p_i on the platform.  Those constraints are soft: MuJoCo
lets them give by an amount set by ``solref``/``solimp`` (see :data:`DEFAULT_SOLIMP`), which is
the one approximation of the twin besides the spherical-joint friction below.  The legs' stroke
and the force limits of the config are not joint limits here: the actuators clamp their force to
the config's range, and the stroke is left to the environment's termination, as for the
closed-form models.

Joint friction (docs/physics.md section 1, "Signs of forces").  The universal joint's torque
-C_u omega_l is the two hinges' viscous damping C_u each (the hinge axes k_i and y_i are
orthogonal, so the torque's work on each hinge rate is exactly -C_u times that rate); the
prismatic joint's -C_p dL/dt is the slide's damping.  The spherical joint's -C_s (omega_l -
omega) has no counterpart: an equality constraint carries no damping, so the MJCF model
**omits C_s**; :class:`~stewart_env.mujoco.MujocoPlant` puts it back as applied torques.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from stewart_env.actuators import BallScrew, ElectricParams
from stewart_env.errors import UsageError
from stewart_env.kinematics import leg_kinematics
from stewart_env.mujoco.library import require_mujoco
from stewart_env.params import PlatformParams
from stewart_env.rotations import rpy_to_matrix

__all__ = ["DEFAULT_SOLIMP", "DEFAULT_SOLREF", "MAX_TIMESTEP", "home_rotation", "number_list", "quaternion", "to_mjcf"]

#: Time constant (s) and damping ratio of the loop-closure constraints' error correction.
#: 0.002 s is the smallest MuJoCo accepts at a 1 ms step (it raises any smaller value to twice
#: the step), so a gap is pulled shut within a few steps; critical damping (1) avoids ringing.
#: Against MuJoCo's default time constant and impedance it keeps the loops closed and the energy
#: conserved far better over free motion (:func:`~stewart_env.mujoco.trajectory_report`; the
#: figures are in the MuJoCo guide, docs/guides/mujoco.md).
DEFAULT_SOLREF = (0.002, 1.0)
#: Impedance of the loop-closure constraints (MuJoCo's d_min, d_max, width, midpoint, power).  The
#: constraint force reaches the fraction d of the force that would hold the loop rigidly, so the
#: platform's accelerations differ from the rigid mechanism's by about (1 - d) / d relative:
#: d = 0.9999, the largest MuJoCo allows, left an error of 5.1e-4 (m/s^2, rad/s^2) on
#: dasgupta1998 (:func:`~stewart_env.mujoco.acceleration_error`, the platform accelerating at about 0.1 g; 5.1e-2 at
#: d = 0.99 and 0.53 at MuJoCo's default 0.9): the error scales with 1 - d and stays below
#: g (1 - d) / d on both shipped platforms (tests/twin/test_mujoco.py).
DEFAULT_SOLIMP = (0.9999, 0.9999, 0.001, 0.5, 2.0)

#: The longest MuJoCo step :func:`to_mjcf` writes, s: beyond it RK4 on a mechanism whose legs swing
#: at several hertz is no simulation at all (the environment's control step is at most 10 s).
MAX_TIMESTEP = 0.1


def number_list(x) -> str:
    """Numbers as MJCF writes them: space-separated, every digit of the float kept.

    Args:
        x: a number or an array of them.
    """
    return " ".join(repr(float(v)) for v in np.atleast_1d(x))


def quaternion(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix (MuJoCo's convention).

    Args:
        R: the rotation matrix (3, 3).
    """
    mj = require_mujoco()
    q = np.empty(4)
    mj.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=np.float64).ravel())
    return q


def _full_inertia(inertia: np.ndarray) -> str:
    return number_list([inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]])


def _check_pair(name: str, value, size: int) -> tuple[float, ...]:
    """``value`` as ``size`` finite floats; a UsageError about the argument ``name`` otherwise."""
    try:
        v = tuple(float(x) for x in value)
    except (TypeError, ValueError):
        raise UsageError.about(name, f"expected {size} numbers, got {value!r}") from None
    if len(v) != size or not all(np.isfinite(v)):
        raise UsageError.about(name, f"expected {size} finite numbers, got {value!r}")
    return v


def to_mjcf(
    params: PlatformParams,
    timestep: float = 1e-3,
    solref: Sequence[float] = DEFAULT_SOLREF,
    solimp: Sequence[float] = DEFAULT_SOLIMP,
    integrator: str = "RK4",
    geometry: bool = True,
    electric: ElectricParams | None = None,
) -> str:
    """MJCF text of the mechanism of ``params`` (see the module docstring), at its home pose.

    Names in the model: bodies ``platform``, ``lower_i``, ``upper_i``; joints ``platform``
    (free), ``u1_i`` (about k_i), ``u2_i`` (about y_i), ``slide_i``; sites ``tip_i`` (upper
    leg at P_i) and ``joint_i`` (platform at p_i); equalities ``loop_i``; actuators ``leg_i``
    (force on the slide, N, within the config's force limits).  i = 0..5.

    Args:
        params: the platform's parameters.
        timestep: MuJoCo's step, s.
        solref: (time constant s, damping ratio) of the six loop-closure constraints, MuJoCo's own
            parameter (its documentation, "Solver parameters"); the default
            :data:`DEFAULT_SOLREF` is explained there.
        solimp: (d_min, d_max, width m, midpoint, power) of the same constraints; the default
            :data:`DEFAULT_SOLIMP` is explained there.
        integrator: MuJoCo's integrator ("RK4", "implicitfast", "Euler", ...).
        geometry: add massless, non-colliding shapes (legs as capsules, the platform and base as
            outlines) so the model shows in MuJoCo's viewer; they carry no mass (inertias are
            explicit) and never collide.
        electric: an electric drive on every leg (e.g. ``params.actuators.electric``): its reflected
            mass becomes each slide's ``armature`` (see the module docstring); its friction and
            force envelope are the drive law's, applied by :class:`~stewart_env.mujoco.MujocoPlant`.
            None: the ideal force source, no armature.

    Returns:
        The MJCF document, text that ``mujoco.MjModel.from_xml_string`` loads.

    Raises:
        ImportError: the ``mujoco`` extra is not installed.
        UsageError: a bad argument (a ValueError), its name as data (``err.argument``:
            ``"timestep"``, ``"solref"``, ``"solimp"``, ``"params"``, ``"electric"``).

    Examples:
        >>> import stewart_env as se
        >>> from stewart_env.mujoco import to_mjcf
        >>> xml = to_mjcf(se.load_platform("dasgupta1998"))
        >>> xml.lstrip().startswith("<mujoco")
        True
    """
    require_mujoco()
    if not isinstance(params, PlatformParams):
        raise UsageError.about("params", f"expected PlatformParams, got {type(params).__name__}")
    try:
        step = float(timestep)
    except (TypeError, ValueError):
        step = np.nan
    if not (np.isfinite(step) and 0 < step <= MAX_TIMESTEP):
        raise UsageError.about("timestep", f"must be a number of seconds in (0, {MAX_TIMESTEP:g}], got {timestep!r}")
    solref = _check_pair("solref", solref, 2)
    solimp = _check_pair("solimp", solimp, 5)
    if not 0 < solimp[0] < 1 or not 0 < solimp[1] < 1:
        raise UsageError.about("solimp", f"d_min and d_max must lie in (0, 1), got {solimp[:2]}")

    if electric is not None and not isinstance(electric, ElectricParams):
        raise UsageError.about("electric", f"expected ElectricParams or None, got {type(electric).__name__}")
    armature = "" if electric is None else f' armature="{number_list(BallScrew.from_params(electric).reflected_mass)}"'

    t0, R0 = params.home_position, home_rotation(params)
    legs = leg_kinematics(params, t0, R0)
    lo_f, hi_f = params.limits.leg_force
    d = params.damping
    eq = f'solref="{number_list(solref)}" solimp="{number_list(solimp)}"'
    out = [
        f'<mujoco model="stewart_{params.name}">',
        '  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>',
        f'  <option timestep="{number_list(timestep)}" integrator="{integrator}" gravity="{number_list(params.gravity)}" '
        'solver="Newton" iterations="100" tolerance="1e-12">',
        '    <flag contact="disable"/>',
        "  </option>",
        '  <default><geom contype="0" conaffinity="0" group="1" rgba="0.6 0.6 0.7 1"/></default>',
        "  <worldbody>",
    ]
    width = 0.02 * float(np.mean(legs.lengths))
    if geometry:
        b = params.base_joints
        out.append(
            f'    <light directional="true" pos="{number_list(t0 + [0, 0, 3 * np.mean(legs.lengths)])}" dir="0 0 -1"/>'
        )
        for i in range(6):
            out.append(
                f'    <geom type="capsule" size="{width:.4g}" fromto="{number_list(b[i])} {number_list(b[(i + 1) % 6])}"/>'
            )
    for i in range(6):
        T = legs.frames[i]
        L = legs.lengths[i]
        up, lo = params.upper_leg[i], params.lower_leg[i]
        out += [
            f'    <body name="lower_{i}" pos="{number_list(params.base_joints[i])}" quat="{number_list(quaternion(T))}">',
            f'      <joint name="u1_{i}" type="hinge" axis="{number_list(T.T @ params.hooke_axes[i])}" damping="{number_list(d.universal)}"/>',
            f'      <joint name="u2_{i}" type="hinge" axis="0 1 0" damping="{number_list(d.universal)}"/>',
            _inertial(lo.mass, lo.com, lo.inertia, "      "),
        ]
        if geometry:
            out.append(
                f'      <geom type="capsule" size="{1.5 * width:.4g}" fromto="0 0 0 {number_list(0.55 * L)} 0 0"/>'
            )
        out += [
            f'      <body name="upper_{i}">',
            f'        <joint name="slide_{i}" type="slide" axis="1 0 0" damping="{number_list(d.prismatic)}"{armature}/>',
            _inertial(up.mass, np.array([L, 0.0, 0.0]) + up.com, up.inertia, "        "),
            f'        <site name="tip_{i}" pos="{number_list(L)} 0 0"/>',
        ]
        if geometry:
            out.append(
                f'        <geom type="capsule" size="{width:.4g}" fromto="{number_list(0.4 * L)} 0 0 {number_list(L)} 0 0" '
                'rgba="0.8 0.8 0.85 1"/>'
            )
        out += ["      </body>", "    </body>"]
    p = params.platform
    out += [
        f'    <body name="platform" pos="{number_list(t0)}" quat="{number_list(quaternion(R0))}">',
        '      <freejoint name="platform"/>',
        _inertial(p.mass, p.com, p.inertia, "      "),
    ]
    for i in range(6):
        out.append(f'      <site name="joint_{i}" pos="{number_list(params.platform_joints[i])}"/>')
        if geometry:
            pj = params.platform_joints
            out.append(
                f'      <geom type="capsule" size="{width:.4g}" fromto="{number_list(pj[i])} {number_list(pj[(i + 1) % 6])}" '
                'rgba="0.3 0.5 0.8 1"/>'
            )
    out += ["    </body>", "  </worldbody>", "  <equality>"]
    out += [f'    <connect name="loop_{i}" site1="tip_{i}" site2="joint_{i}" {eq}/>' for i in range(6)]
    out += ["  </equality>", "  <actuator>"]
    out += [
        f'    <motor name="leg_{i}" joint="slide_{i}" gear="1" ctrlrange="{number_list((lo_f, hi_f))}"/>'
        for i in range(6)
    ]
    out += ["  </actuator>", "</mujoco>", ""]
    return "\n".join(out)


def home_rotation(params: PlatformParams) -> np.ndarray:
    """The platform's rotation at its home pose.

    Args:
        params: the platform's parameters (its ``home_rpy``).
    """
    return rpy_to_matrix(params.home_rpy)


def _inertial(mass: float, com, inertia: np.ndarray, indent: str) -> str:
    if mass <= 0:
        raise ValueError(
            "params: a massless leg part cannot be a MuJoCo body (MuJoCo needs mass and inertia "
            "on every moving body); give it a small mass"
        )
    return f'{indent}<inertial pos="{number_list(com)}" mass="{number_list(mass)}" fullinertia="{_full_inertia(inertia)}"/>'
