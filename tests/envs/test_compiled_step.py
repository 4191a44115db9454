"""The environment's compiled control step (one call per step for the batch) gives what the step
made of its parts gives (the plant, then the task's termination and reward, then the observation
pipeline), bit for bit, whatever the options; the step mode (``PlatformBatch.set_step_mode``)
chooses between them."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import stewart_env  # noqa: F401  (registers StewartPlatform-v0)

CASES = [
    {"task": "setpoint"},
    {
        "task": "setpoint",
        "observation_noise": 0.01,
        "observation_delay": 2,
        "actuator_tau": 0.02,
        "error_integral": True,
        "error_integral_band": 0.5,
        "randomization": {"platform.mass": (0.8, 1.2)},
    },
    {"task": "setpoint", "observation_mode": "sensors", "normalize_observation": False, "error_integral": True},
    {"task": "tracking", "observation_noise": 0.01},
    {"task": "hold", "actuator_tau": 0.02},
    {"task": "disturbance", "observation_mode": "sensors"},
]


def _run(kwargs, compiled: bool, num_envs=3, steps=60):
    envs = gym.make_vec(
        "StewartPlatform-v0", num_envs=num_envs, vectorization_mode="vector_entry_point", max_episode_steps=25, **kwargs
    )
    core = envs.unwrapped._core
    core.set_step_mode("fused" if compiled else "parts")
    rng = np.random.default_rng(1)
    out = [envs.reset(seed=3)[0]]
    for _ in range(steps):
        # large actions too, so that some rows leave the limits and terminate
        obs, reward, terminated, truncated, info = envs.step(rng.uniform(-1.5, 1.5, (num_envs, 6)))
        out += [obs, reward, terminated, truncated]
    envs.close()
    return out, core


@pytest.mark.parametrize("kwargs", CASES)
def test_the_compiled_step_is_the_step_of_parts(kwargs):
    fused, core = _run(kwargs, compiled=True)
    assert core.fused
    parts, core = _run(kwargs, compiled=False)
    assert not core.fused
    assert len(fused) == len(parts)
    for a, b in zip(fused, parts):
        np.testing.assert_array_equal(a, b)


def test_a_task_with_its_own_reward_takes_the_step_of_parts(monkeypatch):
    from stewart_env.tasks import base

    class Graded(type(gym.make("StewartPlatform-v0").unwrapped._core.task)):
        def reward_terms(self, view):
            return {"distance": -view.errors.position_norm}

    env = gym.make("StewartPlatform-v0").unwrapped
    core = env._core
    assert core.fused
    monkeypatch.setattr(core, "task", Graded(core.platform, core.control_dt))
    core.set_step_mode("auto")
    assert not core.fused and base.Task.reward_terms is not Graded.reward_terms
    with pytest.raises(ValueError, match=r"^step_mode='fused': the task 'setpoint' has its own termination or reward"):
        core.set_step_mode("fused")
    assert core.step_mode == "auto"
    env.reset(seed=0)
    _, reward, *_ = env.step(np.zeros(6))
    assert reward == pytest.approx(-core.view.errors.position_norm[0], abs=0.0)
