"""The reset at the step's speed: a batch writes the randomised parameter rows into its own model
in place and starts the reset rows in one compiled call (``BatchStep.reset``), with the numbers of
a row started alone in Python (stewart_env.envs.core, .vector, .dynamics.model, .randomization)."""

from __future__ import annotations

import copy
import pickle

import gymnasium as gym
import numpy as np
import pytest
from batch_reset import batch_reset_arguments
from gymnasium.vector import AutoresetMode

import stewart_env.dynamics.kernels
import stewart_env.randomization
import stewart_env.registration  # noqa: F401  (registers StewartPlatform-v1)
from stewart_env.envs.config import EnvConfig
from stewart_env.envs.core import PlatformBatch
from stewart_env.params import ConfigError
from stewart_env.randomization import Randomization, ScaledRows
from stewart_env.state import PlatformState

pytestmark = pytest.mark.env

ENV_ID = "StewartPlatform-v1"
RANDOMIZATION = {"mass": (0.8, 1.2), "inertia": (0.9, 1.1), "damping": (0.5, 2.0), "legs.com": (0.95, 1.05)}
#: Every option a reset touches: noise (drawn after the episode), delay (every slot of the ring),
#: lag (the holding forces of the row's own parameters), the error integral, randomisation.
EVERYTHING = {
    "observation_noise": 0.02,
    "observation_delay": 2,
    "actuator_tau": 0.02,
    "error_integral": True,
    "randomization": RANDOMIZATION,
}
CASES = [
    {"randomization": RANDOMIZATION},
    EVERYTHING,
    {"task": "tracking", "observation_mode": "sensors", "randomization": RANDOMIZATION},
    {"task": "hold", "actuator_tau": 0.02},
]


def _row_alone(kwargs: dict, rng: np.random.Generator) -> PlatformBatch:
    """The reference: a batch of one row, started in Python (the step of parts) from ``rng``."""
    alone = PlatformBatch(1, EnvConfig.of(**kwargs))
    alone.set_step_mode("parts")
    alone.reset_rows(np.arange(1), [rng])
    return alone


def _assert_row_equals(batch: PlatformBatch, row: int, alone: PlatformBatch, where: str) -> None:
    """Row ``row`` of ``batch`` holds, bit for bit, what the one-row batch ``alone`` holds."""
    pairs = {
        # one parameter row per platform with randomisation, else the nominal model's one
        "packed": (batch._model.packed[min(row, len(batch._model.packed) - 1)], alone._model.packed[0]),
        "state": (
            np.concatenate([x[row].ravel() for x in batch._state]),
            np.concatenate([x[0].ravel() for x in alone._state]),
        ),
        "leg_forces": (batch.leg_forces[row], alone.leg_forces[0]),
        "reference": (
            np.concatenate([x[row].ravel() for x in batch.reference]),
            np.concatenate([x[0].ravel() for x in alone.reference]),
        ),
        "leg_lengths": (batch.leg_lengths[row], alone.leg_lengths[0]),
        "leg_rates": (batch.leg_rates[row], alone.leg_rates[0]),
        "condition": (batch.condition[row], alone.condition[0]),
        "errors": (batch._error_vectors[:, row], alone._error_vectors[:, 0]),
        "error_norms": (batch._error_norms[:, row], alone._error_norms[:, 0]),
        "clock": ((batch.time[row], batch.steps[row]), (alone.time[0], alone.steps[0])),
        "observation ring": (batch.observations._history[:, row], alone.observations._history[:, 0]),
    }
    for name, (got, expected) in pairs.items():
        np.testing.assert_array_equal(got, expected, err_msg=f"{where}: {name}")
    assert batch.episode_params(row) == alone.episode_params(0), f"{where}: episode_params"


