"""The ``stewart-env`` command."""

import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from stewart_env.cli import main

from conftest import exit_code


@pytest.mark.parametrize(
    "command, expected",
    [
        ("demo", "--episodes"),
        ("evaluate", "--internal-model"),
        ("reproduce", "--duration"),
    ],
)
def test_subcommand_help(command, expected, capsys):
    with pytest.raises(SystemExit) as stop:
        main([command, "--help"])
    assert stop.value.code == 0
    assert expected in capsys.readouterr().out


def test_top_level_help_lists_the_subcommands(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    for command in ("demo", "evaluate", "reproduce", "train", "mismatch", "bench", "export-mjcf"):
        assert command in out


def test_bench_is_dispatched_with_its_arguments(monkeypatch):
    import stewart_env.benchmarks
    from stewart_env.dynamics import ModelSpec

    seen = []
    monkeypatch.setattr(stewart_env.benchmarks, "run_bench", lambda *args, **kwargs: seen.append((args, kwargs)))
    assert main(["bench", "--models", "improved", "--env"]) == 0
    assert seen == [
        (("dasgupta1998", [ModelSpec()]), {"env": True, "mujoco": False, "plot": None, "derivatives": False})
    ]


def test_bench_is_a_subparser_with_its_own_help(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["bench", "--help"])
    assert stop.value.code == 0
    assert "usage: stewart-env bench" in capsys.readouterr().out
    with pytest.raises(SystemExit) as stop:
        main(["bench", "--num-envs", "4"])
    assert stop.value.code == 2
    assert "unrecognized arguments: --num-envs 4" in capsys.readouterr().err


def test_demo_prints_the_comparison_table(capsys):
    assert main(["demo", "--episodes", "1"]) == 0
    out = capsys.readouterr().out
    # without compensation the platform sags 27 mm, outside the 2 mm success band; with it, it settles
    rows = {tuple(line.split()[:-5]): line.split()[-5] for line in out.splitlines()[4:8]}  # name -> success
    assert rows == {
        ("PD", "classical"): "0%",
        ("PD", "improved"): "0%",
        ("PD", "+", "gravity", "comp.", "classical"): "100%",
        ("PD", "+", "gravity", "comp.", "improved"): "100%",
    }, out


def test_evaluate_writes_a_report(tmp_path, capsys):
    assert (
        main(
            [
                "evaluate",
                "--policy",
                "pd",
                "ct",
                "--internal-model",
                "classical",
                "--model",
                "improved",
                "--task",
                "tracking",
                "--episodes",
                "1",
                "--max-steps",
                "10",
                "--out",
                str(tmp_path),
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "| PD | improved | tracking |" in out and "| CT (classical) | improved | tracking |" in out
    assert (tmp_path / "results.md").exists() and (tmp_path / "episodes.csv").exists()
    assert (tmp_path / "error_norms.png").exists()


@pytest.mark.extra("rl")
@pytest.mark.filterwarnings("ignore:You have specified a mini-batch size")  # the config's batch, our tiny run
def test_evaluate_a_trained_agent_beside_a_baseline(tmp_path, capsys):
    from stewart_env.agents.training import train

    # a few hundred steps of PPO: an untrained agent, enough to test loading and evaluating it
    train("ppo", tmp_path / "agent", timesteps=64, n_envs=2, checkpoint_freq=0, progress_bar=False)
    assert (
        main(
            [
                "evaluate",
                "--agent",
                str(tmp_path / "agent"),
                "--policy",
                "pd",
                "--model",
                "classical",
                "--episodes",
                "1",
                "--max-steps",
                "5",
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "| PPO (improved) | classical | setpoint | 1 |" in out and "| PD | classical | setpoint | 1 |" in out
    # two agents of one algorithm and model: their rows are named by run directory
    shutil.copytree(tmp_path / "agent", tmp_path / "agent_b")
    assert (
        main(
            [
                "evaluate",
                "--agent",
                str(tmp_path / "agent"),
                str(tmp_path / "agent_b"),
                "--episodes",
                "1",
                "--max-steps",
                "2",
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "| PPO (improved) agent | improved |" in out and "| PPO (improved) agent_b | improved |" in out
    assert main(["evaluate", "--agent", str(tmp_path / "missing")]) == 2
    assert "missing" in capsys.readouterr().err


def test_bad_model_name_is_refused(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["evaluate", "--model", "newtonian"])
    assert stop.value.code == 2
    assert "newtonian" in capsys.readouterr().err


@pytest.mark.skipif(shutil.which("stewart-env") is None, reason="the console script is not installed")
def test_console_script():
    done = subprocess.run(["stewart-env", "reproduce", "--help"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and "--out" in done.stdout


@pytest.mark.parametrize(
    "argv",
    [
        ["train", "--algo", "ppo", "--timesteps", "10"],
        ["evaluate", "--agent", "runs/ppo"],
        ["mismatch", "--algo", "ppo"],
    ],
)
def test_commands_that_need_stable_baselines3_say_which_extra_before_writing(argv, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "stable_baselines3", None)  # find_spec: not installed
    out = tmp_path / "out"
    assert main(argv + ["--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert 'pip install -e ".[rl]"' in err and "torch==2.13.0" in err and "stewart-env[" not in err
    assert len(err.strip().splitlines()) == 1 and err.startswith(f"stewart-env {argv[0]}: error: ")
    assert not out.exists()


@pytest.mark.parametrize(
    "argv",
    [
        ["demo"],
        ["evaluate"],
        ["reproduce"],
        pytest.param(["train", "--algo", "ppo"], marks=pytest.mark.extra("rl")),
        ["mismatch", "--algo", "none"],
    ],
)
def test_unwritable_out_is_refused_before_any_work(argv, tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("")  # a directory cannot be made below a file, even by root
    start = time.perf_counter()
    assert main(argv + ["--out", str(blocker / "out")]) == 2
    err = capsys.readouterr().err
    assert "argument --out" in err and "is not writable: Not a directory" in err
    assert time.perf_counter() - start < 5  # refused up front: no episode, figure or training ran


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs Linux's /proc")
def test_out_on_a_file_system_that_refuses_even_root_is_refused(capsys):
    # permission bits say yes to root everywhere; only a real probe finds that /proc takes no folder
    assert main(["demo", "--out", "/proc/stewart-env-out"]) == 2
    assert "argument --out: output directory '/proc/stewart-env-out' is not writable" in capsys.readouterr().err


def test_the_out_probe_leaves_nothing_behind(tmp_path):
    from stewart_env.files import check_writable

    check_writable(tmp_path / "a" / "b", create=False)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "argv, flag",
    [
        (["train", "--algo", "a2c"], "--algo"),
        (["train", "--algo", "ppo", "--timesteps", "0"], "--timesteps"),
        (["train", "--algo", "ppo", "--timesteps", "1e5"], "--timesteps"),
        (["train", "--algo", "ppo", "--seed", "-1"], "--seed"),
        (["train", "--algo", "ppo", "--n-envs", "two"], "--n-envs"),
        (["train", "--algo", "ppo", "--checkpoint-freq", "-5"], "--checkpoint-freq"),
        (["train", "--algo", "ppo", "--keep-checkpoints", "0"], "--keep-checkpoints"),
        (["train", "--algo", "ppo", "--config", "missing.yml"], "--config"),
        (["train", "--algo", "ppo", "--task", "hover"], "--task"),
        (["train", "--algo", "ppo", "--model", "newtonian"], "--model"),
        (["train", "--algo", "ppo", "--env-kwargs", "control_dt"], "--env-kwargs"),
        (["demo", "--episodes", "0"], "--episodes"),
        (["demo", "--seed", "-3"], "--seed"),
        (["demo", "--platform", "nowhere"], "--platform"),
        (["evaluate", "--max-steps", "0"], "--max-steps"),
        (["reproduce", "--duration", "nan"], "--duration"),
        (["reproduce", "--dt", "inf"], "--dt"),
    ],
)
def test_bad_flag_values_are_argparse_errors_naming_the_flag(argv, flag, tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        main(argv + ["--out", str(tmp_path / "out")])
    assert stop.value.code == 2
    assert f"argument {flag}" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


@pytest.mark.extra("rl")
def test_train_cli_says_how_many_steps_it_ran(tmp_path, capsys):
    config = tmp_path / "ppo.yml"
    config.write_text(
        "StewartPlatform-v1:\n  n_timesteps: 1000\n  policy: MlpPolicy\n  n_envs: 2\n  n_steps: 16\n"
        '  batch_size: 32\n  n_epochs: 1\n  policy_kwargs: "dict(net_arch=[8])"\n'
    )
    assert (
        main(["train", "--algo", "ppo", "--config", str(config), "--timesteps", "40", "--out", str(tmp_path / "run")])
        == 0
    )
    # rollouts of 2 platforms x 16 steps: 40 requested steps take 2 of them
    assert "requested 40 steps, ran 64 (whole rollouts of 32)" in capsys.readouterr().out


def test_reproduce_refuses_a_platform_whose_stroke_the_case_leaves(tmp_path, capsys):
    import yaml

    import stewart_env as se

    d = se.load_platform("dasgupta1998").to_dict()
    d["limits"]["leg_length"] = [1.0, 1.3]  # the case's legs reach about 1.43 m
    path = tmp_path / "short.yaml"
    path.write_text(yaml.safe_dump(d))
    assert main(["reproduce", "--platform", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "leaves the leg stroke" in err and "leg 0" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_export_mjcf_writes_a_model_mujoco_loads(tmp_path, capsys):
    mujoco = pytest.importorskip("mujoco")
    out = tmp_path / "models" / "stewart.xml"
    assert main(["export-mjcf", "--platform", "motion_simulator", "--out", str(out)]) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    model = mujoco.MjModel.from_xml_path(str(out))
    assert (model.nbody, model.neq, model.nu) == (14, 6, 6)  # world, platform, 6 x 2 leg bodies
    # an existing file is overwritten, like the reports of the other commands
    assert main(["export-mjcf", "--platform", "dasgupta1998", "--out", str(out), "--timestep", "0.002"]) == 0
    assert mujoco.MjModel.from_xml_path(str(out)).opt.timestep == 0.002


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--out", "{tmp}"], "argument --out: '{tmp}' is a directory"),
        (["--out", "{tmp}/file/model.xml"], "argument --out: output directory '{tmp}/file' is not writable"),
        (["--out", "{tmp}/m.xml", "--solimp", "1", "1", "0.001", "0.5", "2"], "argument --solimp: d_min and d_max"),
        (["--out", "{tmp}/m.xml", "--solref", "0.02", "nan"], "argument --solref: expected a finite number"),
        (
            ["--out", "{tmp}/m.xml", "--timestep", "1e300"],
            "argument --timestep: must be a number of seconds in (0, 0.1]",
        ),
    ],
)
def test_export_mjcf_errors_name_the_argument(argv, message, tmp_path, capsys):
    pytest.importorskip("mujoco")
    (tmp_path / "file").write_text("")
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    assert exit_code(["export-mjcf", "--platform", "dasgupta1998", *argv]) == 2
    err = capsys.readouterr().err
    assert message.replace("{tmp}", str(tmp_path)) in err and "Traceback" not in err
    assert not (tmp_path / "m.xml").exists()


def test_export_mjcf_write_failure_is_an_error_naming_out(tmp_path, monkeypatch, capsys):
    pytest.importorskip("mujoco")

    write_text = Path.write_text

    def full(self, *args, **kwargs):
        if self.name != "m.xml":  # the up-front probe of --out's folder still succeeds
            return write_text(self, *args, **kwargs)
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Path, "write_text", full)  # a disk that fills up after the up-front check
    assert main(["export-mjcf", "--platform", "dasgupta1998", "--out", str(tmp_path / "m.xml")]) == 2
    err = capsys.readouterr().err
    assert f"argument --out: cannot write '{tmp_path / 'm.xml'}': No space left on device" in err
    assert "Traceback" not in err


def test_export_mjcf_without_mujoco_names_the_extra(tmp_path, monkeypatch, capsys):
    from stewart_env import mujoco as twin

    monkeypatch.setattr(twin.library, "_mj", None)
    assert main(["export-mjcf", "--platform", "dasgupta1998", "--out", str(tmp_path / "m.xml")]) == 2
    assert 'pip install -e ".[mujoco]"' in capsys.readouterr().err
    assert not (tmp_path / "m.xml").exists()


def test_evaluate_runs_a_baseline_on_the_mujoco_plant(capsys):
    pytest.importorskip("mujoco")
    assert (
        main(["evaluate", "--policy", "pd", "--model", "improved", "mujoco", "--episodes", "1", "--max-steps", "5"])
        == 0
    )
    out = capsys.readouterr().out
    assert "| PD | improved | setpoint | 1 |" in out and "| PD | mujoco | setpoint | 1 |" in out
    with pytest.raises(SystemExit):
        main(["evaluate", "--policy", "ct", "--internal-model", "mujoco"])  # a controller needs closed-form dynamics
    assert "argument --internal-model" in capsys.readouterr().err


# -- first contact ---------------------------------------------------------------------------------


def test_version(capsys):
    import stewart_env

    with pytest.raises(SystemExit) as stop:
        main(["--version"])
    assert stop.value.code == 0
    assert capsys.readouterr().out == f"stewart-env {stewart_env.__version__}\n"


@pytest.mark.parametrize(
    "argv, expected",
    [
        (["--help"], "usage: stewart-env [-h] [--version] COMMAND"),
        (["evaluate", "--help"], "usage: stewart-env evaluate"),
    ],
)
def test_python_m_stewart_env_is_the_command(argv, expected):
    done = subprocess.run([sys.executable, "-m", "stewart_env", *argv], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith(expected)


def test_help_texts_say_what_the_user_needs(capsys):
    for verb in ("mismatch", "evaluate"):
        with pytest.raises(SystemExit):
            main([verb, "--help"])
        text = capsys.readouterr().out
        assert "%%" not in text
        if verb == "evaluate":
            assert "--agent" in text.split("options:")[0]  # the description names trained agents


def _without(module: str, argv: list[str]) -> subprocess.CompletedProcess:
    """``stewart-env argv`` in a fresh interpreter where ``module`` cannot be imported, as for a
    user who did not install its extra."""
    # a finder that refuses the module, as an absent one is: not `sys.modules[name] = None`, which
    # other libraries read as present (scipy's array-API checks look torch up in sys.modules)
    code = (
        "import sys, importlib.abc\n"
        "class Absent(importlib.abc.MetaPathFinder):\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        f"        if name == {module!r} or name.startswith({module!r} + '.'):\n"
        "            raise ModuleNotFoundError(f'No module named {name!r}', name=name)\n"
        "sys.meta_path.insert(0, Absent())\n"
        f"from stewart_env.cli import main\nsys.exit(main({argv!r}))"
    )
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize(
    "module, argv, extra",
    [
        ("mujoco", ["evaluate", "--model", "mujoco", "--episodes", "1"], "mujoco"),
        pytest.param(
            "mujoco",
            ["train", "--algo", "ppo", "--model", "mujoco", "--out", "OUT"],
            "mujoco",
            marks=pytest.mark.extra("rl"),
        ),  # without rl, train names that extra first
        ("mujoco", ["bench", "--mujoco"], "mujoco"),
        ("mujoco", ["export-mjcf", "--platform", "dasgupta1998", "--out", "OUT/m.xml"], "mujoco"),
        ("stable_baselines3", ["evaluate", "--agent", "OUT"], "rl"),
        ("torch", ["train", "--algo", "ppo", "--out", "OUT"], "rl"),
        ("stable_baselines3", ["mismatch", "--out", "OUT"], "rl"),
        ("ray", ["mismatch", "--backend", "ray", "--algo", "none", "--out", "OUT"], "distributed"),
    ],
    ids=lambda x: x if isinstance(x, str) else None,
)
def test_a_missing_extra_is_one_line_naming_it(module, argv, extra, tmp_path):
    out = tmp_path / "out"
    done = _without(module, [str(out) if a == "OUT" else a.replace("OUT", str(out)) for a in argv])
    verb = argv[0]
    assert done.returncode == 2, done.stderr
    assert done.stderr.startswith(f"stewart-env {verb}: error: ") and len(done.stderr.splitlines()) == 1, done.stderr
    assert f'pip install -e ".[{extra}]"' in done.stderr and "stewart-env[" not in done.stderr
    assert not out.exists()


def test_a_failed_import_of_an_extra_deep_in_a_command_is_one_line(monkeypatch, capsys):
    """Whatever the command, an ImportError of an extra's module that escapes it is one line."""
    from stewart_env.cli import demo

    def fails(args):
        import ray  # noqa: F401

    monkeypatch.setitem(sys.modules, "ray", None)
    monkeypatch.setattr(demo, "run", fails)
    assert main(["demo"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("stewart-env demo: error: ") and err.rstrip().endswith('pip install -e ".[distributed]"')


@pytest.mark.parametrize("name", ["ppo_6m", "ppo_6m.yml"])
def test_config_takes_a_shipped_config_by_name(name, tmp_path, monkeypatch):
    from stewart_env.agents.training import CONFIG_DIR, config_path
    from stewart_env.cli import build_parser

    monkeypatch.chdir(tmp_path)  # no file of that name here: the shipped one is meant
    args = build_parser().parse_args(["train", "--algo", "ppo", "--config", name, "--out", "run"])
    assert Path(args.config) == CONFIG_DIR / "ppo_6m.yml" and Path(args.config).is_file()
    args = build_parser().parse_args(["mismatch", "--config", name, "--out", "study"])
    assert Path(args.config) == CONFIG_DIR / "ppo_6m.yml"
    assert config_path("ppo", name) == CONFIG_DIR / "ppo_6m.yml"
    (tmp_path / name).write_text("StewartPlatform-v0: {}\n")
    # with the suffix, a file of the name in the working directory is meant; without it, the shipped one always
    assert config_path("ppo", name) == (Path(name) if name.endswith(".yml") else CONFIG_DIR / "ppo_6m.yml")


def test_config_by_an_unknown_name_lists_the_shipped_ones(tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        main(["train", "--algo", "ppo", "--config", "ppo_fast", "--out", str(tmp_path / "run")])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "argument --config: unknown shipped config 'ppo_fast'" in err
    assert (
        "crossq, ppo, ppo_6m, ppo_cueing, ppo_cueing_mpc, ppo_cueing_mpc_residual, ppo_cueing_residual, ppo_integral_6m, ppo_leg_length, ppo_pose, sac, td3, tqc"
        in err
    )


@pytest.mark.parametrize(
    "module, usage",
    [("stewart_env.mujoco", "usage: python -m stewart_env.mujoco"), ("stewart_env.cli", "usage: stewart-env [-h]")],
)
def test_the_modules_run_with_python_m_go_through_the_command_line(module, usage):
    done = subprocess.run([sys.executable, "-m", module, "--help"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith(usage)


# -- the command line: the MuJoCo plant, the study's flags, missing extras, every verb's help ---


def test_evaluate_runs_controllers_on_the_mujoco_plant(capsys):
    pytest.importorskip("mujoco")
    assert main(["evaluate", "--policy", "pd-gc", "--model", "mujoco", "--episodes", "1", "--max-steps", "5"]) == 0
    assert "| mujoco |" in capsys.readouterr().out


def test_train_takes_the_mujoco_plant_as_its_model():
    from stewart_env.cli import build_parser

    args = build_parser().parse_args(["train", "--algo", "ppo", "--out", "run", "--model", "mujoco"])
    assert args.model == "mujoco"


def test_evaluate_keeps_the_internal_model_closed_form(capsys):
    assert exit_code(["evaluate", "--policy", "ct", "--internal-model", "mujoco", "--episodes", "1"]) == 2
    assert "argument --internal-model" in capsys.readouterr().err


@pytest.mark.parametrize(
    "flag, value", [("--seeds", str(2**32)), ("--seeds", "0,0"), ("--max-steps", str(10**11)), ("--episodes", "0")]
)
def test_mismatch_refuses_a_setting_that_cannot_run_naming_the_flag(tmp_path, capsys, flag, value):
    assert exit_code(["mismatch", "--out", str(tmp_path / "study"), "--algo", "none", flag, value]) == 2
    assert f"argument {flag}" in capsys.readouterr().err
    assert not (tmp_path / "study").exists()


def test_mismatch_says_how_to_fix_a_cost_plant_missing_from_the_test_models(tmp_path, capsys):
    code = exit_code(
        [
            "mismatch",
            "--out",
            str(tmp_path / "study"),
            "--algo",
            "none",
            "--test-models",
            "classical",
            "--train-models",
            "improved",
            "--simplifications",
            "none",
            "--no-progress",
        ]
    )
    assert code == 2
    assert "pass --cost-plant" in capsys.readouterr().err


def _run_without(package: str, code: str) -> subprocess.CompletedProcess:
    """Run ``code`` in a fresh interpreter where ``package`` cannot be imported, as for a user
    who did not install its extra."""
    block = f"import sys; sys.modules[{package!r}] = None\n"
    return subprocess.run([sys.executable, "-c", block + code], capture_output=True, text=True, timeout=120)


def test_export_mjcf_without_mujoco_names_the_extra_without_a_traceback(tmp_path):
    run = _run_without(
        "mujoco",
        "from stewart_env.cli import main\n"
        f"sys.exit(main(['export-mjcf', '--platform', 'dasgupta1998', '--out', {str(tmp_path / 'x.xml')!r}]))",
    )
    assert run.returncode == 2
    assert run.stderr.startswith("stewart-env export-mjcf: error: ") and len(run.stderr.splitlines()) == 1
    assert 'pip install -e ".[mujoco]"' in run.stderr and "stewart-env[" not in run.stderr


def test_mujoco_env_without_mujoco_raises_import_error_naming_the_extra():
    run = _run_without(
        "mujoco",
        "import gymnasium as gym, stewart_env\n"
        "try:\n    gym.make('StewartPlatform-v1', model='mujoco')\n"
        "except ImportError as e:\n    print(e)\n    sys.exit(3)\n",
    )
    assert run.returncode == 3, run.stderr
    assert "model='mujoco'" in run.stdout and "[mujoco]" in run.stdout


def test_mismatch_ray_backend_without_ray_names_the_extra(tmp_path):
    run = _run_without(
        "ray",
        "from stewart_env.cli import main\n"
        f"sys.exit(main(['mismatch', '--backend', 'ray', '--algo', 'none', '--out', {str(tmp_path)!r}]))",
    )
    assert run.returncode == 2
    assert "[distributed]" in run.stderr and "Traceback" not in run.stderr


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
