"""The compiled step's contract (docs/layout.md): typed records, each checked and holding its
arrays, built once by their owners; one step chosen by the step mode; the batch asks its plant
only through the Plant interface."""

from __future__ import annotations

import copy
import pickle
import sys

import numpy as np
import pytest

from stewart_env import _core
from stewart_env.envs import StewartPlatformEnv


def _actuator_arrays(n=2):
    return np.zeros((n, 6)), np.zeros((n, 6))


def test_a_record_holds_the_arrays_it_points_into():
    action, forces = _actuator_arrays()
    before = sys.getrefcount(action), sys.getrefcount(forces)
    record = _core.ActuatorRecord(1.0, 0.0, 0.0, action, forces)
    # the record keeps each array alive (references of its own), so no pointer outlives its array
    assert sys.getrefcount(action) > before[0] and sys.getrefcount(forces) > before[1]
    del record
    assert (sys.getrefcount(action), sys.getrefcount(forces)) == before


@pytest.mark.parametrize(
    "action, message",
    [
        (np.zeros((2, 6), dtype=np.float32), "action: expected a C-contiguous array of the step's dtype"),
        (np.zeros((6, 2)).T, "action: expected a C-contiguous array of the step's dtype"),
        (np.zeros((2, 5)), r"action: expected shape \(N, 6\), got \(2, 5\)"),
    ],
)
def test_a_record_refuses_an_array_it_would_have_to_convert(action, message):
    with pytest.raises(ValueError, match=message):
        _core.ActuatorRecord(1.0, 0.0, 0.0, action, np.zeros((2, 6)))


def test_the_step_refuses_records_of_other_batches():
    env = StewartPlatformEnv()
    core = env._core
    actuator = _core.ActuatorRecord(1.0, 0.0, 0.0, *_actuator_arrays(2))
    state, plant, task, observation, outputs = _records_of(core)
    with pytest.raises(ValueError, match="actuator: expected a record of the batch's rows"):
        _core.BatchStep(state, plant, actuator, task, observation, outputs)
    with pytest.raises(ValueError, match="expected a record each, not None"):
        _core.BatchStep(state, plant, None, task, observation, outputs)


def _records_of(core):
    state = _core.StateRecord(
        tuple(core._state),
        tuple(core._backup),
        core.external_wrench,
        core.steps,
        core.time,
        core._non_finite,
        core.leg_lengths,
        core.leg_rates,
        core.condition,
        tuple(core.reference[:4]),
        core._error_vectors,
        core._error_norms,
        core.nominal_model.packed,
        core.control_dt,
        core.platform.limits.max_condition,
    )
    outputs = _core.OutputRecord(core._code, core._terms, core._reward, core._bad, core._observation32)
    return (
        state,
        core.plant.step_record(core.physics_dt, core.substeps),
        core.task.step_record(),
        core.observations.step_record(),
        outputs,
    )


def test_the_step_mode_is_chosen_publicly_and_checked():
    env = StewartPlatformEnv()
    assert env._core.step_mode == "auto" and env._core.fused
    env.set_step_mode("parts")
    assert not env._core.fused
    env.set_step_mode("fused")
    assert env._core.fused and env._core.step_mode == "fused"
    with pytest.raises(ValueError, match=r"^step_mode: expected one of 'auto', 'fused', 'parts', got 'fast'$"):
        env.set_step_mode("fast")
    assert env._core.step_mode == "fused"


class _PlantWithoutCompiledPart:
    """A plant that the compiled step cannot run: the closed-form plant behind the interface only."""

    name = "wrapped"
    closure_error = None

    def __init__(self, inner):
        self.inner = inner

    def step_inplace(self, *args):
        self.inner.step_inplace(*args)

    def set_model(self, model, rows):
        self.inner.set_model(model, rows)

    def step_record(self, physics_dt, substeps):
        return None


def test_a_plant_without_a_compiled_part_takes_the_step_of_parts(monkeypatch):
    env = StewartPlatformEnv()
    core = env._core
    monkeypatch.setattr(core, "plant", _PlantWithoutCompiledPart(core.plant))
    core.set_step_mode("auto")
    assert not core.fused
    with pytest.raises(ValueError, match=r"^step_mode='fused': the plant 'wrapped' has no compiled part"):
        core.set_step_mode("fused")
    obs, _ = env.reset(seed=0)
    obs, reward, *_ = env.step(np.full(6, 0.3))
    assert np.isfinite(obs).all() and np.isfinite(reward)


@pytest.mark.parametrize("clone", [copy.deepcopy, lambda env: pickle.loads(pickle.dumps(env))])
@pytest.mark.parametrize("mode", ["fused", "parts"])
def test_a_copy_keeps_the_step_mode_and_steps_alike(clone, mode):
    env = StewartPlatformEnv(observation_delay=2, randomization={"platform.mass": (0.8, 1.2)})
    env.set_step_mode(mode)
    env.reset(seed=1)
    for _ in range(3):
        env.step(np.full(6, 0.2))
    twin = clone(env)
    assert twin._core.step_mode == mode and twin._core.fused == (mode == "fused")
    for k in range(5):
        a = np.full(6, 0.1 * k - 0.2)
        out, twin_out = env.step(a), twin.step(a)
        np.testing.assert_array_equal(out[0], twin_out[0])
        assert out[1:4] == twin_out[1:4]
    # a reset (new randomised parameters, through the plant's record) in both, the same numbers
    np.testing.assert_array_equal(env.reset(seed=4)[0], twin.reset(seed=4)[0])
    np.testing.assert_array_equal(env.step(np.full(6, 0.5))[0], twin.step(np.full(6, 0.5))[0])


def test_the_plant_builds_its_record_once_and_keeps_it_up_to_date():
    env = StewartPlatformEnv(randomization={"platform.mass": (0.5, 1.5)})
    core = env._core
    record = core.plant.step_record(core.physics_dt, core.substeps)
    # the step's own record: the plant keeps one, so no step is left with parameters of an old reset
    assert core.plant.step_record(core.physics_dt, core.substeps) is record
    flags = record.flags
    env.reset(seed=0)
    assert record.flags == flags and core.plant.step_record(core.physics_dt, core.substeps) is record


def test_the_vector_environment_chooses_its_step_as_the_single_one_does():
    import gymnasium as gym

    envs = gym.make_vec("StewartPlatform-v1", num_envs=3, vectorization_mode="vector_entry_point")
    envs.unwrapped.set_step_mode("parts")
    assert envs.unwrapped._core.step_mode == "parts"
    envs.unwrapped.set_step_mode("fused")  # the default task and plant: the fused step can run
    assert envs.unwrapped._core.fused
    envs.close()


def test_the_step_is_one_object_chosen_once():
    from stewart_env.envs.core import FusedStep, StepOfParts

    env = StewartPlatformEnv()
    core = env._core
    assert type(core._step) is FusedStep
    env.set_step_mode("parts")
    assert type(core._step) is StepOfParts
    env.reset(seed=0)

    class Recorded(StepOfParts):
        calls = 0

        def run(self, batch, *args):
            Recorded.calls += 1
            return super().run(batch, *args)

    # step() asks nothing of the mode: it calls the object it was given, whatever that is
    core._step = Recorded(compiled_plant=True)
    env.step(np.full(6, 0.1))
    env.step(np.full(6, 0.1))
    assert Recorded.calls == 2
