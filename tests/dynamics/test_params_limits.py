"""Tests of the optional limits of a platform's config (stewart_env.params: Limits and the reader):
leg velocity, leg acceleration, force rate and the joints' cone angles."""

import copy
import dataclasses
import math
import pickle

import numpy as np
import pytest

from stewart_env.params import ConfigError, Limits, PlatformParams, load_platform

NEW_KEYS = ("leg_velocity", "leg_acceleration", "force_rate", "universal_joint", "spherical_joint")


def config_with(platform: str, **limits) -> dict:
    """The platform's config with the given entries of `limits` set (None: removed)."""
    config = load_platform(platform).to_dict()
    for key, value in limits.items():
        if value is None:
            config["limits"].pop(key, None)
        else:
            config["limits"][key] = value
    return config


def test_absent_keys_are_no_limits_and_leave_the_config_as_it_was(dasgupta):
    lim = dasgupta.limits
    assert lim.max_leg_velocity == lim.max_leg_acceleration == lim.max_force_rate == math.inf
    assert lim.max_universal_angle == lim.max_spherical_angle == math.inf
    np.testing.assert_array_equal(lim.universal_axes, np.tile([0.0, 0.0, 1.0], (6, 1)))
    np.testing.assert_array_equal(lim.spherical_axes, np.tile([0.0, 0.0, 1.0], (6, 1)))
    # The saved config of a platform without them has none of the new keys, as before.
    assert not set(NEW_KEYS) & set(dasgupta.to_dict()["limits"])
    assert PlatformParams.from_dict(dasgupta.to_dict(), dasgupta.name) == dasgupta


def test_the_motion_simulator_ships_its_bounds(simulator):
    lim = simulator.limits
    assert (lim.max_leg_velocity, lim.max_leg_acceleration, lim.max_force_rate) == (0.8, 8.0, 2.0e6)
    assert (lim.max_universal_angle, lim.max_spherical_angle) == (0.61, 0.70)
    # the axes are the legs' home directions: every cone angle is 0 there (to the axes' 6 printed digits)
    legs = simulator.home_position + simulator.platform_joints - simulator.base_joints
    e = legs / np.linalg.norm(legs, axis=1)[:, None]
    np.testing.assert_allclose(lim.universal_axes, e, atol=2e-6)
    np.testing.assert_array_equal(lim.spherical_axes, lim.universal_axes)
    np.testing.assert_allclose(np.linalg.norm(lim.universal_axes, axis=1), 1.0, rtol=1e-15)
    assert PlatformParams.from_dict(simulator.to_dict(), simulator.name) == simulator
    assert pickle.loads(pickle.dumps(simulator)) == simulator


def test_given_bounds_round_trip_and_shared_axes_are_normalised():
    config = config_with(
        "dasgupta1998",
        leg_velocity=0.5,
        force_rate=1.0e4,
        universal_joint={"max_angle": 1.2},
        spherical_joint={"max_angle": 1.3, "axes": [0.0, 0.0, 2.0]},
    )
    params = PlatformParams.from_dict(config, "custom")
    lim = params.limits
    assert (lim.max_leg_velocity, lim.max_leg_acceleration, lim.max_force_rate) == (0.5, math.inf, 1.0e4)
    np.testing.assert_array_equal(lim.spherical_axes, np.tile([0.0, 0.0, 1.0], (6, 1)))
    saved = lim.to_dict()
    assert saved["universal_joint"] == {"max_angle": 1.2} and "leg_acceleration" not in saved
    assert PlatformParams.from_dict(params.to_dict(), "custom") == params
    assert copy.deepcopy(lim) == lim and hash(lim) != hash(load_platform("dasgupta1998").limits)


@pytest.mark.parametrize(
    ("limits", "message"),
    [
        ({"leg_velocity": 0.0}, r"^limits\.leg_velocity: must be > 0, got 0\.0$"),
        ({"leg_acceleration": -8.0}, r"^limits\.leg_acceleration: must be > 0, got -8\.0$"),
        ({"force_rate": "fast"}, r"^limits\.force_rate: must be a number, got 'fast'"),
        ({"force_rate": math.inf}, r"^limits\.force_rate: not a finite number \(inf\); leave the key out"),
        ({"leg_velocity": True}, r"^limits\.leg_velocity: must be a number, got True"),
        ({"universal_joint": {"max_angle": 4.0}}, r"^limits\.universal_joint\.max_angle: must be in \(0, pi\] rad"),
        ({"spherical_joint": {"max_angle": 0.0}}, r"^limits\.spherical_joint\.max_angle: must be > 0"),
        ({"spherical_joint": {"max_angle": math.nan}}, r"^limits\.spherical_joint\.max_angle: not a finite number"),
        ({"universal_joint": {"maxangle": 1.0}}, r"^limits\.universal_joint: unknown key 'maxangle'"),
        (
            {
                "universal_joint": {
                    "max_angle": 1.2,
                    "axes": [[0.0, 0.0, 1.0]] * 2 + [[0.0, 0.0, 0.0]] + [[0, 0, 1.0]] * 3,
                }
            },
            r"^limits\.universal_joint\.axes\[2\]: zero vector$",
        ),
        ({"spherical_joint": {"axes": [[0.0, 1.0]]}}, r"^limits\.spherical_joint\.axes: expected shape"),
        ({"universal_joint": [1.0]}, r"^limits\.universal_joint: "),
    ],
)
def test_bad_values_name_their_key(limits, message):
    with pytest.raises(ConfigError, match=message):
        PlatformParams.from_dict(config_with("dasgupta1998", **limits))


def test_the_home_pose_must_lie_inside_every_cone():
    # dasgupta1998's legs lean 61.6 deg from the vertical at home (arccos(0.6 / 1.2613)).
    config = config_with("dasgupta1998", universal_joint={"max_angle": 1.0})
    with pytest.raises(
        ConfigError,
        match=r"^limits\.universal_joint\.max_angle: leg 0 is 61\.6 deg from its mounting axis at the home pose, "
        r"above 57\.3 deg$",
    ):
        PlatformParams.from_dict(config)
    config = config_with("dasgupta1998", spherical_joint={"max_angle": 1.05})
    with pytest.raises(ConfigError, match=r"^limits\.spherical_joint\.max_angle: leg 0 is 61\.6 deg"):
        PlatformParams.from_dict(config)
    assert PlatformParams.from_dict(config_with("dasgupta1998", spherical_joint={"max_angle": 1.1}))


def test_direct_construction_checks_the_new_fields(dasgupta):
    lim = dasgupta.limits
    with pytest.raises(ConfigError, match=r"^leg_velocity: must be > 0, got -1\.0$"):
        dataclasses.replace(lim, max_leg_velocity=-1.0)
    with pytest.raises(ConfigError, match=r"^spherical_joint\.axes: expected shape \(6, 3\) or \(3,\)"):
        dataclasses.replace(lim, spherical_axes=np.ones((5, 3)))
    # the limits a platform is given are checked against its home pose too
    with pytest.raises(ConfigError, match=r"^limits\.spherical_joint\.max_angle: leg 0 is 61\.6 deg"):
        dasgupta.replace(limits=dataclasses.replace(lim, max_spherical_angle=0.5))
    assert isinstance(dataclasses.replace(lim, max_force_rate=5.0), Limits)
