"""The ball-screw drive of an electric leg: motor torque and speed to leg force and velocity.

A motor turns a ball screw of lead ``p`` (metres of travel per screw revolution) through a gear
of ratio ``N`` (motor revolutions per screw revolution).  The leg's extension speed
``l_dot`` and the motor's speed ``omega_m`` are tied by the transmission ratio

    k = 2 pi N / p        [rad of motor per metre of leg],   omega_m = k l_dot,

and, with the drive's efficiency ``eta``, a motor torque ``tau_m`` pushes the leg with
``f = eta k tau_m`` (power in, less the screw's and gear's losses).  A motor of rotor inertia
``J_m`` is then seen along the leg's prismatic axis as the reflected mass ``m_r = k^2 J_m``
(its kinetic energy ``J_m omega_m^2 / 2 = m_r l_dot^2 / 2``).  A torque constant ``K_t`` turns
the motor's q-axis current into torque: ``tau_m = K_t i_q``.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

from stewart_env.validation import Interval

_POSITIVE = Interval(numbers.Real, 0.0, 1e12, low_open=True)
_FRACTION = Interval(numbers.Real, 0.0, 1.0, low_open=True)
_NON_NEGATIVE = Interval(numbers.Real, 0.0, 1e12)


@dataclass(frozen=True)
class BallScrew:
    """A ball-screw drive's constants, SI units.

    Attributes:
        lead: p, leg travel per screw revolution, m/rev (> 0).
        gear_ratio: N, motor revolutions per screw revolution (> 0; 1 for a direct drive).
        efficiency: eta, the fraction of the motor's power that reaches the leg, in (0, 1].
        torque_constant: K_t, motor torque per ampere of q-axis current, N m/A (> 0).
        rotor_inertia: J_m, the rotor's (and the screw's, referred to the motor) moment of
            inertia about its axis, kg m^2 (>= 0).
    """

    lead: float
    gear_ratio: float = 1.0
    efficiency: float = 1.0
    torque_constant: float = 1.0
    rotor_inertia: float = 0.0

    def __post_init__(self) -> None:
        """Check each constant's range, naming it."""
        for name, constraint in (
            ("lead", _POSITIVE),
            ("gear_ratio", _POSITIVE),
            ("efficiency", _FRACTION),
            ("torque_constant", _POSITIVE),
            ("rotor_inertia", _NON_NEGATIVE),
        ):
            object.__setattr__(self, name, constraint.check(name, getattr(self, name)))

    @classmethod
    def from_params(cls, params) -> BallScrew:
        """The screw of an electric leg's parameter set.

        Args:
            params: an :class:`~stewart_env.params.ElectricParams` (a platform config's
                ``actuators.electric``).

        Returns:
            Its lead, gear ratio, efficiency, torque constant and rotor inertia as a BallScrew.
        """
        return cls(
            lead=params.lead,
            gear_ratio=params.gear_ratio,
            efficiency=params.efficiency,
            torque_constant=params.torque_constant,
            rotor_inertia=params.rotor_inertia,
        )

    @property
    def ratio(self) -> float:
        """The transmission ratio k = 2 pi N / p, in motor radians per metre of leg travel."""
        return 2.0 * math.pi * self.gear_ratio / self.lead

    @property
    def reflected_mass(self) -> float:
        """The reflected mass m_r = k^2 J_m, kg, the rotor's inertia seen along the leg's prismatic axis."""
        return self.ratio**2 * self.rotor_inertia

    def motor_speed(self, leg_velocity):
        """The motor's speed omega_m = k l_dot, rad/s.

        Args:
            leg_velocity: leg extension speeds l_dot, m/s.
        """
        return self.ratio * np.asarray(leg_velocity, dtype=float)

    def leg_velocity(self, motor_speed):
        """The leg's extension speed l_dot = omega_m / k, m/s: the inverse of :meth:`motor_speed`.

        Args:
            motor_speed: motor speeds omega_m, rad/s.
        """
        return np.asarray(motor_speed, dtype=float) / self.ratio

    def leg_force_from_torque(self, motor_torque):
        """The leg force f = eta k tau_m, N.

        Args:
            motor_torque: motor torques tau_m, N m.
        """
        return self.efficiency * self.ratio * np.asarray(motor_torque, dtype=float)

    def leg_force_from_current(self, current):
        """The leg force f = eta k K_t i_q, N.

        Args:
            current: q-axis currents i_q, A.
        """
        return self.leg_force_from_torque(self.torque_constant * np.asarray(current, dtype=float))

    def current_from_leg_force(self, leg_force):
        """The q-axis current i_q = f / (eta k K_t), A: the inverse of :meth:`leg_force_from_current`.

        Args:
            leg_force: leg forces f, N.
        """
        return np.asarray(leg_force, dtype=float) / (self.efficiency * self.ratio * self.torque_constant)
