"""Files and options as a user's machine and a user's editor leave them: agents read on a laptop
with less memory than the bound of an agent's files, results published under the user's umask,
output folders left clean, documents nested deeply enough to exhaust Python's recursion, and an
edited identification report.  Every case ends in the result or one line naming the file or
option, never a traceback."""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

import stewart_env  # noqa: F401  (registers the environment)
from stewart_env import files
from stewart_env.cli import main
from stewart_env.files import FileError, FolderBusy, lock_folder, publish, publishing_folder, read_regular

#: The bound of an agent's files (stewart_env.agents.training.MAX_AGENT_FILE_BYTES), written out so
#: that the file-layer tests import no training code.
AGENT_FILE_BOUND = 16 << 30
#: Address space a process is given in the capped tests: an 8 GiB laptop's share, and room for
#: numpy and torch (loading a trained agent peaks near 0.9 GiB of address space on Linux x86-64).
ADDRESS_SPACE = 4 << 30
#: A document nested far deeper than Python's recursion limit.
DEEP = 100_000
#: Levels of a deep block mapping: beyond Python's recursion limit, within a config's 1 MiB
#: (each level indented one more space, the file grows as the square of its depth).
BLOCK_LEVELS = 1200


def capped(code: str, *args: str) -> subprocess.CompletedProcess:
    """``code`` run by a new Python whose address space is capped at ADDRESS_SPACE."""
    prelude = f"import resource, sys\nresource.setrlimit(resource.RLIMIT_AS, ({ADDRESS_SPACE}, {ADDRESS_SPACE}))\n"
    return subprocess.run(
        [sys.executable, "-c", prelude + code, *args],
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, "MPLBACKEND": "Agg"},
    )


def run_cli(argv: list[str], capsys) -> tuple[int, str]:
    """(exit code, stderr) of ``stewart-env argv``, argparse's refusals included."""
    try:
        code = main(argv)
    except SystemExit as stop:
        code = stop.code
    return code, capsys.readouterr().err


# -- reading by a file's size, not by its bound ---------------------------------------------------


