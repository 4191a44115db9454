"""The benchmark's report: the tables of the scaling and of MuJoCo beside the kernels, the scaling
figure, and :func:`run_bench`, which runs the measurements and prints them (``stewart-env bench``)."""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

import stewart_env as se
from stewart_env.benchmarks.envs import bench_env, bench_resets_in_steps
from stewart_env.benchmarks.measurements import (
    PEAK_FLOPS_PER_CYCLE,
    bench_model,
    bench_scaling,
    first_evaluation_seconds,
    machine,
)
from stewart_env.benchmarks.mujoco_comparison import bench_mujoco
from stewart_env.dynamics import MODEL_NAMES, ModelSpec


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
                ('env.step (action_mode="pose", actuator="electric")', r["step_env_pose_electric"]),
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
            [
                ("vector env step", r["batch_vector_env"]),
                ("vector env step (pose, electric)", r["batch_vector_env_pose_electric"]),
                ("rollout_inplace", r["batch_rollout"]),
            ],
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
            if value is None:  # not measured (the pose mode's electric rows need the platform's electric set)
                continue
            lines.append(f"| {what} | {theirs_name} | {us(theirs)} | {name} | {us(value)} | {ratio(value, theirs)} |")
    lines.append(
        f"| vector env reset, {r['n_batch']} rows, per row | | | randomised / nominal "
        f"| {us(r['reset_randomized'])} / {us(r['reset_nominal'])} | |"
    )
    return "\n".join(lines)


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


def resets_row(n: int = 1024, runs: int = 3, steps: int = 40) -> str:
    """The report's row of the native vector env with resets: its platform-step under uniformly
    random actions (a policy that still loses the platform, as at the start of training: a row
    resets every ten or so steps), nominal and with
    :data:`~stewart_env.benchmarks.envs.RESET_RANDOMIZATION`, beside its step alone (the held
    platform, no resets), by :func:`~stewart_env.benchmarks.envs.bench_resets_in_steps` run
    ``runs`` times: each ratio over the step alone is the median of the runs, with their lowest
    and highest, so that a run slowed by other load on the machine shows as spread.

    Args:
        n: rows of the vector env.
        runs: runs of the measurement, each of interleaved short loops.
        steps: timed steps of each loop, 1 to 100.

    Returns:
        One line: the step alone and with resets, us a platform-step, the ratios with their
        spread, and the resets a platform-step.
    """
    results = [bench_resets_in_steps(n=n, steps=steps) for _ in range(runs)]

    def median(key: str) -> float:
        return float(np.median([r[key] for r in results]))

    def ratio(kind: str) -> str:
        ratios = [r[f"reset_{kind}_ratio"] for r in results]
        return (
            f"{median(f'reset_{kind}_s') * 1e6:.2f} us, x{median(f'reset_{kind}_ratio'):.2f} "
            f"[{min(ratios):.2f}, {max(ratios):.2f}], {median(f'resets_{kind}'):.3f} resets a platform-step"
        )

    return (
        f"vector env N={n} under uniformly random actions, resets included (median of {runs} runs "
        f"[lowest, highest]): the step alone {median('step_s') * 1e6:.2f} us a platform-step; "
        f"with nominal resets {ratio('nominal')}; with randomised resets {ratio('randomized')}"
    )


def run_bench(
    platform: str = "dasgupta1998",
    models: str | Sequence[str | ModelSpec] = MODEL_NAMES,
    env: bool = False,
    mujoco: bool = False,
    plot: str | None = None,
    derivatives: bool = False,
) -> None:
    """Print the benchmark's tables: the machine, the first evaluation of a fresh process, each of
    the ``models`` on ``platform``, the scaling table (drawn to the PNG file
    ``plot`` if given); with ``env`` the environments; the vector env's step with resets beside
    its step alone (:func:`resets_row`); with ``mujoco`` MuJoCo beside the kernels
    (``stewart_env.extras.MissingExtra`` before any timing if the extra is not installed); with
    ``derivatives`` the exact derivatives beside the values and MuJoCo's finite differences
    (:func:`~stewart_env.benchmarks.derivatives.bench_derivatives`).

    Args:
        platform: the shipped platform's name.
        models: the dynamics models, each a :class:`~stewart_env.dynamics.ModelSpec` (as the
            command line's ``--models`` gives them) or a name parsed here, once; a string is read
            as comma-separated names.
        env: time the environments too.
        mujoco: time MuJoCo beside the kernels.
        plot: the PNG file to draw the scaling figure to, or None.
        derivatives: time the exact derivatives too.

    Raises:
        MissingExtra: with ``mujoco``, MuJoCo is not installed.
        UsageError: an unknown model name (``err.argument`` is ``"models"``), before any timing.
    """
    names = models.split(",") if isinstance(models, str) else models
    specs = [ModelSpec.parse(m.strip() if isinstance(m, str) else m, "models") for m in names]
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
    for spec in specs:
        r = bench_model(spec, params)
        print(
            f"| {spec} | {r['forward_per_s_N1']:,.0f} / {r['kernel_per_s_N1']:,.0f} "
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
        r = bench_env()
        print()
        print(f"single env (gymnasium.make): {r['single_steps_per_s']:,.0f} steps/s")
        print(f"vector env N={r['n_vector']}: {r['vector_platform_steps_per_s']:,.0f} platform-steps/s")
    print()
    print(resets_row())
    if mujoco:
        from stewart_env.mujoco import require_mujoco

        print()
        print(
            f"MuJoCo {require_mujoco().__version__} on the same mechanism (stewart_env.mujoco), platform at rest at home:"
        )
        print(mujoco_table(bench_mujoco(params)))
    if derivatives:
        from stewart_env.benchmarks.derivatives import bench_derivatives, derivatives_table

        print()
        print("exact derivatives (Dynamics.acceleration_jacobians, step_jacobians), a moving state near home:")
        print(derivatives_table(bench_derivatives(params)))
