"""The legs' actuator parameters, the ``actuators:`` section of a platform config: an electric
drive (servo motor and ball screw) and a valve-controlled hydraulic cylinder, each optional, SI
units, every key's range checked.

    actuators:
      electric:  {lead: m, gear_ratio: 1, efficiency: 0.9, torque_constant: N m/A, ...}
      hydraulic: {bore_diameter: m, rod_diameter: m, supply_pressure: Pa, ...}

:class:`ElectricParams` and :class:`HydraulicParams` list each key with its unit and range
(docs/physics.md section 10.7 is their reference table, section 10 their equations).
A value out of its range is a :class:`~stewart_env.params.ConfigError` naming its key, e.g.
``actuators.electric.lead: must be > 0 (a screw advances), got 0.0``.
"""

# Annotations are evaluated here, not postponed: the classes are shown and pickled under
# stewart_env.params, whose namespace could not resolve their names for typing.get_type_hints.

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass

from stewart_env.params.bodies import _ValueObject, set_field
from stewart_env.params.checks import ConfigError, mapping, number, within

__all__ = ["ElectricParams", "HydraulicParams", "ActuatorSets", "actuator_sets_from_config"]


# (key, low, high, low included, why the low bound) of each key: the ranges a value is checked against
_ELECTRIC_RANGES = {
    "lead": (0.0, 1.0, False, "a screw advances"),
    "gear_ratio": (0.0, 1000.0, False, "a gear turns the screw"),
    "efficiency": (0.0, 1.0, False, "some power reaches the leg"),
    "torque_constant": (0.0, 1000.0, False, "current makes torque"),
    "rotor_inertia": (0.0, 1000.0, True, "an inertia is not negative"),
    "back_emf_constant": (0.0, 1000.0, False, "a turning motor makes a voltage"),
    "current_limit": (0.0, 1e5, False, "a drive passes some current"),
    "current_bandwidth": (0.0, 1e7, False, "the current loop responds"),
    "bus_voltage": (0.0, 1e5, False, "the bus drives current"),
    "winding_resistance": (0.0, 1e3, False, "a winding has resistance"),
    "viscous_friction": (0.0, 1e9, True, "friction does not push"),
    "coulomb_friction": (0.0, 1e9, True, "friction does not push"),
    "friction_speed": (0.0, 1e3, False, "the speed scale of the friction's tanh"),
}
_HYDRAULIC_RANGES = {
    "bore_diameter": (0.0, 10.0, False, "a cylinder has a bore"),
    "rod_diameter": (0.0, 10.0, True, "a diameter is not negative"),
    "stroke": (0.0, 100.0, False, "a piston moves"),
    "retracted_length": (0.0, 100.0, False, "a leg has a length"),
    "dead_volume_a": (0.0, 10.0, False, "a chamber keeps some oil at the end of its stroke"),
    "dead_volume_b": (0.0, 10.0, False, "a chamber keeps some oil at the end of its stroke"),
    "supply_pressure": (0.0, 1e9, False, "the pump delivers pressure"),
    "return_pressure": (0.0, 1e9, True, "an absolute pressure is not negative"),
    "bulk_modulus": (0.0, 1e11, False, "oil is compressible, not a vacuum"),
    "oil_density": (0.0, 1e5, False, "oil has mass"),
    "discharge_coefficient": (0.0, 1.0, False, "an orifice passes flow"),
    "valve_area_gradient": (0.0, 10.0, False, "a metering edge opens"),
    "valve_max_opening": (0.0, 1.0, False, "a spool moves"),
    "valve_bandwidth": (0.0, 1e7, False, "the valve responds"),
    "internal_leakage": (0.0, 1.0, True, "a leak does not pump"),
    "external_leakage": (0.0, 1.0, True, "a leak does not pump"),
    "viscous_friction": (0.0, 1e9, True, "friction does not push"),
    "coulomb_friction": (0.0, 1e9, True, "friction does not push"),
    "friction_speed": (0.0, 1e3, False, "the speed scale of the friction's tanh"),
}


def _checked(obj: object, ranges: Mapping) -> None:
    """Check each field of `obj` against its range in `ranges`, storing it as a float."""
    for name, (low, high, closed, why) in ranges.items():
        value = number(getattr(obj, name), name)
        if value < low or (value == low and not closed):
            raise ConfigError(name, f"must be {'>=' if closed else '>'} {low:g} ({why}), got {value}")
        if value > high:
            raise ConfigError(name, f"must be <= {high:g}, got {value}")
        set_field(obj, name, value)


