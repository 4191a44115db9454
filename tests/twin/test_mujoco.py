"""The MuJoCo twin (stewart_env.mujoco) against the exact ``improved`` model."""

import copy
import pickle
from pathlib import Path

import numpy as np
import pytest

from conftest import exit_code

mujoco = pytest.importorskip("mujoco")

import stewart_env as se  # noqa: E402
from stewart_env import mujoco as twin  # noqa: E402
from stewart_env.integrate import rollout_inplace  # noqa: E402

PLATFORMS = ["dasgupta1998", "motion_simulator"]
LOOSE = (0.99, 0.99, 0.001, 0.5, 2.0)


@pytest.fixture(scope="module", params=PLATFORMS)
def params(request):
    return se.load_platform(request.param)


def test_mjcf_loads_with_the_config_masses(params):
    m = mujoco.MjModel.from_xml_string(twin.to_mjcf(params))
    assert (m.nq, m.nv, m.neq, m.nu) == (7 + 6 * 3, 6 + 6 * 3, 6, 6)
    legs = sum(u.mass + d.mass for u, d in zip(params.upper_leg, params.lower_leg))
    # the bodies carry exactly the config's masses (the viewer geometry is massless)
    assert m.body_subtreemass[0] == pytest.approx(params.platform.mass + legs, rel=1e-12)
    np.testing.assert_array_equal(m.actuator_ctrlrange, np.tile(params.limits.leg_force, (6, 1)))
    assert m.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4


def test_acceleration_matches_improved_within_the_softness(params):
    """A soft loop passes through about (1 - d)/d of the unconstrained acceleration (of order g)."""
    g = np.linalg.norm(params.gravity)
    errors = {}
    for solimp in (LOOSE, twin.DEFAULT_SOLIMP):
        d = solimp[0]
        errors[d] = twin.acceleration_error(params, solimp=solimp)
        # measured 0.51-0.77 g (1 - d)/d on both platforms; the bound is the softness itself
        assert errors[d] < g * (1 - d) / d
    # 100x less softness: the error falls with it (measured 100x); 50x leaves room for rounding
    assert errors[twin.DEFAULT_SOLIMP[0]] < errors[LOOSE[0]] / 50


def test_holding_forces_hold_mujoco_platform(params):
    position, angle = twin.holding_drift(params, seconds=1.0)
    # measured 2.4e-6 m, 3.7e-5 rad (dasgupta1998): the soft loops settle by that much, then hold
    assert position < 1e-5
    assert angle < 1e-4


def test_trajectory_energy_and_closure(params):
    r = twin.trajectory_report(params, seconds=1.0)
    # measured 2e-3 (dasgupta1998) and 3e-6 (motion_simulator) of the kinetic energy: the soft
    # loops' damping dissipates a little
    assert r["energy_drift"] < 1e-2 * r["kinetic_energy"]
    # measured 1.3e-6 m and 9e-8 m
    assert r["closure_max"] < 1e-5
    # measured 5e-7 m and 5e-9 m from the improved model after 1 s of motion
    assert r["position_difference"] < 1e-5


def test_mujoco_defaults_open_the_loops(dasgupta):
    """MuJoCo's own constraint defaults let the loops open by millimetres: why the twin sets its own."""
    r = twin.trajectory_report(dasgupta, seconds=1.0, solref=twin.MUJOCO_SOLREF, solimp=twin.MUJOCO_SOLIMP)
    assert r["closure_max"] > 1e-3  # measured 5.6 mm


def test_spherical_friction_is_what_the_twin_leaves_out(dasgupta):
    # measured 1.3e-4: the order of C_s times the joint rates over the platform's inertia
    assert 0 < twin.spherical_friction_effect(dasgupta) < 1e-3


