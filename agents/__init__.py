"""Baseline controllers, the evaluation harness and the reproduction of He et al. (2018).

The package by job: controllers (PD, computed torque, LQR, MPC, washout), evaluation (the harness, the statistics),
studies (the reproduction, time to a precise agent, the model-mismatch study) and training
(stable-baselines3); the names below are re-exported from them.

Importable as ``stewart_env.agents``::

    from stewart_env.agents import PDPolicy, ComputedTorquePolicy, evaluate
    result = evaluate(PDPolicy, {"model": "classical", "task": "setpoint"}, episodes=5, seed=0)
"""

from stewart_env.agents.controllers import (
    PAPER_KD,
    PAPER_KP,
    PD_LAYOUT,
    ComputedTorque,
    ComputedTorquePolicy,
    ComputeTime,
    LinearisedMPC,
    LinearQuadraticRegulator,
    LQRPolicy,
    MPCPolicy,
    PDPolicy,
    TaskSpacePD,
    WashoutParams,
    WashoutPolicy,
    control_step_times,
    pd_control_law,
    pd_control_params,
    preview_acceleration,
    task_space_inertia,
    zoh_pd_gains,
    zoh_spectral_radius,
)
from stewart_env.agents.evaluation import (
    METRICS,
    EvaluationResult,
    Metric,
    compare,
    episode_metrics,
    evaluate,
    markdown_table,
    write_report,
)
from stewart_env.agents.studies.reproduce import reproduce

__all__ = [
    "METRICS",
    "PAPER_KD",
    "PAPER_KP",
    "PD_LAYOUT",
    "ComputeTime",
    "ComputedTorque",
    "ComputedTorquePolicy",
    "EvaluationResult",
    "LQRPolicy",
    "LinearQuadraticRegulator",
    "LinearisedMPC",
    "MPCPolicy",
    "Metric",
    "PDPolicy",
    "TaskSpacePD",
    "WashoutParams",
    "WashoutPolicy",
    "compare",
    "control_step_times",
    "episode_metrics",
    "evaluate",
    "markdown_table",
    "pd_control_law",
    "pd_control_params",
    "preview_acceleration",
    "reproduce",
    "task_space_inertia",
    "write_report",
    "zoh_pd_gains",
    "zoh_spectral_radius",
]
