"""Scheduled cueing episodes side by side: the batched perception and the metrics are those of one
episode at a time, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_env.agents.controllers.washout import WashoutParams, WashoutPolicy
from stewart_env.agents.evaluation.cueing import ScheduledEpisodes, episode_cueing_metrics, perceive, perceive_batch
from stewart_env.errors import UsageError

pytestmark = pytest.mark.env


def test_batched_perception_is_each_episodes_bit_for_bit():
    rng = np.random.default_rng(3)
    f = rng.normal(size=(3, 50, 3)) + np.array([0.0, 0.0, 9.80665])
    w = 0.1 * rng.normal(size=(3, 50, 3))
    lengths = np.array([50, 17, 1])
    batch_f, batch_w = perceive_batch(f, w, lengths, 0.01)
    for i, n in enumerate(lengths):
        one_f, one_w = perceive(f[i, :n], w[i, :n], 0.01)
        assert np.array_equal(batch_f[i, :n], one_f)
        assert np.array_equal(batch_w[i, :n], one_w)


def test_scheduled_episodes_score_each_episode_as_the_metrics_do():
    runner = ScheduledEpisodes([("braking", 1), ("slalom", 3)], {"action_mode": "pose"})
    rows = runner.run(lambda env: WashoutPolicy(env, WashoutParams()), traces=True)
    assert runner.steps.tolist() == [
        len(rows[0]["traces"]["head_specific_force"]),
        len(rows[1]["traces"]["stroke_use"]),
    ]
    for row in rows:
        expected = episode_cueing_metrics(runner.dt, row["traces"], int(row["limit_hits"]))
        for key, value in expected.items():
            assert row[key] == value or (np.isnan(value) and np.isnan(row[key])), key
        assert row["failed"] == 0.0 and row["played"] == 1.0
    # a second run repeats the first: the environment is reset with seed 0 and the schedule again
    again = runner.run(lambda env: WashoutPolicy(env, WashoutParams()))
    assert [r["rms_specific_force_error"] for r in again] == [r["rms_specific_force_error"] for r in rows]
    runner.close()


def test_no_episodes_is_named():
    with pytest.raises(UsageError, match=r"episodes: give at least one \(motion, seed\) pair"):
        ScheduledEpisodes([])