def _batch(params, n, seed=0):
    rng = np.random.default_rng(seed)
    t = params.home_position + rng.uniform(-0.02, 0.02, (n, 3))
    R = se.rpy_to_matrix(params.home_rpy + rng.uniform(-0.05, 0.05, (n, 3)))
    z = np.zeros((n, 3))
    F = se.make_dynamics("improved", params).inverse(t, R, z, z, z, z)
    return t, R, z, z.copy(), F


def test_plant_follows_rollout_inplace(dasgupta):
    n = 3
    t, R, v, w, F = _batch(dasgupta, n)
    W = np.zeros((n, 6))
    W[:, 0] = 50.0  # a push along x, so the platform moves
    W[:, 5] = 5.0
    mine = [x.copy() for x in (t, R, v, w)]
    exact = [x.copy() for x in (t, R, v, w)]
    plant = twin.MujocoPlant([dasgupta] * n)
    for _ in range(10):
        plant.step_inplace(*mine, F, W, 1e-3, 10)
        rollout_inplace(se.make_dynamics("improved", dasgupta), *exact, F, W, 1e-3, 10)
    moved = np.linalg.norm(exact[0] - t, axis=1)
    assert moved.min() > 1e-3  # the wrench moved every platform by millimetres
    # measured 5.5e-8 m over 6 mm of motion: the soft loops' relative error of 1e-4, plus their settling
    np.testing.assert_allclose(mine[0], exact[0], atol=1e-6)
    np.testing.assert_allclose(mine[1], exact[1], atol=1e-5)  # measured 5.0e-7
    assert plant.closure_error.shape == (n,) and (plant.closure_error < 1e-6).all()  # measured 5e-8 m
    # R comes from a normalised quaternion, so it is orthonormal to a few ulps
    np.testing.assert_allclose(np.einsum("nij,nkj->nik", mine[1], mine[1]), np.tile(np.eye(3), (n, 1, 1)), atol=1e-12)


def test_plant_restarts_a_row_set_from_outside_and_keeps_nan_rows(dasgupta):
    n = 3
    t, R, v, w, F = _batch(dasgupta, n)
    W = np.zeros((n, 6))
    state = [x.copy() for x in (t, R, v, w)]
    plant = twin.MujocoPlant([dasgupta] * n)
    plant.step_inplace(*state, F, W, 1e-3, 5)
    # a reset of row 1 to another pose; row 2 poisoned
    state[0][1] = dasgupta.home_position
    state[1][1] = np.eye(3)
    state[0][2] = np.nan
    F[1] = se.make_dynamics("improved", dasgupta).inverse(dasgupta.home_position, np.eye(3), *[np.zeros(3)] * 4)
    plant.step_inplace(*state, F, W, 1e-3, 5)
    # row 1 restarted at home with its legs by inverse kinematics: it stays put (measured 2.3e-9 m)
    assert np.linalg.norm(state[0][1] - dasgupta.home_position) < 1e-6
    assert plant.closure_error[1] < 1e-6  # measured 3e-8 m
    assert np.isnan(state[0][2]).all() and np.isnan(state[1][2]).all() and np.isnan(plant.closure_error[2])
    plant.step_inplace(*state, F, W, 1e-3, 5)
    assert np.isnan(state[0][2]).all()  # stays non-finite
    assert np.isfinite(state[0][:2]).all()


def test_to_mjcf_names_bad_arguments(dasgupta):
    with pytest.raises(ValueError, match="solimp"):
        twin.to_mjcf(dasgupta, solimp=(1.0, 0.99, 0.001, 0.5, 2))
    with pytest.raises(ValueError, match="solref"):
        twin.to_mjcf(dasgupta, solref=(0.02,))
    with pytest.raises(ValueError, match="timestep"):
        twin.to_mjcf(dasgupta, timestep=0.0)
    with pytest.raises(ValueError, match="timestep: must be a number of seconds"):
        twin.to_mjcf(dasgupta, timestep="x")
    with pytest.raises(ValueError, match="nthread"):
        twin.MujocoPlant(dasgupta, nthread=-1)
    with pytest.raises(ValueError, match="params"):
        twin.to_mjcf("dasgupta1998")