@pytest.mark.parametrize("kwargs", CASES, ids=["randomised", "everything", "tracking-sensors", "hold-lag"])
def test_reset_rows_equal_the_row_started_alone(kwargs):
    n = 7
    envs = gym.make_vec(ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", max_episode_steps=20, **kwargs)
    core = envs.unwrapped._core
    assert core.fused  # the compiled reset is the one under test
    started = core.reset_rows
    checked = []

    def reset_and_check(rows, rngs, batch_infos=False):
        before = [copy.deepcopy(rng) for rng in rngs]  # each row's generator as the reset finds it
        infos = started(rows, rngs, batch_infos)
        for j, row in enumerate(rows.tolist()):
            _assert_row_equals(core, row, _row_alone(kwargs, before[j]), f"row {row}, reset {len(checked)}")
        checked.append(len(rows))
        return infos

    core.reset_rows = reset_and_check
    for seed in (0, 21):
        envs.reset(seed=seed)
        actions = np.random.default_rng(seed).uniform(-1.0, 1.0, (45, n, 6)).astype(np.float32)
        for a in actions:
            envs.step(a)
    envs.close()
    # every row reset at the seeds, and uniformly random actions end rows within a few steps
    assert checked[0] == n and len(checked) > 10 and sum(checked) > 4 * n


def test_a_handed_out_model_never_changes_and_an_unread_one_is_written_in_place():
    envs = gym.make_vec(ENV_ID, num_envs=4, vectorization_mode="vector_entry_point", randomization=RANDOMIZATION)
    envs.reset(seed=0)
    core = envs.unwrapped._core
    own = core._model
    record_parameters = own.packed  # the array the plant's record of the compiled step points into
    envs.reset(seed=1, options={"reset_mask": np.array([True, False, True, False])})
    # not read: the same model and array, rows 0 and 2 rewritten in place
    assert core._model is own and own.packed is record_parameters
    handed_out = envs.unwrapped.model
    numbers, params = handed_out.packed.copy(), tuple(handed_out.params)
    envs.reset(seed=2)
    # read: the batch goes on with a copy, and what was read keeps the numbers it had
    assert core._model is not handed_out and core.plant.model is core._model
    np.testing.assert_array_equal(handed_out.packed, numbers)
    assert tuple(handed_out.params) == params and not handed_out.packed.flags.writeable
    assert not np.array_equal(core._model.packed, numbers)
    envs.close()


@pytest.mark.parametrize(
    "clone", [copy.deepcopy, lambda env: pickle.loads(pickle.dumps(env))], ids=["deepcopy", "pickle"]
)
def test_a_copy_after_resets_resets_and_steps_as_the_original(clone):
    envs = gym.make_vec(ENV_ID, num_envs=5, vectorization_mode="vector_entry_point", max_episode_steps=15, **EVERYTHING)
    envs.reset(seed=3)
    rng = np.random.default_rng(3)
    for _ in range(25):  # through autoresets
        envs.step(rng.uniform(-1.0, 1.0, (5, 6)).astype(np.float32))
    twin = clone(envs)
    original = envs.unwrapped._core._model.packed.copy()
    for k in range(30):
        a = rng.uniform(-1.0, 1.0, (5, 6)).astype(np.float32)
        out, twin_out = envs.step(a), twin.step(a)
        for x, y in zip(out[:4], twin_out[:4]):
            np.testing.assert_array_equal(x, y, err_msg=f"step {k}")
    np.testing.assert_array_equal(envs.unwrapped._core._model.packed, twin.unwrapped._core._model.packed)
    # the copy's resets write into its own model, not the original's
    twin.reset(seed=99)
    assert not np.shares_memory(twin.unwrapped._core._model.packed, envs.unwrapped._core._model.packed)
    assert not np.array_equal(original, envs.unwrapped._core._model.packed)  # the original reset rows itself
    envs.close()
    twin.close()


@pytest.mark.parametrize("n", [1, 6])
def test_all_rows_no_rows_and_one_row_reset_alike_in_both_step_modes(n):
    runs = {}
    for step_mode in ("fused", "parts"):
        envs = gym.make_vec(ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", **EVERYTHING)
        envs.unwrapped.set_step_mode(step_mode)
        out = [envs.reset(seed=8)]
        # no rows: nothing changes, the observation stays, no row has a reset info
        out.append(envs.reset(options={"reset_mask": np.zeros(n, dtype=bool)}))
        np.testing.assert_array_equal(out[-1][0], out[0][0])
        assert not out[-1][1]["_randomization"].any()
        envs.step(np.full((n, 6), 0.3, dtype=np.float32))
        # every row at once, without a new seed: the generators go on
        out.append(envs.reset(options={"reset_mask": np.ones(n, dtype=bool)}))
        out.append(envs.step(np.full((n, 6), -0.2, dtype=np.float32)))
        runs[step_mode] = out
        envs.close()
    for a, b in zip(runs["fused"], runs["parts"]):
        for x, y in zip(a, b):
            if isinstance(x, dict):
                assert x.keys() == y.keys()
                continue
            np.testing.assert_array_equal(x, y)


def test_every_row_ending_at_one_step_resets_them_all_in_one_call():
    n = 8
    envs = gym.make_vec(
        ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", max_episode_steps=3, randomization=RANDOMIZATION
    )
    envs.reset(seed=5)
    core = envs.unwrapped._core
    calls = []
    started = core.reset_rows
    core.reset_rows = lambda rows, rngs, b=False: calls.append(rows.tolist()) or started(rows, rngs, b)
    hold = np.zeros((n, 6), dtype=np.float32)
    for _ in range(3):
        _, _, terminated, truncated, _ = envs.step(hold)
    assert (terminated | truncated).all()  # truncated together
    obs, reward, terminated, truncated, infos = envs.step(hold)  # next-step autoreset of every row
    assert calls == [list(range(n))]
    assert (reward == 0).all() and not terminated.any() and not truncated.any()
    assert infos["_randomization"].all() and np.isfinite(obs).all()
    envs.close()


@pytest.mark.parametrize(
    "change, message",
    [
        ({"rows": np.array([0, 3], dtype=np.int64)}, r"^rows: 3 is outside the batch of 3 rows$"),
        ({"rows": np.array([-1, 0], dtype=np.int64)}, r"^rows: -1 is outside the batch of 3 rows$"),
        ({"rows": np.array([0, 1], dtype=np.int32)}, r"^rows: expected a C-contiguous array of the step's dtype$"),
        ({"leg_forces": np.zeros((2, 5))}, r"^leg_forces: expected shape \(2, 6\), got \(2, 5\)$"),
        ({"error_norms": np.zeros((4, 3))}, r"^error_norms: expected shape \(4, 2\), got \(4, 3\)$"),
        ({"leg_lengths": np.zeros((6, 2)).T}, r"^leg_lengths: expected a C-contiguous array of the step's dtype$"),
        ({"start": (np.zeros((2, 3)),) * 3}, r"^start, reference: expected \(position, rotation"),
    ],
)
def test_the_compiled_reset_refuses_bad_arguments_before_writing_anything(change, message):
    core = PlatformBatch(3, EnvConfig.of())
    core.reset_rows(np.arange(3), [np.random.default_rng(s) for s in range(3)])
    before = [x.copy() for x in (*core._state, core.leg_lengths, core.time, core._error_norms)]
    arguments = {**batch_reset_arguments(core, 2), **change}
    with pytest.raises(ValueError, match=message):
        core._step.compiled.reset(*arguments.values())
    for x, y in zip(before, (*core._state, core.leg_lengths, core.time, core._error_norms)):
        np.testing.assert_array_equal(x, y)


def test_set_packed_rows_writes_in_place_and_with_packed_rows_copies():
    batch = PlatformBatch(4, EnvConfig.of(randomization=RANDOMIZATION))
    model, spec = batch._model, batch.randomization
    factors = spec.sample_rows([np.random.default_rng(s) for s in (1, 2)])
    rows = np.empty((2, model.packed.shape[1]))
    spec.scale_packed_rows(batch.nominal_model.packed[0], factors, rows)
    array, before = model.packed, model.packed.copy()
    new = model.with_packed_rows([3, 1], rows, spec.rows_params(batch.platform, factors))
    np.testing.assert_array_equal(model.packed, before)  # a new model: this one unchanged
    model.set_packed_rows(np.array([3, 1]), rows, spec.rows_params(batch.platform, factors))
    assert model.packed is array and not array.flags.writeable  # in place, read-only again
    np.testing.assert_array_equal(model.packed, new.packed)
    np.testing.assert_array_equal(model.packed[[0, 2]], before[[0, 2]])
    np.testing.assert_array_equal(model.packed[[3, 1]], rows)
    # row 3's parameters are the first factors' PlatformParams, built when read
    assert model.params[3] == spec.apply(batch.platform, dict(zip(spec.ranges, factors[0].tolist())))
    assert model.params[1] == new.params[1]


@pytest.mark.parametrize(
    "rows, packed_rows, sources, message",
    [
        ([4], "row", "sources", r"^rows: 4 is outside the batch of 4 parameter rows$"),
        ([0], np.full((1, 229), np.nan), "sources", r"^packed_rows: contains NaN or inf$"),
        ([0, 1], "row", "sources", r"^packed_rows: expected shape \(2, 229\), got \(1, 229\)$"),
        ([0], "row", 3.0, r"^sources: expected a sequence, one per row, or a function of the row, got float$"),
        ([0], "row", [3.0], r"^sources: expected PlatformParams or a function returning them, got float$"),
    ],
)
def test_set_packed_rows_refuses_and_leaves_the_model_unchanged(rows, packed_rows, sources, message):
    batch = PlatformBatch(4, EnvConfig.of(randomization=RANDOMIZATION))
    model = batch._model
    row = model.packed[:1].copy()
    before, items = model.packed.copy(), list(model.params._items)
    with pytest.raises(ValueError, match=message):
        model.set_packed_rows(
            rows,
            row if isinstance(packed_rows, str) else packed_rows,
            (lambda j: batch.platform) if isinstance(sources, str) else sources,
        )
    np.testing.assert_array_equal(model.packed, before)
    assert model.params._items == items


def test_subset_keeps_the_rows_in_their_order_and_refuses_bad_rows():
    batch = PlatformBatch(4, EnvConfig.of(randomization=RANDOMIZATION))
    batch.reset_rows(np.arange(4), [np.random.default_rng(s) for s in range(4)])
    model = batch._model
    part = model.subset(np.array([2, 0]))
    np.testing.assert_array_equal(part.packed, model.packed[[2, 0]])
    assert tuple(part.params) == (model.params[2], model.params[0]) and part.name == model.name
    z = np.zeros((2, 3))
    state = PlatformState(np.tile(batch.platform.home_position, (2, 1)), np.tile(np.eye(3), (2, 1, 1)), z, z)
    np.testing.assert_array_equal(
        part.inverse(*state, z, z),
        model.inverse(*(np.concatenate([x] * 2) for x in state), np.zeros((4, 3)), np.zeros((4, 3)))[[2, 0]],
    )
    with pytest.raises(ValueError, match=r"^rows: 4 is outside the batch of 4 parameter rows$"):
        model.subset([4])
    with pytest.raises(ValueError, match=r"^rows: expected at least one row$"):
        model.subset([])


def test_scaled_rows_build_each_rows_platform_when_called_and_pickle():
    spec = Randomization({"platform.mass": (0.5, 1.5), "damping": (0.5, 2.0)})
    batch = PlatformBatch(1, EnvConfig.of())
    factors = spec.sample_rows([np.random.default_rng(s) for s in (4, 5)])
    rows = spec.rows_params(batch.platform, factors)
    assert isinstance(rows, ScaledRows)
    heavier = rows(1)
    assert heavier.platform.mass == batch.platform.platform.mass * factors[1, 0]  # one multiplication
    assert pickle.loads(pickle.dumps(rows))(1) == heavier


def test_a_vector_env_with_next_step_and_same_step_autoresets_keeps_its_infos():
    # the masked step infos (np.where): the value of their dtype where the row stepped, 0 elsewhere
    for mode in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
        envs = gym.make_vec(
            ENV_ID, num_envs=4, vectorization_mode="vector_entry_point", max_episode_steps=2, autoreset_mode=mode
        )
        envs.reset(seed=0)
        for _ in range(3 if mode == AutoresetMode.NEXT_STEP else 2):  # the step after the rows ended, or that step
            *_, infos = envs.step(np.zeros((4, 6), dtype=np.float32))
        source = infos if mode == AutoresetMode.NEXT_STEP else infos["final_info"]
        assert not source["_time"].any() if mode == AutoresetMode.NEXT_STEP else source["_time"].all()
        assert source["termination"].dtype == np.int64 and source["is_success"].dtype == np.bool_
        assert source["time"].dtype == np.float64
        envs.close()


def test_the_benchmark_row_gives_both_ratios_with_their_spread(monkeypatch):
    from stewart_env.benchmarks import report

    runs = iter([(1.0, 1.1, 1.3), (1.0, 1.2, 1.2), (2.0, 2.6, 2.2)])  # (step alone, nominal, randomised) s

    def measured(n, steps):
        step, nominal, randomized = next(runs)
        return {
            "n": n,
            "step_s": step * 1e-6,
            "reset_nominal_s": nominal * 1e-6,
            "reset_randomized_s": randomized * 1e-6,
            "reset_nominal_ratio": nominal / step,
            "reset_randomized_ratio": randomized / step,
            "resets_nominal": 0.09,
            "resets_randomized": 0.1,
        }

    monkeypatch.setattr(report, "bench_resets_in_steps", measured)
    row = report.resets_row(n=16, runs=3)
    assert row.startswith("vector env N=16 under uniformly random actions, resets included (median of 3 runs")
    assert "the step alone 1.00 us a platform-step" in row
    # ratios 1.1, 1.2, 1.3 (median 1.2) and 1.3, 1.2, 1.1 (median 1.2): each with its lowest and highest
    assert "with nominal resets 1.20 us, x1.20 [1.10, 1.30], 0.090 resets a platform-step" in row
    assert "with randomised resets 1.30 us, x1.20 [1.10, 1.30], 0.100 resets a platform-step" in row


def test_scale_packed_rows_with_every_key_equals_scale_packed_in_any_output_layout():
    # every key: parts scaled by the product of three factors, multiplied in _multipliers' order
    spec = Randomization({key: (0.9, 1.1) for key in stewart_env.randomization.KEYS})
    nominal = PlatformBatch(1, EnvConfig.of()).nominal_model.packed[0]
    factors = spec.sample_rows([np.random.default_rng(s) for s in range(64)])
    contiguous, strided = np.empty((64, nominal.size)), np.empty((nominal.size, 64)).T
    spec.scale_packed_rows(nominal, factors, contiguous)
    spec.scale_packed_rows(nominal, factors, strided)
    for j in range(64):
        row = np.empty_like(nominal)
        spec.scale_packed(nominal, dict(zip(spec.ranges, factors[j].tolist())), row)
        np.testing.assert_array_equal(contiguous[j], row)
        np.testing.assert_array_equal(strided[j], row)


def test_scale_packed_rows_names_a_parameter_beyond_its_magnitude():
    spec = Randomization({"platform.inertia": (0.5, 1000.0)})
    nominal = PlatformBatch(1, EnvConfig.of()).nominal_model.packed[0].copy()
    nominal[stewart_env.dynamics.kernels.PACKED_SLICES["platform.inertia"]] *= (
        1e9  # at most 4.2e9, within the 1e12 bound, which 1000 times it is not
    )
    factors = np.array([[1.0], [1000.0]])
    with pytest.raises(ConfigError, match=r"platform\.inertia.*exceeds"):
        spec.scale_packed_rows(nominal, factors, np.empty((2, nominal.size)))
