"""Tasks of the Stewart platform environment: what the platform should do and how it is scored.

``setpoint`` (reach and hold a pose), ``tracking`` (follow a sinusoidal reference),
``disturbance`` (hold home against a random external wrench), ``hold`` (hold home under a
random payload) and ``cueing`` (make a person on the platform perceive a vehicle's motion).  See :mod:`stewart_env.tasks.base` for the interface a task implements; a new
task is one module with a :class:`Task` subclass, added to :data:`TASKS` here.
"""

from __future__ import annotations

from typing import Any

from stewart_env.params import PlatformParams
from stewart_env.state import PlatformState, Reference
from stewart_env.tasks.base import (
    LIMIT_REASONS,
    Errors,
    RewardWeights,
    Scales,
    StepView,
    Task,
    check_option_names,
    tracking_errors,
)
from stewart_env.tasks.cueing.task import CueingTask
from stewart_env.tasks.disturbance import DisturbanceTask
from stewart_env.tasks.hold import HoldTask
from stewart_env.tasks.setpoint import SetpointTask
from stewart_env.tasks.tracking import TrackingTask

TASKS: dict[str, type[Task]] = {
    cls.name: cls for cls in (SetpointTask, TrackingTask, DisturbanceTask, HoldTask, CueingTask)
}

__all__ = [
    "LIMIT_REASONS",
    "TASKS",
    "CueingTask",
    "DisturbanceTask",
    "Errors",
    "HoldTask",
    "PlatformState",
    "Reference",
    "RewardWeights",
    "Scales",
    "SetpointTask",
    "StepView",
    "Task",
    "TrackingTask",
    "make_task",
    "tracking_errors",
]


def make_task(
    task: str | type[Task],
    params: PlatformParams,
    control_dt: float,
    options: dict[str, Any] | None = None,
    version: int | None = None,
) -> Task:
    """The task ``task`` on ``params`` with ``options``, as under the environment's ``version``.

    Args:
        task: a name in :data:`TASKS` or a :class:`Task` subclass.
        params: the platform's parameters.
        control_dt: the control step, s.
        options: the task's options (``task_options`` of the environment), or None for none.
        version: the environment's version (None: the current one); the defaults the task's
            class gives for that version (``Task.version_defaults``) fill the options
            ``options`` leaves out.

    Returns:
        The :class:`Task`.

    Raises:
        ValueError: an unknown task, an unknown option or an option out of its range (the message
            names it).

    Examples:
        >>> import stewart_env as se
        >>> from stewart_env.tasks import make_task
        >>> task = make_task("tracking", se.load_platform("dasgupta1998"), control_dt=0.01)
        >>> type(task).__name__
        'TrackingTask'
    """
    if isinstance(task, str):
        if task not in TASKS:
            raise ValueError(f"task: unknown task {task!r}; choose one of {', '.join(TASKS)}")
        cls = TASKS[task]
    elif isinstance(task, type) and issubclass(task, Task):
        cls = task
    else:
        raise ValueError(f"task: expected a task name ({', '.join(TASKS)}) or a Task subclass, got {task!r}")
    if options is None:
        options = {}
    if not isinstance(options, dict):
        raise ValueError(f"task_options: expected a dict of options, got {options!r}")
    if version is not None:
        options = {**cls.version_defaults.get(version, {}), **options}
    check_option_names(cls, options)
    return cls(params, control_dt, **options)
