"""Tests of the reset's compiled draws and candidate poses (stewart_env/_core/cpp/env/reset_draws.hpp):
each row's random() numbers taken through its generator's bit generator, bit for bit those of
``Generator.random``, and the set-point task's candidates, those of numpy and pose_margins."""

import threading

import numpy as np
import pytest

from stewart_env import _core, load_platform
from stewart_env.dynamics import kernels as K
from stewart_env.dynamics import make_dynamics
from stewart_env.params import ConfigError
from stewart_env.randomization import Randomization, draw_unit_rows
from stewart_env.rotations import rpy_to_matrix
from stewart_env.tasks.base import pose_margins
from stewart_env.tasks.setpoint import SetpointTask

BIT_GENERATORS = (np.random.PCG64, np.random.PCG64DXSM, np.random.MT19937, np.random.Philox, np.random.SFC64)


def generators(seed: int, bit_generator=np.random.PCG64, m: int = 5) -> list[np.random.Generator]:
    return [np.random.Generator(bit_generator(seed + j)) for j in range(m)]


@pytest.mark.parametrize("bit_generator", BIT_GENERATORS, ids=lambda b: b.__name__)
@pytest.mark.parametrize("k", [1, 12, 18])
def test_the_compiled_draws_are_each_generators_random_numbers(bit_generator, k):
    rngs, again = generators(3, bit_generator), generators(3, bit_generator)
    out = np.empty((len(rngs), k))
    draw_unit_rows(rngs, out)
    for j, rng in enumerate(again):
        assert out[j].tolist() == rng.random(k).tolist()
        # the generator's state advanced by exactly those numbers: the next draws agree
        assert rngs[j].random(3).tolist() == rng.random(3).tolist()
        assert rngs[j].normal(size=2).tolist() == rng.normal(size=2).tolist()


def test_the_compiled_draws_follow_jumped_spawned_and_mid_stream_generators():
    def made():
        base = np.random.default_rng(11)
        base.random(7)  # mid-stream
        jumped = np.random.Generator(np.random.PCG64(5).jumped(3))
        return [base, jumped, *base.spawn(2), np.random.default_rng(np.random.SeedSequence(9).spawn(1)[0])]

    rngs, again = made(), made()
    out = np.empty((len(rngs), 13))
    draw_unit_rows(rngs, out)
    assert out.tolist() == [rng.random(13).tolist() for rng in again]


def test_a_generator_the_call_does_not_know_draws_in_python_from_that_row_on():
    class Counting(np.random.Generator):
        """A Generator of another type: its own random() must be the one called."""

        calls = 0

        def random(self, *args, **kwargs):
            type(self).calls += 1
            return super().random(*args, **kwargs)

    def made():
        return [np.random.default_rng(0), Counting(np.random.PCG64(1)), np.random.default_rng(2)]

    out = np.empty((3, 4))
    assert _core.draw_uniform_rows(made(), np.random.Generator, out) == 1  # stopped at row 1
    assert Counting.calls == 0
    draw_unit_rows(made(), out)
    assert Counting.calls == 1  # row 1's own random(), then row 2 in Python too
    assert out.tolist() == [np.random.default_rng(s).random(4).tolist() for s in range(3)]


def test_a_generator_shared_by_rows_draws_them_one_after_the_other():
    rng = np.random.default_rng(4)
    out = np.empty((3, 5))
    draw_unit_rows([rng, rng, rng], out)
    assert out.ravel().tolist() == np.random.default_rng(4).random(15).tolist()


def test_the_compiled_draws_release_each_generators_lock_and_wait_for_a_held_one():
    rng = np.random.default_rng(6)
    lock = rng.bit_generator.lock
    lock.acquire()
    out = np.empty((1, 3))
    thread = threading.Thread(target=draw_unit_rows, args=([rng], out))
    thread.start()
    thread.join(0.2)
    assert thread.is_alive()  # it waits for the lock another holder has
    lock.release()
    thread.join(10.0)
    assert not thread.is_alive()
    assert lock.acquire(blocking=False)  # and let go of it
    lock.release()
    assert out[0].tolist() == np.random.default_rng(6).random(3).tolist()


def test_the_compiled_draws_refuse_wrong_arrays():
    rngs = generators(0, m=2)
    with pytest.raises(ValueError, match="out: expected shape"):
        _core.draw_uniform_rows(rngs, np.random.Generator, np.empty((3, 4)))
    with pytest.raises(TypeError):
        _core.draw_uniform_rows(rngs, np.random.Generator, np.empty((2, 4), dtype=np.float32))
    with pytest.raises(TypeError, match="generator_type"):
        _core.draw_uniform_rows(rngs, 1, np.empty((2, 4)))


