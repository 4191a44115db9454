"""The legs' actuators: what turns a drive's command into the force along each leg.

``transmission`` holds the ball-screw drive's kinematics and statics (the one place where a
motor's torque, current and speed are converted to a leg's force and velocity); ``params`` the
parameter sets of a platform config's ``actuators:`` section (electric, hydraulic) and
``models`` the actuator models over the compiled batch step (lag, electric, hydraulic) and the
leg servo (docs/physics.md section 10).
"""

from stewart_env.actuators.models import ElectricActuator, HydraulicActuator, IdealActuator, LagActuator, LegServo
from stewart_env.actuators.params import ActuatorSets, ElectricParams, HydraulicParams, load_actuators
from stewart_env.actuators.transmission import BallScrew

__all__ = [
    "BallScrew",
    "ElectricParams",
    "HydraulicParams",
    "ActuatorSets",
    "load_actuators",
    "IdealActuator",
    "LagActuator",
    "ElectricActuator",
    "HydraulicActuator",
    "LegServo",
]
