"""The new features as an outside user meets them: hostile arguments get a clear error naming the
argument (never a raw traceback, a silent wrong number or a NaN), copies are independent, and the
command line says which extra to install."""

import copy
import pickle
import subprocess
import sys
from pathlib import Path

import numba
import numpy as np
import pytest

import stewart_env as se
from stewart_env.cli import main


@pytest.fixture(scope="module")
def model(dasgupta):
    return se.make_dynamics("improved", dasgupta)


@pytest.fixture
def home(model):
    """The home pose (position, rotation) and a zero rate."""
    ws = model.workspace(1)
    return ws.position[0].copy(), ws.rotation[0].copy(), np.zeros(3)


# -- Workspace ----------------------------------------------------------------------------------


@pytest.mark.parametrize("n", [0, -1, True, 1.0, 2.5, "2", None, np.float64(2.0)])
def test_workspace_refuses_a_batch_size_that_is_not_a_positive_integer(model, n):
    with pytest.raises(ValueError, match=r"^n: "):
        model.workspace(n)


@pytest.mark.parametrize("n", [10**9, 2**62, 2**63, 10**30])
def test_workspace_too_large_to_allocate_is_refused_naming_n(model, n):
    with pytest.raises(ValueError, match=r"^n: a workspace of \d+ platforms needs .* GiB"):
        model.workspace(n)


def test_workspace_set_state_refuses_a_batch_of_another_size(model, home):
    _, R, z = home
    with pytest.raises(ValueError, match=r"^position: .*n = 1, got a batch of 2"):
        model.workspace(1).set_state(np.zeros((2, 3)), R, z, z)


def test_workspace_set_state_refuses_complex_numbers(model, home):
    t, R, z = home
    with pytest.raises(ValueError, match=r"^position: .*complex"):
        model.workspace(1).set_state(t.astype(complex), R, z, z)


def test_workspace_n_must_match_the_models_parameter_rows(model, dasgupta):
    two_rows = model.with_params([dasgupta, dasgupta])
    with pytest.raises(ValueError, match=r"^n: the model has 2 parameter rows"):
        two_rows.workspace(3)


@pytest.mark.parametrize("argument, value, message", [
    ("position", [np.nan, 0.0, 0.4], r"^position: contains NaN or inf"),
    ("velocity", [np.inf, 0.0, 0.0], r"^velocity: contains NaN or inf"),
    ("rotation", 2 * np.eye(3), r"^rotation: not a rotation matrix"),
    ("rotation", -np.eye(3), r"^rotation: not a rotation matrix"),
    ("position", np.zeros(4), r"^position: expected shape \(3,\)"),
    ("position", "abc", r"^position: expected an array of numbers"),
])
def test_workspace_set_state_refuses_naming_the_argument(model, home, argument, value, message):
    t, R, z = home
    ws = model.workspace(1)
    state = {**dict(position=t, rotation=R, velocity=z, angular_velocity=z), argument: value}
    before = ws.position.copy()
    with pytest.raises(ValueError, match=message):
        ws.set_state(**state)
    np.testing.assert_array_equal(ws.position, before)  # a refused state leaves the arrays as they were


def test_workspace_set_state_takes_float32_and_integer_arrays(model, home):
    _, R, z = home
    ws = model.workspace(1)
    ws.set_state(np.array([0, 0, 1]), np.eye(3, dtype=int), np.zeros(3, int), z.astype(np.float32))
    assert ws.position.dtype == np.float64
    np.testing.assert_array_equal(ws.position, [[0.0, 0.0, 1.0]])
    ws.set_state(np.array([0.0, 0.0, 0.4], np.float32), R.astype(np.float32), z, z)
    np.testing.assert_array_equal(ws.position, [[0.0, 0.0, np.float32(0.4)]])


def test_workspace_check_finds_what_was_written_in_place(model):
    ws = model.workspace(1)
    ws.position[0, 0] = np.nan
    with pytest.raises(ValueError, match=r"^position: contains NaN"):
        ws.check()
    ws.position[0, 0] = 0.0
    ws.rotation[0] = 2 * np.eye(3)
    with pytest.raises(ValueError, match=r"^rotation: not a rotation matrix"):
        ws.check()


