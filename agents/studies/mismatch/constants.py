"""The mismatch study's constants, its statistic per metric and its error class."""

from __future__ import annotations

from stewart_env.agents.training import MANIFEST, MODEL_FILE, VECNORMALIZE_FILE
from stewart_env.dynamics.model import SIMPLIFICATIONS as SIMPLIFICATION_TEXT
from stewart_env.errors import UsageError

__all__ = [
    "AGENTS_DIR",
    "AGENT_FILES",
    "AUTO_THREADS",
    "BACKENDS",
    "CELLS_DIR",
    "CONTROLLERS",
    "CPUS_PER_JOB",
    "DEFAULT_CONTROLLERS",
    "DEFAULT_RANDOMIZATION",
    "DEFAULT_STATISTIC",
    "EVAL_SEED_OFFSET",
    "FAILURE_THRESHOLD",
    "MAX_CELL_BYTES",
    "MAX_STEPS",
    "QUICK_TIMESTEPS",
    "RANKING_METRICS",
    "RAY_AUTH_HINT",
    "RAY_CONNECT_TIMEOUT",
    "RAY_INSTALL_HINT",
    "SIMPLIFICATIONS",
    "SIMPLIFICATION_TEXT",
    "STATISTIC",
    "STUDY_FILE",
    "TRUE_MODEL",
    "MismatchError",
    "statistic",
]


class MismatchError(UsageError):
    """A study request that cannot be carried out (a bad setting, a folder holding another
    study or another study's agents, a damaged cell); the message names the argument or path."""


#: The model-based controllers a study builds on each model, by kind: task-space PD with the model's
#: holding forces, computed torque, the LQR around home and the linearised MPC (extra ``mpc``), the
#: last two from the model's control step Jacobians (stewart_env.agents.controllers).
CONTROLLERS = ("pd", "ct", "lqr", "mpc")
#: Those of a study that names none: PD and computed torque.
DEFAULT_CONTROLLERS = ("pd", "ct")

#: Environment steps per RL agent of the quick default study: a smoke-scale budget (such agents
#: still lose the platform); --timesteps 1500000 or more for agents that hold a set point.
QUICK_TIMESTEPS = 20_000
#: The classical model's simplifications, each a switch on the improved model.
SIMPLIFICATIONS = tuple(SIMPLIFICATION_TEXT)
#: Domain randomisation of the DR row: per-episode factors on the nominal parameters.  The legs'
#: inertial parameters get the widest ranges because three of the classical model's four
#: simplifications (C1-C3) concern the legs' dynamics.
DEFAULT_RANDOMIZATION: dict[str, tuple[float, float]] = {
    "platform.mass": (0.8, 1.2),
    "platform.inertia": (0.8, 1.2),
    "platform.com": (0.5, 1.5),
    "legs.mass": (0.5, 1.5),
    "legs.inertia": (0.5, 2.0),
    "legs.com": (0.5, 1.5),
    "damping": (0.0, 2.0),
}
#: Evaluation episodes use seeds EVAL_SEED_OFFSET + i, away from the training runs' seeds.
EVAL_SEED_OFFSET = 100_000
#: The longest evaluation episode, in control steps (1e5 s at the default 10 ms step): a longer one
#: is a typo, not a study.
MAX_STEPS = 10**7
#: The metrics whose differences measure a simplification's cost, on the true plant: the static
#: error (where a wrong model shows most on a set point) and the transient error, each in position
#: and orientation, and the effort: the force peak and the control energy (a learned agent's peak
#: is often the actuators' limit, so only its energy shows how hard it pushes).  Settling time and
#: overshoot are left out: undefined in the episodes that never settle.
RANKING_METRICS = (
    "steady_state_position_error",
    "steady_state_orientation_error",
    "rms_position_error",
    "rms_orientation_error",
    "peak_leg_force",
    "control_energy",
)
TRUE_MODEL = "improved"
#: A cell whose controller succeeds in fewer than this share of the episodes is marked failed: its
#: heatmap cell is hatched grey, and its differences are marked, not ranked.
FAILURE_THRESHOLD = 0.5
#: The statistic of each metric's cells: the success rate is a share (a mean); every other
#: metric an interquartile mean.
STATISTIC = {"success": "mean"}
DEFAULT_STATISTIC = "iqm"
#: CPUs each training run and each evaluation requests from Ray: training runs on one torch
#: thread (training.single_thread), and an evaluation steps one batch of platforms.
CPUS_PER_JOB = 1
#: ``--physics-threads``'s default: each job on the threads of the CPUs it was given (on Ray,
#: CPUS_PER_JOB), or the package's default in this process (the local backend).
AUTO_THREADS = "auto"
BACKENDS = ("local", "ray")
#: A cluster started with ``ray start`` checks a token when one exists in ~/.ray/auth_token (any
#: earlier local Ray instance writes it), and a driver joining it by an explicit address sends the
#: token only when told to.
RAY_AUTH_HINT = (
    "; if the cluster checks a token (Ray 2.59 and later do when ~/.ray/auth_token exists), set "
    "RAY_AUTH_MODE=token and give its token in ~/.ray/auth_token or RAY_AUTH_TOKEN (see "
    "`ray get-auth-token` on the head node), or join with --ray-address auto on the head node"
)
#: Seconds to wait for a Ray head node to accept a connection before refusing its address.
RAY_CONNECT_TIMEOUT = 5.0
RAY_INSTALL_HINT = 'install the distributed extra: pip install -e ".[distributed]" (ray)'
#: Settings recorded in study.json: a second run in the same directory must match them.
STUDY_FILE = "study.json"
CELLS_DIR = "cells"
AGENTS_DIR = "agents"
#: Bound of a finished cell's file read back (every metric of every episode of one evaluation).
MAX_CELL_BYTES = 256 << 20
#: The files of an agent folder that loading it needs (and that a Ray worker sends back).
AGENT_FILES = (MANIFEST, MODEL_FILE, VECNORMALIZE_FILE)


def statistic(metric: str) -> str:
    """The statistic ("mean" or "iqm") a metric's cells report.

    Args:
        metric: the metric's name.
    """
    return STATISTIC.get(metric, DEFAULT_STATISTIC)
