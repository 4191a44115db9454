"""MuJoCo simulating a batch of N platforms, stepped like :func:`stewart_env.integrate.rollout_inplace`.

The spherical joints' friction, which the MJCF model omits (:mod:`stewart_env.mujoco.mjcf`), is
put back as torques held over each call (zero-order hold over a control step, from the state at
the step's start; ``spherical_friction``).  :func:`~stewart_env.mujoco.spherical_friction_effect`
measures what omitting it changes, and :func:`~stewart_env.mujoco.plant_difference` what the held
torques leave (``python -m stewart_env.mujoco``; figures in the README).

With ``actuator="electric"`` the legs are the platform config's electric drives (docs/physics.md
section 10.4): the plant's command is then the six current set points, A, and at every MuJoCo step
the plant advances the current loops by the compiled ``electric_step`` (the drive law of
:class:`~stewart_env.actuators.ElectricActuator`: current limit, back-EMF voltage envelope,
first-order current loop, viscous and smooth Coulomb friction) at the legs' rates of the step's
start, and holds the force it gives over the step, as the closed-form environment steps its
drive; the rotor's reflected mass is the slides' armature (:func:`~stewart_env.mujoco.to_mjcf`).
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from stewart_env import _core
from stewart_env.actuators import ElectricActuator, ElectricParams
from stewart_env.dynamics.model import make_dynamics
from stewart_env.kinematics import leg_kinematics
from stewart_env.mujoco.library import quiet_mujoco, require_mujoco, require_rollout
from stewart_env.mujoco.mjcf import DEFAULT_SOLIMP, DEFAULT_SOLREF
from stewart_env.mujoco.twin import Twin, wrench_at_com
from stewart_env.params import PlatformParams

__all__ = ["ACTUATORS", "MujocoPlant"]

#: The legs' actuators the plant simulates (its ``actuator`` argument): the ideal force source, or
#: the platform config's electric drives.
ACTUATORS = ("ideal", "electric")


class MujocoPlant:
    """MuJoCo simulating a batch of N platforms, stepped like :func:`stewart_env.integrate.rollout_inplace`.

    ``closure_error`` (N,), m: the largest loop-closure gap |tip_i - joint_i| of each row after
    the last :meth:`step_inplace` (NaN for a row that is not finite).

    With ``actuator="electric"``, ``current`` (N, 6), A, holds the motor currents (the drives'
    state, carried from call to call; :meth:`reset_currents` sets them, e.g. at an episode's
    start) and ``drive_force`` (N, 6), N, the leg forces the drives applied over the last MuJoCo
    step.

    Args:
        params_rows: one PlatformParams for every row, or a sequence of N (e.g.
            domain-randomised); rows with equal parameters share one compiled model.
        timestep, solref, solimp: as in :func:`to_mjcf`; :meth:`step_inplace` sets MuJoCo's step
            to its ``dt`` (RK4 throughout).
        nthread: threads of ``mujoco.rollout``, which steps the rows (0: the calling thread;
            default: every core when N > 1, else the calling thread).
        spherical_friction: add the spherical joints' friction, which the MJCF model cannot
            carry, as torques held over each call (see the module docstring).
        actuator: ``"ideal"`` (the default: :meth:`step_inplace`'s command is the leg forces, N)
            or ``"electric"`` (every row's ``params.actuators.electric`` drives its legs; the
            command is the current set points, A; see the module docstring).

    Raises:
        ImportError: the ``mujoco`` extra is not installed (the message says how to install it).
        ValueError: a bad argument, named in the message.

    Examples:
        One platform held by its holding forces for 10 ms of 1 ms steps stays at home, its
        loops closed:

        >>> import numpy as np, stewart_env as se
        >>> from stewart_env.mujoco import MujocoPlant
        >>> params = se.load_platform("dasgupta1998")
        >>> plant = MujocoPlant(params, nthread=0)
        >>> position, rotation = params.home_position[None].copy(), np.eye(3)[None].copy()
        >>> velocity, angular_velocity = np.zeros((1, 3)), np.zeros((1, 3))
        >>> model = se.make_dynamics("improved", params)
        >>> forces = model.inverse(position, rotation, velocity, angular_velocity, np.zeros((1, 3)), np.zeros((1, 3)))
        >>> plant.step_inplace(position, rotation, velocity, angular_velocity, forces, np.zeros((1, 6)), 1e-3, 10)
        >>> bool(np.abs(position - params.home_position).max() < 1e-5 and plant.closure_error[0] < 1e-5)
        True
    """

    #: The plant's name in the environment's ``plant`` argument (see stewart_env.envs.plant).
    name = "mujoco"
    #: What a copy or pickle carries: the settings and the arrays of the simulation; MuJoCo's
    #: compiled models, data and thread pool are rebuilt from them (:meth:`__setstate__`).
    _CARRIED = (
        "params",
        "_settings",
        "_nthread",
        "spherical_friction",
        "actuator",
        "current",
        "drive_force",
        "_states",
        "_control",
        "_last",
        "closure_error",
    )

    def __init__(
        self,
        params_rows: PlatformParams | Sequence[PlatformParams],
        timestep: float = 1e-3,
        solref: Sequence[float] = DEFAULT_SOLREF,
        solimp: Sequence[float] = DEFAULT_SOLIMP,
        nthread: int | None = None,
        spherical_friction: bool = True,
        actuator: str = "ideal",
    ):
        mj = require_mujoco()
        rows = [params_rows] if isinstance(params_rows, PlatformParams) else list(params_rows)
        if not rows or not all(isinstance(p, PlatformParams) for p in rows):
            raise ValueError("params_rows: expected a PlatformParams or a non-empty sequence of them")
        n = len(rows)
        self.params = tuple(rows)
        self._settings = (timestep, tuple(solref), tuple(solimp))
        if nthread is not None and (
            isinstance(nthread, bool) or not isinstance(nthread, (int, np.integer)) or nthread < 0
        ):
            raise ValueError(
                f"nthread: expected a non-negative integer (0: the calling thread) or None, got {nthread!r}"
            )
        self._nthread = ((os.cpu_count() or 1) if n > 1 else 0) if nthread is None else int(nthread)
        self.spherical_friction = bool(spherical_friction)
        if actuator not in ACTUATORS:
            raise ValueError(f"actuator: expected one of {', '.join(map(repr, ACTUATORS))}, got {actuator!r}")
        self.actuator = actuator
        for p in rows:
            self._check_drive(p)
        self.current = np.zeros((n, 6))
        self.drive_force = np.zeros((n, 6))
        self._build()
        m = self.models[0]
        self._states = np.zeros((n, mj.mj_stateSize(m, self._spec)))
        self._control = np.zeros((n, mj.mj_stateSize(m, self._control_spec)))
        self.closure_error = np.full(n, np.nan)
        # The state each row returned last: a row given anything else was reset or set by the caller.
        self._last = (
            np.full((n, 3), np.nan),
            np.full((n, 3, 3), np.nan),
            np.full((n, 3), np.nan),
            np.full((n, 3), np.nan),
        )

    def _build(self) -> None:
        """MuJoCo's side of the plant from ``params`` and the settings: compiled models (shared by
        equal rows), scratch data, the rollout pool and the offsets into MuJoCo's vectors."""
        mj = require_mujoco()
        mj_rollout = require_rollout()
        self._twins: dict[PlatformParams, Twin] = {}
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
        self._slide = 1 + m.nq + first.v_slide  # the slides' rates dL/dt in MuJoCo's state vector
        self._drives: dict[ElectricParams, np.ndarray] = {}  # the packed row of each drive in use
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

    def _twin(self, params: PlatformParams) -> Twin:
        """The compiled model of ``params``, shared by every row with equal parameters."""
        if params not in self._twins:
            tw = Twin(params, *self._settings, electric=self._electric(params))
            self._twins[params] = tw
            self._scratch[id(tw)] = require_mujoco().MjData(tw.model)
        return self._twins[params]

    def _electric(self, params: PlatformParams) -> ElectricParams | None:
        """The drive a row of ``params`` carries: its config's electric set, or None (ideal)."""
        return params.actuators.electric if self.actuator == "electric" else None

    def _check_drive(self, params: PlatformParams) -> None:
        """A ValueError naming ``actuator`` if the plant's actuator needs a section ``params`` lacks."""
        if self.actuator == "electric" and params.actuators.electric is None:
            raise ValueError(
                f"actuator: 'electric' needs the platform config's actuators: electric: section, "
                f"which {params.name!r} has not"
            )

    def reset_currents(self, rows: Sequence[int] | None = None, current=0.0) -> None:
        """Set the electric drives' motor currents (``actuator="electric"``), e.g. where an episode
        starts: to 0, or to the current that holds the platform.

        Args:
            rows: the batch rows (None: all).
            current: A, a scalar, a row of six or one row of six per row.

        Raises:
            ValueError: a row outside the batch, or currents of the wrong shape or not finite.
        """
        index = np.arange(len(self.twins)) if rows is None else np.asarray(rows, dtype=np.intp).reshape(-1)
        if index.size and (index.min() < 0 or index.max() >= len(self.twins)):
            raise ValueError(f"rows: expected rows of the batch of {len(self.twins)}, got {index.tolist()[:5]}")
        try:
            value = np.broadcast_to(np.asarray(current, dtype=np.float64), (index.size, 6))
        except ValueError:
            raise ValueError(
                f"current: expected a scalar, (6,) or ({index.size}, 6), got {np.shape(current)}"
            ) from None
        if not np.isfinite(value).all():
            raise ValueError("current: expected finite currents, A")
        self.current[index] = value

    def set_params(self, rows: Sequence[int], params: Sequence[PlatformParams]) -> None:
        """Give batch rows ``rows`` the parameters ``params`` (one each; e.g. randomised at a reset).
        The structure of the mechanism must stay that of the first row (six legs, the same joints),
        which every PlatformParams has; those rows restart at their next step.

        Args:
            rows: the batch rows.
            params: their new parameters, one per row.

        Raises:
            ValueError: not one PlatformParams per row, or a row outside the batch.
        """
        rows = [int(r) for r in rows]
        if len(rows) != len(params):
            raise ValueError(f"params: expected one per row ({len(rows)}), got {len(params)}")
        plist = list(self.params)
        for p in params:
            if isinstance(p, PlatformParams):
                self._check_drive(p)
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

    def set_model(self, model, rows: Sequence[int]) -> None:
        """Give batch rows ``rows`` the parameters of those rows of ``model`` (a
        :class:`~stewart_env.dynamics.Dynamics` with one parameter row per batch row): the
        environment's plant interface, see :meth:`set_params`.

        Args:
            model: the batch's dynamics model.
            rows: the batch rows whose parameters are new.
        """
        self.set_params(rows, [model.params_of(i) for i in rows])

    def step_record(self, physics_dt: float, substeps: int) -> None:
        """The environment's plant interface: MuJoCo has no part in the batch's compiled step
        (the batch steps it with :meth:`step_inplace`).

        Args:
            physics_dt: the integrator's step, s (unused).
            substeps: the integrator's steps per control step (unused).
        """
        return None

    def step_inplace(
        self, position, rotation, velocity, angular_velocity, leg_forces, external_wrench, dt: float, steps: int
    ) -> None:
        """Advance every row by ``steps`` MuJoCo steps of ``dt`` s, leg forces (N,6) (with
        ``actuator="electric"``: the drives' current set points, A, the drives stepping at every
        MuJoCo step) and external wrench (N,6) [force at P, N; moment, N m; {B}] held constant; overwrite position (N,3),
        rotation (N,3,3), velocity (N,3) and angular_velocity (N,3) (platform P's origin, {B},
        as the closed-form models) with MuJoCo's platform state.  No argument checks, of the
        arrays nor of ``dt`` and ``steps`` (the environment's per-step path, like
        ``rollout_inplace``: a NaN ``dt`` turns every row NaN, ``steps`` <= 0 does nothing).  A row whose state differs from what this plant returned
        last starts afresh from that state (legs by inverse kinematics, loops closed); a row
        that is not finite, or that MuJoCo finds diverging, comes back NaN and stays so.

        Args:
            position: (N,3) m, the position of P's origin in {B}.
            rotation: (N,3,3) rotation matrices, columns = {P} axes.
            velocity: (N,3) m/s, the velocity of P's origin in {B}.
            angular_velocity: (N,3) rad/s, the platform's angular velocity in {B}.
            leg_forces: (N,6) N, the legs' actuator forces; with ``actuator="electric"`` the
                current set points, A.
            external_wrench: (N,6) [F_ext at P, N; M_ext, N m] in {B}.
            dt: MuJoCo's step, s.
            steps: the number of steps.
        """
        mj = require_mujoco()
        state = (position, rotation, velocity, angular_velocity)
        alive = (
            np.isfinite(position).all(1)
            & np.isfinite(rotation).all((1, 2))
            & np.isfinite(velocity).all(1)
            & np.isfinite(angular_velocity).all(1)
        )
        changed = alive & ~np.all(
            [np.equal(x, y).reshape(len(x), -1).all(1) for x, y in zip(state, self._last)], axis=0
        )
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
        control[:, self._xfrc : self._xfrc + 6] = wrench_at_com(rotation, self._com, external_wrench)
        if self.spherical_friction and alive.any():
            self._spherical_friction(alive, state)
        steps = int(steps)
        if self.actuator == "electric":
            command = np.broadcast_to(leg_forces, (len(self.twins), 6))  # as the ideal controls broadcast
            for _ in range(steps):
                rows = np.flatnonzero(alive)
                if not rows.size:
                    break
                # the drives at the legs' rates of the step's start, their force held over the step
                control[rows, :6] = self._drive(rows, command, dt)
                self._advance(alive, rows, 1, dt)
        else:
            self._advance(alive, np.flatnonzero(alive), steps, dt)
        self._write(alive, state)

    def _drive(self, rows: np.ndarray, command, dt: float) -> np.ndarray:
        """The electric drives of ``rows`` over one step of ``dt``: their currents advanced by the
        compiled drive law (``electric_step``, the step of
        :class:`~stewart_env.actuators.ElectricActuator`) at the slides' rates dL/dt, and the leg
        forces it gives within each row's force limits (its model's ``ctrlrange``, where MuJoCo
        would clamp them too), recorded in ``drive_force``."""
        groups: dict[ElectricParams, list[int]] = {}
        for r in rows:
            groups.setdefault(self.params[r].actuators.electric, []).append(int(r))
        for drive, members in groups.items():
            if drive not in self._drives:
                self._drives[drive] = ElectricActuator(drive).packed
            index = np.array(members)
            current = np.ascontiguousarray(self.current[index])
            force = np.empty_like(current)
            _core.electric_step(
                self._drives[drive],
                float(dt),
                np.ascontiguousarray(command[index], dtype=np.float64),
                np.ascontiguousarray(self._states[index][:, self._slide]),
                current,
                force,
            )
            self.current[index] = current
            # each row's own force limits, which the row's compiled model has as ctrlrange
            limits = np.array([self.models[r].actuator_ctrlrange for r in members])  # (k, 6, 2)
            self.drive_force[index] = np.clip(force, limits[..., 0], limits[..., 1])
        return self.drive_force[rows]

    def _advance(self, alive: np.ndarray, rows: np.ndarray, steps: int, dt: float) -> None:
        """``steps`` MuJoCo steps of ``rows`` (the live rows) with their controls held; a row that
        diverges is marked dead in ``alive``."""
        if not rows.size or steps <= 0:
            return
        control = self._control
        every = rows.size == len(self.twins)
        models = self.models if every else [self.models[i] for i in rows]
        initial = self._states if every else self._states[rows]
        # the same controls at every step; shapes exact, so rollout's own checks are skipped
        controls = np.empty((rows.size, steps, control.shape[1]))
        controls[:] = (control if every else control[rows])[:, None, :]
        out = np.empty((rows.size, steps, self._states.shape[1]))
        with quiet_mujoco():
            self._pool.rollout(
                models,
                self._datas,
                initial,
                controls,
                control_spec=self._control_spec,
                state=out,
                nstep=steps,
                skip_checks=True,
            )
        end = initial[:, 0] + steps * dt
        self._states[rows] = out[:, -1]
        # MuJoCo resets a diverging simulation to its home pose and time 0: the clock tells
        alive[rows[np.abs(out[:, -1, 0] - end) > 0.5 * dt]] = False

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
            control[rows, at : at + 3] = 0.0
            control[rows, at + 3 : at + 6] = torque[:, leg]
        control[rows, self._xfrc + 3 : self._xfrc + 6] -= torque.sum(axis=1)

    def _write(self, alive, state) -> None:
        """The platform state of every live row from MuJoCo's state vectors; NaN for the others."""
        mj = require_mujoco()
        position, rotation, velocity, angular_velocity = state
        s = self._states
        quat = s[:, self._q + 3 : self._q + 7]
        quat = quat / np.linalg.norm(quat, axis=1, keepdims=True)
        w, x, y, z = quat.T
        R = np.stack(
            [
                1 - 2 * (y * y + z * z),
                2 * (x * y - w * z),
                2 * (x * z + w * y),
                2 * (x * y + w * z),
                1 - 2 * (x * x + z * z),
                2 * (y * z - w * x),
                2 * (x * z - w * y),
                2 * (y * z + w * x),
                1 - 2 * (x * x + y * y),
            ],
            axis=1,
        ).reshape(-1, 3, 3)
        position[alive] = s[alive, self._q : self._q + 3]
        rotation[alive] = R[alive]
        velocity[alive] = s[alive, self._v : self._v + 3]
        # MuJoCo's free joint carries the angular velocity in the body frame
        angular_velocity[alive] = np.einsum("nij,nj->ni", R[alive], s[alive, self._v + 3 : self._v + 6])
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