def test_missing_mujoco_names_the_extra(dasgupta, monkeypatch):
    monkeypatch.setattr(twin.library, "_mj", None)
    with pytest.raises(ImportError, match=r'pip install -e "\.\[mujoco\]"'):
        twin.to_mjcf(dasgupta)


def test_accuracy_report_command(capsys):
    from stewart_env.cli.mujoco_accuracy import main

    assert main(["dasgupta1998"]) == 0
    out = capsys.readouterr().out
    assert "| twin default (0.002 1.0; 0.9999) | 5.0" in out  # the figure DEFAULT_SOLIMP's comment quotes
    assert "| MuJoCo default (0.02 1.0; 0.9) |" in out and "holding forces" in out
    with pytest.raises(SystemExit):
        main(["nowhere"])
    assert "argument platforms: unknown platform 'nowhere'" in capsys.readouterr().err


def test_plant_reports_a_diverging_row_as_nan_and_serves_mixed_parameters(dasgupta, tmp_path, monkeypatch, capfd):
    monkeypatch.chdir(tmp_path)  # where MuJoCo's default handler would write MUJOCO_LOG.TXT
    heavy = dasgupta.replace(platform=type(dasgupta.platform)(60.0, dasgupta.platform.com, dasgupta.platform.inertia))
    n = 2
    t, R, v, w, F = _batch(dasgupta, n)
    W = np.zeros((n, 6))
    W[0, 0] = 1e20  # MuJoCo resets a simulation whose accelerations blow up; the plant must not hide it
    state = [x.copy() for x in (t, R, v, w)]
    plant = twin.MujocoPlant([dasgupta, heavy])
    plant.step_inplace(*state, F, W, 1e-3, 10)
    assert np.isnan(state[0][0]).all() and np.isnan(plant.closure_error[0])
    # the plant reports the divergence; MuJoCo neither prints it nor litters the working directory
    assert list(tmp_path.iterdir()) == [] and "WARNING" not in capfd.readouterr().out
    config = mujoco.MjLogConfig.get()
    assert config.logto_file and config.logto_console  # MuJoCo's own settings are back
    # row 1: 50 % heavier than the forces hold, it sinks like the improved model of its own parameters
    exact = [x[1:].copy() for x in (t, R, v, w)]
    rollout_inplace(se.make_dynamics("improved", heavy), *exact, F[1:], W[1:], 1e-3, 10)
    assert exact[0][0, 2] < t[1, 2] - 1e-5  # it moved
    np.testing.assert_allclose(state[0][1], exact[0][0], atol=1e-7)  # measured 1e-9 m over 10 ms


def test_plant_rows_take_new_parameters(dasgupta):
    heavy = dasgupta.replace(platform=type(dasgupta.platform)(60.0, dasgupta.platform.com, dasgupta.platform.inertia))
    n = 2
    t, R, v, w, F = _batch(dasgupta, n)
    W = np.zeros((n, 6))
    plant = twin.MujocoPlant([dasgupta] * n)
    state = [x.copy() for x in (t, R, v, w)]
    plant.step_inplace(*state, F, W, 1e-3, 10)
    plant.set_params([1], [heavy])
    assert plant.params == (dasgupta, heavy) and len(plant._twins) == 2
    state = [x.copy() for x in (t, R, v, w)]
    plant.step_inplace(*state, F, W, 1e-3, 10)
    exact = [x.copy() for x in (t, R, v, w)]
    rollout_inplace(se.make_dynamics("improved", [dasgupta, heavy]), *exact, F, W, 1e-3, 10)
    np.testing.assert_allclose(state[0], exact[0], atol=1e-7)  # measured 1e-9 m; row 1 sinks 1.5e-4 m
    plant.set_params([1], [dasgupta])
    assert len(plant._twins) == 1  # the heavy model is no longer kept
    with pytest.raises(ValueError, match="rows: 2"):
        plant.set_params([2], [dasgupta])


