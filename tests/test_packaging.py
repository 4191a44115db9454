"""Every module finds the shipped configs alike, installed or from the source tree."""

import importlib.resources
from pathlib import Path

import pytest

import stewart_env.params as params_module
from stewart_env.agents import training
from stewart_env.params import config_dir

REPOSITORY = Path(__file__).resolve().parent.parent


@pytest.mark.parametrize(("kind", "example"), [("platforms", "dasgupta1998.yaml"), ("agents", "ppo.yml")])
def test_config_dir_is_the_checkouts_configs(kind, example):
    assert config_dir(kind) == REPOSITORY / "configs" / kind
    assert (config_dir(kind) / example).is_file()


def test_training_reads_the_agent_configs_through_config_dir():
    assert training.CONFIG_DIR == config_dir("agents")
    assert training.read_hyperparameters("ppo", None)  # the shipped ppo.yml


@pytest.mark.parametrize("installed", ["missing", "without configs"])
def test_config_dir_falls_back_to_the_source_tree(installed, monkeypatch, tmp_path):
    def files(name):
        if installed == "missing":
            raise ModuleNotFoundError(f"No module named {name!r}")
        return tmp_path  # an installed stewart_env.configs that holds no platforms/ folder

    monkeypatch.setattr(importlib.resources, "files", files)
    assert config_dir("platforms") == REPOSITORY / "configs" / "platforms"
    assert "dasgupta1998" in params_module.available_platforms()
