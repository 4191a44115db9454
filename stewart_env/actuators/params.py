"""The actuator parameter sets of a platform config's ``actuators:`` section, as the actuators see
them: :class:`~stewart_env.params.ElectricParams`, :class:`~stewart_env.params.HydraulicParams`
and :class:`~stewart_env.params.ActuatorSets` (defined, with their checks, beside the platform's
other parameters in ``stewart_env.params.actuators``, which reads them), and
:func:`load_actuators`, a platform's sets by its name or file.
"""

from __future__ import annotations

import os

from stewart_env.params import load_platform
from stewart_env.params.actuators import (
    ActuatorSets,
    ElectricParams,
    HydraulicParams,
    actuator_sets_from_config,
)

__all__ = ["ActuatorSets", "ElectricParams", "HydraulicParams", "actuator_sets_from_config", "load_actuators"]


def load_actuators(name_or_path: str | os.PathLike) -> ActuatorSets:
    """The actuator sets of a platform: its config's ``actuators:`` section, read and checked with
    the rest of the platform (:func:`stewart_env.load_platform`).

    Args:
        name_or_path: a shipped platform's name (``"motion_simulator"``) or a config file.

    Returns:
        The platform's sets (each None where the config gives none).

    Raises:
        ConfigError: the config cannot be read or holds an invalid value (naming the file and key).
    """
    return load_platform(name_or_path).actuators
