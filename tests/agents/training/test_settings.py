"""A training run's request is one checked frozen record, built once at train()'s entry."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from stewart_env.agents.training import DEFAULT_KEEP_CHECKPOINTS, TrainingError, TrainSettings

pytestmark = pytest.mark.extra("rl")


def test_the_request_is_checked_at_construction_and_frozen(tmp_path):
    settings = TrainSettings("ppo", str(tmp_path / "run"), seed=3)
    assert settings.out == tmp_path / "run" and isinstance(settings.out, Path)
    assert settings.keep_checkpoints == DEFAULT_KEEP_CHECKPOINTS and settings.algorithm.__name__ == "PPO"
    with pytest.raises(dataclasses.FrozenInstanceError):
        settings.seed = 4


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"seed": -1}, "seed"),
        ({"timesteps": 0}, "timesteps"),
        ({"n_envs": 1.5}, "n_envs"),
        ({"checkpoint_freq": -1}, "checkpoint_freq"),
        ({"keep_checkpoints": 0}, "keep_checkpoints"),
    ],
)
def test_a_bad_setting_is_refused_by_name(kwargs, name, tmp_path):
    with pytest.raises(TrainingError, match=rf"^{name}: ") as err:
        TrainSettings("ppo", tmp_path, **kwargs)
    assert err.value.argument == name


def test_an_unknown_algorithm_is_refused_first(tmp_path):
    with pytest.raises(TrainingError, match="nope"):
        TrainSettings("nope", tmp_path, seed=-1)
