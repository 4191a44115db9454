"""Dynamics models of the Stewart platform: compiled kernels and the classes that call them."""

from stewart_env.dynamics.model import (
    MODEL_NAMES,
    SWITCHES,
    Dynamics,
    make_dynamics,
    pack_params,
)

__all__ = ["MODEL_NAMES", "SWITCHES", "Dynamics", "make_dynamics", "pack_params"]
