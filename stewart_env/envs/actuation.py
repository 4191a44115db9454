"""The actuation at the physics rate: an action mode's inner loop and an actuator model.

When the action is not a leg force held over the control step (``action_mode="leg_length"`` or
``"pose"``) or the actuator is a drive with states of its own (``actuator="electric"`` or
``"hydraulic"``), the compiled step runs, per RK4 substep, the leg sensors, the inner loop that
turns the action's set point into leg-force set points, the actuator that turns those into the
forces the legs feel, and the dynamics with the electric drive's reflected masses
(``stewart_env/_core/cpp/env/actuation.hpp``; docs/physics.md section 10.8).  :class:`Actuation`
gathers what that step reads from the platform and the arguments, holds the actuators' state
(n, 6, 3) and sets it at a reset; :meth:`Actuation.record` is its part of the compiled step.
"""

from __future__ import annotations

import math

import numpy as np

from stewart_env import _core
from stewart_env.actuators import ElectricActuator, HydraulicActuator, LegServo
from stewart_env.dynamics import Dynamics
from stewart_env.envs.config import ACTION_MODES, ACTUATORS, DRIVES, POSE_LAWS, ActuatorConfig
from stewart_env.errors import UsageError
from stewart_env.params import PlatformParams
from stewart_env.rotations import matrix_to_rpy

__all__ = ["SERVO_BANDWIDTH", "SERVO_DAMPING_RATIO", "Actuation"]

#: The -3 dB bandwidth of the leg servos and of the pose laws' loops, rad/s (5 Hz: a motion base's
#: position loop, well below the 500 Hz current loop and the 100 Hz valve).
SERVO_BANDWIDTH = 2.0 * math.pi * 5.0
#: Their damping ratio.
SERVO_DAMPING_RATIO = 0.7
#: The hydraulic force loop opens the valve fully at a force error of this fraction of the
#: cylinder's full-supply force P_s A_A (a loop time constant of a few ms with the motion
#: simulator's valve and oil).
HYDRAULIC_FULL_OPENING = 1.0
#: The hydraulic cylinder's pressures reported: the span they are scaled over is P_s - P_r.
_STATES = 3


def _drive_params(actuator: str, platform: PlatformParams):
    """The platform's parameter set of a drive, or a UsageError naming ``actuator=`` and the platform."""
    params = getattr(platform.actuators, actuator)
    if params is None:
        raise UsageError.about(
            "actuator",
            f"the platform {platform.name!r} has no {actuator!r} set in its actuators: section "
            f"(it has: {', '.join(k for k in DRIVES if getattr(platform.actuators, k)) or 'none'})",
        )
    if actuator == "hydraulic":
        platform.actuators.check_stroke(tuple(platform.limits.leg_length))
    return params


