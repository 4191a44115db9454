"""The environment's electric drive on the MuJoCo plant (plant="mujoco", actuator="electric"): the
plant carries the drives, commanded by current set points, against the closed form's compiled step."""

import copy

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import stewart_env.registration  # noqa: F401  (registers StewartPlatform-v1)
from stewart_env.errors import UsageError

mujoco = pytest.importorskip("mujoco")

pytestmark = pytest.mark.env

ENV_ID = "StewartPlatform-v1"
ELECTRIC = {
    "platform": "motion_simulator",
    "task": "setpoint",
    "task_options": {"randomize": False},
    "actuator": "electric",
    "observe_actuators": True,
}


def test_gymnasium_checker_passes_the_electric_drive_on_mujoco():
    env = gym.make(ENV_ID, plant="mujoco", **ELECTRIC)
    check_env(env.unwrapped, skip_render_check=True)
    assert env.unwrapped._core.plant.actuator == "electric"


def test_electric_drive_on_mujoco_agrees_with_the_closed_form():
    plant, exact = gym.make(ENV_ID, plant="mujoco", **ELECTRIC), gym.make(ENV_ID, **ELECTRIC)
    obs_m, _ = plant.reset(seed=0)
    obs_c, _ = exact.reset(seed=0)
    # the same start: the task's state, the drives' equilibrium currents observed alike
    np.testing.assert_array_equal(obs_m, obs_c)
    batch_m, batch_c = plant.unwrapped._core, exact.unwrapped._core
    np.testing.assert_array_equal(batch_m.plant.current, batch_c.actuation.state[:, :, 0])
    assert np.abs(batch_m.plant.current).max() > 1.0  # holding currents, not zeros
    a = np.full(6, 0.1)
    for _ in range(30):
        obs_m, _, terminated, _, _ = plant.step(a)
        obs_c, _, _, _, _ = exact.step(a)
    assert not terminated
    # the observed currents are the plant's drives' currents
    np.testing.assert_array_equal(batch_m.actuation.state[:, :, 0], batch_m.plant.current)
    np.testing.assert_array_equal(batch_m.leg_forces, batch_m.plant.drive_force)
    # 0.3 s under the same set points (the platform moves ~0.1 m), the reflected masses as MuJoCo's
    # armature: measured 1.3e-7 m apart; 1e-6 m is the twin's bound for the ideal actuator
    # (tests/twin/test_env_mujoco.py), far below the motion
    assert np.abs(plant.unwrapped.state.position - batch_c.platform.home_position).max() > 0.05
    np.testing.assert_allclose(plant.unwrapped.state.position, exact.unwrapped.state.position, rtol=0, atol=1e-6)
    # the current loops have settled on the same set points in both (measured equal); 1e-6 A of
    # the ~30 A holding currents allows the loops' last rounding
    np.testing.assert_allclose(batch_m.plant.current, batch_c.actuation.state[:, :, 0], rtol=0, atol=1e-6)


def test_pose_and_leg_length_modes_on_mujoco_stay_refused_naming_the_argument():
    for mode in ("pose", "leg_length"):
        with pytest.raises(UsageError, match=r"action_mode.*'mujoco' plant takes leg forces only"):
            gym.make(ENV_ID, plant="mujoco", **dict(ELECTRIC, action_mode=mode))


def test_a_copy_of_the_electric_drive_on_mujoco_continues_bit_for_bit():
    env = gym.make(ENV_ID, plant="mujoco", **ELECTRIC)
    env.reset(seed=0)
    a = np.full(6, -0.2)
    for _ in range(3):
        env.step(a)
    twin_env = copy.deepcopy(env)
    for _ in range(3):
        obs, *_ = env.step(a)
        obs_copy, *_ = twin_env.step(a)
    np.testing.assert_array_equal(obs, obs_copy)  # the drives' currents travel with the copy
