"""The legs' actuators: what turns a drive's command into the force along each leg.

``transmission`` holds the ball-screw drive's kinematics and statics (the one place where a
motor's torque, current and speed are converted to a leg's force and velocity).
"""

from stewart_env.actuators.transmission import BallScrew

__all__ = ["BallScrew"]
