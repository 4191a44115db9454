"""The electric drive brakes at any speed: the back-EMF bounds the current that drives the motor
with its speed, not the current against it (docs/physics.md section 10.4).  Bounding both, a leg
that ran past the no-load speed had no force to stop it and fell to the end of its stroke."""

import numpy as np
import pytest

from stewart_env.actuators import ElectricActuator, load_actuators
from stewart_env.agents.studies.actuation import PoseCommand, env_kwargs_of

ELECTRIC = load_actuators("motion_simulator").electric


def test_past_the_no_load_speed_the_drive_brakes_at_its_current_limit():
    drive = ElectricActuator(ELECTRIC)
    speed0 = drive.no_load_speed
    l_dot = np.array([[1.5, -1.5, 1.5, -1.5, 0.5, -0.5]]) * speed0
    # against the speed (braking) in legs 0, 1, 4, 5; with it (motoring) in legs 2, 3
    command = np.array([[-1e4, 1e4, 1e4, -1e4, -1e4, 1e4]])
    for _ in range(60):  # 60 steps of exp(-pi): the current has converged
        drive.step(command, l_dot, 1e-3)
    limit = ELECTRIC.current_limit
    # braking: the current limit at any speed; motoring past the no-load speed: nothing
    assert drive.current[0] == pytest.approx([-limit, limit, 0.0, 0.0, -limit, limit], rel=1e-12, abs=1e-9)


def test_the_pose_mode_s_leg_servos_on_the_electric_drives_hold_a_set_point_they_overran():
    import gymnasium as gym

    env = gym.make("StewartPlatform-v1", **env_kwargs_of("pose", "ik", "electric", "setpoint"))
    policy = PoseCommand(env)
    # evaluation episode 1 of the actuation study: two legs retract past the no-load speed
    # (1.14 m/s) under gravity within 60 ms; a drive that could not brake let them reach the stroke
    obs, _ = env.reset(seed=10_001)
    for _ in range(500):
        obs, _, terminated, truncated, info = env.step(policy.predict(obs)[0])
        if terminated or truncated:
            break
    assert not terminated and info["is_success"]