def test_workspace_arrays_cannot_be_rebound(model):
    ws = model.workspace(1)
    with pytest.raises(AttributeError):
        ws.position = np.zeros((1, 3))


@pytest.mark.parametrize("dt", [0.0, -1e-3, np.nan, np.inf, "0.001", None, np.array([1e-3, 1e-3])])
def test_workspace_step_refuses_a_bad_dt(model, dt):
    with pytest.raises(ValueError, match=r"^dt: "):
        model.workspace(1).step(dt)


@pytest.mark.parametrize("steps", [-1, 1.5, np.nan, np.inf, "3", True, 10**30])
def test_workspace_step_refuses_bad_steps(model, steps):
    with pytest.raises(ValueError, match=r"^steps: "):
        model.workspace(1).step(1e-3, steps)


@pytest.mark.parametrize("how", [copy.deepcopy, lambda ws: pickle.loads(pickle.dumps(ws))], ids=["deepcopy", "pickle"])
def test_a_copied_workspace_is_independent_and_bit_identical(model, how):
    ws = model.workspace(1)
    ws.leg_forces[0] = 1000.0
    expected = ws.forward().copy()
    twin = how(ws)
    assert not np.shares_memory(twin.position, ws.position)
    np.testing.assert_array_equal(twin.forward(), expected)
    twin.position[0, 2] += 0.01
    twin.forward()
    np.testing.assert_array_equal(ws.forward(), expected)
    assert not twin.model.packed.flags.writeable  # the copy's model stays immutable


@pytest.mark.parametrize("how", [copy.deepcopy, lambda m: pickle.loads(pickle.dumps(m))], ids=["deepcopy", "pickle"])
def test_a_copied_model_gives_the_same_numbers(model, home, how):
    t, R, z = home
    forces = np.full(6, 1000.0)
    np.testing.assert_array_equal(how(model).forward(t, R, z, z, forces)[0], model.forward(t, R, z, z, forces)[0])


def test_scale_packed_names_a_wrong_or_read_only_out_row(model):
    from stewart_env.randomization import Randomization
    rnd = Randomization({"platform.mass": (0.8, 1.2)})
    with pytest.raises(ValueError, match=r"^out_row: "):
        rnd.scale_packed(model.packed[0], {"platform.mass": 1.0}, np.empty(3))
    with pytest.raises(ValueError, match=r"^out_row: read-only"):
        rnd.scale_packed(model.packed[0], {"platform.mass": 1.0}, model.packed[0])


# -- rollout with a control law -----------------------------------------------------------------


def _wrong_signature(time, position):
    pass


@numba.njit
def _jitted(time, position, rotation, velocity, angular_velocity, params, forces):
    forces[0] = 0.0


def _returns_a_value(time, position, rotation, velocity, angular_velocity, params, n_params, forces):
    return 1.0


def _nan_forces(time, position, rotation, velocity, angular_velocity, params, n_params, forces):
    for i in range(6):
        forces[i] = np.nan


def _python_law(time, position, rotation, velocity, angular_velocity, params, forces):
    forces[:] = 0.0


@pytest.mark.parametrize("law", [
    _python_law, lambda *a: None, _jitted, numba.cfunc("void(float64, CPointer(float64))")(_wrong_signature),
    numba.cfunc("float64(float64, CPointer(float64), CPointer(float64), CPointer(float64), CPointer(float64), "
                "CPointer(float64), int64, CPointer(float64))")(_returns_a_value),
], ids=["python", "lambda", "njit", "wrong-signature", "returns-a-value"])
def test_rollout_refuses_a_law_that_is_not_a_compiled_law_naming_control_law(model, home, law):
    t, R, z = home
    with pytest.raises(ValueError, match=r"^control_law: "):
        se.rollout(model, t, R, z, z, steps=10, control_law=law)


