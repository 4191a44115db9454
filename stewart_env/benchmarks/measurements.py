"""The compiled core's figures: forward evaluations and rollouts per model, the scaling over batch
sizes with the flop count and the machine's peak, a fresh process's first evaluation, the machine.
"""

from __future__ import annotations

import os
import platform as _platform
import subprocess
import sys
import time

import numpy as np

import stewart_env as se
from stewart_env import _core
from stewart_env.dynamics import kernels as K

_FIRST_CALL = (
    "import time; t0 = time.perf_counter(); import numpy as np, stewart_env as se; "
    "p = se.load_platform('dasgupta1998'); m = se.make_dynamics('improved', p); "
    "m.forward(p.home_position, np.eye(3), np.zeros(3), np.zeros(3), np.full(6, 180.0)); "
    "print(time.perf_counter() - t0)"
)


def _best_of(fn, repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def _batch_state(model, n: int, rng: np.random.Generator):
    """Poses near home, at rest, with the leg forces that hold each one: the platform barely
    moves over 1 s, so every row does the same work."""
    params = model.params[0]
    t = params.home_position + rng.uniform(-0.02, 0.02, (n, 3))
    R = se.rpy_to_matrix(params.home_rpy + rng.uniform(-0.05, 0.05, (n, 3)))
    z = np.zeros((n, 3))
    return t, R, z, z.copy(), model.inverse(t, R, z, z, z, z)


def bench_model(name: str, params, sizes=(1, 1024), repeats: int = 5) -> dict:
    """Forward evaluations/s and 1 s rollout wall time (s) for each batch size.

    Args:
        name: the dynamics model's name.
        params: the platform.
        sizes: the batch sizes N.
        repeats: the loops timed per figure, of which the best counts (2 for the rollouts of N > 1).

    Returns:
        The figures by name, ``forward_per_s_N{n}`` (``Dynamics.forward``), ``kernel_per_s_N{n}``
        (the compiled kernel alone) and ``rollout_1s_N{n}`` (s), for each n in ``sizes``.
    """
    model = se.make_dynamics(name, params)
    rng = np.random.default_rng(0)
    out = {}
    for n in sizes:
        t, R, v, w, F = _batch_state(model, n, rng)
        calls = max(1, 20000 // n)

        # the loops' functions run within their iteration; their defaults bind this iteration's values
        def forward_loop(calls=calls, t=t, R=R, v=v, w=w, F=F):
            for _ in range(calls):
                model.forward(t, R, v, w, F)

        acc = np.empty((n, 6))
        W = np.zeros((n, 6))

        def kernel_loop(calls=calls, t=t, R=R, v=v, w=w, F=F, W=W, acc=acc):
            for _ in range(calls):
                K.forward_batch(model.packed, model.flags, t, R, v, w, F, W, acc)

        forward_loop()
        kernel_loop()
        out[f"forward_per_s_N{n}"] = calls * n / _best_of(forward_loop, repeats)
        out[f"kernel_per_s_N{n}"] = calls * n / _best_of(kernel_loop, repeats)
        out[f"rollout_1s_N{n}"] = _best_of(
            lambda t=t, R=R, v=v, w=w, F=F: se.rollout(model, t, R, v, w, F, dt=1e-3, steps=1000),
            repeats if n == 1 else 2,
        )
    return out


def _per_call(fns: dict, calls: int, repeats: int, clock=time.perf_counter, reset=None) -> dict:
    """Seconds per call of each function in ``fns`` (name -> function) by ``clock``: the best of
    ``repeats`` loops of ``calls`` calls, after one untimed call each (which loads or compiles what
    the first call needs).  The loops take turns, so that load from other work on the machine
    falls on all of them alike and their ratios hold.  ``reset``, if given, runs untimed before
    every loop (e.g. to put a simulation that drifts back at its start)."""
    for fn in fns.values():
        fn()
    best = dict.fromkeys(fns, np.inf)
    for _ in range(repeats):
        for name, fn in fns.items():
            if reset is not None:
                reset()
            t0 = clock()
            for _ in range(calls):
                fn()
            best[name] = min(best[name], (clock() - t0) / calls)
    return best


#: Batch sizes of the scaling table.
SCALING_SIZES = (1, 16, 256, 1024, 8192)
#: Double-precision flops one core retires per cycle at most: one 8-lane fused multiply-add
#: (AVX-512) per cycle, 2 flops per lane.  Without fused multiply-adds (the kernels are compiled
#: with -ffp-contract=off, so that every platform gets the same rounding) half of it is the most
#: a mix of additions and multiplications reaches.
PEAK_FLOPS_PER_CYCLE = 16


def vector_peak_flops() -> float:
    """The machine's double-precision vector peak, flop/s: cores x clock (the ``cpu MHz`` of
    /proc/cpuinfo, 2.5 GHz where it is not found) x :data:`PEAK_FLOPS_PER_CYCLE`."""
    mhz = 2500.0
    try:
        with open("/proc/cpuinfo") as f:
            mhz = max(float(line.split(":", 1)[1]) for line in f if line.startswith("cpu MHz"))
    except (OSError, ValueError):
        pass
    return (os.cpu_count() or 1) * mhz * 1e6 * PEAK_FLOPS_PER_CYCLE


def forward_flops(model) -> int:
    """Floating-point operations (+, -, *, /, sqrt) of one forward evaluation of ``model``, at
    home at rest under its holding forces: the compiled kernel run once on a counting number type.

    Args:
        model: the dynamics model (its first parameter row counts).
    """
    params = model.params_of(0)
    t, R = params.home_position, se.rpy_to_matrix(params.home_rpy)
    z = np.zeros(3)
    return _core.forward_flops(model.packed[:1], model.flags, t, R, z, z, model.inverse(t, R, z, z, z, z))


def bench_scaling(
    params,
    model_name: str = "improved",
    sizes=SCALING_SIZES,
    repeats: int = 5,
    seconds: float = 0.05,
    substeps: int = 10,
    dt: float = 1e-3,
) -> dict:
    """Throughput of the batched kernels over batch sizes: for each N in ``sizes``, forward
    evaluations/s (``Workspace.forward``) and control steps of ``substeps`` RK4 steps of ``dt``
    per second and platform (``Workspace.step``), by the wall clock and per second of CPU time
    of this process (all its threads: what each busy core delivers, which other work on a shared
    machine changes far less); the best of ``repeats`` loops of about ``seconds`` each.  The
    fraction of :func:`vector_peak_flops` each reaches counts :func:`forward_flops` flops per
    evaluation, 4 evaluations per RK4 step (the integrator's own few hundred flops per step are
    not counted); per CPU second, against one core's peak.

    Args:
        params: the platform.
        model_name: the dynamics model's name.
        sizes: the batch sizes N.
        repeats: the loops timed per figure, of which the best counts.
        seconds: the length of a loop, s.
        substeps: the RK4 steps of a control step.
        dt: the RK4 step, s.

    Returns:
        The result, a dict with ``model``, ``flops``, ``peak`` (flop/s), ``substeps``, ``dt`` and
        ``rows``, one dict of figures per N.
    """
    model = se.make_dynamics(model_name, params)
    flops, peak = forward_flops(model), vector_peak_flops()
    core_peak = peak / (os.cpu_count() or 1)
    rows = []
    for n in sizes:
        t, R, v, w, F = _batch_state(model, n, np.random.default_rng(0))
        ws = model.workspace(n)
        start = (t, R, v, w)

        # the loops' functions run within their iteration; their defaults bind this iteration's values
        def back_to_start(ws=ws, start=start, F=F):
            ws.set_state(*start)
            ws.leg_forces[:] = F

        def step(ws=ws):
            ws.step(dt, substeps)

        back_to_start()
        row = {"n": n}
        for name, fn, evals in (("evals", ws.forward, 1), ("steps", step, 4 * substeps)):
            fn()
            t0 = time.perf_counter()
            fn()
            calls = max(1, int(seconds / max(time.perf_counter() - t0, 1e-7)))
            for clock, suffix in ((time.perf_counter, "per_s"), (time.process_time, "per_cpu_s")):
                per_call = _per_call({name: fn}, calls, repeats, clock, reset=back_to_start)[name]
                row[f"{name}_{suffix}"] = n / per_call
            row[f"{name}_peak"] = row[f"{name}_per_s"] * evals * flops / peak
            row[f"{name}_core_peak"] = row[f"{name}_per_cpu_s"] * evals * flops / core_peak
        rows.append(row)
    return {"model": model.name, "flops": flops, "peak": peak, "substeps": substeps, "dt": dt, "rows": rows}


def first_evaluation_seconds() -> float:
    """Seconds from a fresh interpreter's start to its first forward evaluation."""
    res = subprocess.run([sys.executable, "-c", _FIRST_CALL], capture_output=True, text=True, check=True)
    return float(res.stdout.strip().splitlines()[-1])


def machine() -> str:
    """One line naming the machine the figures come from, and the instruction-set target of the
    kernels that ran (``stewart_env._core.TARGET``)."""
    cpu = _platform.processor() or _platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return (
        f"{cpu}, {os.cpu_count()} cores, kernels for {_core.TARGET}, Python {_platform.python_version()}, "
        f"numpy {np.__version__}"
    )
