"""The start observation made in the compiled reset (``BatchStep.reset`` with ``observe``): the
numbers of the observation pipeline's ``reset_rows`` after the step of parts' start, a start
observation that is not finite included, and the compiled reset's refusals before it writes
anything (stewart_env.envs.core, .observation)."""

from __future__ import annotations

import numpy as np
import pytest
from batch_reset import batch_reset_arguments

from stewart_env.envs.config import EnvConfig
from stewart_env.envs.core import PlatformBatch
from stewart_env.state import PlatformState

pytestmark = pytest.mark.env

#: Every part of the start observation: noise, every slot of a delay ring, the error integral,
#: the pose block and the sensors' block.
OPTIONS = [
    {"observation_noise": 0.02, "observation_delay": 2, "error_integral": True},
    {"observation_mode": "sensors", "normalize_observation": False, "observation_delay": 1},
]


def _batches(options: dict) -> tuple[PlatformBatch, PlatformBatch]:
    """Two batches of 4 rows at the same state after a step: the fused step's and the step of parts'."""
    batches = []
    for mode in ("fused", "parts"):
        batch = PlatformBatch(4, EnvConfig.of(**options))
        batch.set_step_mode(mode)
        batch.reset_rows(np.arange(4), [np.random.default_rng(s) for s in range(4)])
        batch.step(np.full((4, 6), 0.3), [np.random.default_rng(10 + s) for s in range(4)])
        batches.append(batch)
    assert batches[0]._step.observes and not batches[1]._step.observes
    return batches[0], batches[1]


def _start(position: list[list[float]]) -> PlatformState:
    m = len(position)
    return PlatformState(np.array(position), np.tile(np.eye(3), (m, 1, 1)), np.zeros((m, 3)), np.zeros((m, 3)))


def _observation_state(batch: PlatformBatch) -> list[np.ndarray]:
    obs = batch.observations
    integral = [] if obs.error_integral is None else [obs.error_integral.copy()]
    return [obs._history.copy(), obs._pending.copy(), np.array(obs._any_pending), *integral]


@pytest.mark.parametrize("options", OPTIONS)
def test_the_compiled_start_observation_is_the_pipelines_one_even_when_not_finite(options):
    fused, parts = _batches(options)
    rows = np.array([3, 1], dtype=np.int64)
    # row 3 starts far beyond the float32 range: its observation is made finite and it is pending
    start = _start([[1e300, 0.0, 0.0], [0.01, -0.02, 1.0]])
    state, errors = fused._start_observed_rows(
        rows, start, None, None, None, [np.random.default_rng(7), np.random.default_rng(8)]
    )
    view = parts._start_rows(rows, start, None)
    parts.observations.reset_rows(rows, view, [np.random.default_rng(7), np.random.default_rng(8)])
    for a, b in zip(state, view.state):
        np.testing.assert_array_equal(a, b)
    for a, b in zip(errors, view.errors):
        np.testing.assert_array_equal(a, b)
    for a, b in zip(_observation_state(fused), _observation_state(parts)):
        np.testing.assert_array_equal(a, b)
    assert fused.observations._pending.tolist() == [False, False, False, True]
    assert fused.observations._any_pending
    # the finite guard's bound: the float32 range (the position's entry, clipped)
    assert np.abs(fused.observations.latest[3]).max() == np.finfo(np.float32).max
    # the first step after ends the pending row as not finite, in both step modes
    codes = [b.step(np.zeros((4, 6)), [np.random.default_rng(s) for s in range(4)])[1] for b in (fused, parts)]
    np.testing.assert_array_equal(codes[0], codes[1])
    assert fused.reasons(codes[0])[3] == "non_finite"


@pytest.mark.parametrize(
    "change, message",
    [
        ({"noise": np.zeros((2, 5))}, r"^noise: expected shape \(2, \d+\), got \(2, 5\)$"),
        ({"noise": np.zeros((30, 2)).T}, r"^noise: expected a C-contiguous array of the step's dtype$"),
        ({"noise": np.zeros((2, 30), dtype=np.float32)}, r"^noise: expected a C-contiguous array of the step's dtype$"),
        ({"noise": np.zeros((2, 30)), "observe": False}, r"^noise: expected None without observe$"),
    ],
)
def test_the_compiled_reset_refuses_a_bad_noise_before_writing_anything(change, message):
    batch, _ = _batches({"observation_delay": 1})
    before = [x.copy() for x in (*batch._state, batch.time, *_observation_state(batch))]
    arguments = {**batch_reset_arguments(batch, 2, measured=False, observe=True, noise=None), **change}
    with pytest.raises(ValueError, match=message):
        batch._step.compiled.reset(*arguments.values())
    for x, y in zip(before, (*batch._state, batch.time, *_observation_state(batch))):
        np.testing.assert_array_equal(x, y)