def test_rollout_law_giving_nan_forces_raises_naming_the_rows(model, home):
    t, R, z = home
    nan_forces = numba.cfunc(se.dynamics.rk4.numba_law_signature())(_nan_forces)
    with pytest.raises(FloatingPointError, match=r"non-finite in batch rows \[0\]"):
        se.rollout(model, t, R, z, z, steps=10, control_law=nan_forces)
    final = se.rollout(model, t, R, z, z, steps=10, control_law=nan_forces, check_finite=False)[0]
    assert np.isnan(final).all()  # unchecked, the rows come back NaN for the caller to see


@pytest.fixture(scope="module")
def pd_row(dasgupta, model):
    from stewart_env.agents.pd import pd_control_params
    ws = model.workspace(1)
    z = np.zeros(3)
    return pd_control_params(dasgupta, se.Reference(ws.position[0].copy(), ws.rotation[0].copy(), z, z))


@pytest.mark.parametrize("params, message", [
    ("nan", r"^control_params: contains NaN or inf"),
    ("3d", r"^control_params: expected an array \(P,\) or \(N, P\)"),
    ("str", r"^control_params: "),
])
def test_rollout_refuses_bad_control_params_naming_them(model, home, pd_row, params, message):
    from stewart_env.agents.pd import pd_control_law
    t, R, z = home
    value = {"nan": np.full_like(pd_row, np.nan), "3d": pd_row[None, None], "str": "abc"}[params]
    with pytest.raises(ValueError, match=message):
        se.rollout(model, t, R, z, z, steps=10, control_law=pd_control_law, control_params=value)


def test_rollout_takes_leg_forces_or_a_law_not_both(model, home, pd_row):
    from stewart_env.agents.pd import pd_control_law
    t, R, z = home
    with pytest.raises(ValueError, match=r"^leg_forces: "):
        se.rollout(model, t, R, z, z, np.zeros(6), steps=10, control_law=pd_control_law, control_params=pd_row)
    with pytest.raises(ValueError, match=r"^control_params: given without a control_law"):
        se.rollout(model, t, R, z, z, np.zeros(6), steps=10, control_params=pd_row)


@pytest.mark.parametrize("every", [0, -1, 3, 2.5, "2", 10**30])
def test_rollout_refuses_a_record_every_that_does_not_divide_steps(model, home, every):
    t, R, z = home
    with pytest.raises(ValueError, match=r"^record_every: "):
        se.rollout(model, t, R, z, z, np.zeros(6), steps=100, record_every=every)


def test_rollout_records_the_pd_law_every_tenth_step(model, home, pd_row):
    from stewart_env.agents.pd import pd_control_law
    t, R, z = home
    trajectory = se.rollout(model, t, R, z, z, dt=1e-3, steps=100, control_law=pd_control_law,
                            control_params=pd_row, record_every=10)
    assert trajectory.time.shape == (11,) and trajectory.position.shape == (11, 3)
    assert trajectory.leg_forces.shape == (11, 6)
    np.testing.assert_allclose(trajectory.time[[0, 1, -1]], [0.0, 0.01, 0.1], rtol=0, atol=1e-15)  # 10 * 1e-3 sums
    np.testing.assert_array_equal(trajectory.position[0], t)  # the start is recorded as given
    # the PD law held at home keeps the platform within 0.2 mm over 0.1 s (it sags ~0.12 mm under gravity)
    assert np.abs(trajectory.position - t).max() < 2e-4
    assert np.isfinite(trajectory.leg_forces).all()


@pytest.mark.parametrize("dt", [0, -1e-3, np.inf, np.nan])
def test_rollout_refuses_a_bad_dt(model, home, dt):
    t, R, z = home
    with pytest.raises(ValueError, match=r"^dt: "):
        se.rollout(model, t, R, z, z, np.zeros(6), dt=dt, steps=1)


# -- the environment's keywords and tasks -------------------------------------------------------


@pytest.fixture
def make():
    gym = pytest.importorskip("gymnasium")

    def make(**kwargs):
        env = gym.make("StewartPlatform-v1", **kwargs)
        env.reset(seed=0)
        return env
    return make


@pytest.mark.parametrize("name", ["termination_cost", "ctrl_cost_weight", "position_reward_scale"])
def test_old_reward_keywords_say_they_moved_to_task_options(make, name):
    with pytest.raises(TypeError, match=rf"the reward weights are options of the task: pass task_options=\{{'{name}'"):
        make(**{name: 1.0})