def test_plant_holds_the_spherical_friction_the_mjcf_cannot_carry(simulator):
    held = twin.plant_difference(simulator, seconds=1.0)
    omitted = twin.plant_difference(simulator, seconds=1.0, spherical_friction=False)
    # measured 1.8e-3 m without C_s (5 N m s/rad on an 8 t platform) and 1.6e-5 m with it held over 10 ms steps
    assert omitted[0] > 1e-3
    assert held[0] < 1e-4 and held[0] < omitted[0] / 50


def test_plant_copies_and_pickles_continue_bit_for_bit(dasgupta):
    import copy
    import pickle

    heavy = dasgupta.replace(platform=type(dasgupta.platform)(60.0, dasgupta.platform.com, dasgupta.platform.inertia))
    n = 2
    t, R, v, w, F = _batch(dasgupta, n)
    W = np.zeros((n, 6))
    W[:, 3] = 20.0  # a moment: the platforms move
    plant = twin.MujocoPlant([dasgupta] * n)
    plant.set_params([1], [heavy])
    state = [x.copy() for x in (t, R, v, w)]
    for _ in range(3):
        plant.step_inplace(*state, F, W, 1e-3, 10)
    copies = [
        (copy.deepcopy(plant), [x.copy() for x in state]),
        (pickle.loads(pickle.dumps(plant)), [x.copy() for x in state]),
    ]
    for _ in range(5):
        plant.step_inplace(*state, F, W, 1e-3, 10)
        for other, other_state in copies:
            other.step_inplace(*other_state, F, W, 1e-3, 10)
    for other, other_state in copies:
        assert other.params == (dasgupta, heavy)
        for a, b in zip(state, other_state):
            np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(plant.closure_error, other.closure_error)
    assert np.abs(state[0] - t).max() > 1e-4  # they did move


# -- export-mjcf and the MuJoCo plant as a user meets them -------------------------------------


from stewart_env.cli import main  # noqa: E402


def test_export_mjcf_writes_a_model_mujoco_loads_into_a_new_folder(tmp_path, capsys):
    mujoco = pytest.importorskip("mujoco")
    out = tmp_path / "missing" / "folder" / "x.xml"
    assert main(["export-mjcf", "--platform", "dasgupta1998", "--out", str(out)]) == 0
    m = mujoco.MjModel.from_xml_path(str(out))
    assert m.neq == 6  # one connect constraint closes each leg's loop


@pytest.mark.parametrize(
    "content, message",
    [
        ("hello: [\n", "not valid YAML"),
        ("gravity: !!python/object/apply:os.system ['echo hi']\n", "not valid YAML"),
        ("[]\n", "expected a mapping"),
        ("", "expected a mapping"),
    ],
)
def test_export_mjcf_refuses_a_hostile_platform_file_in_one_line(tmp_path, capsys, content, message):
    pytest.importorskip("mujoco")
    platform = tmp_path / "hostile.yaml"
    platform.write_text(content)
    with pytest.raises(SystemExit) as stop:
        main(["export-mjcf", "--platform", str(platform), "--out", str(tmp_path / "x.xml")])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "argument --platform" in err and message in err and "Traceback" not in err
    assert not (tmp_path / "x.xml").exists()


def test_export_mjcf_refuses_a_directory_as_out(tmp_path, capsys):
    pytest.importorskip("mujoco")
    assert main(["export-mjcf", "--platform", "dasgupta1998", "--out", str(tmp_path)]) == 2
    assert "argument --out" in capsys.readouterr().err


def test_export_mjcf_write_failure_names_out_without_a_traceback(tmp_path, capsys):
    pytest.importorskip("mujoco")
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    for out in ([("/dev/full", "No space left")] if Path("/dev/full").exists() else []) + [(blocker / "x.xml", "")]:
        assert main(["export-mjcf", "--platform", "dasgupta1998", "--out", str(out[0])]) == 2
        err = capsys.readouterr().err
        assert "argument --out" in err and out[1] in err and "Traceback" not in err


