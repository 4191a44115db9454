"""Benchmark of the compiled core (and, with ``--env``, of the environments).

    python -m stewart_env.bench            # or: stewart-env bench

For each model: forward-dynamics evaluations per second at N = 1 and N = 1024 platforms, through
``Dynamics.forward`` (argument checks included) and through the compiled kernel alone; and
the wall time of ``rollout`` over 1 s of simulated time at dt = 1 ms (4000 evaluations per
platform with RK4) for N = 1 and N = 1024.  Also the time a fresh Python process takes from
start to its first forward evaluation, which shows whether the compiled kernels come from the
on-disk cache.  Timings are the best of several repeats, so other load on the machine shows
as little as possible.
"""

from __future__ import annotations

import argparse
import os
import platform as _platform
import subprocess
import sys
import time

import numpy as np

import stewart_env as se
from stewart_env.dynamics import MODEL_NAMES
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
    """Forward evaluations/s and 1 s rollout wall time (s) for each batch size."""
    model = se.make_dynamics(name, params)
    rng = np.random.default_rng(0)
    out = {}
    for n in sizes:
        t, R, v, w, F = _batch_state(model, n, rng)
        calls = max(1, 20000 // n)

        def forward_loop():
            for _ in range(calls):
                model.forward(t, R, v, w, F)

        acc = np.empty((n, 6))
        W = np.zeros((n, 6))

        def kernel_loop():
            for _ in range(calls):
                K.forward_batch(model.packed, model.flags, t, R, v, w, F, W, acc)

        forward_loop()
        kernel_loop()
        out[f"forward_per_s_N{n}"] = calls * n / _best_of(forward_loop, repeats)
        out[f"kernel_per_s_N{n}"] = calls * n / _best_of(kernel_loop, repeats)
        out[f"rollout_1s_N{n}"] = _best_of(lambda: se.rollout(model, t, R, v, w, F, dt=1e-3, steps=1000),
                                           repeats if n == 1 else 2)
    return out


def first_evaluation_seconds() -> float:
    """Seconds from a fresh interpreter's start to its first forward evaluation."""
    res = subprocess.run([sys.executable, "-c", _FIRST_CALL], capture_output=True, text=True, check=True)
    return float(res.stdout.strip().splitlines()[-1])


def machine() -> str:
    """One line naming the machine the figures come from."""
    cpu = _platform.processor() or _platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{cpu}, {os.cpu_count()} cores, Python {_platform.python_version()}, numpy {np.__version__}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="stewart-env bench", description=__doc__.split("\n\n")[0])
    parser.add_argument("--platform", default="dasgupta1998", help="platform config name or YAML path")
    parser.add_argument("--models", default=",".join(MODEL_NAMES), help="comma-separated model names")
    parser.add_argument("--env", action="store_true", help="also benchmark the single and vector environments")
    args = parser.parse_args(argv)
    params = se.load_platform(args.platform)

    print(f"machine: {machine()}")
    print(f"platform: {params.name}")
    first = first_evaluation_seconds()
    print(f"fresh process to first forward evaluation: {first:.2f} s")
    print()
    print("| model | forward/s N=1 (API / kernel) | forward/s N=1024 (API / kernel) "
          "| rollout 1 s N=1 | rollout 1 s N=1024 |")
    print("|---|---|---|---|---|")
    for name in args.models.split(","):
        r = bench_model(name.strip(), params)
        print(f"| {name} | {r['forward_per_s_N1']:,.0f} / {r['kernel_per_s_N1']:,.0f} "
              f"| {r['forward_per_s_N1024']:,.0f} / {r['kernel_per_s_N1024']:,.0f} "
              f"| {r['rollout_1s_N1'] * 1e3:.2f} ms | {r['rollout_1s_N1024']:.2f} s |")
    if args.env:
        from stewart_env.envs.bench_env import bench_env

        r = bench_env()
        print()
        print(f"single env (gymnasium.make): {r['single_steps_per_s']:,.0f} steps/s")
        print(f"vector env N={r['n_vector']}: {r['vector_platform_steps_per_s']:,.0f} platform-steps/s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
