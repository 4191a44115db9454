"""Tests of stewart_env.params: the config schema, defaults, immutability and validation."""

import copy
import dataclasses
import pickle
from pathlib import Path

import numpy as np
import pytest
import yaml

from stewart_env.params import (
    ConfigError,
    Damping,
    Limits,
    PlatformParams,
    RigidBody,
    available_platforms,
    load_platform,
)
from stewart_env.rotations import rpy_to_matrix

pytestmark = pytest.mark.physics

CONFIG_DIR = Path(__file__).resolve().parents[2] / "configs" / "platforms"
SHIPPED = ("dasgupta1998", "motion_simulator")


@pytest.fixture(scope="module")
def dasgupta_config():
    with open(CONFIG_DIR / "dasgupta1998.yaml", encoding="utf-8") as f:
        return yaml.safe_load(f)


@pytest.fixture
def config(dasgupta_config):
    """A fresh, valid config dict to mutate."""
    return copy.deepcopy(dasgupta_config)


def home_legs(params):
    """(6, 3) leg vectors S_i at the home pose, in {B}."""
    rotation = rpy_to_matrix(params.home_rpy)
    return params.home_position + params.platform_joints @ rotation.T - params.base_joints


def physical_keys(config):
    """The config without the environment's keys: the physical parameters alone."""
    return {k: v for k, v in config.items() if k not in ("limits", "home")}


# ---------------------------------------------------------------------------------------------
# Loading and round trips


@pytest.mark.parametrize("name", SHIPPED)
def test_load_by_name_and_by_path_agree(name):
    by_name = load_platform(name)
    by_str_path = load_platform(str(CONFIG_DIR / f"{name}.yaml"))
    by_path = load_platform(CONFIG_DIR / f"{name}.yaml")
    assert by_name.name == by_path.name == name
    assert by_name == by_str_path == by_path
    assert name in available_platforms()


def test_unknown_platform_name_lists_the_available_ones():
    with pytest.raises(ValueError, match=r"unknown platform 'no_such_robot'.*dasgupta1998.*motion_simulator"):
        load_platform("no_such_robot")


def test_missing_file_is_not_taken_for_a_name(tmp_path):
    with pytest.raises(ConfigError, match=r"dasgupta1998\.yaml: cannot read the file: No such file"):
        load_platform(tmp_path / "dasgupta1998.yaml")


@pytest.mark.parametrize("name", SHIPPED)
def test_round_trip_through_dict_and_yaml(name, tmp_path):
    params = load_platform(name)
    d = params.to_dict()
    assert PlatformParams.from_dict(d, name=name) == params
    # Plain Python types only: safe_dump refuses numpy scalars and arrays.
    path = tmp_path / f"{name}_copy.yaml"
    path.write_text(yaml.safe_dump(d), encoding="utf-8")
    again = PlatformParams.from_yaml(path)
    assert again.name == f"{name}_copy"
    assert again.replace(name=name) == params
    assert hash(again.replace(name=name)) == hash(params)


def test_dasgupta_values_match_the_paper(dasgupta_config):
    params = load_platform("dasgupta1998")
    assert params.platform.mass == 40.0
    np.testing.assert_array_equal(params.platform.com, [0.04, 0.03, -0.06])
    np.testing.assert_array_equal(params.upper_leg[5].com, [-0.6, -0.08, 0.08])
    np.testing.assert_array_equal(params.lower_leg[0].com, [0.4, 0.14, -0.18])
    assert (params.damping.universal, params.damping.prismatic, params.damping.spherical) == (1e-4, 1e-3, 2e-4)
    np.testing.assert_allclose(np.linalg.norm(home_legs(params), axis=1), 1.262, atol=1e-3)


def test_dasgupta_case_pose_lies_inside_the_stroke():
    params = load_platform("dasgupta1998")
    legs = np.array([0.1, 0.0, 0.4]) + params.platform_joints @ rpy_to_matrix([0, 0, -0.2]).T - params.base_joints
    lengths = np.linalg.norm(legs, axis=1)
    lo, hi = params.limits.leg_length
    assert np.all((lo < lengths) & (lengths < hi))
    np.testing.assert_allclose([lengths.min(), lengths.max()], [1.09, 1.43], atol=5e-3)


