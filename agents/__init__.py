"""Baseline controllers, the evaluation harness and the reproduction of He et al. (2018).

Importable as ``stewart_env.agents``::

    from stewart_env.agents import PDPolicy, ComputedTorquePolicy, evaluate
    result = evaluate(PDPolicy, {"model": "classical", "task": "setpoint"}, episodes=5, seed=0)
"""

from stewart_env.agents.computed_torque import ComputedTorque, ComputedTorquePolicy, preview_acceleration
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
from stewart_env.agents.pd import (
    PAPER_KD,
    PAPER_KP,
    PD_LAYOUT,
    PDPolicy,
    TaskSpacePD,
    pd_control_law,
    pd_control_params,
    task_space_inertia,
    zoh_pd_gains,
    zoh_spectral_radius,
)
from stewart_env.agents.reproduce import reproduce

__all__ = [
    "METRICS",
    "PAPER_KD",
    "PAPER_KP",
    "PD_LAYOUT",
    "ComputedTorque",
    "ComputedTorquePolicy",
    "EvaluationResult",
    "Metric",
    "PDPolicy",
    "TaskSpacePD",
    "compare",
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
