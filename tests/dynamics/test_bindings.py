"""The compiled bindings given input arrays they must convert (strided views, Fortran order, float32):
the same numbers as from C-contiguous float64 arrays, the converted copies held for as long as they
are read.  tests/dynamics/test_sanitizer.py runs these under AddressSanitizer, which would report
a read of a copy already freed."""

import numpy as np
import pytest

import stewart_env as se
from stewart_env import _core

from physics_reference import random_state

pytestmark = pytest.mark.physics


def strided(a):
    """``a`` as a non-contiguous view of a larger array (every other entry of its last axis)."""
    a = np.asarray(a, dtype=np.float64)
    wide = np.zeros(a.shape[:-1] + (2 * a.shape[-1],))
    wide[..., ::2] = a
    return wide[..., ::2]


def states(params, n, seed=0):
    rng = np.random.default_rng(seed)
    t, R, v, w = (np.stack(x) for x in zip(*(random_state(params, rng, speed=0.5) for _ in range(n))))
    return t, R, v, w, rng


def test_regressor_fourier_series_and_flop_count_take_converted_arrays(dasgupta):
    model = se.make_dynamics("improved", dasgupta)
    t, R, v, w, rng = states(dasgupta, 5)
    acc = rng.normal(size=(5, 6))
    plain = np.empty((5, 6, _core.N_THETA))
    _core.regressor_batch(model.packed, model.flags, t, R, v, w, acc, plain)
    converted = np.empty_like(plain)
    _core.regressor_batch(
        strided(model.packed),
        model.flags,
        strided(t),
        np.asfortranarray(R),
        strided(v),
        strided(w),
        strided(acc),
        converted,
    )
    assert np.array_equal(converted, plain)

    q0, a, b, times = rng.normal(size=6), rng.normal(size=(6, 3)), rng.normal(size=(6, 3)), np.linspace(0, 2, 7)
    plain = np.empty((7, 3, 6))
    _core.fourier_series(q0, a, b, 1.5, times, plain)
    converted = np.empty_like(plain)
    _core.fourier_series(strided(q0), np.asfortranarray(a), strided(b), 1.5, strided(times), converted)
    assert np.array_equal(converted, plain)

    z, F = np.zeros(3), np.full(6, 180.0)
    assert _core.forward_flops(
        strided(model.packed), model.flags, strided(t[0]), np.asfortranarray(R[0]), z, z, F.astype(np.float32)
    ) == _core.forward_flops(model.packed, model.flags, t[0], R[0], z, z, F)


def test_batch_kernels_take_converted_arrays(dasgupta):
    model = se.make_dynamics("improved+c1", dasgupta)
    n = 40  # over MIN_PARALLEL_WORK for a rollout: the helper threads read the converted copies too
    t, R, v, w, rng = states(dasgupta, n, seed=1)
    F = 180 + 60 * rng.normal(size=(n, 6))
    W = rng.normal(size=(n, 6))
    v32 = v.astype(np.float32)  # widened exactly on the way in
    for kernel in (_core.forward_batch, _core.inverse_batch):
        plain, converted = np.empty((n, 6)), np.empty((n, 6))
        kernel(model.packed, model.flags, t, R, v32.astype(np.float64), w, F, W, plain)
        kernel(
            strided(model.packed),
            model.flags,
            strided(t),
            np.asfortranarray(R),
            v32,
            strided(w),
            strided(F),
            strided(W),
            converted,
        )
        assert np.array_equal(converted, plain)
    M, h = np.empty((n, 6, 6)), np.empty((n, 6))
    M2, h2 = np.empty_like(M), np.empty_like(h)
    _core.mass_bias_batch(model.packed, model.flags, t, R, v, w, W, M, h)
    _core.mass_bias_batch(
        strided(model.packed), model.flags, strided(t), np.asfortranarray(R), strided(v), strided(w), strided(W), M2, h2
    )
    assert np.array_equal(M2, M) and np.array_equal(h2, h)
    states_after = []
    for convert in (False, True):
        tt, RR, vv, ww = t.copy(), R.copy(), v.copy(), w.copy()
        args = (strided(model.packed), strided(F), strided(W)) if convert else (model.packed, F, W)
        _core.rollout_batch(args[0], model.flags, tt, RR, vv, ww, args[1], args[2], 1e-3, 10)
        states_after.append((tt, RR, vv, ww))
    for got, want in zip(*states_after):
        assert np.array_equal(got, want)
