"""The step infos the environments return: one source for their keys and values."""

from __future__ import annotations

import functools

import numpy as np

__all__ = ["SUCCESS_KEYS", "row_info", "step_values", "term_key"]

#: The info keys of a step's outcome for the success criterion, in the order of
#: :meth:`~stewart_env.envs.core.PlatformBatch.track_success`: the position error |e_p| (m), the
#: orientation error's angle (rad) and whether the episode, ended at this step, succeeds.
SUCCESS_KEYS = ("position_error", "orientation_error", "is_success")


@functools.cache
def term_key(name: str) -> str:
    """The info key of a reward term: ``reward_<name>`` (made once per name: it is on the step path).

    Args:
        name: the reward term's name.
    """
    return f"reward_{name}"


def step_values(
    terms: dict[str, np.ndarray],
    code: np.ndarray,
    time: np.ndarray,
    closure_error: np.ndarray | None,
    success: tuple[np.ndarray, np.ndarray, np.ndarray],
    costs: dict[str, np.ndarray] | None = None,
    task_values: dict[str, np.ndarray] | None = None,
) -> dict[str, np.ndarray]:
    """Every row's step info, by key: ``reward_<term>`` (float64), ``termination`` (int64 code),
    ``time`` (float64, s), when the plant reports it ``closure_error`` (float64, m), and
    ``position_error``, ``orientation_error`` (float64, m and rad) and ``is_success`` (bool), the
    arrays ``success`` of :meth:`~stewart_env.envs.core.PlatformBatch.track_success`, then the
    constraint costs ``cost`` and ``cost_<constraint>`` (float64), then the task's own values
    (:meth:`~stewart_env.tasks.Task.step_info`); each an (n, ...) array of its own (copied where
    the batch goes on writing into it).

    Args:
        terms: each reward term's values, by name, (n,) arrays.
        code: the termination code of each row (n,).
        time: each row's episode time (n,), s.
        closure_error: each row's loop-closure error (n,), m, or None when the plant does not report it.
        success: the (position error, orientation error, success) arrays (n,) of
            :meth:`~stewart_env.envs.core.PlatformBatch.track_success`.
        costs: the step's constraint costs by key, (n,) arrays of their own
            (:meth:`~stewart_env.envs.costs.BatchCosts.info`), or None.
        task_values: the task's values by key, (n, ...) arrays of their own, or None.
    """
    values = {term_key(k): v for k, v in terms.items()}
    values["termination"] = code.copy()
    values["time"] = time.copy()
    if closure_error is not None:
        values["closure_error"] = closure_error.copy()
    values.update(zip(SUCCESS_KEYS, success))
    if costs is not None:
        values.update(costs)
    if task_values:
        values.update(task_values)
    return values


def row_info(
    terms: dict[str, np.ndarray],
    code: np.ndarray,
    time: np.ndarray,
    closure_error: np.ndarray | None,
    row: int,
    success: tuple[float, float, bool],
    costs: dict[str, float] | None = None,
    task_values: dict[str, np.ndarray] | None = None,
) -> dict[str, np.generic]:
    """Row ``row``'s step info, the values of :func:`step_values` as numpy numbers (the single
    environment's info), read straight from the batch's arrays, and ``success`` the row's
    (position error, orientation error, success) of
    :meth:`~stewart_env.envs.core.PlatformBatch.track_success_of_row`.

    Args:
        terms: each reward term's values, by name, (n,) arrays.
        code: the termination code of each row (n,).
        time: each row's episode time (n,), s.
        closure_error: each row's loop-closure error (n,), m, or None when the plant does not report it.
        row: the row whose info it is.
        success: the row's (position error, m; orientation error, rad; success) of
            :meth:`~stewart_env.envs.core.PlatformBatch.track_success_of_row`.
        costs: the row's constraint costs by key (:meth:`~stewart_env.envs.costs.BatchCosts.info`
            of the row), given as float64, or None.
        task_values: the task's values by key, (n, ...) arrays, or None; the row's entry of each.
    """
    info = {term_key(k): v[row] for k, v in terms.items()}
    info["termination"] = code[row]
    info["time"] = time[row]
    if closure_error is not None:
        info["closure_error"] = closure_error[row]
    position, orientation, succeeded = success
    info["position_error"] = np.float64(position)
    info["orientation_error"] = np.float64(orientation)
    info["is_success"] = np.bool_(succeeded)
    if costs is not None:
        for key, value in costs.items():
            info[key] = np.float64(value)
    if task_values:
        for key, value in task_values.items():
            info[key] = value[row]
    return info