def test_the_compiled_candidates_are_numpys_poses_and_pose_margins():
    params = load_platform("dasgupta1998")
    task = SetpointTask(params, 0.01, position_range=[0.2, 0.2, 0.12], angle_range=0.35)  # some rejected
    unit = np.random.default_rng(8).random((400, 6))
    found = task._candidates(unit)
    # the former numpy path, number for number
    pose = np.concatenate((params.home_position, params.home_rpy)) + (-1.0 + 2.0 * unit) * np.concatenate(
        (task.position_range, task.angle_range)
    )
    position, rpy = np.ascontiguousarray(pose[:, :3]), np.ascontiguousarray(pose[:, 3:])
    rotation = rpy_to_matrix(rpy)
    sensors = (np.empty((400, 6)), np.empty((400, 6)), np.empty(400))
    ok = pose_margins(task.kinematics, position, rpy, rotation=rotation, sensors=sensors)
    assert 0 < ok.sum() < 400
    assert found.position.tolist() == position.tolist()
    assert found.rotation.tolist() == rotation.tolist()
    assert found.ok.tolist() == ok.tolist()
    for a, b in zip(found.sensors, sensors):
        assert a.tolist() == b.tolist()


def test_the_compiled_candidates_refuse_wrong_arrays():
    params = load_platform("dasgupta1998")
    task = SetpointTask(params, 0.01)
    with pytest.raises(ValueError, match="unit: expected shape"):
        task._candidates(np.zeros((4, 5)))


OVERLAPPING = {
    "platform.mass": (0.5, 2.0),
    "legs.inertia": (0.7, 1.3),
    "upper_leg.com": (-1.5, 1.5),
    "mass": (0.9, 1.1),
    "inertia": (0.8, 1.2),
    "damping": (0.0, 2.0),
    "damping.prismatic": (0.5, 1.5),
}


def test_the_compiled_scaling_equals_scale_packed_with_keys_that_multiply():

    spec = Randomization(OVERLAPPING)
    nominal = make_dynamics("improved", load_platform("dasgupta1998")).packed[0]
    factors = spec.sample_rows([np.random.default_rng(s) for s in range(40)])
    out = np.empty((40, nominal.shape[0]))
    spec.scale_packed_rows(nominal, factors, out)
    for j in range(40):
        row = np.empty_like(nominal)
        spec.scale_packed(nominal, dict(zip(spec.ranges, factors[j].tolist())), row)
        assert out[j].tolist() == row.tolist()


def test_the_compiled_scaling_refuses_a_row_as_scale_packed_does():

    spec = Randomization(OVERLAPPING)
    nominal = make_dynamics("improved", load_platform("dasgupta1998")).packed[0]
    factors = spec.sample_rows([np.random.default_rng(s) for s in range(3)])
    factors[1, list(spec.ranges).index("damping.prismatic")] = 1.6  # beyond its range's 1.5
    with pytest.raises(ConfigError, match=r"factors\['damping.prismatic'\].*within \[0.5, 1.5\]"):
        spec.scale_packed_rows(nominal, factors, np.empty((3, nominal.shape[0])))


def test_the_compiled_scaling_refuses_wrong_tables():
    nominal = np.ones(K.N_PARAMS)
    part_of = np.zeros(K.N_PARAMS, dtype=np.int64)
    columns = np.array([[0, -1]], dtype=np.int64)
    args = (nominal, np.ones((2, 1)), part_of, columns, np.zeros(1), np.ones(1), 0, 0.0, 1e9, 0, 1.0, 0.0)
    out, ok = np.empty((2, K.N_PARAMS)), np.empty(2, dtype=bool)
    _core.scale_randomized_rows(*args, out, ok)
    assert ok.tolist() == [True, True] and out.tolist() == [nominal.tolist()] * 2
    with pytest.raises(ValueError, match="columns: expected columns of factors"):
        _core.scale_randomized_rows(*args[:3], np.array([[1]], dtype=np.int64), *args[4:], out, ok)
    with pytest.raises(ValueError, match="part_of"):
        _core.scale_randomized_rows(nominal, args[1], part_of + 2, *args[3:], out, ok)
    with pytest.raises(ValueError, match="inertia_part"):
        _core.scale_randomized_rows(*args[:9], 1, *args[10:], out, ok)
    with pytest.raises(ValueError, match="out: expected shape"):
        _core.scale_randomized_rows(*args, np.empty((3, K.N_PARAMS)), ok)