def test_the_compiled_reset_refuses_to_observe_without_an_observation_record():
    # the tracking task observes terms of its own: the caller makes the observation, and the
    # compiled step has no record of it
    batch = PlatformBatch(2, EnvConfig.of(task="tracking"))
    assert batch.fused and not batch._step.observes
    batch.reset_rows(np.arange(2), [np.random.default_rng(s) for s in range(2)])
    before = [x.copy() for x in (*batch._state, batch.time)]
    with pytest.raises(ValueError, match=r"^observe: the step has no observation record$"):
        batch._step.compiled.reset(*batch_reset_arguments(batch, 2, measured=False, observe=True, noise=None).values())
    for x, y in zip(before, (*batch._state, batch.time)):
        np.testing.assert_array_equal(x, y)


def test_next_step_infos_of_the_rows_reset_instead_of_stepped_are_zeros_of_their_type():
    import gymnasium as gym

    import stewart_env.registration  # noqa: F401  (registers StewartPlatform-v1)

    envs = gym.make_vec("StewartPlatform-v1", num_envs=4, vectorization_mode="vector_entry_point", max_episode_steps=3)
    envs.reset(seed=0)
    hold = np.zeros((4, 6), dtype=np.float32)
    envs.step(hold)
    envs.reset(options={"reset_mask": np.array([True, True, False, False])})
    for _ in range(2):
        _, _, _, truncated, _ = envs.step(hold)
    assert truncated.tolist() == [False, False, True, True]
    _, _, _, _, infos = envs.step(hold)  # rows 2 and 3 are reset, not stepped
    keys = [k for k in infos if not k.startswith("_") and f"_{k}" in infos and isinstance(infos[k], np.ndarray)]
    assert {"reward_position", "termination", "time", "is_success", "cost"} <= set(keys)
    for key in keys:
        assert infos[f"_{key}"].tolist() == [True, True, False, False], key
        assert not infos[key][2:].any(), key
    assert infos["time"][:2].tolist() == [3 * envs.unwrapped._core.control_dt] * 2
    assert infos["termination"].dtype == np.int64 and infos["is_success"].dtype == np.bool_
    envs.close()


class _Unhashable(np.random.Generator):
    """A Generator that compares by its state (so unhashable): the rows' generators of another kind."""

    __hash__ = None

    def __eq__(self, other):
        return self is other


def test_a_generator_shared_by_rows_is_found_among_unhashable_ones_too():
    from stewart_env.envs.core import _shares_a_generator

    a, b = (_Unhashable(np.random.PCG64(s)) for s in (1, 2))
    assert not _shares_a_generator([a, b]) and _shares_a_generator([a, b, a])
    c, d = np.random.default_rng(1), np.random.default_rng(1)
    assert not _shares_a_generator([c, d]) and _shares_a_generator([c, d, c])
    # a reset of rows with unhashable generators of their own draws as with numpy's own
    rows = np.arange(3)
    batches = [PlatformBatch(3, EnvConfig.of()) for _ in range(2)]
    batches[0].reset_rows(rows, [_Unhashable(np.random.PCG64(s)) for s in range(3)])
    batches[1].reset_rows(rows, [np.random.Generator(np.random.PCG64(s)) for s in range(3)])
    for x, y in zip(batches[0]._state, batches[1]._state):
        np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(batches[0].observation, batches[1].observation)


def test_the_compiled_position_error_norm_is_error_norms_bit_for_bit():
    # the success tracker starts from |e_p| as the compiled reset measured it: error_norm's numbers
    from stewart_env.tasks.base import error_norm

    batch = PlatformBatch(64, EnvConfig.of())
    rng = np.random.default_rng(5)
    rows = np.arange(64, dtype=np.int64)
    # positions over many magnitudes (the squares' rounding differs with any other order or a fused multiply-add)
    position = rng.normal(size=(64, 3)) * 10.0 ** rng.uniform(-8, 3, (64, 1)) + batch.platform.home_position
    _, errors = batch._start_observed_rows(rows, _start(position.tolist()), None, None, None, [rng] * 64)
    np.testing.assert_array_equal(errors.position_norm, error_norm(errors.position))
    assert (errors.position_norm > 0).all()