@pytest.mark.parametrize("timestep", ["1e300", "0.5"])
def test_export_mjcf_refuses_a_timestep_no_simulation_could_use(tmp_path, capsys, timestep):
    pytest.importorskip("mujoco")
    assert (
        exit_code(
            ["export-mjcf", "--platform", "dasgupta1998", "--out", str(tmp_path / "x.xml"), "--timestep", timestep]
        )
        == 2
    )
    assert "argument --timestep" in capsys.readouterr().err
    assert not (tmp_path / "x.xml").exists()


def test_to_mjcf_and_the_plant_refuse_bad_settings_naming_them(dasgupta):
    pytest.importorskip("mujoco")
    from stewart_env.mujoco import MujocoPlant, to_mjcf

    with pytest.raises(ValueError, match=r"^timestep: "):
        to_mjcf(dasgupta, timestep="x")
    with pytest.raises(ValueError, match=r"^nthread: "):
        MujocoPlant([dasgupta, dasgupta], nthread=-1)
    with pytest.raises(ValueError, match=r"^params_rows: "):
        MujocoPlant([])


@pytest.mark.parametrize("how", [copy.deepcopy, lambda e: pickle.loads(pickle.dumps(e))], ids=["deepcopy", "pickle"])
def test_mujoco_env_copies_continue_bit_for_bit(make, how):
    pytest.importorskip("mujoco")
    env = make(model="mujoco")
    action = np.full(6, 0.1, np.float32)
    for _ in range(3):
        env.step(action)
    twin = how(env)
    for _ in range(3):
        a, b = env.step(action), twin.step(action)
        np.testing.assert_array_equal(a[0], b[0])
        assert a[1] == b[1] and a[4]["closure_error"] == b[4]["closure_error"]
    env.close()
    twin.close()


def test_mujoco_env_passes_gymnasiums_checker(make):
    pytest.importorskip("mujoco")
    from gymnasium.utils.env_checker import check_env

    env = make(model="mujoco", task="hold")
    with pytest.warns(UserWarning):  # the checker's note on an unbounded observation Box
        check_env(env.unwrapped, skip_render_check=True)


def test_model_names_are_case_insensitive_and_mujoco_is_listed():
    """ "MuJoCo" is the MuJoCo plant as "Improved" is the improved model; an unknown name lists both."""
    pytest.importorskip("mujoco")
    from stewart_env.envs import StewartPlatformEnv

    env = StewartPlatformEnv(model="MuJoCo")
    assert env.unwrapped.plant.name == "mujoco"
    env.close()
    with pytest.raises(ValueError, match=r"^model: unknown model 'nope'.*or 'mujoco'"):
        StewartPlatformEnv(model="nope")


@pytest.mark.parametrize(
    "kwargs, argument, problem",
    [
        ({"solimp": (1.0, 0.99, 0.001, 0.5, 2)}, "solimp", "d_min and d_max must lie in (0, 1), got (1.0, 0.99)"),
        ({"solref": (0.02,)}, "solref", "expected 2 finite numbers, got (0.02,)"),
        ({"solref": ("a", 1)}, "solref", "expected 2 numbers, got ('a', 1)"),
        ({"timestep": 0.0}, "timestep", "must be a number of seconds in (0, 0.1], got 0.0"),
    ],
)
def test_to_mjcf_carries_the_refused_argument_as_data(dasgupta, kwargs, argument, problem):
    from stewart_env.errors import UsageError

    with pytest.raises(UsageError) as info:
        twin.to_mjcf(dasgupta, **kwargs)
    assert (info.value.argument, info.value.problem) == (argument, problem)
    assert str(info.value) == f"{argument}: {problem}"
