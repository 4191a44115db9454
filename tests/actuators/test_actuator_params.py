"""The actuators section of a platform config: read with the platform, written back, and every
non-physical value refused by its file and key."""

import dataclasses
import pickle

import pytest
import yaml

import stewart_env as se
from stewart_env.actuators import ActuatorSets, ElectricParams, HydraulicParams, load_actuators
from stewart_env.params import ConfigError, PlatformParams, config_dir

SHIPPED = config_dir("platforms") / "motion_simulator.yaml"


def test_the_motion_simulator_carries_both_sets():
    sets = load_actuators("motion_simulator")
    assert isinstance(sets.electric, ElectricParams) and isinstance(sets.hydraulic, HydraulicParams)
    assert sets.electric.lead == 0.025 and sets.hydraulic.supply_pressure == 2.1e7
    # back_emf_constant left out: K_e = K_t (SI)
    assert sets.electric.back_emf_constant == sets.electric.torque_constant == 1.95
    assert not load_actuators("dasgupta1998")  # no section: no sets


def test_the_sets_go_through_to_dict_replace_and_pickle():
    params = se.load_platform("motion_simulator")
    assert PlatformParams.from_dict(params.to_dict(), params.name) == params
    assert pickle.loads(pickle.dumps(params.actuators)) == params.actuators
    assert params.replace(actuators=ActuatorSets()).to_dict().get("actuators") is None
    assert "actuators" not in se.load_platform("dasgupta1998").to_dict()


def config_with(tmp_path, section, key, value):
    config = yaml.safe_load(SHIPPED.read_text())
    if value is None:
        del config["actuators"][section][key]
    else:
        config["actuators"][section][key] = value
    path = tmp_path / "platform.yaml"
    path.write_text(yaml.safe_dump(config))
    return path


@pytest.mark.parametrize(
    "section, key, value, refused_key, words",
    [
        ("electric", "lead", 0.0, "lead", "must be > 0"),
        ("electric", "rotor_inertia", -1e-3, "rotor_inertia", "must be >= 0"),
        ("electric", "current_limit", 0.0, "current_limit", "must be > 0"),
        ("electric", "efficiency", 1.2, "efficiency", "must be <= 1"),
        ("electric", "bus_voltage", "high", "bus_voltage", "must be a number"),
        ("electric", "winding_resistance", None, "", "missing key 'winding_resistance'"),
        ("electric", "speed", 1.0, "", "unknown key 'speed'"),
        ("hydraulic", "return_pressure", 2.5e7, "supply_pressure", "must be above return_pressure"),
        ("hydraulic", "rod_diameter", 0.08, "rod_diameter", "must be below bore_diameter"),
        ("hydraulic", "bulk_modulus", -1.4e9, "bulk_modulus", "must be > 0"),
        ("hydraulic", "dead_volume_a", 0.0, "dead_volume_a", "must be > 0"),
    ],
)
def test_a_non_physical_value_is_refused_by_file_and_key(tmp_path, section, key, value, refused_key, words):
    path = config_with(tmp_path, section, key, value)
    with pytest.raises(ConfigError) as err:
        PlatformParams.from_yaml(path)
    expected = f"actuators.{section}" + (f".{refused_key}" if refused_key else "")
    assert err.value.key == expected
    assert str(err.value).startswith(f"{path}: {expected}: ")
    assert words in str(err.value)


def test_a_stroke_short_of_the_leg_lengths_is_refused_by_its_key():
    params = se.load_platform("motion_simulator")
    params.actuators.check_stroke(params.limits.leg_length)  # the shipped set covers 2.26-3.66 m
    # limits may change after loading: a platform with a longer range still loads
    wider = params.replace(limits=dataclasses.replace(params.limits, leg_length=(2.0, 3.9)))
    with pytest.raises(ConfigError) as err:
        wider.actuators.check_stroke(wider.limits.leg_length)
    assert err.value.key == "hydraulic.stroke"
    assert "short of limits.leg_length [2.0, 3.9]" in str(err.value)


def test_an_unknown_actuator_set_lists_the_choices(tmp_path):
    config = yaml.safe_load(SHIPPED.read_text())
    config["actuators"]["pneumatic"] = {}
    path = tmp_path / "platform.yaml"
    path.write_text(yaml.safe_dump(config))
    with pytest.raises(ConfigError, match=r"actuators: unknown key 'pneumatic' \(expected 'electric', 'hydraulic'\)"):
        PlatformParams.from_yaml(path)
