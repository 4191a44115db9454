"""The MuJoCo twin of a platform: the mechanism of any config as MJCF, and a batch plant on it.

    import stewart_env as se
    from stewart_env.mujoco import to_mjcf, MujocoPlant
    xml = to_mjcf(se.load_platform("dasgupta1998"))          # loads with mujoco.MjModel.from_xml_string
    plant = MujocoPlant(se.load_platform("dasgupta1998"))      # step_inplace(...) like rollout_inplace
    drives = MujocoPlant(se.load_platform("motion_simulator"), actuator="electric")  # commands in A

Needs the optional extra: ``pip install -e ".[mujoco]"``.  The package imports without it; the
first call that needs MuJoCo says how to install it.  Its modules, one job each:

* :mod:`~stewart_env.mujoco.library`: the one import of the ``mujoco`` library;
* :mod:`~stewart_env.mujoco.mjcf`: the mechanism as MJCF (:func:`to_mjcf`) and the loops' softness;
* :mod:`~stewart_env.mujoco.twin`: one compiled model, a state set into it (:func:`model_and_data`);
* :mod:`~stewart_env.mujoco.plant`: :class:`MujocoPlant`, N platforms stepped as the environment
  steps them (the environment's plant with ``plant="mujoco"``);
* :mod:`~stewart_env.mujoco.accuracy`: how close the twin comes to the exact model
  (:func:`accuracy_report`), printed by ``python -m stewart_env.mujoco``, with a platform's
  electric drive too (``--actuator electric``: :func:`reflected_mass_error`,
  :func:`electric_agreement`).
"""

from stewart_env.mujoco.accuracy import (
    MUJOCO_SOLIMP,
    MUJOCO_SOLREF,
    acceleration_error,
    accuracy_report,
    electric_agreement,
    holding_drift,
    plant_difference,
    reflected_mass_error,
    spherical_friction_effect,
    trajectory_report,
)
from stewart_env.mujoco.library import require_mujoco
from stewart_env.mujoco.mjcf import DEFAULT_SOLIMP, DEFAULT_SOLREF, to_mjcf
from stewart_env.mujoco.plant import ACTUATORS, MujocoPlant
from stewart_env.mujoco.twin import joint_mass_matrix, model_and_data, platform_acceleration

__all__ = [
    "ACTUATORS",
    "DEFAULT_SOLIMP",
    "DEFAULT_SOLREF",
    "MUJOCO_SOLIMP",
    "MUJOCO_SOLREF",
    "MujocoPlant",
    "acceleration_error",
    "accuracy_report",
    "electric_agreement",
    "holding_drift",
    "joint_mass_matrix",
    "model_and_data",
    "plant_difference",
    "platform_acceleration",
    "reflected_mass_error",
    "require_mujoco",
    "spherical_friction_effect",
    "to_mjcf",
    "trajectory_report",
]
