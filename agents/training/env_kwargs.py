"""``--env-kwargs`` from the command line, and settings made fit for the run manifest (JSON)."""

from __future__ import annotations

import json
from collections.abc import Sequence
from typing import Any

import numpy as np

from stewart_env.agents.training.errors import TrainingError
from stewart_env.agents.training.rundir import MANIFEST

__all__ = ["jsonable", "parse_env_kwargs"]


def parse_env_kwargs(items: Sequence[str] | None) -> dict[str, Any]:
    """``--env-kwargs`` values: one JSON object, or ``key=value`` tokens whose values are JSON
    (numbers, true/false, lists, objects) or else plain strings."""
    out: dict[str, Any] = {}
    for item in items or ():
        text = item.strip()
        if text.startswith("{"):
            try:
                value = json.loads(text)
            except json.JSONDecodeError as exc:
                raise TrainingError(f"--env-kwargs: not a JSON object: {text!r} ({exc})") from None
            out.update(value)
            continue
        key, sep, raw = text.partition("=")
        if not sep or not key:
            raise TrainingError(f"--env-kwargs: expected key=value or a JSON object, got {item!r}")
        try:
            out[key] = json.loads(raw)
        except json.JSONDecodeError:
            out[key] = raw
    return out


def jsonable(value: Any) -> Any:
    """``value`` with tuples and numpy values made JSON-friendly (for run.json)."""
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
    raise TrainingError(f"environment kwarg value {value!r} cannot be written to {MANIFEST}; "
                        "pass names, numbers, lists and dicts")