def test_motion_simulator_is_well_conditioned_at_home():
    params = load_platform("motion_simulator")
    legs = home_legs(params)
    lengths = np.linalg.norm(legs, axis=1)
    e = legs / lengths[:, None]
    jacobian = np.hstack([e, np.cross(params.platform_joints @ rpy_to_matrix(params.home_rpy).T, e)])
    np.testing.assert_allclose(lengths, 2.9609, atol=1e-4)
    assert np.linalg.cond(jacobian) < 10
    np.testing.assert_allclose(np.linalg.norm(params.hooke_axes, axis=1), 1.0, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(params.hooke_axes[:, 2], 0.0)


def test_pickle_keeps_value_and_read_only_arrays():
    params = load_platform("motion_simulator")
    clone = pickle.loads(pickle.dumps(params))
    assert clone == params
    assert not clone.base_joints.flags.writeable
    assert not clone.upper_leg[0].inertia.flags.writeable


# ---------------------------------------------------------------------------------------------
# Immutability


def test_attributes_cannot_be_assigned():
    params = load_platform("dasgupta1998")
    with pytest.raises(dataclasses.FrozenInstanceError):
        params.name = "other"
    with pytest.raises(dataclasses.FrozenInstanceError):
        params.platform.mass = 1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        params.limits.max_angle = 1.0


@pytest.mark.parametrize(
    "getter",
    [
        lambda p: p.base_joints,
        lambda p: p.platform_joints,
        lambda p: p.hooke_axes,
        lambda p: p.gravity,
        lambda p: p.home_position,
        lambda p: p.home_rpy,
        lambda p: p.platform.com,
        lambda p: p.platform.inertia,
        lambda p: p.upper_leg[2].inertia,
        lambda p: p.lower_leg[4].com,
        lambda p: p.limits.position_min,
        lambda p: p.limits.position_max,
    ],
)
def test_arrays_are_float64_and_read_only(getter):
    arr = getter(load_platform("dasgupta1998"))
    assert arr.dtype == np.float64
    with pytest.raises(ValueError, match="read-only"):
        arr[0] = 1.0
    with pytest.raises(ValueError):
        arr.setflags(write=True)


def test_caller_arrays_are_copied():
    com = np.array([0.0, 0.0, 0.1])
    body = RigidBody(mass=1.0, com=com, inertia=[1.0, 1.0, 1.0])
    com[2] = 5.0
    assert body.com[2] == 0.1


# ---------------------------------------------------------------------------------------------
# Shared and per-leg parameters, shorthands, defaults


def test_shared_leg_mapping_is_used_by_all_six_legs():
    params = load_platform("dasgupta1998")
    assert len(params.upper_leg) == len(params.lower_leg) == 6
    assert all(body == params.upper_leg[0] for body in params.upper_leg)
    assert isinstance(params.to_dict()["upper_leg"], dict)


def test_six_leg_list_keeps_each_leg(config):
    legs = [dict(config["lower_leg"], mass=3.0 + i) for i in range(6)]
    config["lower_leg"] = legs
    params = PlatformParams.from_dict(config)
    assert [body.mass for body in params.lower_leg] == [3.0, 4.0, 5.0, 6.0, 7.0, 8.0]
    assert isinstance(params.to_dict()["lower_leg"], list)
    assert PlatformParams.from_dict(params.to_dict()) == params


def test_diagonal_inertia_shorthand_equals_the_full_matrix(config):
    short = PlatformParams.from_dict(config)
    config["upper_leg"]["inertia"] = [[0.0006, 0, 0], [0, 0.06, 0], [0, 0, 0.06]]
    full = PlatformParams.from_dict(config)
    assert short == full
    np.testing.assert_array_equal(short.upper_leg[0].inertia, np.diag([0.0006, 0.06, 0.06]))


def test_hooke_axes_shared_row_is_broadcast_and_normalised(config):
    config["hooke_axes"] = [0.0, 0.0, 2.0]
    params = PlatformParams.from_dict(config)
    np.testing.assert_array_equal(params.hooke_axes, np.tile([0.0, 0.0, 1.0], (6, 1)))


def test_defaults_without_limits_home_and_gravity(config):
    d = physical_keys(config)
    del d["gravity"]
    params = PlatformParams.from_dict(d)
    np.testing.assert_array_equal(params.gravity, [0.0, 0.0, -9.81])
    np.testing.assert_array_equal(params.home_position, 0.0)
    np.testing.assert_array_equal(params.home_rpy, 0.0)
    lengths = np.linalg.norm(home_legs(params), axis=1)
    np.testing.assert_allclose(params.limits.leg_length, (0.8 * lengths.min(), 1.2 * lengths.max()))
    leg_weight = (40.0 + 6 * (1.0 + 3.0)) * 9.81 / 6
    np.testing.assert_allclose(params.limits.leg_force, (-10 * leg_weight, 10 * leg_weight))
    np.testing.assert_allclose(params.limits.position_max - params.limits.position_min, lengths.mean())
    np.testing.assert_allclose(params.limits.position_min + params.limits.position_max, 0.0, atol=1e-15)
    assert params.limits.max_angle == 0.5
    assert params.limits.max_condition == 1000.0


def test_partial_limits_keep_given_entries(config):
    config["limits"] = {"leg_force": [-50.0, 300.0], "workspace": {"max_angle": 0.2}}
    params = PlatformParams.from_dict(config)
    assert params.limits.leg_force == (-50.0, 300.0)
    assert params.limits.max_angle == 0.2
    lengths = np.linalg.norm(home_legs(params), axis=1)
    np.testing.assert_allclose(params.limits.leg_length, (0.8 * lengths.min(), 1.2 * lengths.max()))


def test_home_without_rpy_is_level(config):
    config["home"] = {"position": [0.0, 0.0, 0.4]}
    np.testing.assert_array_equal(PlatformParams.from_dict(config).home_rpy, 0.0)


def test_replace_revalidates_and_shares_a_single_leg_body():
    params = load_platform("dasgupta1998")
    massless = RigidBody(mass=0.0, com=[0.0, 0.0, 0.0], inertia=np.zeros((3, 3)))
    light = params.replace(upper_leg=massless, lower_leg=massless, damping=Damping(0.0, 0.0, 0.0))
    assert light.upper_leg == (massless,) * 6
    assert light.damping.prismatic == 0.0
    assert params.upper_leg[0].mass == 1.0
    with pytest.raises(ConfigError, match=r"^platform\.mass: must be >= 1e-06 kg"):
        params.replace(platform=RigidBody(mass=0.0, com=[0.0, 0.0, 0.0], inertia=np.zeros(3)))
    with pytest.raises(ConfigError, match=r"^limits\.leg_length: leg 0 is"):
        params.replace(limits=dataclasses.replace(params.limits, leg_length=(1.3, 1.6)))


def test_config_error_is_a_value_error_and_names_the_file(tmp_path, config):
    config["damping"]["prismatic"] = -1.0
    path = tmp_path / "broken.yaml"
    path.write_text(yaml.safe_dump(config), encoding="utf-8")
    with pytest.raises(ValueError, match=r"broken\.yaml: damping\.prismatic: must be >= 0, got -1\.0"):
        PlatformParams.from_yaml(path)


# ---------------------------------------------------------------------------------------------
# Validation: every bad input names its key


def set_in(config, path, value):
    """Set config[path[0]][path[1]]... = value."""
    *parents, last = path
    for key in parents:
        config = config[key]
    config[last] = value


def unsymmetric(scale):
    return [[scale, 0.1 * scale, 0.0], [0.0, scale, 0.0], [0.0, 0.0, scale]]


FIVE_LEGS = [{"mass": 1.0, "com": [0, 0, 0], "inertia": [1, 1, 1]}] * 5

# (key path to set, bad value, expected message), one per validation rule.
INVALID = [
    pytest.param(
        ("upper_leg", "inertia"), unsymmetric(0.06), r"^upper_leg\.inertia: not symmetric", id="leg_inertia_unsymmetric"
    ),
    pytest.param(
        ("platform", "inertia"),
        unsymmetric(2.5),
        r"^platform\.inertia: not symmetric",
        id="platform_inertia_unsymmetric",
    ),
    pytest.param(
        ("platform", "mass"), -1, r"^platform\.mass: must be >= 1e-06 kg, got -1", id="platform_mass_negative"
    ),
    pytest.param(("platform", "mass"), 0.0, r"^platform\.mass: must be >= 1e-06 kg, got 0", id="platform_mass_zero"),
    pytest.param(("lower_leg", "mass"), -3.0, r"^lower_leg\.mass: must be >= 0, got -3", id="leg_mass_negative"),
    pytest.param(("upper_leg", "mass"), True, r"^upper_leg\.mass: must be a number", id="mass_is_bool"),
    pytest.param(
        ("damping", "universal"), "1e-4", r"^damping\.universal: must be a number.*1\.0e-4", id="number_as_yaml_text"
    ),
    pytest.param(
        ("base_joints",),
        [[0.0, 0.0, 0.0]] * 5,
        r"^base_joints: expected shape \(6, 3\), got \(5, 3\)",
        id="base_joints_five_rows",
    ),
    pytest.param(
        ("platform_joints",),
        [[0.0, 0.0]] + [[0.0, 0.0, 0.0]] * 5,
        r"^platform_joints: expected numbers of shape \(6, 3\), got rows of unequal lengths",
        id="platform_joints_ragged",
    ),
    pytest.param(
        ("hooke_axes",),
        [0.0, 1.0],
        r"^hooke_axes: expected shape \(6, 3\) or \(3,\), got \(2,\)",
        id="hooke_axes_wrong_shape",
    ),
    pytest.param(
        ("platform", "inertia"),
        [[1.0, 0.0], [0.0, 1.0]],
        r"^platform\.inertia: expected shape",
        id="inertia_wrong_shape",
    ),
    pytest.param(
        ("platform", "com"), [0.0, 0.0], r"^platform\.com: expected shape \(3,\), got \(2,\)", id="com_wrong_shape"
    ),
    pytest.param(("gravity",), [0.0, -9.81], r"^gravity: expected shape \(3,\)", id="gravity_wrong_shape"),
    pytest.param(("home", "rpy"), [0.0], r"^home\.rpy: expected shape \(3,\)", id="home_rpy_wrong_shape"),
    pytest.param(
        ("base_joints", 1, 2),
        float("nan"),
        r"^base_joints\[1\]\[2\]: not a finite number \(nan\)",
        id="base_joints_nan",
    ),
    pytest.param(
        ("platform", "com", 0), float("inf"), r"^platform\.com\[0\]: not a finite number \(inf\)", id="com_inf"
    ),
    pytest.param(("damping", "spherical"), float("nan"), r"^damping\.spherical: not a finite number", id="damping_nan"),
    pytest.param(("gravity", 2), float("-inf"), r"^gravity\[2\]: not a finite number \(-inf\)", id="gravity_inf"),
    pytest.param(
        ("limits", "leg_force", 1), float("nan"), r"^limits\.leg_force\[1\]: not a finite number", id="leg_force_nan"
    ),
    pytest.param(("damping", "prismatic"), -1.0, r"^damping\.prismatic: must be >= 0", id="damping_negative"),
    pytest.param(
        ("damping",),
        {"universal": 0.0, "prismatic": 0.0},
        r"^damping: missing key 'spherical'",
        id="damping_missing_key",
    ),
    pytest.param(("platform", "mas"), 40.0, r"^platform: unknown key 'mas'", id="platform_unknown_key"),
    pytest.param(
        ("limits", "workspace", "max_angel"),
        0.3,
        r"^limits\.workspace: unknown key 'max_angel'",
        id="workspace_unknown_key",
    ),
    pytest.param(("home", "yaw"), 0.3, r"^home: unknown key 'yaw'", id="home_unknown_key"),
    pytest.param(("platform",), 40.0, r"^platform: expected a mapping", id="platform_not_a_mapping"),
    pytest.param(
        ("platform", "inertia"),
        [2.5, 2.7, 0.0],
        r"^platform\.inertia: not positive definite",
        id="platform_inertia_singular",
    ),
    pytest.param(
        ("lower_leg", "inertia"),
        [-0.0045, 0.12, 0.12],
        r"^lower_leg\.inertia: not positive semidefinite",
        id="leg_inertia_indefinite",
    ),
    pytest.param(
        ("upper_leg", "mass"),
        0.0,
        r"^upper_leg\.inertia: must be zero for a massless body",
        id="massless_leg_with_inertia",
    ),
    pytest.param(
        ("upper_leg",), FIVE_LEGS, r"^upper_leg: expected one mapping or a list of six, got a list of 5", id="five_legs"
    ),
    pytest.param(
        ("limits", "leg_length"),
        [1.0, 1.2],
        r"^limits\.leg_length: leg 0 is 1\.2613 m long at the home pose, outside \[1\.0, 1\.2\]",
        id="stroke_excludes_home_leg",
    ),
    pytest.param(
        ("limits", "leg_length"), [0.0, 1.6], r"^limits\.leg_length: minimum must be > 0", id="stroke_min_not_positive"
    ),
    pytest.param(
        ("limits", "leg_length"),
        [1.6, 1.0],
        r"^limits\.leg_length: expected \(min, max\) with min < max",
        id="stroke_reversed",
    ),
    pytest.param(
        ("limits", "leg_force"),
        [100.0, 100.0],
        r"^limits\.leg_force: expected \(min, max\) with min < max",
        id="force_range_empty",
    ),
    pytest.param(
        ("limits", "workspace", "position_max", 2),
        0.25,
        r"^limits\.workspace: position_min .* must be below position_max",
        id="workspace_box_empty",
    ),
    pytest.param(
        ("limits", "workspace", "position_max", 2),
        0.35,
        r"^limits\.workspace: home position .* outside the box",
        id="workspace_excludes_home",
    ),
    pytest.param(
        ("limits", "workspace", "max_angle"),
        0.0,
        r"^limits\.workspace\.max_angle: must be in \(0, pi\]",
        id="max_angle_not_positive",
    ),
    pytest.param(
        ("limits", "max_condition"), 0.5, r"^limits\.max_condition: must be > 1", id="max_condition_below_one"
    ),
]


@pytest.mark.parametrize("path, value, message", INVALID)
def test_invalid_value_names_its_key(config, path, value, message):
    set_in(config, path, value)
    with pytest.raises(ConfigError, match=message):
        PlatformParams.from_dict(config)


def test_model_refuses_a_home_pose_conditioned_beyond_max_condition(config, tmp_path):
    """The Jacobian at the home pose is the kernels': the model built on the platform checks its
    condition number, for a platform from a dict, a file or the environment's arguments alike."""
    from stewart_env.dynamics import Dynamics
    from stewart_env.envs import StewartPlatformEnv

    message = r"^limits\.max_condition: the Jacobian's condition number at the home pose is 3\.621, above 2\.0$"
    config["limits"]["max_condition"] = 2.0
    params = PlatformParams.from_dict(config)
    assert params.limits.max_condition == 2.0
    with pytest.raises(ConfigError, match=message):
        Dynamics("improved", params)
    nominal = Dynamics("improved", load_platform("dasgupta1998"))
    with pytest.raises(ConfigError, match=message):
        nominal.with_rows([0], [params])
    path = tmp_path / "ill_conditioned.yaml"
    path.write_text(yaml.safe_dump(config), encoding="utf-8")
    with pytest.raises(ConfigError, match=message):
        StewartPlatformEnv(platform=path)
    config["limits"]["max_condition"] = 3.7  # just above the home pose's 3.621
    Dynamics("improved", PlatformParams.from_dict(config))


def test_missing_top_level_key(config):
    del config["platform_joints"]
    with pytest.raises(ConfigError, match=r"^missing key 'platform_joints'$"):
        PlatformParams.from_dict(config)


def test_misspelt_top_level_key_is_reported_as_unknown(config):
    config["plaform"] = config.pop("platform")
    with pytest.raises(ConfigError, match=r"^unknown key 'plaform' \(expected 'base_joints'"):
        PlatformParams.from_dict(config)


def test_config_must_be_a_mapping():
    with pytest.raises(ConfigError, match=r"^expected a mapping, got None$"):
        PlatformParams.from_dict(None)


def test_hooke_axis_zero_vector(config):
    config["hooke_axes"] = [[0.0, 0.0, 1.0]] * 6
    config["hooke_axes"][2] = [0.0, 0.0, 0.0]
    with pytest.raises(ConfigError, match=r"^hooke_axes\[2\]: zero vector$"):
        PlatformParams.from_dict(config)


def test_hooke_axis_parallel_to_its_leg_at_home(config):
    legs = home_legs(PlatformParams.from_dict(config))
    axes = np.tile([0.0, 0.0, 1.0], (6, 1))
    axes[3] = -legs[3]  # antiparallel is as singular as parallel
    config["hooke_axes"] = axes.tolist()
    with pytest.raises(ConfigError, match=r"^hooke_axes\[3\]: parallel to leg 3 at the home pose \(angle 0\.0 deg\)"):
        PlatformParams.from_dict(config)


def test_six_leg_list_error_names_the_leg(config):
    legs = [copy.deepcopy(config["upper_leg"]) for _ in range(6)]
    legs[2]["inertia"] = unsymmetric(0.06)
    config["upper_leg"] = legs
    with pytest.raises(ConfigError, match=r"^upper_leg\[2\]\.inertia: not symmetric"):
        PlatformParams.from_dict(config)


def test_home_required_when_the_default_pose_is_invalid(config):
    d = physical_keys(config)
    d["platform_joints"] = d["base_joints"]  # zero-length legs at the default pose
    with pytest.raises(ConfigError, match=r"^missing key 'home': the default home pose .* leg 0 has zero length"):
        PlatformParams.from_dict(d)


def test_zero_length_leg_at_a_given_home(config):
    config["platform_joints"] = config["base_joints"]
    config["home"] = {"position": [0.0, 0.0, 0.0]}
    with pytest.raises(ConfigError, match=r"^home\.position: leg 0 has zero length at the home pose"):
        PlatformParams.from_dict(config)


def test_dataclasses_validate_on_direct_construction():
    with pytest.raises(ConfigError, match=r"^prismatic: must be >= 0"):
        Damping(universal=0.0, prismatic=-1.0, spherical=0.0)
    with pytest.raises(ConfigError, match=r"^inertia: not symmetric"):
        RigidBody(mass=1.0, com=[0.0, 0.0, 0.0], inertia=unsymmetric(1.0))
    with pytest.raises(ConfigError, match=r"^workspace\.position_min: expected shape \(3,\)"):
        Limits(
            leg_length=(1.0, 2.0),
            leg_force=(-1.0, 1.0),
            position_min=[0.0, 0.0],
            position_max=[1.0, 1.0, 1.0],
            max_angle=0.5,
            max_condition=1000.0,
        )
    params = load_platform("dasgupta1998")
    with pytest.raises(ConfigError, match=r"^upper_leg: expected a RigidBody or a sequence of six"):
        params.replace(upper_leg=params.upper_leg[:5])
    with pytest.raises(ConfigError, match=r"^damping: expected a Damping"):
        params.replace(damping={"universal": 0.0, "prismatic": 0.0, "spherical": 0.0})


# ----------------------------------------------------------------------------------------------
# Domain randomisation on packed rows: the same numbers as building and packing PlatformParams.


def _every_key_spec():
    from stewart_env.randomization import KEYS

    # every key, so that up to three factors multiply one parameter; negative CoM factors mirror
    return {k: ((-2.0, 2.0) if k.endswith("com") else (0.5, 2.0)) for k in KEYS}


@pytest.mark.parametrize("name", SHIPPED)
def test_scale_packed_equals_packing_the_randomised_params_bit_for_bit(name):
    from stewart_env.dynamics.model import pack_params
    from stewart_env.randomization import Randomization

    params = load_platform(name)
    nominal = pack_params(params)
    r = Randomization(_every_key_spec())
    rng = np.random.default_rng(7)
    out = np.empty_like(nominal)
    for _ in range(100):
        factors = r.sample(rng)
        r.scale_packed(nominal, factors, out)
        assert np.array_equal(out, pack_params(r.apply(params, factors)))


def test_scale_packed_checks_the_factors_against_the_spec():
    from stewart_env.dynamics.model import pack_params
    from stewart_env.randomization import Randomization

    r = Randomization({"mass": (0.5, 2.0), "com": (-1.0, 1.0)})
    nominal = pack_params(load_platform("dasgupta1998"))
    out = np.empty_like(nominal)
    for factors, message in [
        ({"mass": 2.5}, r"factors\['mass'\]: expected a number within \[0.5, 2.0\]"),
        ({"mass": float("nan")}, r"factors\['mass'\]"),
        ({"com": True}, r"factors\['com'\]"),
        ({"inertia": 1.0}, "factors: key 'inertia' is not in the randomisation spec"),
        ([1.0], "factors: expected a dict"),
    ]:
        with pytest.raises(ConfigError, match=message):
            r.scale_packed(nominal, factors, out)


def test_scale_packed_names_a_wrong_row():
    import stewart_env as se
    from stewart_env.randomization import Randomization

    model = se.make_dynamics("improved", load_platform("dasgupta1998"))
    r = Randomization({"mass": (0.5, 2.0)})
    factors = r.sample(np.random.default_rng(0))
    with pytest.raises(ValueError, match=r"out_row: expected a float64 array of shape \(229,\)"):
        r.scale_packed(model.packed[0], factors, np.empty(3))
    with pytest.raises(ValueError, match="out_row: read-only"):
        r.scale_packed(model.packed[0], factors, model.packed[0])
    with pytest.raises(ValueError, match=r"nominal_row: expected a float64 array of shape \(229,\)"):
        r.scale_packed(model.packed, factors, np.empty(229))


def test_scale_packed_refuses_what_apply_refuses(config):
    from stewart_env.dynamics.model import pack_params
    from stewart_env.randomization import Randomization

    config["platform"]["mass"] = 5e-4
    params = PlatformParams.from_dict(config)
    r = Randomization({"platform.mass": (1e-3, 1e-3), "inertia": (1e-3, 1e-3)})
    factors = r.sample(np.random.default_rng(0))
    # 5e-4 kg scaled by 1e-3 is below the platform's smallest mass, 1e-6 kg
    with pytest.raises(ConfigError, match="platform.mass"):
        r.apply(params, factors)
    with pytest.raises(ConfigError, match="platform.mass"):
        r.scale_packed(pack_params(params), factors, np.empty(pack_params(params).shape))


def test_rows_set_from_packed_numbers_build_their_params_only_when_read():
    import stewart_env as se
    from stewart_env.randomization import Randomization

    params = load_platform("dasgupta1998")
    model = se.make_dynamics("improved", [params] * 3)
    r = Randomization(_every_key_spec())
    factors = r.sample(np.random.default_rng(3))
    row = np.empty((1, model.packed.shape[1]))
    r.scale_packed(model.packed[0], factors, row[0])
    built = []

    def source():
        built.append(1)
        return r.apply(params, factors)

    new = model.with_packed_rows([1], row, [source])
    assert np.array_equal(new.packed[1], row[0]) and np.array_equal(new.packed[0], model.packed[0])
    assert len(new.params) == 3 and not built  # len and the packed numbers need no PlatformParams
    assert new.params_of(1) == r.apply(params, factors) and new.params[1] is new.params_of(1)
    assert len(built) == 1  # built once, then kept
    reference = se.make_dynamics("improved", [params, r.apply(params, factors), params])
    t, R = params.home_position, np.eye(3)
    F = np.full((3, 6), 200.0)
    assert np.array_equal(
        new.forward(t, R, np.zeros(3), np.zeros(3), F)[0], reference.forward(t, R, np.zeros(3), np.zeros(3), F)[0]
    )
    with pytest.raises(ValueError, match=r"packed_rows: expected shape \(1, 229\)"):
        model.with_packed_rows([1], row[0], [source])
    with pytest.raises(ValueError, match="rows: 5 is outside the batch of 3"):
        model.with_packed_rows([5], row, [source])
    with pytest.raises(ValueError, match="packed_rows: contains NaN or inf"):
        model.with_packed_rows([0], np.full_like(row, np.nan), [source])
    with pytest.raises(ValueError, match="sources: expected PlatformParams or a function"):
        model.with_packed_rows([0], row, [3.0])