@dataclass(frozen=True, eq=False)
class ElectricParams(_ValueObject):
    """An electric leg: a servo motor turning a ball screw through a gear, SI units.

    Attributes:
        lead: p, leg travel per screw revolution, m, in (0, 1].
        gear_ratio: N, motor revolutions per screw revolution, in (0, 1000].
        efficiency: eta, the screw's and gear's, in (0, 1].
        torque_constant: K_t, N m/A, in (0, 1000].
        rotor_inertia: J_m, the rotor's and screw's about the motor axis, kg m^2, in [0, 1000].
        current_limit: i_max, the drive's peak current, A, in (0, 1e5].
        current_bandwidth: omega_c, the current loop's bandwidth, rad/s, in (0, 1e7].
        bus_voltage: U, the drive's DC bus, V, in (0, 1e5].
        winding_resistance: R, ohm, in (0, 1e3].
        viscous_friction: b, on the leg, N s/m, in [0, 1e9].
        coulomb_friction: f_c, on the leg, N, in [0, 1e9].
        friction_speed: v_s, the speed scale of the Coulomb friction's tanh, m/s, in (0, 1e3].
        back_emf_constant: K_e, V s/rad, in (0, 1000]; None (the config leaves it out): K_t, which
            it equals in SI units for a motor of sinusoidal back-EMF.

    Raises:
        ConfigError: a value out of its range (the message names the key).
    """

    lead: float
    gear_ratio: float
    efficiency: float
    torque_constant: float
    rotor_inertia: float
    current_limit: float
    current_bandwidth: float
    bus_voltage: float
    winding_resistance: float
    viscous_friction: float
    coulomb_friction: float
    friction_speed: float
    back_emf_constant: float | None = None

    def __post_init__(self) -> None:
        if self.back_emf_constant is None:
            set_field(self, "back_emf_constant", self.torque_constant)
        _checked(self, _ELECTRIC_RANGES)

    @classmethod
    def from_dict(cls, d: Mapping) -> "ElectricParams":
        """From a config mapping of the attributes' keys (``back_emf_constant`` optional).

        Args:
            d: the mapping (see the class docstring for the units).

        Raises:
            ConfigError: a missing or unknown key, or a value out of its range.
        """
        names = [f.name for f in dataclasses.fields(cls)]
        d = mapping(d, "", names[:-1], names[-1:])
        return cls(**d)

    def to_dict(self) -> dict:
        """The config mapping of :meth:`from_dict`, every key written."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}


@dataclass(frozen=True, eq=False)
class HydraulicParams(_ValueObject):
    """A valve-controlled single-rod cylinder (Merritt 1967), SI units; pressures absolute.

    Attributes:
        bore_diameter: D, m, in (0, 10]: piston area A_A = pi D^2 / 4.
        rod_diameter: d, m, in [0, D): annulus area A_B = pi (D^2 - d^2) / 4.
        stroke: s, m, in (0, 100].
        retracted_length: l_0, the leg's length with the piston at the retracted end, m, in
            (0, 100]; :meth:`ActuatorSets.check_stroke` checks that [l_0, l_0 + s] covers a
            platform's limits.leg_length.
        dead_volume_a: V_A0, chamber A's oil at the retracted end with its line, m^3, in (0, 10].
        dead_volume_b: V_B0, chamber B's oil at the extended end with its line, m^3, in (0, 10].
        supply_pressure: P_s, Pa, in (0, 1e9].
        return_pressure: P_r, Pa, in [0, P_s).
        bulk_modulus: beta, the effective one (entrained air and hoses included), Pa, in (0, 1e11].
        oil_density: rho, kg/m^3, in (0, 1e5].
        discharge_coefficient: C_d, in (0, 1].
        valve_area_gradient: w, the metering edges' width, m, in (0, 10].
        valve_max_opening: x_max, the spool's travel, m, in (0, 1].
        valve_bandwidth: omega_v, the servo valve's first-order bandwidth, rad/s, in (0, 1e7].
        internal_leakage: C_il, across the piston, m^3/(s Pa), in [0, 1].
        external_leakage: C_el, out of each chamber, m^3/(s Pa), in [0, 1].
        viscous_friction: b, N s/m, in [0, 1e9].
        coulomb_friction: f_c, N, in [0, 1e9].
        friction_speed: v_s, m/s, in (0, 1e3].

    Raises:
        ConfigError: a value out of its range (the message names the key).
    """

    bore_diameter: float
    rod_diameter: float
    stroke: float
    retracted_length: float
    dead_volume_a: float
    dead_volume_b: float
    supply_pressure: float
    return_pressure: float
    bulk_modulus: float
    oil_density: float
    discharge_coefficient: float
    valve_area_gradient: float
    valve_max_opening: float
    valve_bandwidth: float
    internal_leakage: float
    external_leakage: float
    viscous_friction: float
    coulomb_friction: float
    friction_speed: float

    def __post_init__(self) -> None:
        _checked(self, _HYDRAULIC_RANGES)
        if not self.rod_diameter < self.bore_diameter:
            raise ConfigError(
                "rod_diameter", f"must be below bore_diameter {self.bore_diameter}, got {self.rod_diameter}"
            )
        if not self.return_pressure < self.supply_pressure:
            raise ConfigError(
                "supply_pressure",
                f"must be above return_pressure {self.return_pressure}, got {self.supply_pressure}",
            )

    @property
    def area_a(self) -> float:
        """A_A = pi D^2 / 4, the piston side's area, m^2."""
        return math.pi * self.bore_diameter**2 / 4.0

    @property
    def area_b(self) -> float:
        """A_B = pi (D^2 - d^2) / 4, the rod side's (annulus) area, m^2."""
        return math.pi * (self.bore_diameter**2 - self.rod_diameter**2) / 4.0

    @classmethod
    def from_dict(cls, d: Mapping) -> "HydraulicParams":
        """From a config mapping of the attributes' keys.

        Args:
            d: the mapping (see the class docstring for the units).

        Raises:
            ConfigError: a missing or unknown key, or a value out of its range.
        """
        d = mapping(d, "", [f.name for f in dataclasses.fields(cls)])
        return cls(**d)

    def to_dict(self) -> dict:
        """The config mapping of :meth:`from_dict`."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}


@dataclass(frozen=True, eq=False)
class ActuatorSets(_ValueObject):
    """The actuator parameter sets of a platform, each None where its config gives none.

    Attributes:
        electric: the electric drive's, or None.
        hydraulic: the hydraulic cylinder's, or None.

    Raises:
        ConfigError: a set of another type (naming it).
    """

    electric: ElectricParams | None = None
    hydraulic: HydraulicParams | None = None

    def __post_init__(self) -> None:
        for name, cls in (("electric", ElectricParams), ("hydraulic", HydraulicParams)):
            value = getattr(self, name)
            if value is not None and not isinstance(value, cls):
                raise ConfigError(name, f"must be a {cls.__name__} or None, got a {type(value).__name__}")

    def __bool__(self) -> bool:
        return self.electric is not None or self.hydraulic is not None

    def to_dict(self) -> dict:
        """The config mapping (the ``actuators:`` section) of the sets given."""
        return {name: getattr(self, name).to_dict() for name in ("electric", "hydraulic") if getattr(self, name)}

    def check_stroke(self, leg_length: tuple[float, float]) -> None:
        """Check that the hydraulic cylinder's stroke covers a platform's leg-length range: what a
        platform driven by the cylinder needs (its limits may change after loading, so loading
        does not ask it).

        Args:
            leg_length: (min, max) of the platform's limits.leg_length, m.

        Raises:
            ConfigError: a range outside [retracted_length, retracted_length + stroke], naming
                ``hydraulic.stroke``.
        """
        cylinder = self.hydraulic
        if cylinder is None:
            return
        lo, hi = cylinder.retracted_length, cylinder.retracted_length + cylinder.stroke
        slack = 1e-9 * hi  # the sum's rounding: a stroke that ends exactly at the limit covers it
        if leg_length[0] < lo - slack or leg_length[1] > hi + slack:
            raise ConfigError(
                "hydraulic.stroke",
                f"the cylinder spans [{lo}, {hi}] m (retracted_length, + stroke), "
                f"short of limits.leg_length [{leg_length[0]}, {leg_length[1]}]",
            )


def actuator_sets_from_config(value: object) -> ActuatorSets:
    """The actuator sets of a config's ``actuators:`` mapping ({electric: .., hydraulic: ..}, each
    optional).

    Args:
        value: the raw mapping.

    Returns:
        The checked sets.

    Raises:
        ConfigError: an unknown or missing key, or a value out of its range, named by its path
            below ``actuators`` (e.g. ``electric.lead``; the platform's reader puts it under
            ``actuators``).
    """
    d = mapping(value, "", (), ("electric", "hydraulic"))
    sets = {}
    for name, cls in (("electric", ElectricParams), ("hydraulic", HydraulicParams)):
        if name in d:
            with within(name):
                sets[name] = cls.from_dict(d[name])
    return ActuatorSets(**sets)
