"""The ball-screw transmission: hand cases and refused constants."""

import math

import pytest

from stewart_env.actuators import BallScrew
from stewart_env.errors import UsageError


def test_reflected_mass_and_force_of_a_hand_case():
    """A 10 mm lead, 2:1 gear, 90 % efficient screw with a 1e-3 kg m^2 rotor and K_t = 0.5 N m/A."""
    screw = BallScrew(lead=0.01, gear_ratio=2.0, efficiency=0.9, torque_constant=0.5, rotor_inertia=1e-3)
    k = 2 * math.pi * 2.0 / 0.01  # 1256.637... rad/m
    assert screw.ratio == pytest.approx(k, rel=1e-15)  # rounding of one product and quotient
    assert screw.reflected_mass == pytest.approx(1579.1367041742973, rel=1e-14)  # k^2 J_m by hand
    assert float(screw.leg_force_from_current(10.0)) == pytest.approx(0.9 * k * 0.5 * 10.0, rel=1e-15)
    assert float(screw.current_from_leg_force(screw.leg_force_from_current(7.0))) == pytest.approx(7.0, rel=1e-15)
    assert float(screw.motor_speed(0.1)) == pytest.approx(k * 0.1, rel=1e-15)


@pytest.mark.parametrize(
    "key, value",
    [
        ("lead", 0.0),
        ("gear_ratio", -1.0),
        ("efficiency", 1.5),
        ("torque_constant", float("nan")),
        ("rotor_inertia", -1e-3),
    ],
)
def test_non_physical_constants_are_refused_by_name(key, value):
    kwargs = {"lead": 0.01, key: value}
    with pytest.raises(UsageError) as info:
        BallScrew(**kwargs)
    assert info.value.argument == key
