"""A study's finished evaluations (its cells) on disk: where each lives, what its numbers depend
on, and its metrics and intervals read back."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from stewart_env.agents.evaluation.statistics import Interval, stratified_bootstrap
from stewart_env.agents.studies.mismatch.constants import CELLS_DIR, MAX_CELL_BYTES, MismatchError, statistic
from stewart_env.agents.studies.mismatch.results import Row
from stewart_env.agents.training import MODEL_FILE, read_manifest
from stewart_env.files import read_json

__all__ = [
    "cell_intervals",
    "cell_path",
    "cell_spec",
    "cell_values",
    "cell_wall_time",
    "metric_values",
    "read_cell",
    "stored_cells",
    "stored_metrics",
]


def cell_path(out: Path, row: Row, plant: str, seed: int | None) -> Path:
    """The file of ``row``'s cell on ``plant`` (one per training seed of a learned row).

    Args:
        out: the study's folder.
        row: the controller.
        plant: the test plant's model name.
        seed: the training seed of a learned row's agent; None for a model-based row.
    """
    from stewart_env.agents.evaluation.evaluation import slug

    return (
        out / CELLS_DIR / slug(row.label) / slug(plant) / ("model_based.json" if seed is None else f"seed_{seed}.json")
    )


def cell_spec(row: Row, plant: str, seed: int | None, common: Mapping[str, Any]) -> dict[str, Any]:
    """What an evaluation's numbers depend on (``common``: the study's
    :meth:`~.settings.MismatchSettings.evaluation`, with the agents' env kwargs for a learned row);
    a finished cell is reused only if all of it is equal.

    Args:
        row: the controller.
        plant: the test plant's model name.
        seed: the training seed of a learned row's agent; None for a model-based row.
        common: the study's evaluation settings (:meth:`~.settings.MismatchSettings.evaluation`).
    """
    spec = {"controller": row.label, "kind": row.kind, "design_model": row.model, "plant": plant, **common}
    if row.platform is not None:  # only then: the cells of studies without controller platforms stay valid
        spec["design_platform"] = row.platform
    if seed is not None:
        spec["agent_seed"] = seed
        spec["agent_sha256"] = read_manifest(row.agents[seed])["files"][MODEL_FILE]
    return spec


def read_cell(path: Path) -> dict[str, Any]:
    """A finished cell's file: its spec and its metrics per episode.

    Args:
        path: the cell's file.
    """
    cell = read_json(path, MAX_CELL_BYTES, "cell file")
    if not (isinstance(cell, dict) and isinstance(cell.get("spec"), dict) and isinstance(cell.get("metrics"), dict)):
        raise MismatchError(
            f"{path}: not a cell of a mismatch study (no spec and metrics); remove it to compute the cell again"
        )
    return cell


def stored_cells(out: Path, row: Row, plant: str) -> list[dict[str, Any]]:
    """A stored cell's files (:func:`read_cell`), one per seed (one for a model-based row).

    Args:
        out: the study's folder.
        row: the controller.
        plant: the test plant's model name.
    """
    return [read_cell(cell_path(out, row, plant, seed)) for seed in (row.seeds or (None,))]


def stored_metrics(out: Path, row: Row, plant: str) -> list[dict[str, list[float]]]:
    """A stored cell's metrics per episode, one dict per seed (one for a model-based row).

    Args:
        out: the study's folder.
        row: the controller.
        plant: the test plant's model name.
    """
    return [cell["metrics"] for cell in stored_cells(out, row, plant)]


def cell_wall_time(cell: Mapping[str, Any]) -> float | None:
    """The evaluation's wall time (s) a cell file records; None if it records none (a cell written
    before evaluations were timed) or no finite time.

    Args:
        cell: the cell's file, as :func:`read_cell` reads it.
    """
    t = cell.get("wall_time")
    if isinstance(t, (int, float)) and not isinstance(t, bool) and math.isfinite(t) and t >= 0:
        return float(t)
    return None


def metric_values(stored: list[dict[str, list[float]]], metric: str) -> np.ndarray:
    """One metric's values, (seeds, episodes), of a cell's :func:`stored_metrics`.

    Args:
        stored: the cell's :func:`stored_metrics`.
        metric: the metric's name.
    """
    return np.array([s[metric] for s in stored], dtype=float)


def cell_values(out: Path, row: Row, plant: str, metric: str) -> np.ndarray:
    """A stored cell's values of one metric, (seeds, episodes).

    Args:
        out: the study's folder.
        row: the controller.
        plant: the test plant's model name.
        metric: the metric's name.
    """
    return metric_values(stored_metrics(out, row, plant), metric)


def cell_intervals(stored: list[dict[str, list[float]]]) -> dict[str, Interval]:
    """Every metric's interval of a cell's :func:`stored_metrics`.

    Args:
        stored: the cell's :func:`stored_metrics`.
    """
    from stewart_env.agents.evaluation.evaluation import METRICS

    return {m.key: stratified_bootstrap(metric_values(stored, m.key), statistic(m.key)) for m in METRICS}
