"""How long the study's jobs took and what the same jobs would take on more machines: each
agent's training time (its run.json), each evaluation's (its cell), and the study's makespan on
N machines, scheduled from those measured times."""

from __future__ import annotations

import heapq
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from stewart_env.agents.studies.mismatch.constants import CPUS_PER_JOB

__all__ = ["JobTimes", "describe", "duration", "makespan", "scale_out"]


@dataclass
class JobTimes:
    """The measured wall time (s) of each of the study's jobs: ``training`` one per agent, from its
    run.json (the training loop alone: a worker's start and the agent's transfer are not in it);
    ``evaluation`` one per cell whose file records it (cells written before evaluations were timed
    do not), ``untimed_cells`` the others."""

    training: list[float]
    evaluation: list[float]
    untimed_cells: int = 0


def makespan(times: Sequence[float], slots: int) -> float:
    """The wall time of ``times``' jobs on ``slots`` workers, each job given to the worker free
    first, longest job first (a list schedule within 4/3 of the shortest possible).

    Args:
        times: the jobs' durations, s.
        slots: the number of workers.
    """
    if slots < 1:
        raise ValueError(f"slots: expected at least 1, got {slots}")
    finish = [0.0] * min(slots, len(times))
    if not finish:
        return 0.0
    for t in sorted(times, reverse=True):
        heapq.heapreplace(finish, finish[0] + float(t))
    return max(finish)


def scale_out(times: JobTimes, cpus_per_machine: int, machines: Sequence[int] = (1, 2, 5, 10)) -> list[dict]:
    """For each count N of ``machines`` of ``cpus_per_machine`` CPUs: the study's training and
    evaluation makespans (s) with every job on :data:`CPUS_PER_JOB` CPUs, trainings first (the
    evaluations need the agents), as the study runs them; evaluation None unless every cell was
    timed.

    Args:
        times: the study's measured job times.
        cpus_per_machine: the CPUs of one machine.
        machines: the machine counts N to compute.
    """
    rows = []
    for n in machines:
        slots = max(1, (n * cpus_per_machine) // CPUS_PER_JOB)
        evaluation = None if times.untimed_cells else makespan(times.evaluation, slots)
        rows.append(
            {
                "machines": n,
                "cpus": n * cpus_per_machine,
                "slots": slots,
                "training": makespan(times.training, slots),
                "evaluation": evaluation,
            }
        )
    return rows


def describe(times: Sequence[float]) -> str:
    """'median a (b to c), d in all' of a list of job times, each a :func:`duration`.

    Args:
        times: the job times, s.
    """
    if not len(times):
        return "none"
    t = np.asarray(times, dtype=float)
    return f"median {duration(np.median(t))} ({duration(t.min())} to {duration(t.max())}), {duration(t.sum())} in all"


def duration(seconds: float | None) -> str:
    """A duration for the table: s below two minutes, min below two hours, h above.

    Args:
        seconds: the duration, s (None or not finite: ``-``).
    """
    if seconds is None or not math.isfinite(seconds):
        return "-"
    if seconds < 120:
        return f"{seconds:.3g} s"
    if seconds < 7200:
        return f"{seconds / 60:.1f} min"
    return f"{seconds / 3600:.2f} h"
