"""The MuJoCo twin of a platform: the mechanism of any config as MJCF, and a batch plant on it.

    import stewart_env as se
    from stewart_env.mujoco import to_mjcf, MujocoPlant
    xml = to_mjcf(se.load_platform("dasgupta1998"))          # loads with mujoco.MjModel.from_xml_string
    plant = MujocoPlant(se.load_platform("dasgupta1998"))      # step_inplace(...) like rollout_inplace

Needs the optional extra: ``pip install -e ".[mujoco]"``.

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
**omits C_s**.  :class:`MujocoPlant` puts it back as applied torques held over each of its calls
(zero-order hold over a control step, from the state at the step's start; ``spherical_friction``).
:func:`spherical_friction_effect` measures what omitting it changes, and :func:`plant_difference`
what the held torques leave: over 1 s of motion at 10 ms control steps, the plant's platform
ends 1.9e-4 m (dasgupta1998) and 1.8e-3 m (motion_simulator) from the improved model's without
them, 1.4e-6 m and 1.6e-5 m with them (``python -m stewart_env.mujoco``).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Sequence

import numpy as np

from stewart_env.dynamics.model import make_dynamics
from stewart_env.kinematics import leg_kinematics
from stewart_env.params import Damping, PlatformParams
from stewart_env.rotations import rotation_error, rpy_to_matrix

try:
    import mujoco as _mj
except ImportError:  # the optional extra is missing
    _mj = None

__all__ = [
    "DEFAULT_SOLIMP",
    "DEFAULT_SOLREF",
    "MUJOCO_SOLIMP",
    "MUJOCO_SOLREF",
    "MujocoPlant",
    "acceleration_error",
    "accuracy_report",
    "holding_drift",
    "model_and_data",
    "plant_difference",
    "platform_acceleration",
    "spherical_friction_effect",
    "to_mjcf",
    "trajectory_report",
]

#: Time constant (s) and damping ratio of the loop-closure constraints' error correction.
#: 0.002 s is the smallest MuJoCo accepts at a 1 ms step (it raises any smaller value to twice
#: the step), so a gap is pulled shut within a few steps; critical damping (1) avoids ringing.
#: Over 1 s of free motion of dasgupta1998 (:func:`trajectory_report`) it keeps the loops closed
#: to 1.3 um and the energy to 1.6 mJ of 0.79 J kinetic, against 11 um and 27 mJ at MuJoCo's
#: default time constant 0.02 s (and 5.6 mm and 13 J with MuJoCo's default solimp as well).
DEFAULT_SOLREF = (0.002, 1.0)
#: Impedance of the loop-closure constraints (MuJoCo's d_min, d_max, width, midpoint, power).  The
#: constraint force reaches the fraction d of the force that would hold the loop rigidly, so the
#: platform's accelerations differ from the rigid mechanism's by about (1 - d) / d relative:
#: d = 0.9999, the largest MuJoCo allows, left an error of 5.1e-4 (m/s^2, rad/s^2) on
#: dasgupta1998 (:func:`acceleration_error`, the platform accelerating at about 0.1 g; 5.1e-2 at
#: d = 0.99 and 0.53 at MuJoCo's default 0.9): the error scales with 1 - d and stays below
#: g (1 - d) / d on both shipped platforms (tests/test_mujoco.py).
DEFAULT_SOLIMP = (0.9999, 0.9999, 0.001, 0.5, 2.0)

#: The longest MuJoCo step :func:`to_mjcf` writes, s: beyond it RK4 on a mechanism whose legs swing
#: at several hertz is no simulation at all (the environment's control step is at most 10 s).
MAX_TIMESTEP = 0.1

_INSTALL_HINT = ('the MuJoCo twin needs the optional extra: pip install "stewart-env[mujoco]" '
                 '(in a source checkout: pip install -e ".[mujoco]")')


def _require_mujoco():
    if _mj is None:
        raise ImportError(f"stewart_env.mujoco: the package 'mujoco' is not installed; {_INSTALL_HINT}")
    return _mj


def _num(x) -> str:
    return " ".join(repr(float(v)) for v in np.atleast_1d(x))


def _quat(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix (MuJoCo's convention)."""
    mj = _require_mujoco()
    q = np.empty(4)
    mj.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=np.float64).ravel())
    return q


def _full_inertia(I: np.ndarray) -> str:
    return _num([I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]])


