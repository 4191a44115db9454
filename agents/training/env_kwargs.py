"""``--env-kwargs`` from the command line, and settings made fit for the run manifest (JSON)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from stewart_env.agents.training.errors import TrainingError
from stewart_env.agents.training.rundir import MANIFEST
from stewart_env.files import DocumentError, load_json
from stewart_env.params.checks import excerpt

__all__ = ["jsonable", "parse_env_kwargs"]


def _refuse(problem: str) -> TrainingError:
    """The error of an ``--env-kwargs`` value: ``--env-kwargs: <problem>``, argument ``env_kwargs``."""
    return TrainingError(f"--env-kwargs: {problem}", argument="env_kwargs", problem=problem)


def parse_env_kwargs(items: Sequence[str] | None) -> dict[str, Any]:
    """``--env-kwargs`` values: one JSON object, or ``key=value`` tokens whose values are JSON
    (numbers, true/false, lists, objects) or else plain strings.

    Args:
        items: the ``--env-kwargs`` values (None: none).
    """
    out: dict[str, Any] = {}
    for item in items or ():
        text = item.strip()
        if text.startswith("{"):
            try:
                value = load_json(text)
            except DocumentError as exc:
                raise _refuse(f"not a JSON object: {excerpt(text)!r} ({exc.problem})") from None
            out.update(value)
            continue
        key, sep, raw = text.partition("=")
        if not sep or not key:
            raise _refuse(f"expected key=value or a JSON object, got {excerpt(item)!r}")
        try:
            out[key] = load_json(raw)
        except DocumentError as exc:
            if exc.nested:
                raise _refuse(f"{key}: {exc.problem}") from None
            out[key] = raw
    return out


def jsonable(value: Any) -> Any:
    """``value`` with tuples and numpy values made JSON-friendly (for run.json).

    Args:
        value: the value.
    """
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise TrainingError(
        f"environment kwarg value {value!r} cannot be written to {MANIFEST}; pass names, numbers, lists and dicts"
    )
