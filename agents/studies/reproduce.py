"""Reproduction of the case study of He et al. (2018): classical versus improved dynamics under
the task-space PD law.

The platform starts at rest at t0 = (0.1, 0, 0.395) m, rpy0 = (0, 0, -0.2) rad and is driven to
td = (0.1, 0, 0.4) m, rpyd = rpy0 (on another platform: the same offsets from its home pose,
:func:`stewart_env.tasks.setpoint.paper_case`, refused where they leave the leg stroke) by the
paper's PD law with its gains (:mod:`.pd`), evaluated as a continuous controller: the closed loop
(plant dynamics + law) is integrated by :func:`stewart_env.rollout`, whose RK4 evaluates the
compiled law :func:`~stewart_env.agents.controllers.pd.pd_control_law` at every stage, not held over a
control period as in the environment.  The same run is made with the ``classical``, ``improved``
and ``improved_centroidal`` models.

Figures (PNG, like the paper's Fig. 6-10): leg lengths, leg rates, platform displacement and
velocity, angles and angular velocity, leg forces; each panel overlays classical and improved and
shows improved - classical beneath.  ``summary.md`` reports, per quantity,

* the peak-value difference: for each component k, each model's largest transient extremum
  peak_m,k (:func:`transient_peaks`: the interior local extremum of largest |q|; the start is
  excluded because there the PD law acts on the same state for both models, so e.g. the leg
  forces' initial spike cannot differ), and the relative difference
  |peak_classical,k - peak_improved,k| / |peak_improved,k|, largest over the components whose
  improved peak is at least 5 % of the quantity's largest (a component that stays near zero has
  no peak to compare); this is our reading of the paper's "differ at the peaks ... 45.94 %";
* the largest pointwise difference max_t,k |q_classical - q_improved| / max_t,k |q_improved|;

where q is the quantity itself for rates, velocities and forces and its change from the initial
value for leg lengths, displacement and angles (the two models start from the same pose, and a
1.2 m leg length would hide millimetre differences); plus the largest pointwise difference, on
the same measure, between ``improved`` and ``improved_centroidal`` over all quantities (the two
forms of the same dynamics: rounding only).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.ticker import FuncFormatter

import stewart_env as se
from stewart_env.agents.controllers.pd import PAPER_KD, PAPER_KP, TaskSpacePD, pd_control_law
from stewart_env.agents.evaluation.evaluation import curve_style, new_figure
from stewart_env.files import lock_folder, publish, publishing
from stewart_env.progress import progress as progress_bar
from stewart_env.state import Reference
from stewart_env.tasks.setpoint import paper_case

MODELS = ("classical", "improved", "improved_centroidal")

#: Quantities of the report: key, title, unit, display factor from SI, change from the start?
QUANTITIES = (
    ("leg_length", "leg length change", "mm", 1e3, True),
    ("leg_rate", "leg rate", "mm/s", 1e3, False),
    ("displacement", "displacement", "mm", 1e3, True),
    ("velocity", "velocity", "mm/s", 1e3, False),
    ("angles", "angle change", "mrad", 1e3, True),
    ("angular_velocity", "angular velocity", "mrad/s", 1e3, False),
    ("leg_force", "leg force", "N", 1.0, False),
)
#: Components whose improved peak is below this share of the quantity's largest are not compared.
PEAK_FLOOR = 0.05


@dataclass
class CaseTrajectory:
    """One closed-loop run, sampled: time (T,) s and, per sample, in {B} and SI units:
    displacement (T,3) = position of P's origin, m; velocity (T,3) m/s; angles (T,3) roll, pitch,
    yaw, rad; angular_velocity (T,3) rad/s; leg_length (T,6) m; leg_rate (T,6) m/s;
    leg_force (T,6) N (the PD law's output at the sample)."""

    model: str
    time: np.ndarray
    displacement: np.ndarray
    velocity: np.ndarray
    angles: np.ndarray
    angular_velocity: np.ndarray
    leg_length: np.ndarray
    leg_rate: np.ndarray
    leg_force: np.ndarray

    def quantity(self, key: str, from_start: bool) -> np.ndarray:
        """The quantity ``key`` (T, k), minus its initial value if ``from_start``.

        Args:
            key: a field of the trajectory, a key of ``QUANTITIES`` (``"leg_force"``, ...).
            from_start: whether to subtract the initial value (a change from the start).
        """
        q = getattr(self, key)
        return q - q[0] if from_start else q


def simulate_case_study(
    model_name: str,
    platform: se.PlatformParams,
    controller: TaskSpacePD,
    duration: float = 1.0,
    dt: float = 2e-4,
    sample_dt: float | None = None,
    progress=None,
) -> CaseTrajectory:
    """Integrate the case study's closed loop with RK4, the controller evaluated at every stage.

    Args:
        model_name: the plant's dynamics model (``"classical"``, ``"improved"``, ...).
        platform: the platform's parameters.
        controller: the PD law (its compiled :func:`~stewart_env.agents.controllers.pd.pd_control_law` runs
            inside the integrator).
        duration: the simulated time, s.
        dt: the integrator's step, s.
        sample_dt: the time between recorded samples, s, a multiple of ``dt``; default ``dt`` (the
            transient under the paper's gains lasts about 50 ms, and coarser samples cut its peaks).
        progress: a :func:`stewart_env.progress.progress` bar advanced by the steps run, or None.

    Returns:
        The sampled :class:`CaseTrajectory`.

    Raises:
        ValueError: a duration, dt or sample_dt out of its range (named).
    """
    sample_dt = dt if sample_dt is None else sample_dt
    if not (np.isfinite(duration) and duration > 0):
        raise ValueError(f"duration: must be a positive number of seconds, got {duration}")
    if not (np.isfinite(dt) and 0 < dt <= sample_dt):
        raise ValueError(f"dt: must be positive and at most sample_dt = {sample_dt} s, got {dt}")
    every = int(round(sample_dt / dt))
    if abs(every * dt - sample_dt) > 1e-9 * sample_dt:
        raise ValueError(f"sample_dt: must be a multiple of dt = {dt} s, got {sample_dt}")
    case = paper_case(platform)
    model = se.make_dynamics(model_name, platform)
    zero = np.zeros(3)
    reference = Reference(case.target_position, se.rpy_to_matrix(case.target_rpy), zero, zero)
    steps = int(round(duration / sample_dt)) * every
    run = se.rollout(
        model,
        case.start_position,
        se.rpy_to_matrix(case.start_rpy),
        zero,
        zero,
        dt=dt,
        steps=steps,
        control_law=pd_control_law,
        control_params=controller.control_params(reference),
        record_every=every,
    )
    if progress is not None:
        progress.update(steps)
    legs = se.leg_kinematics(model, run.position, run.rotation, run.velocity, run.angular_velocity, model=model_name)
    return CaseTrajectory(
        model.name,
        run.time,
        run.position,
        run.velocity,
        se.matrix_to_rpy(run.rotation),
        run.angular_velocity,
        legs.lengths,
        legs.rates,
        run.leg_forces,
    )


def transient_peaks(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The largest extremum of the transient of each component of q (T, k): among the interior
    local extrema (samples where the slope changes sign), the one of largest |q|; a component
    without one (monotone) takes its final value.

    Args:
        q: the samples of a quantity (T, k).

    Returns:
        (values (k,), sample indices (k,)) of the peaks.
    """
    slope = np.diff(q, axis=0)
    turning = slope[:-1] * slope[1:] < 0  # (T-2, k): sample j + 1 is a local extremum
    candidates = np.where(turning, q[1:-1], 0.0)
    j = np.argmax(np.abs(candidates), axis=0)
    cols = np.arange(q.shape[1])
    has = turning.any(axis=0)
    return np.where(has, candidates[j, cols], q[-1]), np.where(has, j + 1, q.shape[0] - 1)


def peak_differences(reference: CaseTrajectory, other: CaseTrajectory) -> dict[str, dict]:
    """Per quantity of :data:`QUANTITIES`: the peak-value difference and the largest pointwise
    difference of ``other`` against ``reference`` (module docstring), both relative (fractions).

    Args:
        reference: the trajectory compared against (the improved model's).
        other: the trajectory compared.

    Returns:
        A dict by quantity key of dicts of ``"peak_reference"`` and ``"peak_other"`` (the two
        peaks of the component where the peak-value difference is largest, SI, signed),
        ``"peak_time"`` (s, of the reference's peak), ``"peak_difference"``, ``"peak_component"``
        (index) and ``"pointwise_difference"``.
    """
    out = {}
    for key, _, _, _, from_start in QUANTITIES:
        a, b = reference.quantity(key, from_start), other.quantity(key, from_start)
        (peak_a, at), (peak_b, _) = transient_peaks(a), transient_peaks(b)
        compared = np.abs(peak_a) >= PEAK_FLOOR * np.abs(peak_a).max()
        rel = np.where(compared, np.abs(peak_b - peak_a) / np.where(compared, np.abs(peak_a), 1.0), -np.inf)
        k = int(np.argmax(rel))
        out[key] = {
            "peak_reference": float(peak_a[k]),
            "peak_other": float(peak_b[k]),
            "peak_time": float(reference.time[at[k]]),
            "peak_difference": float(rel[k]),
            "peak_component": k,
            "pointwise_difference": float(np.abs(b - a).max() / np.abs(a).max()),
        }
    return out


def _component_names(key: str) -> list[str]:
    if key in ("leg_length", "leg_rate", "leg_force"):
        return [f"leg {i + 1}" for i in range(6)]
    return ["roll", "pitch", "yaw"] if key in ("angles", "angular_velocity") else ["x", "y", "z"]


def plot_comparison(
    path: Path, keys: tuple[str, ...], classical: CaseTrajectory, improved: CaseTrajectory, title: str
) -> None:
    """One figure: a panel per component of each quantity in ``keys`` (three panels a row),
    classical and improved overlaid, improved - classical in a small axis beneath.

    Args:
        path: the PNG file written.
        keys: the quantities drawn, keys of ``QUANTITIES``.
        classical: the classical model's trajectory.
        improved: the improved model's trajectory.
        title: the figure's title.
    """
    spec = {q[0]: q for q in QUANTITIES}
    panels = [(key, k) for key in keys for k in range(len(_component_names(key)))]
    rows = len(panels) // 3
    fig = new_figure(figsize=(13, 3.4 * rows), layout="constrained")
    grid = fig.add_gridspec(2 * rows, 3, height_ratios=[3, 1.3] * rows)
    t = improved.time
    for n, (key, k) in enumerate(panels):
        _, name, unit, factor, from_start = spec[key]
        qc = classical.quantity(key, from_start)[:, k] * factor
        qi = improved.quantity(key, from_start)[:, k] * factor
        top = fig.add_subplot(grid[2 * (n // 3), n % 3])
        bottom = fig.add_subplot(grid[2 * (n // 3) + 1, n % 3], sharex=top)
        # classical wide beneath, improved narrower and dashed on top: both show where they agree
        top.plot(t, qc, color="tab:blue", label="classical", **curve_style(0))
        top.plot(t, qi, color="tab:red", label="improved", **curve_style(1))
        top.set_title(f"{name}, {_component_names(key)[k]}", fontsize=10)
        top.set_ylabel(unit)
        top.tick_params(labelbottom=False)
        top.grid(alpha=0.3)
        bottom.plot(t, qi - qc, color="black", lw=1.0)
        bottom.set_ylabel(f"diff., {unit}", fontsize=8)
        bottom.grid(alpha=0.3)
        # the transient lasts tens of milliseconds of the run: linear time to 1 ms, logarithmic beyond
        bottom.set_xscale("symlog", linthresh=1e-3, linscale=0.3)
        bottom.set_xlim(0, t[-1])
        bottom.xaxis.set_major_formatter(FuncFormatter(lambda x, _: f"{x:g}"))
        if n // 3 == rows - 1:
            bottom.set_xlabel("time (s), logarithmic beyond 1 ms")
        if n == 0:
            top.legend(fontsize=9, loc="best")
    fig.suptitle(title + "  (lower axes: improved - classical)", fontsize=12)
    with publishing(path) as tmp:
        fig.savefig(tmp, dpi=110)


FIGURES = (
    ("fig6_leg_lengths.png", ("leg_length",), "Leg lengths, change from the start (cf. paper Fig. 6)"),
    ("fig7_leg_rates.png", ("leg_rate",), "Leg rates dL/dt (cf. paper Fig. 7)"),
    (
        "fig8_displacement_velocity.png",
        ("displacement", "velocity"),
        "Platform displacement from the start and velocity of P (cf. paper Fig. 8)",
    ),
    (
        "fig9_angles_angular_velocity.png",
        ("angles", "angular_velocity"),
        "Roll-pitch-yaw change from the start and angular velocity (cf. paper Fig. 9)",
    ),
    ("fig10_leg_forces.png", ("leg_force",), "Leg forces of the PD law (cf. paper Fig. 10)"),
)


def _triple(x: np.ndarray) -> str:
    """A pose's three numbers as the paper writes them: (0.1, 0, 0.395)."""
    return "(" + ", ".join(f"{v:.6g}" for v in x + 0.0) + ")"  # + 0.0 turns -0 into 0


def _summary_markdown(runs: dict[str, CaseTrajectory], diff: dict[str, dict], centroidal: float, settings: dict) -> str:
    case = settings["case"]
    lines = [
        "# Case study of He et al. (2018): classical versus improved dynamics",
        "",
        "Platform `{platform}`; start t0 = {start} m, rpy0 = {rpy} rad, at rest; target "
        "td = {target} m, rpyd = rpy0; task-space PD law with the paper's gains (Kp = diag(4e5, 4e5, "
        "4e6, 5e4, 5e4, 1e5), Kd = diag(1e4, 1e4, 2e4, 1e3, 1e3, 2e3)), gravity compensation {gravity}; "
        "continuous control: RK4 with dt = {dt:g} s, the law evaluated at every stage; {duration:g} s "
        "simulated, sampled every {sample_dt:g} s; run time {seconds:.1f} s.".format(
            start=_triple(case.start_position),
            rpy=_triple(case.start_rpy),
            target=_triple(case.target_position),
            **settings,
        ),
        "",
        "Measures (q is the change from the start for leg length, displacement and angles, the value "
        "itself otherwise):",
        "",
        "- peak-value difference: |peak_classical - peak_improved| / |peak_improved| per component, peak = "
        "the largest extremum of the transient (the interior local extremum of largest |q|; the start is "
        "left out, since there the PD law acts on the same state for both models), the largest over the "
        f"components whose improved peak is at least {PEAK_FLOOR:.0%} of the quantity's largest;",
        "- pointwise difference: max over time and components of |q_classical - q_improved|, divided by "
        "max over time and components of |q_improved|.",
        "",
        "| quantity | peak-value difference | at | peak, classical | peak, improved | pointwise difference |",
        "|---|---|---|---|---|---|",
    ]
    for key, name, unit, factor, _ in QUANTITIES:
        d = diff[key]
        lines.append(
            f"| {name} ({unit}) | {100 * d['peak_difference']:.2f} % | "
            f"{_component_names(key)[d['peak_component']]}, t = {1e3 * d['peak_time']:.1f} ms | "
            f"{d['peak_other'] * factor:.4g} | {d['peak_reference'] * factor:.4g} | "
            f"{100 * d['pointwise_difference']:.2f} % |"
        )
    final = runs["improved"]
    lines += [
        "",
        "The paper reports 45.94 % as the largest leg-force difference; our inertias and Hooke axes are "
        "substitutes for its lost tables, so our numbers are our own.",
        "",
        f"improved vs improved_centroidal (two forms of the same dynamics), largest pointwise difference "
        f"over all quantities: {centroidal:.3e} (relative).",
        "",
        f"Final position error (improved): {1e3 * np.linalg.norm(case.target_position - final.displacement[-1]):.4f} mm.",
        "",
        "Figures: " + ", ".join(f"`{f[0]}`" for f in FIGURES) + ".",
        "",
    ]
    return "\n".join(lines)


def reproduce(
    out,
    duration: float = 1.0,
    dt: float = 2e-4,
    sample_dt: float | None = None,
    platform: str = "dasgupta1998",
    gravity_compensation: bool = False,
    progress: bool = True,
) -> dict:
    """Run the case study on ``MODELS``, write the figures and ``summary.md`` into ``out``.

    ``out`` is locked for the whole run (``stewart_env.files.lock_folder``) and every file is
    published atomically.

    Args:
        out: the directory of the figures and ``summary.md``, made if missing.
        duration: the simulated time, s (see :func:`simulate_case_study`).
        dt: the integrator's step, s.
        sample_dt: the time between recorded samples, s, a multiple of ``dt``; default ``dt``.
        platform: a shipped config's name or a YAML path.
        gravity_compensation: add the holding forces to the paper's law (off: the law as we have it).
        progress: whether to show a progress bar.

    Returns:
        A dict of ``"runs"`` (a ``CaseTrajectory`` by model), ``"differences"`` (per
        quantity, classical against improved, by :func:`peak_differences` with improved the
        reference), ``"centroidal_difference"`` (the largest relative pointwise difference improved
        vs improved_centroidal) and ``"seconds"`` (the run time).

    Raises:
        stewart_env.files.FolderBusy: another command is writing into ``out``.
        stewart_env.files.WriteError: a write failed (a full disk); the message names the file.
    """
    start = time.perf_counter()
    params = se.load_platform(platform)
    case = paper_case(params)  # refuses, before any work, a platform whose stroke the case leaves
    with lock_folder(out) as out:
        controller = TaskSpacePD(params, PAPER_KP, PAPER_KD, gravity_compensation=gravity_compensation)
        sample_dt = dt if sample_dt is None else sample_dt
        steps = int(round(duration / sample_dt)) * int(round(sample_dt / dt))
        runs = {}
        with progress_bar(total=steps * len(MODELS), desc="case study", unit="step", disable=not progress) as bar:
            for name in MODELS:
                bar.set_postfix_str(name)
                runs[name] = simulate_case_study(name, params, controller, duration, dt, sample_dt, bar)
        diff = peak_differences(runs["improved"], runs["classical"])
        same = peak_differences(runs["improved"], runs["improved_centroidal"])
        centroidal = max(d["pointwise_difference"] for d in same.values())
        for filename, keys, title in FIGURES:
            plot_comparison(out / filename, keys, runs["classical"], runs["improved"], title)
        seconds = time.perf_counter() - start
        settings = {
            "platform": platform,
            "gravity": "on" if gravity_compensation else "off",
            "dt": dt,
            "duration": duration,
            "sample_dt": sample_dt,
            "seconds": seconds,
            "case": case,
        }
        publish(out / "summary.md", _summary_markdown(runs, diff, centroidal, settings))
    return {"runs": runs, "differences": diff, "centroidal_difference": centroidal, "seconds": seconds}