def _check_pair(name: str, value, size: int) -> tuple[float, ...]:
    try:
        v = tuple(float(x) for x in value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected {size} numbers, got {value!r}") from None
    if len(v) != size or not all(np.isfinite(v)):
        raise ValueError(f"{name}: expected {size} finite numbers, got {value!r}")
    return v


def to_mjcf(params: PlatformParams, timestep: float = 1e-3, solref: Sequence[float] = DEFAULT_SOLREF,
            solimp: Sequence[float] = DEFAULT_SOLIMP, integrator: str = "RK4", geometry: bool = True) -> str:
    """MJCF text of the mechanism of ``params`` (see the module docstring), at its home pose.

    timestep: MuJoCo's step, s.  solref (time constant s, damping ratio) and solimp (d_min, d_max,
    width m, midpoint, power): softness of the six loop-closure constraints, MuJoCo's own
    parameters (its documentation, "Solver parameters"); the defaults :data:`DEFAULT_SOLREF`
    and :data:`DEFAULT_SOLIMP` are explained there.  integrator: MuJoCo's ("RK4",
    "implicitfast", "Euler", ...).  geometry: add massless, non-colliding shapes (legs as
    capsules, the platform and base as outlines) so the model shows in MuJoCo's viewer; they
    carry no mass (inertias are explicit) and never collide.

    Names in the model: bodies ``platform``, ``lower_i``, ``upper_i``; joints ``platform``
    (free), ``u1_i`` (about k_i), ``u2_i`` (about y_i), ``slide_i``; sites ``tip_i`` (upper
    leg at P_i) and ``joint_i`` (platform at p_i); equalities ``loop_i``; actuators ``leg_i``
    (force on the slide, N, within the config's force limits).  i = 0..5.
    """
    _require_mujoco()
    if not isinstance(params, PlatformParams):
        raise ValueError(f"params: expected PlatformParams, got {type(params).__name__}")
    try:
        step = float(timestep)
    except (TypeError, ValueError):
        step = np.nan
    if not (np.isfinite(step) and 0 < step <= MAX_TIMESTEP):
        raise ValueError(f"timestep: must be a number of seconds in (0, {MAX_TIMESTEP:g}], got {timestep!r}")
    solref = _check_pair("solref", solref, 2)
    solimp = _check_pair("solimp", solimp, 5)
    if not 0 < solimp[0] < 1 or not 0 < solimp[1] < 1:
        raise ValueError(f"solimp: d_min and d_max must lie in (0, 1), got {solimp[:2]}")

    t0, R0 = params.home_position, _home_rotation(params)
    legs = leg_kinematics(params, t0, R0)
    lo_f, hi_f = params.limits.leg_force
    d = params.damping
    eq = f'solref="{_num(solref)}" solimp="{_num(solimp)}"'
    out = [
        f'<mujoco model="stewart_{params.name}">',
        '  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>',
        f'  <option timestep="{_num(timestep)}" integrator="{integrator}" gravity="{_num(params.gravity)}" '
        'solver="Newton" iterations="100" tolerance="1e-12">',
        '    <flag contact="disable"/>',
        '  </option>',
        '  <default><geom contype="0" conaffinity="0" group="1" rgba="0.6 0.6 0.7 1"/></default>',
        '  <worldbody>',
    ]
    width = 0.02 * float(np.mean(legs.lengths))
    if geometry:
        b = params.base_joints
        out.append(f'    <light directional="true" pos="{_num(t0 + [0, 0, 3 * np.mean(legs.lengths)])}" dir="0 0 -1"/>')
        for i in range(6):
            out.append(f'    <geom type="capsule" size="{width:.4g}" fromto="{_num(b[i])} {_num(b[(i + 1) % 6])}"/>')
    for i in range(6):
        T = legs.frames[i]
        L = legs.lengths[i]
        up, lo = params.upper_leg[i], params.lower_leg[i]
        out += [
            f'    <body name="lower_{i}" pos="{_num(params.base_joints[i])}" quat="{_num(_quat(T))}">',
            f'      <joint name="u1_{i}" type="hinge" axis="{_num(T.T @ params.hooke_axes[i])}" damping="{_num(d.universal)}"/>',
            f'      <joint name="u2_{i}" type="hinge" axis="0 1 0" damping="{_num(d.universal)}"/>',
            _inertial(lo.mass, lo.com, lo.inertia, "      "),
        ]
        if geometry:
            out.append(f'      <geom type="capsule" size="{1.5 * width:.4g}" fromto="0 0 0 {_num(0.55 * L)} 0 0"/>')
        out += [
            '      <body name="upper_{0}">'.format(i),
            f'        <joint name="slide_{i}" type="slide" axis="1 0 0" damping="{_num(d.prismatic)}"/>',
            _inertial(up.mass, np.array([L, 0.0, 0.0]) + up.com, up.inertia, "        "),
            f'        <site name="tip_{i}" pos="{_num(L)} 0 0"/>',
        ]
        if geometry:
            out.append(f'        <geom type="capsule" size="{width:.4g}" fromto="{_num(0.4 * L)} 0 0 {_num(L)} 0 0" '
                       'rgba="0.8 0.8 0.85 1"/>')
        out += ['      </body>', '    </body>']
    p = params.platform
    out += [
        f'    <body name="platform" pos="{_num(t0)}" quat="{_num(_quat(R0))}">',
        '      <freejoint name="platform"/>',
        _inertial(p.mass, p.com, p.inertia, "      "),
    ]
    for i in range(6):
        out.append(f'      <site name="joint_{i}" pos="{_num(params.platform_joints[i])}"/>')
        if geometry:
            pj = params.platform_joints
            out.append(f'      <geom type="capsule" size="{width:.4g}" fromto="{_num(pj[i])} {_num(pj[(i + 1) % 6])}" '
                       'rgba="0.3 0.5 0.8 1"/>')
    out += ['    </body>', '  </worldbody>', '  <equality>']
    out += [f'    <connect name="loop_{i}" site1="tip_{i}" site2="joint_{i}" {eq}/>' for i in range(6)]
    out += ['  </equality>', '  <actuator>']
    out += [f'    <motor name="leg_{i}" joint="slide_{i}" gear="1" ctrlrange="{_num((lo_f, hi_f))}"/>' for i in range(6)]
    out += ['  </actuator>', '</mujoco>', '']
    return "\n".join(out)


def _home_rotation(params: PlatformParams) -> np.ndarray:
    return rpy_to_matrix(params.home_rpy)


def _inertial(mass: float, com, inertia: np.ndarray, indent: str) -> str:
    if mass <= 0:
        raise ValueError("params: a massless leg part cannot be a MuJoCo body (MuJoCo needs mass and inertia "
                         "on every moving body); give it a small mass")
    return f'{indent}<inertial pos="{_num(com)}" mass="{_num(mass)}" fullinertia="{_full_inertia(inertia)}"/>'


class _Twin:
    """One compiled MJCF model of a platform, with the addresses the plant reads and writes."""

    def __init__(self, params: PlatformParams, timestep: float, solref, solimp):
        mj = _require_mujoco()
        self.params = params
        self.model = mj.MjModel.from_xml_string(to_mjcf(params, timestep, solref, solimp, geometry=False))
        m = self.model
        legs = leg_kinematics(params, params.home_position, _home_rotation(params))
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
        axes (orthogonal, so each is a dot product) and dL_i/dt."""
        mj = _require_mujoco()
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
        qpos[self.q_free:self.q_free + 3] = t
        qpos[self.q_free + 3:self.q_free + 7] = _quat(R)
        qvel[self.v_free:self.v_free + 3] = v
        qvel[self.v_free + 3:self.v_free + 6] = R.T @ w  # MuJoCo's free joint: angular velocity in the body frame
        mj.mj_forward(self.model, data)

    def closure_gap(self, data) -> float:
        """Largest distance |tip_i - joint_i| (m) over the six loops, at data's current qpos."""
        mj = _require_mujoco()
        mj.mj_kinematics(self.model, data)
        gap = data.site_xpos[self.tips] - data.site_xpos[self.joints]
        return float(np.sqrt((gap * gap).sum(axis=1).max()))

    def set_wrench(self, data, t, R, leg_forces, wrench) -> None:
        """Leg forces as controls; the external wrench as MuJoCo's applied force (:func:`_wrench_at_com`)."""
        data.ctrl[:] = leg_forces
        data.xfrc_applied[self.body] = _wrench_at_com(R[None], self.params.platform.com[None], wrench[None])[0]


@contextlib.contextmanager
def _quiet_mujoco():
    """MuJoCo's default log handler neither prints nor writes MUJOCO_LOG.TXT into the current
    directory while the plant steps: a diverging row is reported as NaN instead (the previous
    configuration is restored afterwards)."""
    mj = _require_mujoco()
    before = mj.MjLogConfig.get()
    quiet = mj.MjLogConfig.get()
    quiet.logto_console = quiet.logto_file = False
    quiet.set()
    try:
        yield
    finally:
        before.set()


def _wrench_at_com(R: np.ndarray, com: np.ndarray, wrench: np.ndarray) -> np.ndarray:
    """The external wrench [force at P; moment] (N,6), {B}, as the equivalent [force; moment] at
    the platform's CoM (MuJoCo's ``xfrc_applied``): the moment gains (P - CoM) x force.
    R (N,3,3); com (N,3), the CoM in {P}."""
    a = -np.einsum("nij,nj->ni", R, com)  # P - CoM in {B}
    f = wrench[:, :3]
    out = wrench.copy()
    # the moment of f about the CoM, a x f, written out: numpy's cross costs more than the rest here
    out[:, 3] += a[:, 1] * f[:, 2] - a[:, 2] * f[:, 1]
    out[:, 4] += a[:, 2] * f[:, 0] - a[:, 0] * f[:, 2]
    out[:, 5] += a[:, 0] * f[:, 1] - a[:, 1] * f[:, 0]
    return out


class MujocoPlant:
    """MuJoCo simulating a batch of N platforms, stepped like :func:`stewart_env.integrate.rollout_inplace`.

    params_rows: one PlatformParams for every row, or a sequence of N (e.g. domain-randomised);
    rows with equal parameters share one compiled model.  timestep, solref, solimp: as in
    :func:`to_mjcf`; :meth:`step_inplace` sets MuJoCo's step to its ``dt`` (RK4 throughout).
    nthread: threads of ``mujoco.rollout``, which steps the rows (0: the calling thread; default:
    every core when N > 1, else the calling thread).  spherical_friction: add the spherical joints' friction, which the
    MJCF model cannot carry, as torques held over each call (see the module docstring).

    ``closure_error`` (N,), m: the largest loop-closure gap |tip_i - joint_i| of each row after
    the last :meth:`step_inplace` (NaN for a row that is not finite).
    """

    #: What a copy or pickle carries: the settings and the arrays of the simulation; MuJoCo's
    #: compiled models, data and thread pool are rebuilt from them (:meth:`__setstate__`).
    _CARRIED = ("params", "_settings", "_nthread", "spherical_friction", "_states", "_control", "_last",
                "closure_error")

    def __init__(self, params_rows: PlatformParams | Sequence[PlatformParams], timestep: float = 1e-3,
                 solref: Sequence[float] = DEFAULT_SOLREF, solimp: Sequence[float] = DEFAULT_SOLIMP,
                 nthread: int | None = None, spherical_friction: bool = True):
        mj = _require_mujoco()
        rows = [params_rows] if isinstance(params_rows, PlatformParams) else list(params_rows)
        if not rows or not all(isinstance(p, PlatformParams) for p in rows):
            raise ValueError("params_rows: expected a PlatformParams or a non-empty sequence of them")
        n = len(rows)
        self.params = tuple(rows)
        self._settings = (timestep, tuple(solref), tuple(solimp))
        if nthread is not None and (isinstance(nthread, bool) or not isinstance(nthread, (int, np.integer))
                                    or nthread < 0):
            raise ValueError(f"nthread: expected a non-negative integer (0: the calling thread) or None, got {nthread!r}")
        self._nthread = ((os.cpu_count() or 1) if n > 1 else 0) if nthread is None else int(nthread)
        self.spherical_friction = bool(spherical_friction)
        self._build()
        m = self.models[0]
        self._states = np.zeros((n, mj.mj_stateSize(m, self._spec)))
        self._control = np.zeros((n, mj.mj_stateSize(m, self._control_spec)))
        self.closure_error = np.full(n, np.nan)
        # The state each row returned last: a row given anything else was reset or set by the caller.
        self._last = (np.full((n, 3), np.nan), np.full((n, 3, 3), np.nan), np.full((n, 3), np.nan),
                      np.full((n, 3), np.nan))

    def _build(self) -> None:
        """MuJoCo's side of the plant from ``params`` and the settings: compiled models (shared by
        equal rows), scratch data, the rollout pool and the offsets into MuJoCo's vectors."""
        mj = _require_mujoco()
        from mujoco import rollout as mj_rollout

        self._twins: dict[PlatformParams, _Twin] = {}
        self._scratch = {}  # one MjData per compiled model: setting a row's state, measuring its loops
        self.twins = [self._twin(p) for p in self.params]
        self.models = [tw.model for tw in self.twins]
        self._pool = mj_rollout.Rollout(nthread=self._nthread)
        self._datas = [mj.MjData(self.models[0]) for _ in range(max(1, self._nthread))]
        first = self.twins[0]
        m = first.model
        self._spec = mj.mjtState.mjSTATE_FULLPHYSICS
        self._control_spec = mj.mjtState.mjSTATE_CTRL | mj.mjtState.mjSTATE_XFRC_APPLIED
        # offsets in MuJoCo's state vector (time, qpos, qvel, ...) and control vector (ctrl, xfrc_applied)
        self._q = 1 + first.q_free
        self._v = 1 + m.nq + first.v_free
        self._xfrc = m.nu + 6 * first.body
        self._uppers = m.nu + 6 * np.array([mj.mj_name2id(m, mj.mjtObj.mjOBJ_BODY, f"upper_{i}") for i in range(6)])
        self._com = np.array([p.platform.com for p in self.params])
        self._legs = make_dynamics("improved", list(self.params))  # the legs' angular velocities, for C_s

    def __getstate__(self) -> dict:
        return {name: getattr(self, name) for name in self._CARRIED}

    def __setstate__(self, state: dict) -> None:
        """A copy continues bit for bit: MuJoCo starts every call from the carried state vectors
        with zero warm-start, so rebuilt models and data give the same steps."""
        self.__dict__.update(state)
        self._build()

    def __len__(self) -> int:
        return len(self.twins)

    def _twin(self, params: PlatformParams) -> _Twin:
        """The compiled model of ``params``, shared by every row with equal parameters."""
        if params not in self._twins:
            tw = _Twin(params, *self._settings)
            self._twins[params] = tw
            self._scratch[id(tw)] = _require_mujoco().MjData(tw.model)
        return self._twins[params]

    def set_params(self, rows: Sequence[int], params: Sequence[PlatformParams]) -> None:
        """Give batch rows ``rows`` the parameters ``params`` (one each; e.g. randomised at a reset).
        The structure of the mechanism must stay that of the first row (six legs, the same joints),
        which every PlatformParams has; those rows restart at their next step."""
        rows = [int(r) for r in rows]
        if len(rows) != len(params):
            raise ValueError(f"params: expected one per row ({len(rows)}), got {len(params)}")
        plist = list(self.params)
        for r, p in zip(rows, params):
            if not 0 <= r < len(plist):
                raise ValueError(f"rows: {r} is outside the batch of {len(plist)} rows")
            if not isinstance(p, PlatformParams):
                raise ValueError(f"params: expected PlatformParams, got {type(p).__name__}")
            plist[r] = p
            self.twins[r] = self._twin(p)
            self.models[r] = self.twins[r].model
            self._com[r] = p.platform.com
            self._legs = self._legs.with_rows([r], [p])
            for a in self._last:
                a[r] = np.nan
        self.params = tuple(plist)
        # compiled models nobody uses any more are dropped
        used = {id(tw) for tw in self.twins}
        self._twins = {p: tw for p, tw in self._twins.items() if id(tw) in used}
        self._scratch = {k: d for k, d in self._scratch.items() if k in used}

    def step_inplace(self, position, rotation, velocity, angular_velocity, leg_forces, external_wrench,
                     dt: float, steps: int) -> None:
        """Advance every row by ``steps`` MuJoCo steps of ``dt`` s, leg forces (N,6) and external
        wrench (N,6) [force at P, N; moment, N m; {B}] held constant; overwrite position (N,3),
        rotation (N,3,3), velocity (N,3) and angular_velocity (N,3) (platform P's origin, {B},
        as the closed-form models) with MuJoCo's platform state.  No argument checks, of the
        arrays nor of ``dt`` and ``steps`` (the environment's per-step path, like
        ``rollout_inplace``: a NaN ``dt`` turns every row NaN, ``steps`` <= 0 does nothing).  A row whose state differs from what this plant returned
        last starts afresh from that state (legs by inverse kinematics, loops closed); a row
        that is not finite, or that MuJoCo finds diverging, comes back NaN and stays so."""
        mj = _require_mujoco()
        state = (position, rotation, velocity, angular_velocity)
        alive = (np.isfinite(position).all(1) & np.isfinite(rotation).all((1, 2)) & np.isfinite(velocity).all(1)
                 & np.isfinite(angular_velocity).all(1))
        changed = alive & ~np.all([np.equal(x, y).reshape(len(x), -1).all(1) for x, y in zip(state, self._last)], axis=0)
        for i in np.flatnonzero(changed):
            tw = self.twins[i]
            scratch = self._scratch[id(tw)]
            tw.set_state(scratch, position[i], rotation[i], velocity[i], angular_velocity[i])
            mj.mj_getState(tw.model, scratch, self._states[i], self._spec)
        for tw in self._twins.values():
            tw.model.opt.timestep = dt
        # leg forces as controls, the wrench as MuJoCo's applied force on the platform
        control = self._control
        control[:, :6] = leg_forces
        control[:, self._xfrc:self._xfrc + 6] = _wrench_at_com(rotation, self._com, external_wrench)
        if self.spherical_friction and alive.any():
            self._spherical_friction(alive, state)
        rows = np.flatnonzero(alive)
        steps = int(steps)
        if rows.size and steps > 0:
            every = rows.size == len(self.twins)
            models = self.models if every else [self.models[i] for i in rows]
            initial = self._states if every else self._states[rows]
            # the same controls at every step; shapes exact, so rollout's own checks are skipped
            controls = np.empty((rows.size, steps, control.shape[1]))
            controls[:] = (control if every else control[rows])[:, None, :]
            out = np.empty((rows.size, steps, self._states.shape[1]))
            with _quiet_mujoco():
                self._pool.rollout(models, self._datas, initial, controls, control_spec=self._control_spec,
                                   state=out, nstep=steps, skip_checks=True)
            end = initial[:, 0] + steps * dt
            self._states[rows] = out[:, -1]
            # MuJoCo resets a diverging simulation to its home pose and time 0: the clock tells
            alive[rows[np.abs(out[:, -1, 0] - end) > 0.5 * dt]] = False
        self._write(alive, state)

    def _spherical_friction(self, alive, state) -> None:
        """The spherical joints' friction as applied torques held over the call (zero-order hold):
        -C_s (omega_l,i - omega) on upper leg i and the sum of the opposite on the platform
        (docs/physics.md section 1), from the state at the call's start and the legs' angular
        velocities of inverse kinematics (section 4)."""
        rows = np.flatnonzero(alive)
        position, rotation, velocity, angular_velocity = (x[rows] for x in state)
        legs = self._legs if rows.size == len(self.twins) else self._legs.with_params([self.params[i] for i in rows])
        omega = leg_kinematics(legs, position, rotation, velocity, angular_velocity).omega  # (n,6,3)
        cs = np.array([self.params[i].damping.spherical for i in rows])
        torque = -cs[:, None, None] * (omega - angular_velocity[:, None, :])  # on each leg
        control = self._control
        for leg, at in enumerate(self._uppers):
            control[rows, at:at + 3] = 0.0
            control[rows, at + 3:at + 6] = torque[:, leg]
        control[rows, self._xfrc + 3:self._xfrc + 6] -= torque.sum(axis=1)

    def _write(self, alive, state) -> None:
        """The platform state of every live row from MuJoCo's state vectors; NaN for the others."""
        mj = _require_mujoco()
        position, rotation, velocity, angular_velocity = state
        s = self._states
        quat = s[:, self._q + 3:self._q + 7]
        quat = quat / np.linalg.norm(quat, axis=1, keepdims=True)
        w, x, y, z = quat.T
        R = np.stack([
            1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
        ], axis=1).reshape(-1, 3, 3)
        position[alive] = s[alive, self._q:self._q + 3]
        rotation[alive] = R[alive]
        velocity[alive] = s[alive, self._v:self._v + 3]
        # MuJoCo's free joint carries the angular velocity in the body frame
        angular_velocity[alive] = np.einsum("nij,nj->ni", R[alive], s[alive, self._v + 3:self._v + 6])
        for i in np.flatnonzero(alive):
            tw = self.twins[i]
            scratch = self._scratch[id(tw)]
            mj.mj_setState(tw.model, scratch, s[i], self._spec)
            self.closure_error[i] = tw.closure_gap(scratch)
        dead = ~alive
        for a in (*state, *self._last):
            a[dead] = np.nan
        self.closure_error[dead] = np.nan
        for a, b in zip(self._last, state):
            a[alive] = b[alive]


def model_and_data(params: PlatformParams, position, rotation, velocity=None, angular_velocity=None,
                   leg_forces=None, external_wrench=None, timestep: float = 1e-3,
                   solref: Sequence[float] = DEFAULT_SOLREF, solimp: Sequence[float] = DEFAULT_SOLIMP):
    """MuJoCo's ``(MjModel, MjData)`` of the twin of ``params`` at a platform state, ready for
    ``mujoco.mj_forward`` or ``mj_step``: position (3,), rotation (3,3), velocity (3,),
    angular_velocity (3,) of the platform in {B} (rates zero when left out), the legs' joints
    set by inverse kinematics so the loops are closed; leg_forces (6,) N as the actuators'
    controls and external_wrench (6,) [force at P; moment] applied (zero when left out).
    After ``mj_forward``, ``data.qacc`` holds the accelerations: :func:`platform_acceleration`."""
    mj = _require_mujoco()
    z = np.zeros(3)
    t, R = np.asarray(position, float), np.asarray(rotation, float)
    v = z if velocity is None else np.asarray(velocity, float)
    w = z if angular_velocity is None else np.asarray(angular_velocity, float)
    tw = _Twin(params, timestep, solref, solimp)
    d = mj.MjData(tw.model)
    tw.set_state(d, t, R, v, w)
    tw.set_wrench(d, t, R, np.zeros(6) if leg_forces is None else np.asarray(leg_forces, float),
                  np.zeros(6) if external_wrench is None else np.asarray(external_wrench, float))
    return tw.model, d


def platform_acceleration(model, data) -> tuple[np.ndarray, np.ndarray]:
    """(a, alpha), (3,) each in {B}: the acceleration of P's origin (m/s^2) and the angular
    acceleration (rad/s^2) of the twin's platform in ``data`` after ``mujoco.mj_forward`` or
    ``mj_step``, in the closed-form models' conventions.  MuJoCo's free joint carries the
    angular velocity in the body frame: the rate of that, turned by R, is the spatial alpha."""
    mj = _require_mujoco()
    joint = mj.mj_name2id(model, mj.mjtObj.mjOBJ_JOINT, "platform")
    body = mj.mj_name2id(model, mj.mjtObj.mjOBJ_BODY, "platform")
    acc = data.qacc[model.jnt_dofadr[joint]:model.jnt_dofadr[joint] + 6]
    return acc[:3].copy(), data.xmat[body].reshape(3, 3) @ acc[3:]


def _test_state(params: PlatformParams, seed: int):
    """A valid moving state near home: P's origin within 2 % of the mean leg length, angles within
    0.1 rad, v up to 0.2 m/s, omega up to 0.3 rad/s; and the leg forces that hold that pose at rest."""
    rng = np.random.default_rng(seed)
    scale = float(np.mean(leg_kinematics(params, params.home_position, _home_rotation(params)).lengths))
    t = params.home_position + rng.uniform(-0.02, 0.02, 3) * scale
    R = rpy_to_matrix(params.home_rpy + rng.uniform(-0.1, 0.1, 3))
    v, w = rng.uniform(-0.2, 0.2, 3), rng.uniform(-0.3, 0.3, 3)
    z = np.zeros(3)
    F = make_dynamics("improved", params).inverse(t, R, z, z, z, z)
    return t, R, v, w, F


def _without_spherical_friction(params: PlatformParams) -> PlatformParams:
    d = params.damping
    return params.replace(damping=Damping(d.universal, d.prismatic, 0.0))


def acceleration_error(params: PlatformParams, solref: Sequence[float] = DEFAULT_SOLREF,
                       solimp: Sequence[float] = DEFAULT_SOLIMP, seed: int = 0, force_scale: float = 1.1) -> float:
    """Largest difference (m/s^2 and rad/s^2, one number over the six components) between MuJoCo's
    platform acceleration and the ``improved`` model's (forward dynamics, docs/physics.md section
    5.4) at a valid moving state near home with the legs set by inverse kinematics, under
    ``force_scale`` times the holding forces.  The model compared has C_s = 0, as the twin."""
    mj = _require_mujoco()
    t, R, v, w, F = _test_state(params, seed)
    F = F * force_scale
    m, d = model_and_data(params, t, R, v, w, F, solref=solref, solimp=solimp)
    mj.mj_forward(m, d)
    a, alpha = platform_acceleration(m, d)
    a0, alpha0 = make_dynamics("improved", _without_spherical_friction(params)).forward(t, R, v, w, F)
    return float(np.abs(np.concatenate([a - a0, alpha - alpha0])).max())


def spherical_friction_effect(params: PlatformParams, seed: int = 0) -> float:
    """What omitting the spherical joints' friction C_s changes: the largest difference in the
    ``improved`` model's platform acceleration (m/s^2, rad/s^2) with and without C_s at the
    moving state of :func:`acceleration_error`."""
    t, R, v, w, F = _test_state(params, seed)
    a = make_dynamics("improved", params).forward(t, R, v, w, F)
    b = make_dynamics("improved", _without_spherical_friction(params)).forward(t, R, v, w, F)
    return float(np.abs(np.concatenate(a) - np.concatenate(b)).max())


def plant_difference(params: PlatformParams, seconds: float = 1.0, control_dt: float = 0.01, dt: float = 1e-3,
                     spherical_friction: bool = True, seed: int = 0) -> tuple[float, float]:
    """(position m, rotation rad): how far :class:`MujocoPlant`'s platform ends from the
    ``improved`` model's (every friction included, RK4 at ``dt``) after ``seconds`` of motion from
    the moving state of :func:`acceleration_error` under its holding forces, stepped in calls of
    ``control_dt`` as an environment does, with or without the plant's held spherical friction."""
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


def holding_drift(params: PlatformParams, seconds: float = 1.0, timestep: float = 1e-3,
                  solref: Sequence[float] = DEFAULT_SOLREF, solimp: Sequence[float] = DEFAULT_SOLIMP,
                  seed: int = 0) -> tuple[float, float]:
    """(position drift m, rotation drift rad) of MuJoCo's platform over ``seconds`` under the
    leg forces that ``inverse`` of the ``improved`` model says hold it at rest, from the pose of
    :func:`acceleration_error`: the exact mechanism would not move at all."""
    t, R, _, _, F = _test_state(params, seed)
    plant = MujocoPlant(params, timestep, solref, solimp)
    state = [t[None].copy(), R[None].copy(), np.zeros((1, 3)), np.zeros((1, 3))]
    plant.step_inplace(*state, F[None], np.zeros((1, 6)), timestep, int(round(seconds / timestep)))
    return float(np.linalg.norm(state[0][0] - t)), float(rotation_error(state[1][0], R)[1])


def trajectory_report(params: PlatformParams, seconds: float = 1.0, timestep: float = 1e-3,
                      solref: Sequence[float] = DEFAULT_SOLREF, solimp: Sequence[float] = DEFAULT_SOLIMP,
                      seed: int = 0) -> dict:
    """Energy and loop closure of MuJoCo's twin over a free motion, beside the exact model.

    The platform starts at the moving state of :func:`acceleration_error` under constant holding
    forces, with every joint's friction set to zero, so the exact mechanism conserves
    E = kinetic + gravitational - sum_i F_i L_i (constant leg forces have the potential -F_i L_i).
    Returns a dict: ``energy_drift`` (J, largest |E - E(0)| along the way), ``kinetic_energy``
    (J, at the start, the scale of the motion), ``closure_max`` (m, largest loop gap),
    ``position_difference`` (m, |t_MuJoCo - t_improved| at the end, the ``improved`` model
    integrated with RK4 at the same step), ``seconds`` and ``timestep``.
    """
    mj = _require_mujoco()
    from stewart_env.integrate import rollout

    free = params.replace(damping=Damping(0.0, 0.0, 0.0))
    t, R, v, w, F = _test_state(free, seed)
    tw = _Twin(free, timestep, solref, solimp)
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
    return {"energy_drift": drift, "kinetic_energy": kinetic, "closure_max": closure,
            "position_difference": float(np.linalg.norm(d.qpos[tw.q_free:tw.q_free + 3] - t_ref)),
            "seconds": seconds, "timestep": timestep}


#: MuJoCo's own defaults for constraint softness, for comparison in :func:`accuracy_report`.
MUJOCO_SOLREF = (0.02, 1.0)
MUJOCO_SOLIMP = (0.9, 0.95, 0.001, 0.5, 2.0)


def accuracy_report(params: PlatformParams) -> str:
    """The twin's accuracy on ``params``, as markdown: :func:`acceleration_error` at three
    softnesses, :func:`holding_drift`, :func:`trajectory_report` with the twin's and MuJoCo's
    default softness, and :func:`spherical_friction_effect`.  ``python -m stewart_env.mujoco NAME``."""
    loose = (0.99, 0.99) + DEFAULT_SOLIMP[2:]
    lines = [f"MuJoCo twin of {params.name} (stewart_env.mujoco), against the improved model:", "",
             "| loop softness (solref; solimp d) | platform acceleration error | closure, 1 s free motion "
             "| energy drift / kinetic energy | position vs improved after 1 s |", "|---|---|---|---|---|"]
    for label, solref, solimp in (("twin default", DEFAULT_SOLREF, DEFAULT_SOLIMP),
                                  ("d = 0.99", DEFAULT_SOLREF, loose),
                                  ("MuJoCo default", MUJOCO_SOLREF, MUJOCO_SOLIMP)):
        acc = acceleration_error(params, solref, solimp)
        r = trajectory_report(params, solref=solref, solimp=solimp)
        lines.append(f"| {label} ({_num(solref)}; {solimp[0]:g}) | {acc:.2e} | {r['closure_max']:.2e} m "
                     f"| {r['energy_drift']:.2e} J / {r['kinetic_energy']:.3g} J | {r['position_difference']:.2e} m |")
    position, angle = holding_drift(params)
    held, omitted = plant_difference(params), plant_difference(params, spherical_friction=False)
    lines += ["", f"holding forces of `inverse`, 1 s: platform drifts {position:.2e} m and {angle:.2e} rad",
              f"spherical-joint friction C_s (not in the MJCF model) changes the improved model's acceleration by "
              f"{spherical_friction_effect(params):.2e} (m/s^2, rad/s^2) at the same state",
              f"MujocoPlant vs improved after 1 s of motion in 10 ms steps: {held[0]:.2e} m, {held[1]:.2e} rad with "
              f"C_s held over each step; {omitted[0]:.2e} m, {omitted[1]:.2e} rad without"]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    import argparse

    from stewart_env.params import load_platform

    parser = argparse.ArgumentParser(prog="python -m stewart_env.mujoco", description=accuracy_report.__doc__.split("\n\n")[0])
    parser.add_argument("platforms", nargs="*", default=["dasgupta1998", "motion_simulator"],
                        help="platform config names or YAML paths (default: both shipped platforms)")
    args = parser.parse_args(argv)
    for i, name in enumerate(args.platforms):
        try:
            params = load_platform(name)
        except (ValueError, OSError) as err:
            parser.error(f"argument platforms: {err}")
        print(("\n" if i else "") + accuracy_report(params))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
