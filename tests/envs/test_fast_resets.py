"""Tests of the batched episode start: the rows reset at a step draw and start together, with the
same numbers as starting them one after the other (stewart_env.envs.core, .vector, .tasks,
.randomization)."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import stewart_env.registration  # noqa: F401  (registers StewartPlatform-v1)
from stewart_env.envs.config import EnvConfig
from stewart_env.envs.core import PlatformBatch
from stewart_env.params import ConfigError
from stewart_env.randomization import Randomization
from stewart_env.tasks.setpoint import SetpointTask

pytestmark = pytest.mark.env

ENV_ID = "StewartPlatform-v1"
RANDOMIZATION = {"mass": (0.8, 1.2), "inertia": (0.9, 1.1), "damping": (0.5, 2.0), "legs.com": (0.95, 1.05)}
TASKS = ["setpoint", "tracking", "disturbance", "hold"]


def by_row(monkeypatch):
    """Make every batch start its rows one after the other (the reset the batched one replaces)."""
    monkeypatch.setattr(PlatformBatch, "_draw_episodes", PlatformBatch._draw_episodes_by_row)


def rollout(n, kwargs, mode, seed, steps=60):
    """Observations, rewards, flags and infos of a vector run under uniformly random actions, which
    lose the platform within a few steps: many rows reset at most steps."""
    envs = gym.make_vec(
        ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", autoreset_mode=mode, max_episode_steps=25, **kwargs
    )
    actions = np.random.default_rng(seed).uniform(-1.0, 1.0, (steps, n, 6)).astype(np.float32)
    out = [envs.reset(seed=seed)]
    resets = 0
    for a in actions:
        out.append(envs.step(a))
        resets += int(np.count_nonzero(out[-1][2] | out[-1][3]))
    state = envs.unwrapped.get_attr("state")
    envs.close()
    return out, state, resets


def assert_same(a, b, where=""):
    """Exact equality of nested tuples, lists, dicts and arrays (object arrays element by element)."""
    if isinstance(a, dict):
        assert a.keys() == b.keys(), where
        for k in a:
            assert_same(a[k], b[k], f"{where}[{k!r}]")
    elif isinstance(a, (tuple, list)):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{where}[{i}]")
    elif isinstance(a, np.ndarray) and a.dtype == object:
        assert a.shape == b.shape, where
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{where}[{i}]")
    elif isinstance(a, np.ndarray):
        assert a.dtype == b.dtype, where
        np.testing.assert_array_equal(a, b, err_msg=where)
    else:
        assert a == b or (a is None and b is None), where


@pytest.mark.parametrize("task", TASKS)
@pytest.mark.parametrize("randomization", [None, RANDOMIZATION], ids=["nominal", "randomised"])
@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP], ids=["next", "same"])
def test_batched_reset_equals_row_by_row_reset(monkeypatch, task, randomization, mode):
    kwargs = {"task": task, "randomization": randomization}
    for seed in (0, 7, 123):
        batched, batched_state, resets = rollout(9, kwargs, mode, seed)
        with monkeypatch.context() as m:
            by_row(m)
            single, single_state, _ = rollout(9, kwargs, mode, seed)
        assert resets >= 9  # the runs cross many autoresets
        assert_same(batched, single, f"seed {seed}")
        assert_same(batched_state, single_state, f"seed {seed} state")


def test_batched_reset_with_observation_noise_delay_lag_and_integral(monkeypatch):
    kwargs = {
        "observation_noise": 0.02,
        "observation_delay": 2,
        "actuator_tau": 0.02,
        "error_integral": True,
        "randomization": RANDOMIZATION,
    }
    batched = rollout(6, kwargs, AutoresetMode.NEXT_STEP, 5)
    by_row(monkeypatch)
    assert_same(batched, rollout(6, kwargs, AutoresetMode.NEXT_STEP, 5))


def test_rows_that_share_a_generator_draw_one_after_the_other():
    # a generator given to two rows: row 0 draws all of its episode before row 1 starts
    batch = PlatformBatch(2, EnvConfig.of(randomization=RANDOMIZATION))
    shared = np.random.default_rng(3)
    infos = batch.reset_rows(np.arange(2), [shared, shared])
    alone = PlatformBatch(1, EnvConfig.of(randomization=RANDOMIZATION))
    rng = np.random.default_rng(3)
    for row in range(2):
        info = alone.reset_rows(np.arange(1), [rng])[0]
        assert_same(info, infos[row])
        np.testing.assert_array_equal(alone.position[0], batch.position[row])
        np.testing.assert_array_equal(alone.model.packed[0], batch.model.packed[row])


def test_vector_reset_infos_are_gymnasiums_row_by_row():
    envs = gym.make_vec(ENV_ID, num_envs=5, vectorization_mode="vector_entry_point", randomization=RANDOMIZATION)
    _, infos = envs.reset(seed=4)
    mask = np.array([False, True, False, True, True])
    _, masked = envs.reset(seed=[None, 9, None, 10, 11], options={"reset_mask": mask})
    # Gymnasium's own rule, one row at a time, on the per-row infos of the same draws
    batch = PlatformBatch(5, EnvConfig.of(randomization=RANDOMIZATION))
    rows = np.flatnonzero(mask)
    expected = {}
    for i, info in zip(rows, batch.reset_rows(rows, [np.random.default_rng(s) for s in (9, 10, 11)])):
        expected = envs.unwrapped._add_info(expected, info, int(i))
    assert_same(masked, expected)
    assert infos["randomization"]["mass"].dtype == np.float64 and infos["_randomization"].all()
    envs.close()


def test_setpoint_batched_draws_equal_the_row_by_row_draws_with_many_rejections():
    # the whole workspace box and angle range: about half the candidate poses are rejected
    config = EnvConfig.of(task_options={"position_range": [0.25, 0.25, 0.15], "angle_range": [0.3, 0.3, 0.3]})
    task = PlatformBatch(1, config).task
    assert isinstance(task, SetpointTask)
    seeds = range(200)
    start, episode = task.initialize_episodes([np.random.default_rng(s) for s in seeds])
    rejected = 0
    for j, s in enumerate(seeds):
        rng = np.random.default_rng(s)
        row_start, row_episode = task.initialize_episode(rng)
        for a, b in zip(start, row_start):
            np.testing.assert_array_equal(a[j], b)
        for k, v in row_episode.items():
            np.testing.assert_array_equal(episode[k][j], v)
        # the next number of each generator: both consumed the same draws
        batched_rng = np.random.default_rng(s)
        task.initialize_episodes([batched_rng])
        assert batched_rng.random() == rng.random()
        first = np.random.default_rng(s).random(12).reshape(2, 6)
        rejected += int(not task._candidates(first)[2].all())
    assert rejected >= 20  # the rows that go on drawing row by row are exercised


def test_setpoint_batched_draws_keep_the_draw_limit(monkeypatch):
    from stewart_env.tasks import setpoint

    task = PlatformBatch(1, EnvConfig.of()).task
    monkeypatch.setattr(setpoint, "_MAX_DRAWS", 3)
    monkeypatch.setattr(
        setpoint.SetpointTask,
        "_candidates",
        lambda self, unit: (np.zeros((len(unit), 3)), np.zeros((len(unit), 3, 3)), np.zeros(len(unit), dtype=bool)),
    )
    monkeypatch.setattr(setpoint, "pose_margins", lambda *a, **k: np.array([False]))
    rng = np.random.default_rng(0)
    with pytest.raises(RuntimeError, match="no pose inside the limits .* in 3 draws"):
        task.initialize_episodes([rng])
    # 2 batched draws, then the 1 left of the start's 3: 3 candidates of 6 numbers
    np.testing.assert_array_equal(rng.random(), np.random.default_rng(0).random(19)[-1])


def test_randomization_sample_rows_pinned_and_equal_to_sample():
    spec = Randomization({"platform.mass": (0.8, 1.2), "damping": (0.5, 2.0)})
    factors = spec.sample_rows([np.random.default_rng(0), np.random.default_rng(1)])
    # hand case: low + (high - low) * the generator's first two numbers
    u0 = np.random.default_rng(0).random(2)
    assert factors[0, 0] == 0.8 + (1.2 - 0.8) * u0[0] and factors[0, 1] == 0.5 + (2.0 - 0.5) * u0[1]
    assert factors[0].tolist() == [1.0547846749285816, 0.9046800706458055]  # pinned: the same draws as today
    for j, s in enumerate((0, 1)):
        assert list(spec.sample(np.random.default_rng(s)).values()) == factors[j].tolist()


def test_scale_packed_rows_equals_scale_packed_and_names_a_refused_factor():
    spec = Randomization(RANDOMIZATION)
    batch = PlatformBatch(1, EnvConfig.of())
    nominal = batch.nominal_model.packed[0]
    factors = spec.sample_rows([np.random.default_rng(s) for s in range(50)])
    out = np.empty((50, nominal.shape[0]))
    spec.scale_packed_rows(nominal, factors, out)
    for j in range(50):
        row = np.empty_like(nominal)
        spec.scale_packed(nominal, dict(zip(spec.ranges, factors[j].tolist())), row)
        np.testing.assert_array_equal(out[j], row)
    factors[7, list(spec.ranges).index("mass")] = 5.0
    with pytest.raises(ConfigError, match=r"factors\['mass'\].*within \[0.8, 1.2\]"):
        spec.scale_packed_rows(nominal, factors, out)


def test_bench_resets_in_steps_reports_the_step_with_and_without_resets():
    from stewart_env.benchmarks import bench_resets_in_steps

    r = bench_resets_in_steps(n=8, steps=20, repeats=1)
    assert r["resets_step"] == 0.0  # held, no row ends within the run
    # uniformly random actions lose the platform within some ten steps
    assert r["resets_nominal"] > 0.02 and r["resets_randomized"] > 0.02
    assert r["reset_nominal_ratio"] == r["reset_nominal_s"] / r["step_s"] > 0
    with pytest.raises(ValueError, match="steps: expected 1 to 100"):
        bench_resets_in_steps(n=2, steps=500)