@pytest.mark.parametrize("name, value", [
    ("termination_cost", np.nan), ("termination_cost", np.inf), ("ctrl_cost_weight", -1.0),
    ("ctrl_cost_weight", 1e300), ("position_reward_scale", 0.0), ("velocity_cost_weight", "1"),
])
def test_hostile_reward_weights_are_refused_naming_the_option(make, name, value):
    with pytest.raises((ValueError, TypeError), match=rf"task_options\['{name}'\]"):
        make(task_options={name: value})


@pytest.mark.parametrize("options", [{"max_payload": -1.0}, {"max_payload": np.nan}, {"max_payload": 401.0},
                                     {"max_payload": True}, {"payload_radius": np.inf}])
def test_hold_task_refuses_hostile_payload_options(make, options):
    name = next(iter(options))
    with pytest.raises((ValueError, TypeError), match=rf"task_options\['{name}'\]"):
        make(task="hold", task_options=options)


def test_an_option_of_another_task_is_refused_listing_the_valid_ones(make):
    with pytest.raises(ValueError, match=r"unknown option\(s\) 'max_payload' for task 'setpoint'; valid options: "):
        make(task="setpoint", task_options={"max_payload": 3.0})


def test_hold_task_runs_and_rewards_are_finite(make):
    env = make(task="hold")
    for _ in range(5):
        _, reward, terminated, truncated, _ = env.step(np.zeros(6, np.float32))
        assert np.isfinite(reward)


# -- the MuJoCo twin ----------------------------------------------------------------------------


def test_export_mjcf_writes_a_model_mujoco_loads_into_a_new_folder(tmp_path, capsys):
    mujoco = pytest.importorskip("mujoco")
    out = tmp_path / "missing" / "folder" / "x.xml"
    assert main(["export-mjcf", "--platform", "dasgupta1998", "--out", str(out)]) == 0
    m = mujoco.MjModel.from_xml_path(str(out))
    assert m.neq == 6  # one connect constraint closes each leg's loop


@pytest.mark.parametrize("content, message", [
    ("hello: [\n", "not valid YAML"),
    ("gravity: !!python/object/apply:os.system ['echo hi']\n", "not valid YAML"),
    ("[]\n", "expected a mapping"),
    ("", "expected a mapping"),
])
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
    assert _exit_code(["export-mjcf", "--platform", "dasgupta1998", "--out", str(tmp_path / "x.xml"),
                       "--timestep", timestep]) == 2
    assert "argument --timestep" in capsys.readouterr().err
    assert not (tmp_path / "x.xml").exists()


def _exit_code(argv) -> int:
    """The command's exit code, whether argparse (SystemExit) or the command (its return) refused."""
    try:
        return main(argv)
    except SystemExit as stop:
        return stop.code


def test_to_mjcf_and_the_plant_refuse_bad_settings_naming_them(dasgupta):
    pytest.importorskip("mujoco")
    from stewart_env.mujoco import MujocoPlant, to_mjcf
    with pytest.raises(ValueError, match=r"^timestep: "):
        to_mjcf(dasgupta, timestep="x")
    with pytest.raises(ValueError, match=r"^nthread: "):
        MujocoPlant([dasgupta, dasgupta], nthread=-1)
    with pytest.raises(ValueError, match=r"^params_rows: "):
        MujocoPlant([])


def test_evaluate_runs_controllers_on_the_mujoco_plant(capsys):
    pytest.importorskip("mujoco")
    assert main(["evaluate", "--policy", "pd-gc", "--model", "mujoco", "--episodes", "1", "--max-steps", "5"]) == 0
    assert "| mujoco |" in capsys.readouterr().out


def test_train_takes_the_mujoco_plant_as_its_model():
    from stewart_env.cli import build_parser
    args = build_parser().parse_args(["train", "--algo", "ppo", "--out", "run", "--model", "mujoco"])
    assert args.model == "mujoco"


def test_evaluate_keeps_the_internal_model_closed_form(capsys):
    assert _exit_code(["evaluate", "--policy", "ct", "--internal-model", "mujoco", "--episodes", "1"]) == 2
    assert "argument --internal-model" in capsys.readouterr().err


