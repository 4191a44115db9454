"""The study's two jobs, training one agent and running one evaluation: top-level functions,
since Ray workers import them by name, that take and return plain values (an agent travels as
its files' bytes: a worker's file system need not be the driver's); and :func:`on_threads`, which
runs a job on as many physics threads as its worker was given CPUs."""

from __future__ import annotations

import os
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import stewart_env as se
from stewart_env.agents.studies.mismatch.constants import AGENT_FILES
from stewart_env.agents.training import MAX_AGENT_FILE_BYTES, load_agent, train
from stewart_env.dynamics import ModelSpec
from stewart_env.files import read_regular

__all__ = ["agent_files", "evaluate_job", "make_policy", "on_threads", "train_job"]


def on_threads(threads: int, job: Callable, *args):
    """``job(*args)`` with the batches of the physics on ``threads`` threads
    (:func:`stewart_env.set_num_threads`), set at the start of the job: a worker given ``threads``
    CPUs among others on one machine then uses no more than them.

    Args:
        threads: the worker's CPUs.
        job: the job, e.g. :func:`train_job`.
        *args: its arguments.

    Returns:
        What ``job`` returns.
    """
    se.set_num_threads(threads)
    return job(*args)


def train_job(training: dict[str, Any], timesteps: int) -> dict[str, bytes]:
    """Train one agent (``training``: the keywords of :func:`~stewart_env.agents.training.train`)
    in a temporary folder of the worker and return its files' bytes.

    Args:
        training: the keywords of :func:`~stewart_env.agents.training.train` but ``out`` and ``timesteps``.
        timesteps: the environment steps to train for.
    """
    with tempfile.TemporaryDirectory(prefix="stewart-env-agent-") as tmp:
        folder = Path(tmp) / "agent"
        train(**training, out=folder, timesteps=timesteps)
        return agent_files(folder)


def agent_files(folder: Path) -> dict[str, bytes]:
    """The bytes of an agent's files in ``folder``, by name (what travels to and from workers).

    Args:
        folder: the agent's folder.
    """
    return {
        name: read_regular(folder / name, MAX_AGENT_FILE_BYTES)
        for name in AGENT_FILES
        if os.path.lexists(folder / name)
    }


def _load_agent(agent):
    """An agent from its folder (a path) or from its files' bytes (a dict), written to a
    temporary folder first."""
    if not isinstance(agent, dict):
        return load_agent(agent)
    with tempfile.TemporaryDirectory(prefix="stewart-env-agent-") as tmp:
        for name, data in agent.items():
            (Path(tmp) / name).write_bytes(data)
        return load_agent(tmp)


def make_policy(kind: str, model: str | ModelSpec, agent=None, platform: str | None = None):
    """A policy (or a factory env -> policy) for :func:`~stewart_env.agents.evaluation.evaluate`:
    the PD law with model ``model``'s holding forces, CT, the LQR or the MPC with internal model
    ``model``, or the trained ``agent`` (a folder, or its files' bytes).  The model-based
    controllers are built on ``platform`` (a platform name or config path) when given, on the
    plant's nominal platform otherwise.

    Args:
        kind: the controller's kind: ``"pd"``, ``"ct"``, ``"lqr"``, ``"mpc"`` or ``"agent"``.
        model: the dynamics model the controller is built on, best its
            :class:`~stewart_env.dynamics.ModelSpec` (a name is parsed by the controller).
        agent: the trained agent: its folder or its files' bytes (``kind="agent"`` only).
        platform: the platform PD and CT are built on (None: the plant's nominal platform).
    """
    if kind == "agent":
        return _load_agent(agent)
    believed = None
    if platform is not None:
        from stewart_env.params import load_platform

        believed = load_platform(platform)
    if kind == "ct":
        from stewart_env.agents.controllers.computed_torque import ComputedTorquePolicy

        return lambda env: ComputedTorquePolicy(env, model, platform=believed)
    if kind == "pd":
        from stewart_env.agents.controllers.pd import PDPolicy

        return lambda env: PDPolicy(env, gravity_compensation=True, gravity_model=model, platform=believed)
    if kind == "lqr":
        from stewart_env.agents.controllers.lqr import LQRPolicy

        return lambda env: LQRPolicy(env, model, platform=believed)
    if kind == "mpc":
        from stewart_env.agents.controllers.mpc import MPCPolicy

        return lambda env: MPCPolicy(env, model, platform=believed)
    raise ValueError(f"kind: expected 'pd', 'ct', 'lqr', 'mpc' or 'agent', got {kind!r}")


def evaluate_job(
    spec: dict[str, Any], design_model: ModelSpec | str, plant: ModelSpec | str, agent=None
) -> dict[str, Any]:
    """One evaluation: the controller of ``spec`` (a cell's spec) on its plant (with the
    actuator of ``spec["plant_actuator"]`` when the spec has one); every metric per episode, the episodes' terminations, and the job's wall time (s, the policy's loading included).

    Args:
        spec: the cell's spec (:func:`~.cells.cell_spec`), which names the models.
        design_model: the model of ``spec["design_model"]``, parsed: its
            :class:`~stewart_env.dynamics.ModelSpec` (:attr:`~.settings.MismatchSettings.models`).
        plant: the model of ``spec["plant"]``, parsed: its spec, or ``"mujoco"``.
        agent: the trained agent of a learned row: its folder or its files' bytes.

    Returns:
        ``{"metrics": {key: [value per episode]}, "terminations": [...], "wall_time": s}``.
    """
    from stewart_env.agents.evaluation.evaluation import METRICS, evaluate

    start = time.perf_counter()
    policy = make_policy(spec["kind"], design_model, agent, spec.get("design_platform"))
    plant_kwargs = {**spec["env_kwargs"], "model": plant, "task": spec["task"]}
    if spec.get("plant_actuator") is not None:  # the plants' drives, not those the controller was built on
        plant_kwargs["actuator"] = spec["plant_actuator"]
    result = evaluate(
        policy,
        plant_kwargs,
        episodes=spec["episodes"],
        seed=spec["eval_seed"],
        label=spec["controller"],
        max_steps=spec["max_steps"],
        position_tolerance=spec["position_tolerance"],
        orientation_tolerance=spec["orientation_tolerance"],
        progress=False,
    )
    return {
        "metrics": {metric.key: [ep.metrics[metric.key] for ep in result.episodes] for metric in METRICS},
        "terminations": [ep.termination for ep in result.episodes],
        "wall_time": time.perf_counter() - start,
    }
