"""Dynamics models of the Stewart platform: compiled kernels, the model spec (ModelSpec, Switch), the model
(Dynamics), its data (Workspace), its derivatives (Dynamics.acceleration_jacobians and step_jacobians:
AccelerationJacobians, StepJacobians) and the threads of the batches (set_num_threads, get_num_threads; the
environment variable STEWART_ENV_THREADS)."""

from stewart_env.dynamics.derivatives import AccelerationJacobians, StepJacobians
from stewart_env.dynamics.model import (
    MODEL_NAMES,
    SWITCHES,
    Dynamics,
    make_dynamics,
    pack_params,
)
from stewart_env.dynamics.spec import ModelSpec, Switch
from stewart_env.dynamics.threads import get_num_threads, set_num_threads
from stewart_env.dynamics.workspace import Workspace

__all__ = [
    "MODEL_NAMES",
    "SWITCHES",
    "AccelerationJacobians",
    "Dynamics",
    "ModelSpec",
    "StepJacobians",
    "Switch",
    "Workspace",
    "get_num_threads",
    "make_dynamics",
    "pack_params",
    "set_num_threads",
]
