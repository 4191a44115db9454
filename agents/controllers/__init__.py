"""The baseline controllers: the task-space PD law (He et al. 2018, eq. 56), computed torque, and
the model-based LQR and MPC, each as a control law and as a policy of the environment; and
classical washout, the motion cueing baseline.

The package, one module per controller: :mod:`~stewart_env.agents.controllers.pd` (the PD law,
its compiled form and its discrete-time gains),
:mod:`~stewart_env.agents.controllers.computed_torque` (the inverse-dynamics controller),
:mod:`~stewart_env.agents.controllers.lqr` (the LQR around home, from the control step's exact
Jacobians), :mod:`~stewart_env.agents.controllers.mpc` (the linearised MPC with the force limits,
extra ``mpc``), :mod:`~stewart_env.agents.controllers.washout` (classical washout for the cueing
task), :mod:`~stewart_env.agents.controllers.cueing_mpc` (model-predictive cueing, extra ``mpc``); and :mod:`~stewart_env.agents.controllers.timing` (a controller's compute time per control
step against the control period).
"""

from stewart_env.agents.controllers.computed_torque import ComputedTorque, ComputedTorquePolicy, preview_acceleration
from stewart_env.agents.controllers.cueing_mpc import CueingMPC, CueingMPCParams, CueingMPCPolicy
from stewart_env.agents.controllers.lqr import LinearQuadraticRegulator, LQRPolicy
from stewart_env.agents.controllers.mpc import LinearisedMPC, MPCPolicy
from stewart_env.agents.controllers.pd import (
    PAPER_KD,
    PAPER_KP,
    PD_LAYOUT,
    EnvPolicy,
    PDPolicy,
    TaskSpacePD,
    pd_control_law,
    pd_control_params,
    task_space_inertia,
    zoh_pd_gains,
    zoh_spectral_radius,
)
from stewart_env.agents.controllers.timing import ComputeTime, control_step_times
from stewart_env.agents.controllers.washout import Washout, WashoutParams, WashoutPolicy, load_washout_params

__all__ = [
    "PAPER_KD",
    "PAPER_KP",
    "PD_LAYOUT",
    "ComputeTime",
    "ComputedTorque",
    "ComputedTorquePolicy",
    "CueingMPC",
    "CueingMPCParams",
    "CueingMPCPolicy",
    "EnvPolicy",
    "LQRPolicy",
    "LinearQuadraticRegulator",
    "LinearisedMPC",
    "MPCPolicy",
    "PDPolicy",
    "TaskSpacePD",
    "Washout",
    "WashoutParams",
    "WashoutPolicy",
    "load_washout_params",
    "control_step_times",
    "pd_control_law",
    "pd_control_params",
    "preview_acceleration",
    "task_space_inertia",
    "zoh_pd_gains",
    "zoh_spectral_radius",
]