@pytest.mark.parametrize("flag, value", [("--seeds", str(2**32)), ("--seeds", "0,0"), ("--max-steps", str(10**11)),
                                         ("--episodes", "0")])
def test_mismatch_refuses_a_setting_that_cannot_run_naming_the_flag(tmp_path, capsys, flag, value):
    assert _exit_code(["mismatch", "--out", str(tmp_path / "study"), "--algo", "none", flag, value]) == 2
    assert f"argument {flag}" in capsys.readouterr().err
    assert not (tmp_path / "study").exists()


def test_mismatch_says_how_to_fix_a_cost_plant_missing_from_the_test_models(tmp_path, capsys):
    code = _exit_code(["mismatch", "--out", str(tmp_path / "study"), "--algo", "none", "--test-models", "classical",
                       "--train-models", "improved", "--simplifications", "none", "--no-progress"])
    assert code == 2
    assert "pass --cost-plant" in capsys.readouterr().err


def _run_without(package: str, code: str) -> subprocess.CompletedProcess:
    """Run ``code`` in a fresh interpreter where ``package`` cannot be imported, as for a user
    who did not install its extra."""
    block = f"import sys; sys.modules[{package!r}] = None\n"
    return subprocess.run([sys.executable, "-c", block + code], capture_output=True, text=True, timeout=120)


def test_export_mjcf_without_mujoco_names_the_extra_without_a_traceback(tmp_path):
    run = _run_without("mujoco", "from stewart_env.cli import main\n"
                                 f"sys.exit(main(['export-mjcf', '--platform', 'dasgupta1998', '--out', {str(tmp_path / 'x.xml')!r}]))")
    assert run.returncode == 2
    assert run.stderr.startswith("stewart-env export-mjcf: error: ") and len(run.stderr.splitlines()) == 1
    assert 'pip install -e ".[mujoco]"' in run.stderr and "stewart-env[" not in run.stderr


def test_mujoco_env_without_mujoco_raises_import_error_naming_the_extra():
    run = _run_without("mujoco", "import gymnasium as gym, stewart_env\n"
                                 "try:\n    gym.make('StewartPlatform-v1', model='mujoco')\n"
                                 "except ImportError as e:\n    print(e)\n    sys.exit(3)\n")
    assert run.returncode == 3, run.stderr
    assert "model='mujoco'" in run.stdout and "[mujoco]" in run.stdout


def test_mismatch_ray_backend_without_ray_names_the_extra(tmp_path):
    run = _run_without("ray", "from stewart_env.cli import main\n"
                              f"sys.exit(main(['mismatch', '--backend', 'ray', '--algo', 'none', '--out', {str(tmp_path)!r}]))")
    assert run.returncode == 2
    assert "[distributed]" in run.stderr and "Traceback" not in run.stderr


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


# -- the command line ---------------------------------------------------------------------------


def _subcommands():
    import argparse

    from stewart_env.cli import build_parser
    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sorted(action.choices.items())


@pytest.mark.parametrize("name, parser", _subcommands(), ids=lambda x: x if isinstance(x, str) else "")
def test_every_subcommands_help_formats(name, parser):
    text = parser.format_help()  # argparse %-formats every help string: a bare % in one breaks --help
    assert f"stewart-env {name}" in text


def test_model_names_are_case_insensitive_and_mujoco_is_listed():
    """"MuJoCo" is the MuJoCo plant as "Improved" is the improved model; an unknown name lists both."""
    pytest.importorskip("mujoco")
    from stewart_env.envs import StewartPlatformEnv

    env = StewartPlatformEnv(model="MuJoCo")
    assert env.unwrapped.plant.name == "mujoco"
    env.close()
    with pytest.raises(ValueError, match=r"^model: unknown model 'nope'.*or 'mujoco'"):
        StewartPlatformEnv(model="nope")


def test_a_vector_env_too_large_for_memory_names_num_envs():
    from stewart_env.envs import StewartPlatformVectorEnv

    with pytest.raises(ValueError, match="^num_envs: 2147483647 platforms do not fit"):
        StewartPlatformVectorEnv(2**31 - 1)
