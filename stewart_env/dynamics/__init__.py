"""Dynamics models of the Stewart platform: compiled kernels, the model (Dynamics) and its data (Workspace)."""

from stewart_env.dynamics.model import (
    MODEL_NAMES,
    SWITCHES,
    Dynamics,
    make_dynamics,
    pack_params,
)
from stewart_env.dynamics.workspace import Workspace

__all__ = ["MODEL_NAMES", "SWITCHES", "Dynamics", "Workspace", "make_dynamics", "pack_params"]
