"""A shipped platform's name against what the working directory holds: a folder or file named
like a shipped platform (left by ``--out dasgupta1998``) never hides it.  The rule: a string with
no path separator and no .yaml/.yml suffix is a shipped platform's name; anything with a
separator or a YAML suffix, or a Path, is a file."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import pytest

import stewart_env  # noqa: F401  (registers the environment)
from stewart_env.params import ConfigError, load_platform
from stewart_env.params.shipped import config_dir, is_platform_name


@pytest.fixture
def cluttered(tmp_path, monkeypatch):
    """A working directory holding a folder named dasgupta1998 and a file named motion_simulator."""
    (tmp_path / "dasgupta1998").mkdir()
    (tmp_path / "dasgupta1998" / "run.json").write_text("{}")
    (tmp_path / "motion_simulator").write_text("not a config\n")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_the_default_platform_and_the_shipped_names_load_whatever_the_working_directory_holds(cluttered):
    env = gym.make("StewartPlatform-v1")
    assert env.unwrapped.platform.name == "dasgupta1998"
    env.close()
    assert load_platform("dasgupta1998").name == "dasgupta1998"
    assert load_platform("motion_simulator").name == "motion_simulator"
    assert gym.make("StewartPlatform-v1", platform="motion_simulator").unwrapped.platform.name == "motion_simulator"


@pytest.mark.parametrize(
    "given", ["./dasgupta1998", Path("dasgupta1998"), "./motion_simulator", Path("motion_simulator")], ids=str
)
def test_a_path_is_a_file_and_its_error_names_the_path(cluttered, given):
    with pytest.raises(ConfigError) as caught:
        load_platform(given)
    message = str(caught.value)
    assert message.startswith(
        f"{given}: not a platform config: a config file's name ends in .yaml or .yml; "
        "a shipped platform is named by a string alone, with no path"
    ), message


def test_a_yaml_file_in_the_working_directory_is_read_by_its_suffix_or_its_separator(cluttered):
    text = (config_dir("platforms") / "dasgupta1998.yaml").read_text()
    (cluttered / "robot.yaml").write_text(text)
    (cluttered / "dasgupta1998.yml").write_text(text)
    assert load_platform("robot.yaml").name == "robot"
    assert load_platform("./robot.yaml").name == "robot"
    assert load_platform("dasgupta1998.yml").name == "dasgupta1998"
    with pytest.raises(ConfigError, match=r"^nope\.yaml: cannot read the file: No such file or directory$"):
        load_platform("nope.yaml")


def test_an_unknown_name_says_how_a_path_is_told_apart(cluttered):
    with pytest.raises(
        ConfigError,
        match=r"^unknown platform 'robot\.json'; available: dasgupta1998, "
        r"motion_simulator \(a config file's path has a / or ends in \.yaml or "
        r"\.yml\)$",
    ):
        load_platform("robot.json")


@pytest.mark.parametrize(
    "given, name",
    [
        ("dasgupta1998", True),
        ("motion_simulator", True),
        ("robot.json", True),
        ("robot.yaml", False),
        ("ROBOT.YML", False),
        ("./dasgupta1998", False),
        ("dir/robot", False),
        (Path("dasgupta1998"), False),
    ],
    ids=str,
)
def test_is_platform_name_is_the_rule(given, name):
    assert is_platform_name(given) is name


def test_the_command_line_and_the_mismatch_study_keep_the_shipped_name(cluttered, capsys):
    from stewart_env.agents.studies.mismatch import MismatchSettings
    from stewart_env.cli import main

    assert MismatchSettings(test_models=["improved"], algo=None, platform="dasgupta1998").platform == "dasgupta1998"
    assert main(["evaluate", "--platform", "dasgupta1998", "--episodes", "1", "--max-steps", "5"]) == 0
    try:
        code = main(["evaluate", "--platform", "./dasgupta1998", "--episodes", "1"])
    except SystemExit as stop:
        code = stop.code
    assert code == 2 and "argument --platform: ./dasgupta1998: not a platform config" in capsys.readouterr().err


def test_a_folder_named_like_a_shipped_agent_config_does_not_hide_it(tmp_path, monkeypatch):
    from stewart_env.agents.training import config_path
    from stewart_env.agents.training.errors import TrainingError

    monkeypatch.chdir(tmp_path)
    (tmp_path / "ppo").mkdir()  # left by --out ppo
    (tmp_path / "sac").write_text("not a config")
    assert config_path("ppo", "ppo") == config_path("ppo", None)
    assert config_path("sac", "sac").read_bytes() == config_path("sac", None).read_bytes()
    with pytest.raises(TrainingError, match=r"unknown shipped config 'nosuch'; shipped: crossq, ppo"):
        config_path("ppo", "nosuch")
    # a name with the suffix is the working directory's file where there is one
    (tmp_path / "ppo.yml").write_text("StewartPlatform-v1: {}\n")
    assert config_path("ppo", "ppo.yml").resolve() == tmp_path / "ppo.yml"
