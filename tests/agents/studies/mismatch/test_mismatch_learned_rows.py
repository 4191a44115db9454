"""The learned rows beside the model-based ones (the derivatives guide's controllers' table): agents
of the shipped config, and model-based rows that come out the same with or without them."""

from __future__ import annotations

import csv
import json

import pytest

from stewart_env.agents.studies.mismatch import run_mismatch
from stewart_env.agents.training import config_path

# PPO runs here are a rollout of 2 platforms, smaller than the config's minibatch on purpose.
pytestmark = pytest.mark.filterwarnings("ignore:You have specified a mini-batch size:UserWarning")

# the table's request on a tiny budget: one model, two model-based families, 2 episodes of 40 steps
REQUEST = dict(
    train_models=["improved"],
    test_models=["improved"],
    task="setpoint",
    simplifications=[],
    controllers=["pd", "ct"],
    episodes=2,
    max_steps=40,
    progress=False,
)


def _matrix(out):
    with open(out / "matrix.csv") as f:
        return {row["controller"]: row for row in csv.DictReader(f)}


def test_model_based_rows_are_the_same_with_a_learned_row_and_the_agents_use_the_shipped_config(tmp_path):
    run_mismatch(tmp_path / "none", algo=None, **REQUEST)
    alone = _matrix(tmp_path / "none")
    out = tmp_path / "ppo"
    run_mismatch(out, algo="ppo", timesteps=200, n_envs=2, **REQUEST)
    beside = _matrix(out)
    assert list(alone) == ["PD + gravity comp. [improved]", "CT [improved]"]
    assert list(beside) == [*alone, "PPO [improved]"]
    for label, row in alone.items():
        assert beside[label] == row, label  # every figure and interval, as written, bit for bit
    # no --config: the shipped configs/agents/ppo.yml, its error integral in the agent's observation
    run = json.loads((out / "agents" / "improved" / "seed_0" / "run.json").read_text())
    assert run["config"] == str(config_path("ppo", None))
    assert config_path("ppo", None).name == "ppo.yml"
    assert run["env_kwargs"]["error_integral"] is True
    assert run["env_kwargs"]["error_integral_band"] == 0.01
