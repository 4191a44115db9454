"""The step infos the environments return: one source for their keys and values."""

from __future__ import annotations

import functools

import numpy as np

__all__ = ["step_values", "term_key"]


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
