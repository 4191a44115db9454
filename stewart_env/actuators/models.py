"""The legs' actuator models as Python objects over the compiled step (docs/physics.md section 10):
each owns its state arrays, rows x 6 legs, and advances them by one call of the compiled batch
step, the call the environment's compiled step makes per physics substep.

- :class:`IdealActuator`: the force source, force = command;
- :class:`LagActuator`: a first-order lag of time constant tau (tau = 0: the ideal force source);
- :class:`ElectricActuator`: a current-controlled servo motor on a ball screw (command: the
  q-axis current set point, A), its reflected mass for the dynamics;
- :class:`HydraulicActuator`: a servo valve and a single-rod cylinder (command: the spool set
  point over its travel, in [-1, 1]);
- :class:`LegServo`: the leg-length servo (P on the length error, D on the leg's rate, optional I)
  whose output is the actuator's command.

Forces are N (> 0 extends the leg), lengths m, rates m/s, currents A, pressures Pa (absolute).
Every object pickles with its state and parameters.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from stewart_env import _core
from stewart_env.actuators.transmission import BallScrew
from stewart_env.params.actuators import ElectricParams, HydraulicParams
from stewart_env.validation import Interval

__all__ = ["IdealActuator", "LagActuator", "ElectricActuator", "HydraulicActuator", "LegServo", "N_LEGS"]

N_LEGS = 6

_ROWS = Interval(numbers.Integral, 1, 1 << 24)
_SUBSTEPS = Interval(numbers.Integral, 1, 1 << 20)
_TIME_CONSTANT = Interval(numbers.Real, 0.0, 1e6)
_POSITIVE = Interval(numbers.Real, 0.0, 1e12, low_open=True)
_NON_NEGATIVE = Interval(numbers.Real, 0.0, 1e12)
_DAMPING_RATIO = Interval(numbers.Real, 0.0, 100.0, low_open=True)


def _legs(value, name: str, n: int) -> np.ndarray:
    """`value` as a C-contiguous float64 (n, 6) array (a scalar or a (6,) row broadcast), or
    ValueError naming it."""
    arr = np.asarray(value, dtype=np.float64)
    try:
        arr = np.broadcast_to(arr, (n, N_LEGS))
    except ValueError:
        raise ValueError(f"{name}: expected shape ({n}, {N_LEGS}) or one broadcast to it, got {arr.shape}") from None
    return np.ascontiguousarray(arr)


def _rows(rows, n: int):
    """The rows a reset touches: all (None) or the given indices, checked."""
    if rows is None:
        return slice(None)
    index = np.asarray(rows, dtype=np.intp).reshape(-1)
    if index.size and (index.min() < -n or index.max() >= n):
        raise IndexError(f"rows: expected indices of a batch of {n}, got {index.tolist()[:5]}")
    return index


def _packed(keys: tuple[str, ...], values: dict) -> np.ndarray:
    """The packed row of `keys` (the compiled model's order) read from `values`."""
    return np.array([float(values[key]) for key in keys], dtype=np.float64)


class LagActuator:
    """A first-order lag from the command to the leg force, tau f_dot = u - f, stepped exactly
    with the command held over each step (tau = 0: the ideal force source, f = u).

    Args:
        n: rows (platforms).
        tau: the time constant, s, >= 0.

    Attributes:
        force: (n, 6) the leg forces, N (the state).

    Raises:
        UsageError: `n` or `tau` out of range (naming it).
    """

    def __init__(self, n: int = 1, tau: float = 0.0):
        self.n = _ROWS.check("n", n)
        self.tau = _TIME_CONSTANT.check("tau", tau)
        self.force = np.zeros((self.n, N_LEGS))

    def reset(self, rows=None, force=0.0) -> None:
        """Set the lag's state.

        Args:
            rows: the rows to set (None: all).
            force: the forces they start from, N (a scalar, a (6,) row or one per row).

        Raises:
            IndexError: a row outside the batch.
        """
        self.force[_rows(rows, self.n)] = force

    def step(self, command, dt: float) -> np.ndarray:
        """Advance by dt and return the leg forces (the state array itself).

        Args:
            command: (n, 6) force commands, N.
            dt: the step, s.

        Returns:
            The (n, 6) leg forces at the step's end, N.
        """
        _core.lag_step(self.tau, float(dt), _legs(command, "command", self.n), self.force)
        return self.force


class IdealActuator(LagActuator):
    """The ideal force source: the leg force is the command (a :class:`LagActuator` of tau = 0).

    Args:
        n: rows (platforms).

    Attributes:
        force: (n, 6) the leg forces, N.

    Raises:
        UsageError: `n` out of range.
    """

    def __init__(self, n: int = 1):
        super().__init__(n=n, tau=0.0)


class ElectricActuator:
    """Servo motors on ball screws, one per leg, in current control (docs/physics.md section 10.4).

    The current loop is a first-order lag of bandwidth omega_c towards the set point clipped to
    the current limit and, for a current with the leg's motion (motoring), to the voltage
    envelope (U - K_e |omega_m|) / R at the leg's rate (a braking current only to the limit); the
    leg force is eta k K_t i less the viscous and (tanh-smoothed) Coulomb friction.  The rotor's
    inertia is not in the force: it enters the dynamics as :attr:`reflected_mass`.

    Args:
        params: the drive's parameters (a platform's ``actuators.electric``).
        n: rows (platforms).

    Attributes:
        params: the parameters.
        screw: the ball screw (:class:`BallScrew`): ratio, reflected mass, force from current.
        current: (n, 6) the motor currents, A (the state).
        force: (n, 6) the last step's leg forces, N.

    Raises:
        UsageError: `n` out of range.
        TypeError: `params` not an ElectricParams.
    """

    def __init__(self, params: ElectricParams, n: int = 1):
        if not isinstance(params, ElectricParams):
            raise TypeError(f"params: expected an ElectricParams, got {type(params).__name__}")
        self.params = params
        self.n = _ROWS.check("n", n)
        self.screw = BallScrew.from_params(params)
        values = params.to_dict()
        values["ratio"] = self.screw.ratio
        self.packed = _packed(_core.ELECTRIC_KEYS, values)
        self.current = np.zeros((self.n, N_LEGS))
        self.force = np.zeros((self.n, N_LEGS))

    def reset(self, rows=None, current=0.0) -> None:
        """Set the motor currents.

        Args:
            rows: the rows to set (None: all).
            current: the currents they start from, A (a scalar, a (6,) row or one per row).

        Raises:
            IndexError: a row outside the batch.
        """
        self.current[_rows(rows, self.n)] = current

    @property
    def reflected_mass(self) -> float:
        """m_r = k^2 J_m, the rotor's inertia along each leg, kg (the dynamics' ``m_r``)."""
        return self.screw.reflected_mass

    @property
    def stall_force(self) -> float:
        """The largest leg force at rest (friction aside), eta k K_t i_max, N."""
        return float(self.screw.leg_force_from_current(self.params.current_limit))

    @property
    def no_load_speed(self) -> float:
        """U / (K_e k), the leg speed at which the back-EMF takes the whole bus voltage, m/s."""
        return float(self.screw.leg_velocity(self.params.bus_voltage / self.params.back_emf_constant))

    def current_from_torque(self, torque) -> np.ndarray:
        """The current set points i = tau_m / K_t of motor torque commands, A.

        Args:
            torque: motor torques, N m.
        """
        return np.asarray(torque, dtype=np.float64) / self.params.torque_constant

    def step(self, command, leg_velocity, dt: float) -> np.ndarray:
        """Advance the current loops by dt and return the leg forces.

        Args:
            command: (n, 6) current set points, A.
            leg_velocity: (n, 6) leg rates l_dot, m/s, held over the step.
            dt: the step, s.

        Returns:
            The (n, 6) leg forces at the step's end, N (the array ``force``).
        """
        _core.electric_step(
            self.packed,
            float(dt),
            _legs(command, "command", self.n),
            _legs(leg_velocity, "leg_velocity", self.n),
            self.current,
            self.force,
        )
        return self.force


class HydraulicActuator:
    """Valve-controlled single-rod cylinders, one per leg (Merritt 1967; docs/physics.md section 10.5).

    The spool follows its set point as a first-order lag of bandwidth omega_v; each chamber's
    pressure obeys dP/dt = beta / V(l) (Q - A l_dot -/+ leakage), Q through the open metering edge;
    the pressures are stepped by backward Euler (closed form), stable whatever the oil's stiffness,
    so `substeps` only refines the valve's and the orifices' accuracy.  The leg's motion is held
    over a step: the coupling with the mechanism is explicit, stable for omega_h dt < 2 (with the
    motion simulator's set, omega_h ~ 90 rad/s: any physics step below 20 ms).

    Args:
        params: the cylinder's parameters (a platform's ``actuators.hydraulic``).
        n: rows (platforms).
        substeps: steps of the valve and pressures per call.

    Attributes:
        params: the parameters.
        state: (n, 6, 3) spool position x_v, m, and chamber pressures P_A, P_B, Pa (the state);
            at first as :meth:`reset` leaves it: the spool centred, no net pressure force.
        force: (n, 6) the last step's leg forces, N.

    Raises:
        UsageError: `n` or `substeps` out of range.
        TypeError: `params` not a HydraulicParams.
    """

    def __init__(self, params: HydraulicParams, n: int = 1, substeps: int = 1):
        if not isinstance(params, HydraulicParams):
            raise TypeError(f"params: expected a HydraulicParams, got {type(params).__name__}")
        self.params = params
        self.n = _ROWS.check("n", n)
        self.substeps = _SUBSTEPS.check("substeps", substeps)
        values = params.to_dict()
        values.update(
            area_a=params.area_a,
            area_b=params.area_b,
            # K = C_d w sqrt(2 / rho): the orifice equation's constant per metre of spool
            orifice_gain=params.discharge_coefficient
            * params.valve_area_gradient
            * math.sqrt(2.0 / params.oil_density),
        )
        self.packed = _packed(_core.HYDRAULIC_KEYS, values)
        self.state = np.zeros((self.n, N_LEGS, 3))
        self.force = np.zeros((self.n, N_LEGS))
        self.reset()

    def reset(self, rows=None, force=0.0) -> None:
        """Centre the spools and set the chamber pressures that push with `force` around the
        mean of supply and return: P_A A_A - P_B A_B = force and P_A A_A + P_B A_B =
        P_m (A_A + A_B), P_m = (P_s + P_r) / 2 (a centred, critically lapped spool passes no flow,
        so these pressures stay).

        Args:
            rows: the rows to set (None: all).
            force: the pressure force each leg starts with, N (a scalar, a (6,) row or one per row).

        Raises:
            IndexError: a row outside the batch.
        """
        p = self.params
        total = 0.5 * (p.supply_pressure + p.return_pressure) * (p.area_a + p.area_b)
        force = np.asarray(force, dtype=np.float64)
        index = _rows(rows, self.n)
        self.state[index, :, 0] = 0.0
        self.state[index, :, 1] = (total + force) / (2.0 * p.area_a)
        self.state[index, :, 2] = (total - force) / (2.0 * p.area_b)

    def chamber_volumes(self, leg_length) -> tuple[np.ndarray, np.ndarray]:
        """The chambers' volumes (V_A, V_B) at leg lengths l, m^3 (the piston clipped to its stroke).

        Args:
            leg_length: leg lengths, m.
        """
        p = self.params
        x = np.clip(np.asarray(leg_length, dtype=np.float64) - p.retracted_length, 0.0, p.stroke)
        return p.dead_volume_a + p.area_a * x, p.dead_volume_b + p.area_b * (p.stroke - x)

    def natural_frequency(self, mass: float, leg_length) -> np.ndarray:
        """The hydraulic natural frequency omega_h = sqrt(beta (A_A^2 / V_A + A_B^2 / V_B) / m) of a
        mass m on the cylinder with its valve closed (the oil's two springs in parallel), rad/s.

        Args:
            mass: the moving mass, kg.
            leg_length: leg lengths, m.
        """
        p = self.params
        mass = _POSITIVE.check("mass", mass)
        V_A, V_B = self.chamber_volumes(leg_length)
        return np.sqrt(p.bulk_modulus * (p.area_a**2 / V_A + p.area_b**2 / V_B) / mass)

    def step(self, command, leg_length, leg_velocity, dt: float) -> np.ndarray:
        """Advance the valves and chambers by dt and return the leg forces.

        Args:
            command: (n, 6) spool set points over the spool's travel, clipped to [-1, 1].
            leg_length: (n, 6) leg lengths, m, held over the step.
            leg_velocity: (n, 6) leg rates, m/s, held over the step.
            dt: the step, s.

        Returns:
            The (n, 6) leg forces at the step's end, N (the array ``force``).
        """
        _core.hydraulic_step(
            self.packed,
            float(dt),
            self.substeps,
            _legs(command, "command", self.n),
            _legs(leg_length, "leg_length", self.n),
            _legs(leg_velocity, "leg_velocity", self.n),
            self.state,
            self.force,
        )
        return self.force


class LegServo:
    """The leg-length servo: command = (K_p (l_ref - l) - K_d l_dot + K_i integral) / g, the
    actuator's command for the force the law asks (docs/physics.md section 10.6).

    Args:
        stiffness: K_p, N/m, >= 0.
        damping: K_d, N s/m (may be negative where the leg's own friction damps enough).
        integral: K_i, N/(m s), >= 0.
        force_per_unit: g, the actuator's force per unit of command (eta k K_t for an electric
            current command, 1 for a force command), > 0.
        n: rows (platforms).

    Attributes:
        gains: (4,) K_p, K_d, K_i, g (the compiled law's order).
        integral_state: (n, 6) the integral of the length error, m s.

    Raises:
        UsageError: a gain or `n` out of range (naming it).
    """

    def __init__(self, stiffness: float, damping: float, integral: float = 0.0, force_per_unit: float = 1.0, n=1):
        self.n = _ROWS.check("n", n)
        stiffness = _NON_NEGATIVE.check("stiffness", stiffness)
        damping = Interval(numbers.Real, -1e12, 1e12).check("damping", damping)
        integral = _NON_NEGATIVE.check("integral", integral)
        force_per_unit = _POSITIVE.check("force_per_unit", force_per_unit)
        self.gains = np.array([stiffness, damping, integral, force_per_unit], dtype=np.float64)
        self.integral_state = np.zeros((self.n, N_LEGS))
        self.command = np.zeros((self.n, N_LEGS))

    def reset(self, rows=None) -> None:
        """Clear the error integral.

        Args:
            rows: the rows to clear (None: all).

        Raises:
            IndexError: a row outside the batch.
        """
        self.integral_state[_rows(rows, self.n)] = 0.0

    @classmethod
    def from_bandwidth(
        cls,
        bandwidth: float,
        damping_ratio: float,
        mass: float,
        viscous_friction: float = 0.0,
        force_per_unit: float = 1.0,
        n: int = 1,
    ) -> LegServo:
        """The servo that makes a leg of mass m (its share of the load plus the reflected mass)
        follow its set point with -3 dB bandwidth omega_b and damping ratio zeta: K_p = m omega_n^2,
        K_d = 2 zeta omega_n m - b, omega_n = omega_b / bandwidth_ratio(zeta).

        Args:
            bandwidth: omega_b, rad/s, > 0.
            damping_ratio: zeta, > 0.
            mass: m, kg, > 0.
            viscous_friction: b, the leg's own viscous friction, N s/m, >= 0.
            force_per_unit: g, N per unit of the actuator's command, > 0.
            n: rows.

        Returns:
            The servo.

        Raises:
            UsageError: an argument out of range (naming it).
        """
        gains = _core.servo_gains(
            _POSITIVE.check("bandwidth", bandwidth),
            _DAMPING_RATIO.check("damping_ratio", damping_ratio),
            _POSITIVE.check("mass", mass),
            _NON_NEGATIVE.check("viscous_friction", viscous_friction),
            _POSITIVE.check("force_per_unit", force_per_unit),
        )
        return cls(*gains, n=n)

    def step(self, setpoint, leg_length, leg_velocity, dt: float) -> np.ndarray:
        """The actuator's command for this step; the error's integral advanced by dt.

        Args:
            setpoint: (n, 6) leg-length set points l_ref, m.
            leg_length: (n, 6) leg lengths l, m.
            leg_velocity: (n, 6) leg rates l_dot, m/s.
            dt: the step, s.

        Returns:
            The (n, 6) commands (the array ``command``).
        """
        _core.leg_servo(
            self.gains,
            float(dt),
            _legs(setpoint, "setpoint", self.n),
            _legs(leg_length, "leg_length", self.n),
            _legs(leg_velocity, "leg_velocity", self.n),
            self.integral_state,
            self.command,
        )
        return self.command
