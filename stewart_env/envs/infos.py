"""The step infos the environments return: one source for their keys and values."""

from __future__ import annotations

import functools

import numpy as np

__all__ = ["row_info", "step_values", "term_key"]


@functools.cache
def term_key(name: str) -> str:
    """The info key of a reward term: ``reward_<name>`` (made once per name: it is on the step path)."""
    return f"reward_{name}"


def step_values(terms: dict[str, np.ndarray], code: np.ndarray, time: np.ndarray,
                closure_error: np.ndarray | None) -> dict[str, np.ndarray]:
    """Every row's step info, by key: ``reward_<term>`` (float64), ``termination`` (int64 code),
    ``time`` (float64, s) and, when the plant reports it, ``closure_error`` (float64, m); each an
    (n,) array of its own (copied where the batch goes on writing into it)."""
    values = {term_key(k): v for k, v in terms.items()}
    values["termination"] = code.copy()
    values["time"] = time.copy()
    if closure_error is not None:
        values["closure_error"] = closure_error.copy()
    return values


def row_info(terms: dict[str, np.ndarray], code: np.ndarray, time: np.ndarray, closure_error: np.ndarray | None,
             row: int) -> dict[str, np.generic]:
    """Row ``row``'s step info, the values of :func:`step_values` as numpy numbers (the single
    environment's info), read straight from the batch's arrays."""
    info = {term_key(k): v[row] for k, v in terms.items()}
    info["termination"] = code[row]
    info["time"] = time[row]
    if closure_error is not None:
        info["closure_error"] = closure_error[row]
    return info