def test_a_small_file_is_read_with_the_agent_bound_in_an_address_space_smaller_than_the_bound(tmp_path):
    small = tmp_path / "model.zip"
    small.write_bytes(b"x" * 1000)
    done = capped(
        f"from stewart_env.files import read_regular\nprint(len(read_regular(sys.argv[1], {AGENT_FILE_BOUND})))\n",
        str(small),
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "1000"


@pytest.mark.skipif(not Path("/proc/self/status").is_file(), reason="needs Linux's /proc")
def test_a_file_larger_than_its_reported_size_is_still_bounded():
    # /proc files are regular files of size 0 by fstat that hold hundreds of bytes
    assert os.stat("/proc/self/status").st_size == 0
    assert b"Pid:" in read_regular("/proc/self/status", 1 << 20)
    with pytest.raises(FileError, match=r"/proc/self/status: larger than 10 bytes"):
        read_regular("/proc/self/status", 10)


@pytest.mark.extra("rl")
def test_a_trained_agent_loads_in_an_address_space_smaller_than_the_bound_of_its_files(tmp_path):
    from stewart_env.agents.training import ENV_ID, MAX_AGENT_FILE_BYTES, train

    assert MAX_AGENT_FILE_BYTES == AGENT_FILE_BOUND > ADDRESS_SPACE
    config = tmp_path / "ppo.yml"
    config.write_text(
        yaml.safe_dump(
            {
                ENV_ID: {
                    "n_timesteps": 32,
                    "policy": "MlpPolicy",
                    "n_envs": 2,
                    "normalize": "dict(norm_obs=True, norm_reward=True)",
                    "n_steps": 16,
                    "batch_size": 32,
                    "n_epochs": 1,
                    "policy_kwargs": "dict(net_arch=dict(pi=[8], vf=[8]))",
                }
            }
        )
    )
    train("ppo", tmp_path / "agent", timesteps=32, config=config, progress_bar=False)
    done = capped(
        "from stewart_env.agents.training import load_agent\nprint(load_agent(sys.argv[1]).num_timesteps)\n",
        str(tmp_path / "agent"),
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "32"


# -- published files get the umask's modes -------------------------------------------------------


@contextlib.contextmanager
def umask(mask: int):
    old = os.umask(mask)
    try:
        yield
    finally:
        os.umask(old)


@pytest.mark.parametrize("mask, file_mode, folder_mode", [(0o022, 0o644, 0o755), (0o077, 0o600, 0o700)])
def test_published_files_and_folders_have_the_modes_of_the_umask(tmp_path, mask, file_mode, folder_mode):
    with umask(mask):
        publish(tmp_path / "summary.md", "text")
        with publishing_folder(tmp_path / "figures") as folder:
            (folder / "a.png").write_bytes(b"png")
        with files.publishing(tmp_path / "model.zip") as tmp:
            tmp.write_bytes(b"zip")
    assert oct((tmp_path / "summary.md").stat().st_mode & 0o777) == oct(file_mode)
    assert oct((tmp_path / "model.zip").stat().st_mode & 0o777) == oct(file_mode)
    assert oct((tmp_path / "figures").stat().st_mode & 0o777) == oct(folder_mode)
    assert oct((tmp_path / "figures" / "a.png").stat().st_mode & 0o777) == oct(file_mode)


# -- the lock file goes when its command ends -----------------------------------------------------


def test_the_lock_file_is_removed_when_the_command_ends(tmp_path, capsys):
    folder = tmp_path / "out"
    with lock_folder(folder):
        assert (folder / files.LOCK_FILE).read_text().strip() == str(os.getpid())
    assert list(folder.iterdir()) == []
    files.check_not_busy(folder)
    with pytest.raises(RuntimeError):
        with lock_folder(folder):
            raise RuntimeError("a command failing")
    assert list(folder.iterdir()) == []
    # a command: evaluate --out writes its results and leaves no lock file
    assert main(["evaluate", "--policy", "pd", "--episodes", "1", "--max-steps", "5", "--out", str(folder)]) == 0
    names = sorted(p.name for p in folder.iterdir())
    assert names and files.LOCK_FILE not in names, names


def test_a_locker_that_opened_the_removed_lock_file_locks_the_new_one(tmp_path, monkeypatch):
    """The race of removing the lock file: a second command opens it, the holder ends (removes it
    and closes it), the second command's flock then succeeds on the removed file.  It must notice
    and lock the file the path names, so that a third command is refused."""
    folder = tmp_path / "out"
    holder = contextlib.ExitStack()
    holder.enter_context(lock_folder(folder))
    real_flock, ended = fcntl.flock, []

    def flock_once_the_holder_ended(fd, operation):
        if operation & fcntl.LOCK_EX and not ended:
            ended.append(True)
            holder.close()  # the holder ends between the second command's open and its flock
        return real_flock(fd, operation)

    monkeypatch.setattr(files.fcntl, "flock", flock_once_the_holder_ended)
    monkeypatch.setattr(files, "check_not_busy", lambda directory: None)  # it ran before the holder ended
    monkeypatch.setattr(files, "_LOCK_RETRY_SECONDS", 0.0)
    with lock_folder(folder):
        lock = folder / files.LOCK_FILE
        assert ended and lock.read_text().strip() == str(os.getpid())
        with pytest.raises(FolderBusy, match=rf"\(PID {os.getpid()}\)"):
            with lock_folder(folder):
                pass
    assert not lock.exists()


def test_check_not_busy_looks_again_when_the_lock_file_it_opened_was_removed(tmp_path, monkeypatch):
    folder = tmp_path / "out"
    first, second = contextlib.ExitStack(), contextlib.ExitStack()
    first.enter_context(lock_folder(folder))
    real_flock, swapped = fcntl.flock, []

    def flock_once_another_command_holds_the_folder(fd, operation):
        if not swapped:
            swapped.append(True)
            first.close()  # the holder ends as check_not_busy opens its lock file
            second.enter_context(lock_folder(folder))  # and another command takes the folder
        return real_flock(fd, operation)

    monkeypatch.setattr(files.fcntl, "flock", flock_once_another_command_holds_the_folder)
    with pytest.raises(FolderBusy, match=rf"\(PID {os.getpid()}\)"):
        files.check_not_busy(folder)
    second.close()
    files.check_not_busy(folder)
    assert list(folder.iterdir()) == []


# -- documents nested deeper than Python's recursion ----------------------------------------------


def deep_yaml_mapping(levels: int) -> str:
    """A block mapping ``levels`` deep under the environment's id (a hyperparameter file's shape)."""
    return "StewartPlatform-v1:\n" + "".join(" " * i + "k:\n" for i in range(1, levels)) + " " * levels + "v: 1\n"


@pytest.mark.parametrize(
    "text",
    ["[" * DEEP, "[" * 101 + "]" * 101, '{"k": ' * 101 + "1" + "}" * 101, b"[" * DEEP],
    ids=["lists", "101 lists", "101 objects", "bytes"],
)
def test_load_json_refuses_a_deep_document_in_one_line(text):
    with pytest.raises(files.DocumentError, match=r"^not valid JSON \(nested more than 100 levels deep\)$"):
        files.load_json(text)
    assert files.load_json("[" * 100 + "]" * 100) is not None  # the bound itself is decoded


@pytest.mark.parametrize(
    "text",
    ["[" * DEEP, "{a: " * DEEP, deep_yaml_mapping(BLOCK_LEVELS)],
    ids=["flow lists", "flow mappings", "block mappings"],
)
def test_load_yaml_refuses_a_deep_document_in_one_line(text):
    with pytest.raises(
        files.DocumentError,
        match=r"^not valid YAML: line \d+, column \d+: nested more than 100 "
        r"levels deep$",
    ):
        files.load_yaml(text)


def test_load_yaml_tells_the_depth_by_the_error_type_not_its_words():
    with pytest.raises(files.DocumentError) as info:
        files.load_yaml("[" * 101 + "]" * 101)
    assert info.value.nested

    class Worded(yaml.SafeLoader):
        """A loader whose own error (not the depth) says "levels deep"."""

        def compose_node(self, parent, index):
            raise yaml.composer.ComposerError(None, None, "three levels deep in a list", self.peek_event().start_mark)

    with pytest.raises(files.DocumentError, match="three levels deep in a list$") as info:
        files.load_yaml("[1]", Worded)
    assert not info.value.nested


@pytest.mark.extra("rl")  # evaluate --agent and train name a missing rl extra before they read a file
def test_a_deep_run_json_is_one_line_for_evaluate_and_resume(tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    (run / "run.json").write_text("[" * DEEP)
    for argv in (
        ["evaluate", "--agent", str(run), "--episodes", "1"],
        ["train", "--algo", "ppo", "--resume", "--out", str(run), "--no-progress"],
    ):
        code, err = run_cli(argv, capsys)
        assert code == 2 and err.strip().endswith(
            f"{run / 'run.json'}: not valid JSON (nested more than 100 levels deep)"
        ), err
        assert len(err.strip().splitlines()) == 1, err


def test_a_deep_report_is_one_line_for_identify_predicted_by(tmp_path, capsys):
    report = tmp_path / "report.json"
    report.write_text('{"a": ' * DEEP)
    code, err = run_cli(["identify", "--predicted-by", str(report), "--out", str(tmp_path / "run")], capsys)
    assert code == 2 and err.strip() == (
        f"stewart-env identify: error: --predicted-by: {report}: not valid JSON (nested more than 100 levels deep)"
    )


@pytest.mark.parametrize(
    "token",
    ['{"a": ' * DEEP, "observation_noise=" + "[" * DEEP, "observation_noise=" + "[" * 101 + "]" * 101],
    ids=["object", "key=lists", "key=101 lists"],
)
def test_deep_env_kwargs_are_one_line_naming_the_option(tmp_path, capsys, token):
    code, err = run_cli(["train", "--algo", "ppo", "--env-kwargs", token, "--out", str(tmp_path / "run")], capsys)
    assert code == 2 and "--env-kwargs" in err and "nested more than 100 levels deep" in err, err[-500:]
    assert "Traceback" not in err and len(err.strip().splitlines()[-1]) < 300
    code, err = run_cli(
        [
            "mismatch",
            "--algo",
            "none",
            "--train-models",
            "improved",
            "--test-models",
            "improved",
            "--env-kwargs",
            token,
            "--out",
            str(tmp_path / "study"),
        ],
        capsys,
    )
    last = err.strip().splitlines()[-1]  # argparse's usage lines, then the error
    assert (
        code == 2
        and last.startswith("stewart-env mismatch: error: argument --env-kwargs")
        and "nested more than" in last
    )
    assert "Traceback" not in err and len(last) < 300, err[-500:]


def test_a_key_value_env_kwarg_that_is_not_json_is_still_a_string():
    from stewart_env.agents.training import parse_env_kwargs

    assert parse_env_kwargs(["platform=dasgupta1998", "name=[draft"]) == {"platform": "dasgupta1998", "name": "[draft"}


@pytest.mark.parametrize(
    "text",
    ["[" * DEEP, "{a: " * DEEP, deep_yaml_mapping(BLOCK_LEVELS)],
    ids=["flow lists", "flow mappings", "block mappings"],
)
def test_a_deep_platform_yaml_is_a_config_error_naming_the_file(tmp_path, capsys, text):
    import gymnasium as gym

    from stewart_env.params import ConfigError, load_platform

    path = tmp_path / "robot.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=rf"{path}.*nested more than 32 levels deep"):
        load_platform(path)
    with pytest.raises(ConfigError, match=rf"{path}.*nested more than 32 levels deep"):
        gym.make("StewartPlatform-v1", platform=str(path))
    code, err = run_cli(["evaluate", "--platform", str(path), "--episodes", "1"], capsys)
    assert code == 2 and "--platform" in err and "nested more than 32 levels deep" in err.splitlines()[-1], err


@pytest.mark.extra("rl")  # train names a missing rl extra before it reads the config
@pytest.mark.parametrize("text", ["[" * DEEP, deep_yaml_mapping(BLOCK_LEVELS)], ids=["flow lists", "block mappings"])
def test_a_deep_hyperparameter_yaml_is_one_line_naming_the_file(tmp_path, capsys, text):
    config = tmp_path / "ppo.yml"
    config.write_text(text)
    code, err = run_cli(
        [
            "train",
            "--algo",
            "ppo",
            "--config",
            str(config),
            "--timesteps",
            "32",
            "--out",
            str(tmp_path / "run"),
            "--no-progress",
        ],
        capsys,
    )
    assert code == 2 and err.strip().startswith(f"stewart-env train: error: {config}: not valid YAML: line ")
    assert err.strip().endswith("nested more than 100 levels deep") and len(err.strip().splitlines()) == 1, err


# -- an edited identification report --------------------------------------------------------------


def minimal_report() -> dict:
    """The fields of a report.json that ``identify --predicted-by`` reads, as identify writes them."""
    return {
        "platform": "dasgupta1998",
        "settings": {"model": "improved", "noise_force": 1.0},
        "fitted_duration": 5.0,
        "base_parameters": [
            {"name": "platform.m", "wls": 12.5, "wls_std": 0.1},
            {"name": "damping.b", "wls": 0.0, "wls_std": 0.02},
        ],
    }


def edited(path: str, value) -> dict:
    """minimal_report() with the value at ``path`` (keys and list indices by dots) replaced, or
    removed when ``value`` is the ``removed`` sentinel."""
    report = minimal_report()
    *parents, last = [int(part) if part.isdigit() else part for part in path.split(".")]
    node = report
    for part in parents:
        node = node[part]
    if value is removed:
        del node[last]
    else:
        node[last] = value
    return report


removed = object()


@pytest.mark.parametrize(
    "path, value, says",
    [
        ("settings.noise_force", 0, "settings.noise_force: expected a number > 0, got 0"),
        ("settings.noise_force", "NaN", "settings.noise_force: expected a number > 0, got 'NaN'"),
        ("settings.noise_force", removed, "not a report.json of stewart-env identify (no settings.noise_force)"),
        ("fitted_duration", "5", "fitted_duration: expected a number > 0, got '5'"),
        ("fitted_duration", -5.0, "fitted_duration: expected a number > 0, got -5.0"),
        ("fitted_duration", None, "fitted_duration: expected a number > 0, got None"),
        ("fitted_duration", [5.0], "fitted_duration: expected a number > 0, got [5.0]"),
        ("fitted_duration", removed, "not a report.json of stewart-env identify (no fitted_duration)"),
        ("base_parameters.1.wls_std", 0.0, "base_parameters[1].wls_std: expected a number > 0, got 0.0"),
        ("base_parameters.1.wls_std", None, "base_parameters[1].wls_std: expected a number > 0, got None"),
        ("base_parameters.1.wls_std", True, "base_parameters[1].wls_std: expected a number > 0, got True"),
        ("base_parameters.0.wls", "12.5", "base_parameters[0].wls: expected a finite number, got '12.5'"),
        ("base_parameters.0.wls", removed, "not a report.json of stewart-env identify (no base_parameters[0].wls)"),
        ("base_parameters.0.name", 7, "base_parameters[0].name: expected text, got 7"),
        (
            "base_parameters.0",
            [1.0],
            "not a report.json of stewart-env identify (base_parameters[0] is [1.0], not an object)",
        ),
        ("base_parameters", [], "base_parameters: expected a list of base parameters, got []"),
        (
            "base_parameters",
            {"platform.m": 1.0},
            "base_parameters: expected a list of base parameters, got {'platform.m': 1.0}",
        ),
        ("settings", None, "not a report.json of stewart-env identify (settings is None, not an object)"),
        ("platform", 3, "platform: expected text, got 3"),
    ],
    ids=lambda x: None,
)
def test_an_edited_report_is_refused_naming_the_file_and_the_key(tmp_path, capsys, path, value, says):
    from stewart_env.identification.base import IdentificationError
    from stewart_env.identification.experiment import read_report

    report = tmp_path / "report.json"
    report.write_text(json.dumps(edited(path, value)))
    with pytest.raises(IdentificationError) as caught:
        read_report(report)
    assert str(caught.value) == f"{report}: {says}"
    # the command refuses it in one line before any work
    out = tmp_path / "run"
    code, err = run_cli(["identify", "--predicted-by", str(report), "--out", str(out)], capsys)
    assert code == 2 and err == f"stewart-env identify: error: --predicted-by: {report}: {says}\n"
    assert not out.exists()


@pytest.mark.parametrize("literal", ["NaN", "Infinity", "-Infinity", "1e400"])
def test_a_report_with_a_non_finite_number_is_refused(tmp_path, literal):
    from stewart_env.identification.base import IdentificationError
    from stewart_env.identification.experiment import read_report

    report = tmp_path / "report.json"
    report.write_text(json.dumps(minimal_report()).replace('"wls_std": 0.1', f'"wls_std": {literal}'))
    with pytest.raises(
        IdentificationError,
        match=r"base_parameters\[0\]\.wls_std: expected a number > 0, got "
        r"-?(nan|inf)$",
    ):
        read_report(report)


def test_the_unedited_report_is_read_and_the_python_keyword_is_checked_alike(tmp_path):
    from stewart_env.identification import experiment
    from stewart_env.identification.base import IdentificationError
    from stewart_env.params import load_platform

    path = tmp_path / "report.json"
    path.write_text(json.dumps(minimal_report()))
    assert experiment.read_report(path) == minimal_report()
    settings = experiment.Settings(excitation="random", duration=6.0, period=3.0, noise_force=1.0)
    with pytest.raises(IdentificationError, match=r"^--predicted-by: fitted_duration: expected a number > 0, got 0$"):
        experiment.run(settings, load_platform("dasgupta1998"), predicted_by=edited("fitted_duration", 0))


def strict_json(text: str):
    """JSON as the standard has it: NaN and Infinity are not JSON."""

    def refuse(name):
        raise ValueError(f"not strict JSON: {name}")

    return json.loads(text, parse_constant=refuse)


def test_the_report_written_is_strict_json_with_null_for_numbers_that_are_not_finite(tmp_path):
    from stewart_env.identification import experiment
    from stewart_env.params import load_platform

    platform = load_platform("dasgupta1998")
    settings = experiment.Settings(noise_force=1.0)
    row = {
        "name": "platform.m",
        "ols": 1.0,
        "ols_std": float("nan"),
        "wls": 1.0,
        "wls_std": float("inf"),
        "rel_std": None,
        "duration_10pct": None,
        "noise_force_10pct": None,
        "near_zero": False,
        "consistent": 1.0,
        "nominal": 1.0,
    }
    report = {
        "settings": settings.__dict__.copy(),
        "platform": platform.name,
        "samples": 10,
        "delay_samples": 0,
        "fitted_duration": 5.0,
        "rank": 1,
        "n_theta": 1,
        "rank_tolerance": 1e-9,
        "condition_number": float("inf"),
        "condition_number_start": float("nan"),
        "residual_sigma_wls": [1.0, float("-inf")],
        "base_parameters_under_10pct_rel_std": 0,
        "held_out_rms_force": 1.0,
        "held_out_force_error": {"nominal": 1.0, "ols": 1.0, "wls": 1.0, "consistent": 1.0},
        "base_parameters": [row],
    }
    folder = experiment.write(experiment.Result(settings, platform, platform, report), tmp_path / "run")
    written = strict_json((folder / "report.json").read_text())
    assert written["condition_number"] is None and written["condition_number_start"] is None
    assert written["residual_sigma_wls"] == [1.0, None]
    assert written["base_parameters"][0]["ols_std"] is None and written["base_parameters"][0]["wls_std"] is None
    assert written["fitted_duration"] == 5.0 and written["platform"] == "dasgupta1998"
    assert (
        "condition number of the stacked base regressor: inf (random start nan)" in (folder / "report.md").read_text()
    )


@pytest.mark.extra("rl")  # train names a missing rl extra before it reads the config
@pytest.mark.parametrize(
    "expression",
    ["-" * DEEP + "1", "a." * DEEP + "b", "dict(net_arch=" + "[" * DEEP],
    ids=["unary chain", "attribute chain", "brackets"],
)
def test_a_deep_zoo_expression_in_a_hyperparameter_file_is_one_line_naming_the_key(tmp_path, capsys, expression):
    config = tmp_path / "ppo.yml"
    config.write_text(
        yaml.safe_dump(
            {"StewartPlatform-v1": {"n_timesteps": 32, "policy": "MlpPolicy", "policy_kwargs": expression}},
            width=1 << 30,
        )
    )
    code, err = run_cli(
        [
            "train",
            "--algo",
            "ppo",
            "--config",
            str(config),
            "--timesteps",
            "32",
            "--out",
            str(tmp_path / "run"),
            "--no-progress",
        ],
        capsys,
    )
    assert code == 2 and err.startswith("stewart-env train: error: ") and "policy_kwargs: not an expression" in err
    assert len(err.strip().splitlines()) == 1 and len(err) < 300, err[-300:]
