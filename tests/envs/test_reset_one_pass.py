"""Tests of the episode start done in one pass per row: each row's generator called once for its
randomisation factors and its episode's first draws, the same numbers as drawing them in turn, and
the start poses' leg sensors measured once, when the task checks them (stewart_env.envs.core,
.tasks.setpoint, .randomization)."""

import numpy as np
import pytest

from stewart_env.envs.config import EnvConfig
from stewart_env.envs.core import PlatformBatch
from stewart_env.kinematics import leg_sensors_inplace

pytestmark = pytest.mark.env

RANDOMIZATION = {"mass": (0.8, 1.2), "inertia": (0.9, 1.1), "damping": (0.5, 2.0)}


class CountingGenerator:
    """A numpy Generator whose ``random`` calls are counted (every other method passed through)."""

    def __init__(self, seed: int):
        self.rng, self.random_calls = np.random.default_rng(seed), 0

    def random(self, *args, **kwargs):
        self.random_calls += 1
        return self.rng.random(*args, **kwargs)

    def __getattr__(self, name):
        return getattr(self.rng, name)


def test_a_randomised_setpoint_reset_calls_each_generator_once_for_factors_and_poses():
    batch = PlatformBatch(8, EnvConfig.of(randomization=RANDOMIZATION))
    rngs = [CountingGenerator(s) for s in range(8)]
    batch.reset_rows(np.arange(8), rngs)
    # random() drew the factors and the first two candidate poses in one call per row (two before)
    assert [g.random_calls for g in rngs] == [1] * 8


def test_the_one_pass_draws_equal_the_factors_then_the_episode_in_turn():
    seeds = range(64)
    batch = PlatformBatch(64, EnvConfig.of(randomization=RANDOMIZATION))
    rngs = [np.random.default_rng(s) for s in seeds]
    factors, start, episode, _ = batch._draw_episodes(np.arange(64), rngs)
    for j, s in enumerate(seeds):
        rng = np.random.default_rng(s)
        # the row-by-row order: the factors, then the task's episode, from the same generator
        assert list(batch.randomization.sample(rng).values()) == factors[j].tolist()
        row_start, row_episode = batch.task.initialize_episode(rng)
        for a, b in zip(start, row_start):
            np.testing.assert_array_equal(a[j], b)
        for k, v in row_episode.items():
            np.testing.assert_array_equal(episode[k][j], v)
        assert rngs[j].random() == rng.random()  # both consumed the same numbers


@pytest.mark.parametrize(
    "arguments",
    [
        {},
        {"model": "classical"},
        {"platform": "motion_simulator", "actuator": "electric", "action_mode": "pose"},
        # about half the candidates rejected: rows whose start is drawn again row by row
        {"task_options": {"position_range": [0.25, 0.25, 0.15], "angle_range": [0.3, 0.3, 0.3]}},
    ],
)
def test_the_start_sensors_the_task_measured_are_those_of_the_nominal_model(arguments):
    m = 200
    batch = PlatformBatch(m, EnvConfig.of(**arguments))
    rngs = [np.random.default_rng(s) for s in range(m)]
    _, start, _, sensors = batch._draw_episodes(np.arange(m), rngs)
    assert sensors is not None
    expected = (np.empty((m, 6)), np.empty((m, 6)), np.empty(m))
    leg_sensors_inplace(batch.nominal_model, *start, batch.platform.limits.max_condition, *expected)
    for got, want in zip(sensors, expected):
        np.testing.assert_array_equal(got, want)
    # the reset reads them instead of measuring: the batch holds the same numbers
    batch.reset_rows(np.arange(m), [np.random.default_rng(s) for s in range(m)])
    np.testing.assert_array_equal(batch.leg_lengths, expected[0])
    np.testing.assert_array_equal(batch.leg_rates, expected[1])
    np.testing.assert_array_equal(batch.condition, expected[2])


def test_a_measured_reset_reads_the_sensors_it_is_given():
    batch = PlatformBatch(4, EnvConfig.of())
    assert batch.fused
    rngs = [np.random.default_rng(s) for s in range(4)]
    _, start, _, sensors = batch._draw_episodes(np.arange(4), rngs)
    marked = tuple(np.full_like(x, 7.0) for x in sensors)
    batch._start_rows(np.arange(4), start, None, marked)
    # 7 everywhere: read, not measured again (a measurement gives legs of some 0.4-0.6 m)
    assert (batch.leg_lengths == 7.0).all() and (batch.condition == 7.0).all()


def test_a_task_of_its_own_with_the_former_initialize_episodes_still_starts_rows():
    from stewart_env.tasks.hold import HoldTask

    class OwnDraws(HoldTask):
        def initialize_episodes(self, rngs):  # the signature before episode_draws
            return super().initialize_episodes(rngs)

    task = OwnDraws.__new__(OwnDraws)
    task.__dict__.update(PlatformBatch(1, EnvConfig.of(task="hold")).task.__dict__)
    start, episode, sensors = task.initialize_episodes_measured([np.random.default_rng(0), np.random.default_rng(1)])
    assert start.position.shape == (2, 3) and sensors is None
