"""Benchmark of the compiled core (and, with ``--env``, of the environments).

    stewart-env bench

For each model: forward-dynamics evaluations per second at N = 1 and N = 1024 platforms, through
``Dynamics.forward`` (argument checks included) and through the compiled kernel alone; and
the wall time of ``rollout`` over 1 s of simulated time at dt = 1 ms (4000 evaluations per
platform with RK4) for N = 1 and N = 1024.  Also the time a fresh Python process takes from
start to its first forward evaluation (the kernels are compiled when the package is installed,
so this is the import and the first call).  Timings are the best of several repeats, so other load on the machine shows
as little as possible.

The scaling table (:func:`bench_scaling`) gives, for N = 1, 16, 256, 1024 and 8192 platforms, the
batched forward evaluations per second, the 10 ms platform-steps per second (10 RK4 substeps of
1 ms, 40 evaluations) and the fraction of the machine's vector peak each reaches, with the flop
count of one evaluation it assumes (counted by running the kernel once on a number type that counts
its operations); ``--plot PATH`` draws it to a PNG.

With ``--mujoco`` (needs the extra ``mujoco``), MuJoCo times the same mechanism in the same run
(:func:`bench_mujoco`): one forward and one inverse evaluation, a 10 ms control step of RK4
substeps for one platform and for a batch of 1024, and the vector env's reset with and without
domain randomisation; the table gives each beside MuJoCo's and their ratio.
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
from stewart_env.dynamics import MODEL_NAMES
from stewart_env.dynamics import kernels as K
from stewart_env.progress import on_terminal, progress

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


def bench_mujoco(
    params, n_batch: int = 1024, repeats: int = 10, calls: int = 1000, substeps: int = 10, dt: float = 1e-3
) -> dict:
    """MuJoCo and stewart-env side by side on the same mechanism.

    The mechanism is stewart_env.mujoco's twin of ``params``, the platform at home at rest under
    its holding forces.  Seconds per call:

    * ``forward_mujoco`` (``mujoco.mj_forward``), ``forward_api`` (``Dynamics.forward``, N = 1,
      with its checks), ``forward_workspace`` (``Workspace.forward``, N = 1);
    * ``inverse_mujoco`` (``mujoco.mj_inverse``), ``inverse_api`` (``Dynamics.inverse``),
      ``inverse_workspace`` (``Workspace.inverse``), and ``mass_and_bias_workspace``
      (``Workspace.mass_and_bias``, which has no counterpart in MuJoCo's task-space terms);
    * one control step of ``substeps`` RK4 steps of ``dt``, one platform: ``step_mujoco``
      (``mujoco.mj_step``), ``step_plant`` (:class:`stewart_env.mujoco.MujocoPlant`),
      ``step_env`` (``StewartPlatform-v1`` through ``gymnasium.make``, the set-point task from its
      fixed start held by its holding forces), ``step_env_mujoco`` (the same env with
      ``model="mujoco"``),
      ``step_rollout`` (``rollout_inplace``, N = 1), ``step_workspace`` (``Workspace.step``);
    * the same step for ``n_batch`` platforms, per platform: ``batch_mujoco`` (``mujoco.rollout``
      on every core), ``batch_vector_env`` (the native vector env), ``batch_rollout``
      (``rollout_inplace``, N = ``n_batch``);
    * ``reset_randomized`` and ``reset_nominal``: ``reset()`` of the vector env of ``n_batch``
      rows, per row, with :data:`~stewart_env.envs.bench_env.RESET_RANDOMIZATION` and without.

    Each figure is the best of ``repeats`` loops (``calls`` calls for the single-platform figures),
    the loops of a group taking turns.  The single-platform figures are CPU time of this process
    per call (``time.process_time``), the batch figures and the resets wall-clock time; the vector
    env's steps start from its reset (the resets are timed apart).

    Args:
        params: the platform.
        n_batch: the platforms of the batch figures.
        repeats: the loops timed per figure, of which the best counts.
        calls: the calls per loop of the single-platform figures.
        substeps: the RK4 steps of a control step.
        dt: the RK4 step, s.

    Returns:
        The figures above by name (s), with ``substeps``, ``dt`` and ``n_batch``.

    Raises:
        MissingExtra: MuJoCo is not installed (the ``mujoco`` extra).
    """
    import gymnasium as gym

    from stewart_env.envs.bench_env import RESET_RANDOMIZATION, bench_reset, held_env
    from stewart_env.integrate import rollout_inplace
    from stewart_env.mujoco import MujocoPlant, model_and_data, require_mujoco
    from stewart_env.mujoco.library import require_rollout
    from stewart_env.registration import ENV_ID

    mujoco, mujoco_rollout = require_mujoco(), require_rollout()

    model = se.make_dynamics("improved", params)
    t, R = params.home_position, se.rpy_to_matrix(params.home_rpy)
    z = np.zeros(3)
    F = model.inverse(t, R, z, z, z, z)
    out = {"n_batch": n_batch, "substeps": substeps, "dt": dt}
    # One platform: the process's CPU time, which other work on a shared machine inflates far less
    # than the wall clock; every call compared runs on this thread.
    cpu = time.process_time
    bar = progress(total=8, desc="bench --mujoco", disable=not on_terminal())

    m, d = model_and_data(params, t, R, z, z, F, timestep=dt)
    start = mujoco.MjData(m)
    mujoco.mj_copyData(start, m, d)
    ws = model.workspace(1)
    ws.set_state(t, R, z, z)
    ws.leg_forces[0] = F
    out.update(
        _per_call(
            {
                "forward_mujoco": lambda: mujoco.mj_forward(m, d),
                "forward_api": lambda: model.forward(t, R, z, z, F),
                "forward_workspace": ws.forward,
            },
            calls,
            repeats,
            cpu,
        )
    )
    ws.acceleration[0] = 0.0  # Workspace.inverse then writes the holding forces back into leg_forces
    out.update(
        _per_call(
            {
                "inverse_mujoco": lambda: mujoco.mj_inverse(m, d),  # of mj_forward's qacc
                "inverse_api": lambda: model.inverse(t, R, z, z, z, z),
                "inverse_workspace": ws.inverse,
                "mass_and_bias_workspace": ws.mass_and_bias,
            },
            calls,
            repeats,
            cpu,
        )
    )
    bar.update()

    step_calls = max(1, calls // substeps)
    plant = MujocoPlant(params, dt)
    plant_state = [t[None].copy(), R[None].copy(), np.zeros((1, 3)), np.zeros((1, 3))]
    state = [x.copy() for x in plant_state]
    forces, wrench = F[None].copy(), np.zeros((1, 6))
    start_state = [x.copy() for x in plant_state]
    env_kwargs = dict(task_options={"randomize": False}, platform=params, control_dt=dt * substeps, physics_dt=dt)
    env, env_action = held_env(**env_kwargs)
    mj_env, mj_env_action = held_env(model="mujoco", **env_kwargs)

    def back_to_start():
        # the platform at rest under its holding forces is an unstable equilibrium: the rounding
        # error grows about 1e5-fold per simulated second, and a few seconds end it in a singular
        # pose, where a step stops early; each loop of step_calls steps starts at rest again
        mujoco.mj_copyData(d, m, start)
        for x0, *xs in zip(start_state, plant_state, state):
            for x in xs:
                x[...] = x0
        ws.set_state(t, R, z, z)
        env.reset(seed=0)
        mj_env.reset(seed=0)

    out.update(
        _per_call(
            {
                "step_mujoco": lambda: mujoco.mj_step(m, d, nstep=substeps),
                "step_plant": lambda: plant.step_inplace(*plant_state, forces, wrench, dt, substeps),
                "step_rollout": lambda: rollout_inplace(model, *state, forces, wrench, dt, substeps),
                "step_workspace": lambda: ws.step(dt, substeps),
                "step_env": lambda: env.step(env_action),
                "step_env_mujoco": lambda: mj_env.step(mj_env_action),
            },
            step_calls,
            repeats,
            cpu,
            reset=back_to_start,
        )
    )
    env.close()
    mj_env.close()
    bar.update()

    # the batch: MuJoCo's threaded rollout of n_batch platforms from the same state, open loop
    nthread = os.cpu_count() or 1
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    initial = np.empty(mujoco.mj_stateSize(m, spec))
    mujoco.mj_getState(m, start, initial, spec)
    initial = np.tile(initial, (n_batch, 1))
    control = np.tile(F, (n_batch, substeps, 1))
    states = np.empty((n_batch, substeps, initial.shape[1]))
    datas = [mujoco.MjData(m) for _ in range(nthread)]
    bt, bR, bv, bw, bF = _batch_state(model, n_batch, np.random.default_rng(0))
    bW = np.zeros((n_batch, 6))
    venv = gym.make_vec(ENV_ID, num_envs=n_batch, vectorization_mode="vector_entry_point", **env_kwargs)
    venv_actions = np.tile(env_action, (n_batch, 1))
    venv.reset(seed=0)
    with mujoco_rollout.Rollout(nthread=nthread) as pool:
        batch = _per_call(
            {
                "batch_mujoco": lambda: pool.rollout(m, datas, initial, control, state=states),
                "batch_rollout": lambda: rollout_inplace(model, bt, bR, bv, bw, bF, bW, dt, substeps),
                "batch_vector_env": lambda: venv.step(venv_actions),
            },
            1,
            repeats,
            reset=lambda: venv.reset(seed=0),
        )
    venv.close()
    out.update({name: seconds / n_batch for name, seconds in batch.items()})
    bar.update(2)

    bar.update(3)
    out["reset_randomized"] = bench_reset(n_batch, RESET_RANDOMIZATION, max(1, repeats // 2), platform=params)
    out["reset_nominal"] = bench_reset(n_batch, None, max(1, repeats // 2), platform=params)
    bar.update()
    bar.close()
    return out


def mujoco_table(r: dict) -> str:
    """The markdown table of :func:`bench_mujoco`'s result: each figure beside MuJoCo's, and the
    ratio MuJoCo time / stewart-env time (above 1: stewart-env is faster).

    Args:
        r: the result of :func:`bench_mujoco`.
    """
    us = lambda s: "" if s is None else f"{s * 1e6:,.1f} us"  # noqa: E731
    ratio = lambda ours, theirs: "" if theirs is None else f"{theirs / ours:.2f}x"  # noqa: E731
    step = f"{r['substeps'] * r['dt'] * 1e3:g} ms step ({r['substeps']} RK4 substeps)"
    rows = [
        (
            "forward dynamics, 1 platform",
            "mj_forward",
            r["forward_mujoco"],
            [("Workspace.forward", r["forward_workspace"]), ("Dynamics.forward", r["forward_api"])],
        ),
        (
            "inverse dynamics, 1 platform",
            "mj_inverse",
            r["inverse_mujoco"],
            [("Workspace.inverse", r["inverse_workspace"]), ("Dynamics.inverse", r["inverse_api"])],
        ),
        ("mass matrix and bias, 1 platform", "", None, [("Workspace.mass_and_bias", r["mass_and_bias_workspace"])]),
        (
            f"{step}, 1 platform",
            "mj_step",
            r["step_mujoco"],
            [
                ("env.step (gymnasium.make)", r["step_env"]),
                ("Workspace.step", r["step_workspace"]),
                ("rollout_inplace", r["step_rollout"]),
            ],
        ),
        (
            f"{step}, 1 platform, as a plant",
            "MujocoPlant.step_inplace",
            r["step_plant"],
            [("rollout_inplace", r["step_rollout"])],
        ),
        (
            f"{step}, 1 platform, env",
            'env.step (model="mujoco")',
            r["step_env_mujoco"],
            [("env.step (improved)", r["step_env"])],
        ),
        (
            f"{step}, {r['n_batch']} platforms, per platform",
            "mujoco.rollout",
            r["batch_mujoco"],
            [("vector env step", r["batch_vector_env"]), ("rollout_inplace", r["batch_rollout"])],
        ),
    ]
    lines = [
        "(1 platform: CPU time per call; batches and resets: wall-clock time)",
        "",
        "| call | MuJoCo | time | stewart-env | time | MuJoCo / stewart-env |",
        "|---|---|---|---|---|---|",
    ]
    for what, theirs_name, theirs, ours in rows:
        for name, value in ours:
            lines.append(f"| {what} | {theirs_name} | {us(theirs)} | {name} | {us(value)} | {ratio(value, theirs)} |")
    lines.append(
        f"| vector env reset, {r['n_batch']} rows, per row | | | randomised / nominal "
        f"| {us(r['reset_randomized'])} / {us(r['reset_nominal'])} | |"
    )
    return "\n".join(lines)


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


def scaling_table(r: dict) -> str:
    """The markdown table of :func:`bench_scaling`'s result, with the flop count and peak it assumes.

    Args:
        r: the result of :func:`bench_scaling`.
    """
    step = f"{r['substeps'] * r['dt'] * 1e3:g} ms"
    cores = os.cpu_count() or 1
    lines = [
        f"model {r['model']}: {r['flops']:,} flops per forward evaluation (counted); vector peak "
        f"{r['peak'] / 1e9:.1f} GFLOP/s ({cores} cores x clock x {PEAK_FLOPS_PER_CYCLE} flops/cycle), "
        f"{r['peak'] / cores / 1e9:.1f} GFLOP/s per core",
        "",
        f"| platforms N | forward evaluations/s | of peak | per CPU second | of a core's peak "
        f"| {step} platform-steps/s | of peak | per CPU second | of a core's peak |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for row in r["rows"]:
        lines.append(
            f"| {row['n']:,} | {row['evals_per_s']:,.0f} | {row['evals_peak']:.1%} "
            f"| {row['evals_per_cpu_s']:,.0f} | {row['evals_core_peak']:.1%} "
            f"| {row['steps_per_s']:,.0f} | {row['steps_peak']:.1%} "
            f"| {row['steps_per_cpu_s']:,.0f} | {row['steps_core_peak']:.1%} |"
        )
    return "\n".join(lines)


def plot_scaling(r: dict, path) -> None:
    """Draw :func:`bench_scaling`'s result to the PNG ``path``: evaluations/s and platform-steps/s
    over N, log-log, with the peak's evaluation rate for reference.

    Args:
        r: the result of :func:`bench_scaling`.
        path: the PNG file to write.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = [row["n"] for row in r["rows"]]
    fig, ax = plt.subplots(figsize=(7.0, 5.4), layout="constrained")
    ax.loglog(n, [row["evals_per_s"] for row in r["rows"]], "o-", color="C0", label="forward evaluations/s")
    ax.loglog(
        n,
        [row["evals_per_cpu_s"] for row in r["rows"]],
        "o:",
        color="C0",
        mfc="none",
        label="forward evaluations per CPU second",
    )
    ax.loglog(
        n,
        [row["steps_per_s"] for row in r["rows"]],
        "s-",
        color="C1",
        label=f"{r['substeps'] * r['dt'] * 1e3:g} ms platform-steps/s ({4 * r['substeps']} evaluations)",
    )
    ax.loglog(
        n,
        [row["steps_per_cpu_s"] for row in r["rows"]],
        "s:",
        color="C1",
        mfc="none",
        label="platform-steps per CPU second",
    )
    ax.axhline(
        r["peak"] / r["flops"],
        color="C0",
        ls="--",
        lw=0.8,
        label=f"vector peak / {r['flops']:,} flops = {r['peak'] / r['flops'] / 1e6:.1f} M evaluations/s",
    )
    ax.axhline(
        r["peak"] / (4 * r["substeps"] * r["flops"]),
        color="C1",
        ls="--",
        lw=0.8,
        label="vector peak in platform-steps/s",
    )
    ax.set_xlabel("platforms in the batch, N")
    ax.set_ylabel("per second")
    ax.set_title(f"stewart-env batched physics ({r['model']}), {machine().split(',')[0]}", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncols=2)
    fig.savefig(path, dpi=120)
    plt.close(fig)


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


def run_bench(
    platform: str = "dasgupta1998",
    models: str = ",".join(MODEL_NAMES),
    env: bool = False,
    mujoco: bool = False,
    plot: str | None = None,
) -> None:
    """Print the benchmark's tables: the machine, the first evaluation of a fresh process, each of
    the comma-separated ``models`` on ``platform``, the scaling table (drawn to the PNG file
    ``plot`` if given); with ``env`` the environments, with ``mujoco`` MuJoCo beside the kernels
    (``stewart_env.extras.MissingExtra`` before any timing if the extra is not installed).

    Args:
        platform: the shipped platform's name.
        models: the comma-separated model names.
        env: time the environments too.
        mujoco: time MuJoCo beside the kernels.
        plot: the PNG file to draw the scaling figure to, or None.

    Raises:
        MissingExtra: with ``mujoco``, MuJoCo is not installed.
    """
    params = se.load_platform(platform)
    if mujoco:
        from stewart_env import mujoco as twin

        twin.require_mujoco()

    print(f"machine: {machine()}")
    print(f"platform: {params.name}")
    first = first_evaluation_seconds()
    print(f"fresh process to first forward evaluation: {first:.2f} s")
    print()
    print(
        "| model | forward/s N=1 (API / kernel) | forward/s N=1024 (API / kernel) "
        "| rollout 1 s N=1 | rollout 1 s N=1024 |"
    )
    print("|---|---|---|---|---|")
    for name in models.split(","):
        r = bench_model(name.strip(), params)
        print(
            f"| {name} | {r['forward_per_s_N1']:,.0f} / {r['kernel_per_s_N1']:,.0f} "
            f"| {r['forward_per_s_N1024']:,.0f} / {r['kernel_per_s_N1024']:,.0f} "
            f"| {r['rollout_1s_N1'] * 1e3:.2f} ms | {r['rollout_1s_N1024']:.2f} s |"
        )
    print()
    scaling = bench_scaling(params)
    print(scaling_table(scaling))
    if plot:
        plot_scaling(scaling, plot)
        print(f"scaling plot: {plot}")
    if env:
        from stewart_env.envs.bench_env import bench_env

        r = bench_env()
        print()
        print(f"single env (gymnasium.make): {r['single_steps_per_s']:,.0f} steps/s")
        print(f"vector env N={r['n_vector']}: {r['vector_platform_steps_per_s']:,.0f} platform-steps/s")
        from stewart_env.envs.bench_env import bench_resets_in_steps

        r = bench_resets_in_steps()
        print(
            f"vector env N={r['n']} with resets (uniformly random actions; the step alone holds the platform): "
            f"{r['step_s'] * 1e6:.2f} us a platform-step alone, {r['reset_nominal_s'] * 1e6:.2f} us with resets "
            f"(x{r['reset_nominal_ratio']:.2f}, {r['resets_nominal']:.3f} resets a platform-step), "
            f"{r['reset_randomized_s'] * 1e6:.2f} us randomised (x{r['reset_randomized_ratio']:.2f}, "
            f"{r['resets_randomized']:.3f})"
        )
    if mujoco:
        from stewart_env.mujoco import require_mujoco

        print()
        print(
            f"MuJoCo {require_mujoco().__version__} on the same mechanism (stewart_env.mujoco), platform at rest at home:"
        )
        print(mujoco_table(bench_mujoco(params)))
