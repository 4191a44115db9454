"""The reset's glue around its compiled calls: the environment writes the randomised rows it has
checked without checking them again, the same numbers as the public, checked write
(stewart_env.envs.core, .dynamics.model)."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_env.dynamics.model import Dynamics
from stewart_env.envs.config import EnvConfig
from stewart_env.envs.core import PlatformBatch

pytestmark = pytest.mark.env

RANDOMIZATION = {"mass": (0.8, 1.2), "inertia": (0.9, 1.1), "damping": (0.5, 2.0)}


def _rngs(rows, seed=0):
    return [np.random.default_rng([seed, int(r)]) for r in rows]


def test_a_randomised_reset_writes_its_checked_rows_without_checking_them_again(monkeypatch):
    rows = np.array([5, 0, 3])
    checked = PlatformBatch(6, EnvConfig.of(randomization=RANDOMIZATION))
    checked.reset_rows(rows, _rngs(rows))  # before the patch: the numbers of the public write
    expected = checked._model.packed.copy()

    def refuse(*args):
        raise AssertionError("the reset checked its rows again")

    monkeypatch.setattr(Dynamics, "_checked_rows", refuse)
    batch = PlatformBatch(6, EnvConfig.of(randomization=RANDOMIZATION))
    array = batch._model.packed
    batch.reset_rows(rows, _rngs(rows))
    assert batch._model.packed is array and not array.flags.writeable  # in place, read-only again
    np.testing.assert_array_equal(batch._model.packed, expected)
    assert batch._model.params[3] == checked._model.params[3]


def test_the_trusted_write_matches_set_packed_rows_and_copies_a_shared_array():
    batch = PlatformBatch(4, EnvConfig.of(randomization=RANDOMIZATION))
    spec, model = batch.randomization, batch._model
    factors = spec.sample_rows(_rngs(range(2)))
    packed = np.empty((2, model.packed.shape[1]))
    spec.scale_packed_rows(batch.nominal_model.packed[0], factors, packed)
    public = model.with_packed_rows([3, 1], packed, spec.rows_params(batch.platform, factors))
    shared = model.subset([0, 1, 2, 3])  # a fancy-indexed copy: owns its data
    shared._packed = model.packed[:]  # a view of another model's array
    shared._packed.setflags(write=False)
    shared._set_checked_rows(np.array([3, 1]), packed, spec.rows_params(batch.platform, factors))
    np.testing.assert_array_equal(shared.packed, public.packed)
    assert shared.packed.flags.owndata and not shared.packed.flags.writeable
    assert not np.array_equal(model.packed, public.packed)  # the viewed model unchanged
    assert shared.params[1] == public.params[1]
