"""The compiled twin of one platform: MuJoCo's model and the addresses of its joints and sites.

:class:`Twin` sets a platform state into MuJoCo's data (legs by inverse kinematics, loops
closed), applies forces and measures the loops' closure; :func:`model_and_data` and
:func:`platform_acceleration` give MuJoCo's model and data of a state to a user.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from stewart_env.actuators import ElectricParams
from stewart_env.kinematics import leg_kinematics
from stewart_env.mujoco.library import require_mujoco
from stewart_env.mujoco.mjcf import DEFAULT_SOLIMP, DEFAULT_SOLREF, home_rotation, quaternion, to_mjcf
from stewart_env.params import PlatformParams

__all__ = ["Twin", "joint_mass_matrix", "model_and_data", "platform_acceleration", "wrench_at_com"]


class Twin:
    """One compiled MJCF model of a platform, with the addresses the plant reads and writes.

    Args:
        params: the platform's parameters.
        timestep, solref, solimp: as in :func:`~stewart_env.mujoco.to_mjcf`.
        electric: the legs' electric drive (its reflected mass as the slides' armature), or None.
    """

    def __init__(self, params: PlatformParams, timestep: float, solref, solimp, electric: ElectricParams | None = None):
        mj = require_mujoco()
        self.params = params
        self.electric = electric
        self.model = mj.MjModel.from_xml_string(
            to_mjcf(params, timestep, solref, solimp, geometry=False, electric=electric)
        )
        m = self.model
        legs = leg_kinematics(params, params.home_position, home_rotation(params))
        self.home_frames = legs.frames.copy()  # T_i at home: the leg bodies' frames at zero joint angles
        self.home_lengths = legs.lengths.copy()
        self.hooke = params.hooke_axes
        # cosine of the home angle between k_i and the leg (k' = (kx, 0, kz) in {D_i} at home)
        self.home_kx = np.einsum("ij,ij->i", self.hooke, legs.units)

        def adr(kind, table, name):
            return int(table[mj.mj_name2id(m, kind, name)])

        J = mj.mjtObj.mjOBJ_JOINT
        self.q_u1 = np.array([adr(J, m.jnt_qposadr, f"u1_{i}") for i in range(6)])
        self.q_u2 = np.array([adr(J, m.jnt_qposadr, f"u2_{i}") for i in range(6)])
        self.q_slide = np.array([adr(J, m.jnt_qposadr, f"slide_{i}") for i in range(6)])
        self.v_u1 = np.array([adr(J, m.jnt_dofadr, f"u1_{i}") for i in range(6)])
        self.v_u2 = np.array([adr(J, m.jnt_dofadr, f"u2_{i}") for i in range(6)])
        self.v_slide = np.array([adr(J, m.jnt_dofadr, f"slide_{i}") for i in range(6)])
        self.q_free = adr(J, m.jnt_qposadr, "platform")
        self.v_free = adr(J, m.jnt_dofadr, "platform")
        self.body = mj.mj_name2id(m, mj.mjtObj.mjOBJ_BODY, "platform")
        self.tips = np.array([mj.mj_name2id(m, mj.mjtObj.mjOBJ_SITE, f"tip_{i}") for i in range(6)])
        self.joints = np.array([mj.mj_name2id(m, mj.mjtObj.mjOBJ_SITE, f"joint_{i}") for i in range(6)])

    def set_state(self, data, t, R, v, w) -> None:
        """Platform state (P's origin, R, v, omega in {B}) into ``data``, with the leg joints from
        inverse kinematics (docs/physics.md section 4), so the loops start closed and moving with
        the platform: the U-joint angles turn the home frame T_i to the pose's, the slide is
        L_i - L_i(home), and the joint rates are the leg's angular velocity on the two hinge
        axes (orthogonal, so each is a dot product) and dL_i/dt.

        Args:
            data: the twin's ``MjData``, overwritten.
            t: the position of P's origin (3,), m, {B}.
            R: the rotation matrix (3, 3) of {P} in {B}.
            v: the velocity of P's origin (3,), m/s, {B}.
            w: the angular velocity omega (3,), rad/s, {B}.
        """
        mj = require_mujoco()
        mj.mj_resetData(self.model, data)
        legs = leg_kinematics(self.params, t, R, v, w)
        e, y = legs.frames[:, :, 0], legs.frames[:, :, 1]
        k = self.hooke
        kx = np.einsum("ij,ij->i", k, e)
        # Second hinge: the angle between k_i and the leg goes from its home value to today's
        # (the leg turns about y_i, which stays perpendicular to k_i).
        q2 = np.arccos(np.clip(kx, -1, 1)) - np.arccos(np.clip(self.home_kx, -1, 1))
        # First hinge: the turn about k_i that brings the leg, tilted by q2, onto e_i.
        e_home, z_home = self.home_frames[:, :, 0], self.home_frames[:, :, 2]
        tilted = np.cos(q2)[:, None] * e_home - np.sin(q2)[:, None] * z_home
        a = tilted - np.einsum("ij,ij->i", k, tilted)[:, None] * k
        b = e - kx[:, None] * k
        q1 = np.arctan2(np.einsum("ij,ij->i", k, np.cross(a, b)), np.einsum("ij,ij->i", a, b))
        qpos, qvel = data.qpos, data.qvel
        qpos[self.q_u1], qpos[self.q_u2] = q1, q2
        qpos[self.q_slide] = legs.lengths - self.home_lengths
        qvel[self.v_u1] = np.einsum("ij,ij->i", k, legs.omega)
        qvel[self.v_u2] = np.einsum("ij,ij->i", y, legs.omega)
        qvel[self.v_slide] = legs.rates
        qpos[self.q_free : self.q_free + 3] = t
        qpos[self.q_free + 3 : self.q_free + 7] = quaternion(R)
        qvel[self.v_free : self.v_free + 3] = v
        qvel[self.v_free + 3 : self.v_free + 6] = R.T @ w  # MuJoCo's free joint: angular velocity in the body frame
        mj.mj_forward(self.model, data)

    def closure_gap(self, data) -> float:
        """Largest distance |tip_i - joint_i| (m) over the six loops, at data's current qpos.

        Args:
            data: the twin's ``MjData``.
        """
        mj = require_mujoco()
        mj.mj_kinematics(self.model, data)
        gap = data.site_xpos[self.tips] - data.site_xpos[self.joints]
        return float(np.sqrt((gap * gap).sum(axis=1).max()))

    def set_wrench(self, data, t, R, leg_forces, wrench) -> None:
        """Leg forces as controls; the external wrench as MuJoCo's applied force (:func:`wrench_at_com`).

        Args:
            data: the twin's ``MjData``.
            t: the position of P's origin (3,), m, {B} (unused: the wrench's moment is about P).
            R: the rotation matrix (3, 3) of {P} in {B}.
            leg_forces: the leg forces (6,), N.
            wrench: the external wrench [force at P; moment] (6,), N and N m, {B}.
        """
        data.ctrl[:] = leg_forces
        data.xfrc_applied[self.body] = wrench_at_com(R[None], self.params.platform.com[None], wrench[None])[0]


def wrench_at_com(R: np.ndarray, com: np.ndarray, wrench: np.ndarray) -> np.ndarray:
    """The external wrench [force at P; moment] (N,6), {B}, as the equivalent [force; moment] at
    the platform's CoM (MuJoCo's ``xfrc_applied``): the moment gains (P - CoM) x force.

    Args:
        R: the rotation matrices (N, 3, 3) of {P} in {B}.
        com: the platform's CoM (N, 3) in {P}, m.
        wrench: the external wrench [force at P; moment] (N, 6), N and N m, {B}.
    """
    a = -np.einsum("nij,nj->ni", R, com)  # P - CoM in {B}
    f = wrench[:, :3]
    out = wrench.copy()
    # the moment of f about the CoM, a x f, written out: numpy's cross costs more than the rest here
    out[:, 3] += a[:, 1] * f[:, 2] - a[:, 2] * f[:, 1]
    out[:, 4] += a[:, 2] * f[:, 0] - a[:, 0] * f[:, 2]
    out[:, 5] += a[:, 0] * f[:, 1] - a[:, 1] * f[:, 0]
    return out


def model_and_data(
    params: PlatformParams,
    position,
    rotation,
    velocity=None,
    angular_velocity=None,
    leg_forces=None,
    external_wrench=None,
    timestep: float = 1e-3,
    solref: Sequence[float] = DEFAULT_SOLREF,
    solimp: Sequence[float] = DEFAULT_SOLIMP,
    electric: ElectricParams | None = None,
):
    """MuJoCo's ``(MjModel, MjData)`` of the twin of ``params`` at a platform state.

    Ready for ``mujoco.mj_forward`` or ``mj_step``: the legs' joints set by inverse kinematics so
    the loops are closed.  After ``mj_forward``, ``data.qacc`` holds the accelerations:
    :func:`platform_acceleration`.

    Args:
        params: the platform's parameters.
        position: (3,) position of P's origin in {B}, m.
        rotation: (3,3) rotation of {P} in {B}.
        velocity: (3,) m/s, zero when left out.
        angular_velocity: (3,) rad/s, zero when left out.
        leg_forces: (6,) N, the actuators' controls, zero when left out.
        external_wrench: (6,) [force at P; moment] applied, zero when left out.
        timestep: MuJoCo's step, s.
        solref: the loop-closure constraints' (time constant s, damping ratio), as in
            :func:`~stewart_env.mujoco.to_mjcf`.
        solimp: the constraints' impedance, as in :func:`~stewart_env.mujoco.to_mjcf`.
        electric: the legs' electric drive, as in :func:`~stewart_env.mujoco.to_mjcf` (its
            reflected mass as the slides' armature; ``leg_forces`` are then the drive's forces).

    Returns:
        The pair (MjModel, MjData).

    Raises:
        ImportError: the ``mujoco`` extra is not installed.
        UsageError: a bad ``timestep``, ``solref``, ``solimp`` or ``electric``, its name as data
            (``err.argument``), as :func:`~stewart_env.mujoco.to_mjcf` raises it.
    """
    mj = require_mujoco()
    z = np.zeros(3)
    t, R = np.asarray(position, float), np.asarray(rotation, float)
    v = z if velocity is None else np.asarray(velocity, float)
    w = z if angular_velocity is None else np.asarray(angular_velocity, float)
    tw = Twin(params, timestep, solref, solimp, electric)
    d = mj.MjData(tw.model)
    tw.set_state(d, t, R, v, w)
    tw.set_wrench(
        d,
        t,
        R,
        np.zeros(6) if leg_forces is None else np.asarray(leg_forces, float),
        np.zeros(6) if external_wrench is None else np.asarray(external_wrench, float),
    )
    return tw.model, d


def platform_acceleration(model, data) -> tuple[np.ndarray, np.ndarray]:
    """The twin's platform acceleration in the closed-form models' conventions.

    MuJoCo's free joint carries the angular velocity in the body frame: the rate of that, turned
    by R, is the spatial alpha.

    Args:
        model: the twin's MjModel.
        data: its MjData after ``mujoco.mj_forward`` or ``mj_step``.

    Returns:
        The pair (a, alpha), (3,) each in {B}, the acceleration of P's origin (m/s^2) and the
        angular acceleration (rad/s^2).

    Examples:
        The holding forces of the exact model hold the twin too, to its loops' softness:

        >>> import numpy as np, mujoco, stewart_env as se
        >>> from stewart_env.mujoco import model_and_data, platform_acceleration
        >>> params = se.load_platform("dasgupta1998")
        >>> pose = (params.home_position, np.eye(3))
        >>> forces = se.make_dynamics("improved", params).inverse(*pose, np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3))
        >>> model, data = model_and_data(params, *pose, leg_forces=forces)
        >>> mujoco.mj_forward(model, data)
        >>> a, alpha = platform_acceleration(model, data)
        >>> bool(np.abs(a).max() < 1e-2 and np.abs(alpha).max() < 1e-2)
        True
    """
    mj = require_mujoco()
    joint = mj.mj_name2id(model, mj.mjtObj.mjOBJ_JOINT, "platform")
    body = mj.mj_name2id(model, mj.mjtObj.mjOBJ_BODY, "platform")
    acc = data.qacc[model.jnt_dofadr[joint] : model.jnt_dofadr[joint] + 6]
    return acc[:3].copy(), data.xmat[body].reshape(3, 3) @ acc[3:]


def joint_mass_matrix(model, data) -> np.ndarray:
    """MuJoCo's joint-space mass matrix (nv, nv), the slides' armature on its diagonal.

    Args:
        model: the twin's MjModel.
        data: its MjData after ``mujoco.mj_forward`` (which computes the matrix).

    Returns:
        The dense symmetric matrix, in MuJoCo's joint coordinates.
    """
    mj = require_mujoco()
    out = np.zeros((model.nv, model.nv))
    try:  # MuJoCo 4 reads the matrix from data
        mj.mj_fullM(model, data, out)
    except TypeError:  # MuJoCo 3 takes the sparse matrix itself
        mj.mj_fullM(model, out, data.qM)
    return out
