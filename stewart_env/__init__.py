"""stewart-env: the 6-UPS Stewart platform on closed-form Newton-Euler dynamics.

Public API::

    import stewart_env as se
    params = se.load_platform("dasgupta1998")
    model = se.make_dynamics("improved", params)
    lin_acc, ang_acc = model.forward(position, rotation, velocity, angular_velocity, leg_forces)
    leg_forces = model.inverse(position, rotation, velocity, angular_velocity, lin_acc, ang_acc)
    state = se.rollout(model, position, rotation, velocity, angular_velocity, leg_forces, dt=1e-3, steps=1000)
    state = se.rollout(model, ..., control_law=law, control_params=row)   # law: a compiled se.ControlLaw
    ws = model.workspace()          # preallocated arrays: ws.position[0] = ...; ws.forward()
    se.set_num_threads(1)           # threads of the compiled batches (default: one per core, or
                                    # STEWART_ENV_THREADS when the package is imported); se.get_num_threads()
"""

from stewart_env import registration  # noqa: F401  (registers StewartPlatform-v0 and -v1 with Gymnasium)
from stewart_env.dynamics import (
    MODEL_NAMES,
    Dynamics,
    ModelSpec,
    Switch,
    Workspace,
    get_num_threads,
    make_dynamics,
    set_num_threads,
)
from stewart_env.dynamics.rk4 import ControlLaw
from stewart_env.integrate import rollout
from stewart_env.kinematics import (
    ConvergenceError,
    LegKinematics,
    forward_kinematics,
    inverse_kinematics,
    jacobian,
    leg_kinematics,
)
from stewart_env.params import ConfigError, PlatformParams, available_platforms, load_platform
from stewart_env.rotations import matrix_to_rpy, rpy_to_matrix
from stewart_env.state import PlatformState, Reference

__version__ = "0.1.0"

__all__ = [
    "MODEL_NAMES",
    "ConfigError",
    "ControlLaw",
    "ConvergenceError",
    "Dynamics",
    "LegKinematics",
    "ModelSpec",
    "PlatformParams",
    "PlatformState",
    "Reference",
    "Switch",
    "Workspace",
    "available_platforms",
    "forward_kinematics",
    "get_num_threads",
    "inverse_kinematics",
    "jacobian",
    "leg_kinematics",
    "load_platform",
    "make_dynamics",
    "matrix_to_rpy",
    "rollout",
    "rpy_to_matrix",
    "set_num_threads",
]