class Actuation:
    """The actuation of a batch of ``n`` rows at the physics rate (see the module docstring).

    Args:
        config: the actuators' arguments (``physics_rate`` must be true).
        platform: the platform.
        model: the nominal closed-form model (the inner loops' model).
        n: rows.

    Attributes:
        state: (n, 6, 3) the actuators' state: electric [current A, 0, 0]; hydraulic [spool m,
            P_A Pa, P_B Pa]; unused for the ideal and lag actuators.
        reflected_mass: (6,) the legs' reflected masses, kg (the electric drive's, else zero).
        report: the observed actuator states (:meth:`reported`): their scale and offset (K,), or
            None when they are not observed.

    Raises:
        UsageError: a drive the platform has no parameters for (naming ``actuator``).
    """

    def __init__(self, config: ActuatorConfig, platform: PlatformParams, model: Dynamics, n: int):
        self.config = config
        self.n = n
        self.platform = platform
        self.nominal_flags = int(model.flags)
        lim = platform.limits
        self.force_range = np.array(lim.leg_force, dtype=np.float64)
        lo, hi = lim.leg_length
        self.length_map = np.array([0.5 * (lo + hi), 0.5 * (hi - lo)])
        self.pose_mid = np.concatenate([0.5 * (lim.position_min + lim.position_max), platform.home_rpy])
        self.pose_half = np.concatenate([0.5 * (lim.position_max - lim.position_min), np.full(3, lim.max_angle)])
        self.state = np.zeros((n, 6, _STATES))
        self.reflected_mass = np.zeros(6)
        self.lag = 0.0
        self.electric = np.zeros(0)
        self.hydraulic = np.zeros(0)
        self.current_gain, self.force_per_amp, self.valve_gain, self.force_gain = 0.0, 1.0, 0.0, 0.0
        self._electric: ElectricActuator | None = None
        self._hydraulic: HydraulicActuator | None = None
        kind = config.actuator
        if kind == "electric":
            drive = self._electric = ElectricActuator(_drive_params(kind, platform))
            self.electric = drive.packed
            self.force_per_amp = float(drive.screw.leg_force_from_current(1.0))
            self.reflected_mass = np.full(6, drive.reflected_mass)
        elif kind == "hydraulic":
            # n rows: its reset gives the chamber pressures of the rows' holding forces
            cylinder = self._hydraulic = HydraulicActuator(_drive_params(kind, platform), n)
            self.hydraulic = cylinder.packed
            p = cylinder.params
            self.force_gain = 1.0 / (HYDRAULIC_FULL_OPENING * p.supply_pressure * p.area_a)
        self._gains(platform)
        self.report = self._report() if config.observe_actuators else None

    def _gains(self, platform: PlatformParams) -> None:
        """The leg servo's gains (LegServo.from_bandwidth) for a leg carrying its share of the
        platform, its upper leg and its reflected mass; the pose laws' gains for the platform's
        mass and inertia (PD: a wrench per error; computed torque: an acceleration per error)."""
        m_platform = platform.platform.mass
        share = m_platform / 6.0 + float(np.mean([leg.mass for leg in platform.upper_leg])) + self.reflected_mass[0]
        servo = LegServo.from_bandwidth(SERVO_BANDWIDTH, SERVO_DAMPING_RATIO, share, platform.damping.prismatic)
        self.servo = np.array(servo.gains[:2], dtype=np.float64)
        omega = SERVO_BANDWIDTH / _core.bandwidth_ratio(SERVO_DAMPING_RATIO)
        zeta = SERVO_DAMPING_RATIO
        if self.config.pose_law == "computed_torque":
            self.task_kp = np.full(6, omega * omega)
            self.task_kd = np.full(6, 2.0 * zeta * omega)
        else:
            legs = 6.0 * float(np.mean([leg.mass for leg in platform.upper_leg]))
            inertia = np.diag(platform.platform.inertia)
            scale = np.concatenate([np.full(3, m_platform + legs + 6.0 * self.reflected_mass[0]), inertia])
            self.task_kp = scale * omega * omega
            self.task_kd = scale * 2.0 * zeta * omega

    def _report(self) -> tuple[np.ndarray, np.ndarray]:
        """The scale and offset of the reported states: currents over the current limit; the
        pressures P_A, P_B of each leg about the mean of supply and return over half their span."""
        if self._electric is not None:
            return np.full(6, self._electric.params.current_limit), np.zeros(6)
        p = self._hydraulic.params
        return (
            np.full(12, 0.5 * (p.supply_pressure - p.return_pressure)),
            np.full(12, 0.5 * (p.supply_pressure + p.return_pressure)),
        )

    def reported(self, rows=slice(None)) -> np.ndarray:
        """The states a drive reports of ``rows`` (m, K): the motor currents (6, A), or each leg's
        chamber pressures P_A, P_B (12, Pa, leg by leg).

        Args:
            rows: the rows (an index or a slice).
        """
        if self._electric is not None:
            return self.state[rows, :, 0]
        states = self.state[rows, :, 1:]
        return states.reshape(states.shape[0], 12)

    def reset_rows(self, rows: np.ndarray, holding: np.ndarray) -> None:
        """Start the actuators of ``rows`` at equilibrium with the holding forces ``holding`` (m, 6), N:
        the motor currents that push with them at rest, or the chamber pressures that do with the
        spool centred (HydraulicActuator.reset).

        Args:
            rows: (m,) int, the rows.
            holding: (m, 6) the forces that hold each row's start state, N.
        """
        self.state[rows] = 0.0
        if self._electric is not None:
            self.state[rows, :, 0] = holding / self.force_per_amp
        elif self._hydraulic is not None:
            self._hydraulic.reset(rows, force=holding)
            self.state[rows] = self._hydraulic.state[rows]

    def current_set_points(self, action: np.ndarray) -> np.ndarray:
        """The electric drives' current set points (n, 6), A, of the applied actions (n, 6) in
        [-1, 1]: the leg-force set points over the force range, per ``eta k K_t`` (``force_per_amp``,
        as the compiled step's drive takes them).  For a plant that carries the drive (MuJoCo).

        Args:
            action: (n, 6) the applied actions.
        """
        lo, hi = self.force_range
        return (action * (0.5 * (hi - lo)) + 0.5 * (lo + hi)) / self.force_per_amp

    def start_plant_drives(self, plant, rows: np.ndarray) -> None:
        """Start the drives of a plant that carries them (``MujocoPlant(..., actuator="electric")``)
        at the currents of :meth:`reset_rows`; a plant without drives is left as it is.

        Args:
            plant: the batch's plant.
            rows: (m,) int, the rows.
        """
        if getattr(plant, "actuator", "ideal") == "electric":
            plant.reset_currents(rows, self.state[rows, :, 0])

    def take_plant_drives(self, plant, leg_forces: np.ndarray) -> None:
        """After a step of a plant that carries the drives: their currents into :attr:`state`
        (what ``observe_actuators`` reports) and the forces they gave the legs last into
        ``leg_forces`` (n, 6), N.

        Args:
            plant: the batch's plant (``MujocoPlant(..., actuator="electric")``).
            leg_forces: (n, 6) the batch's leg forces, overwritten.
        """
        self.state[:, :, 0] = plant.current
        leg_forces[...] = plant.drive_force

    def pose_command(self, position: np.ndarray, rotation: np.ndarray) -> np.ndarray:
        """The pose mode's action that commands a pose: (position, roll-pitch-yaw) normalised
        over the workspace box and the angles' range (the inverse of the mode's map).

        Args:
            position: (3,) the pose's position of P in {B}, m.
            rotation: (3, 3) its rotation.

        Returns:
            The (6,) action (outside [-1, 1] where the pose is outside the ranges).
        """
        pose = np.concatenate([np.asarray(position, dtype=np.float64), matrix_to_rpy(np.asarray(rotation))])
        return (pose - self.pose_mid) / self.pose_half

    def record(self, physics_dt: float) -> _core.ActuationRecord:
        """The actuation's part of the compiled step, holding :attr:`state`.

        Args:
            physics_dt: the physics step, s (the per-step gains of the lag and the drives' loops).

        Returns:
            A new ``_core.ActuationRecord``.
        """
        c = self.config
        lag = -math.expm1(-physics_dt / c.actuator_tau) if c.actuator == "lag" else 0.0
        current_gain = valve_gain = 0.0
        if self._electric is not None:
            current_gain = -math.expm1(-self._electric.params.current_bandwidth * physics_dt)
        if self._hydraulic is not None:
            valve_gain = -math.expm1(-self._hydraulic.params.valve_bandwidth * physics_dt)
        return _core.ActuationRecord(
            ACTION_MODES.index(c.action_mode),
            POSE_LAWS.index(c.pose_law),
            ACTUATORS.index(c.actuator),
            self.nominal_flags,
            self.force_range,
            self.length_map,
            self.pose_mid,
            self.pose_half,
            self.servo,
            self.task_kp,
            self.task_kd,
            lag,
            self.electric,
            current_gain,
            self.force_per_amp,
            self.hydraulic,
            valve_gain,
            self.force_gain,
            self.reflected_mass,
            self.state,
        )
