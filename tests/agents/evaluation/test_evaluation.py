"""The evaluation harness: metrics against hand-computed values, determinism, the report."""

import csv
import math
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

from stewart_env.agents import PDPolicy, evaluate, write_report
from stewart_env.agents.evaluation.evaluation import (
    ENV_ID,
    ERROR_FLOOR,
    METRICS,
    ORIENTATION_TOLERANCE,
    POSITION_TOLERANCE,
    Episode,
    EvaluationResult,
    control_energy,
    episode_metrics,
    error_norms_figure,
    final_window_mask,
    overshoot,
    rms,
    settling_time,
)
from stewart_env.tasks.base import error_norm


def second_order_step(zeta: float, wn: float, t: np.ndarray) -> np.ndarray:
    """Unit step response y(t) of wn^2 / (s^2 + 2 zeta wn s + wn^2), zeta < 1."""
    wd = wn * math.sqrt(1 - zeta**2)
    return 1 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta / math.sqrt(1 - zeta**2) * np.sin(wd * t))


def test_overshoot_of_a_second_order_step_response():
    t = np.linspace(0.0, 5.0, 50001)
    zeta = 0.3
    y = second_order_step(zeta, 10.0, t)
    expected = 100 * math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2))  # 37.23 %
    # the peak falls between samples 1e-4 s apart: the sampled peak is within 1e-6 of it
    assert overshoot((1 - y)[:, None], 1e-3) == pytest.approx(expected, abs=1e-4)
    # a vector error: the same step along an oblique direction plus a crosswise wobble of no effect
    direction = np.array([0.6, 0.0, 0.8])
    crosswise = np.array([0.0, 1.0, 0.0])
    e = np.outer(1 - y, direction) + np.outer(0.2 * np.sin(3 * t), crosswise)
    assert overshoot(e, 1e-3) == pytest.approx(expected, abs=1e-4)  # exact projection
    assert overshoot(np.exp(-t)[:, None], 1e-3) == 0.0  # never crosses
    assert math.isnan(overshoot(np.full((5, 3), 1e-4), 1e-3))  # no step: starts inside the tolerance


def test_settling_time_of_a_first_order_decay():
    t = np.linspace(0.0, 2.0, 2001)
    tau, tol = 0.1, 0.02
    e = np.exp(-t / tau)
    # inside from the first sample with exp(-t/tau) <= tol: t = tau ln(1/tol) = 0.3912, rounded up to the grid
    expected = math.ceil(tau * math.log(1 / tol) / 1e-3) * 1e-3
    assert settling_time(t, e <= tol) == pytest.approx(expected, abs=1e-12)
    inside = np.array([False, True, False, True, True])
    assert settling_time(np.arange(5.0), inside) == 3.0  # the last entry into the band counts
    assert settling_time(np.arange(3.0), np.array([True, True, True])) == 0.0
    assert math.isnan(settling_time(np.arange(3.0), np.array([True, True, False])))


def test_rms_energy_and_final_window():
    assert rms(np.tile([3.0, 4.0, 0.0], (10, 1))) == pytest.approx(5.0, rel=1e-15)
    t = np.linspace(0.0, 1.0, 100001)
    assert rms(np.sin(2 * np.pi * 5 * t)) == pytest.approx(1 / math.sqrt(2), rel=1e-4)  # 5 whole periods
    time = np.linspace(0.0, 2.0, 201)
    forces = np.tile([100.0, -50.0, 0.0, 10.0, 10.0, 10.0], (200, 1))
    rates = np.tile([-0.1, -0.2, 5.0, 0.0, 0.0, 0.0], (201, 1))
    # |100 * -0.1| + |-50 * -0.2| = 20 W for 2 s; the idle and still legs add nothing
    assert control_energy(time, forces, rates) == pytest.approx(40.0, rel=1e-12)
    # a rate ramping linearly over one step: the trapezoid is exact
    assert control_energy([0.0, 0.5], [[4.0] * 6], [[0.0] * 6, [1.0] * 6]) == pytest.approx(6.0)
    mask = final_window_mask(np.linspace(0.0, 5.0, 501), 0.1)
    assert mask.sum() == 51 and mask[-51:].all()  # t >= 4.5 s
    assert final_window_mask(np.linspace(0.0, 5.0, 501), 0.0).sum() == 1  # at least the last sample


def test_episode_metrics_of_a_synthetic_step():
    t = np.linspace(0.0, 5.0, 501)
    y = second_order_step(0.5, 8.0, t)
    position_error = np.outer(1 - y, [0.05, 0.0, 0.0])  # a 5 cm step along x
    orientation_error = np.outer(1 - y, [0.0, 0.0, 0.2])  # and 0.2 rad about z
    forces = np.full((500, 6), 100.0)
    rates = np.zeros((501, 6))
    m = episode_metrics(
        t,
        position_error,
        orientation_error,
        forces,
        rates,
        terminated=False,
        position_tolerance=2e-3,
        orientation_tolerance=1e-2,
    )
    expected_overshoot = 100 * math.exp(-math.pi * 0.5 / math.sqrt(0.75))  # 16.3 %
    # a 10 ms grid against a 0.45 s oscillation period: the sampled peak is within 0.1 % of the true one
    assert m["position_overshoot"] == pytest.approx(expected_overshoot, rel=1e-3)
    assert m["orientation_overshoot"] == pytest.approx(expected_overshoot, rel=1e-3)
    # both errors are the same signal scaled; the orientation band (1e-2 / 0.2 = 5 %) is the wider
    # one, so the settling time is the last 4 % (2e-3 / 0.05) crossing
    band = np.abs(1 - y) <= 0.04
    assert m["settling_time"] == pytest.approx(t[np.flatnonzero(~band)[-1] + 1])
    assert m["success"] == 1.0
    assert m["peak_leg_force"] == 100.0
    assert m["control_energy"] == 0.0  # nothing moves
    assert m["rms_position_error"] == pytest.approx(0.05 * rms(1 - y), rel=1e-12)
    window = t >= 4.5
    assert m["steady_state_position_error"] == pytest.approx(0.05 * np.abs(1 - y[window]).mean(), rel=1e-12)
    failed = episode_metrics(t, position_error, orientation_error, forces, rates, terminated=True)
    assert failed["success"] == 0.0 and math.isnan(failed["settling_time"])


def test_success_is_the_final_window_rule():
    """The criterion, now the tasks' (latest sample outside the band before the window), is the
    harness's rule as it was written: not terminated and every sample of the final window inside."""
    rng = np.random.default_rng(0)
    verdicts = set()
    for _ in range(2000):
        steps = int(rng.integers(0, 60))
        time = 0.01 * np.arange(steps + 1)
        final_window = float(rng.choice([0.0, 0.1, 0.25, 0.5, 1.0, rng.uniform()]))
        # errors around the band's edge, often inside from some sample on
        scale = np.where(np.arange(steps + 1) >= rng.integers(0, steps + 2), 0.5, 2.0)
        position_error = scale[:, None] * rng.uniform(0.0, 2e-3 / math.sqrt(3), (steps + 1, 3))
        orientation_error = np.outer(scale * rng.uniform(0.3, 1.2, steps + 1), [0.0, 0.0, 1e-2])
        terminated = bool(rng.random() < 0.1)
        inside = (np.linalg.norm(position_error, axis=1) <= POSITION_TOLERANCE) & (
            np.linalg.norm(orientation_error, axis=1) <= ORIENTATION_TOLERANCE
        )
        written = float(not terminated and bool(inside[final_window_mask(time, final_window)].all()))
        metrics = episode_metrics(
            time,
            position_error,
            orientation_error,
            np.zeros((steps, 6)),
            np.zeros((steps + 1, 6)),
            terminated,
            final_window=final_window,
        )
        assert metrics["success"] == written
        verdicts.add(written)
    assert verdicts == {0.0, 1.0}


def test_error_norms_are_numpy_s_norms_bit_for_bit():
    """The environment's errors (``error_norm``, one row or a batch) are the numbers
    ``np.linalg.norm`` gives the harness's recorded errors."""
    vectors = np.random.default_rng(1).standard_normal((20000, 3)) * np.logspace(-9, 1, 20000)[:, None]
    expected = np.linalg.norm(vectors, axis=1)
    assert np.array_equal(error_norm(vectors), expected)
    assert [error_norm(v) for v in vectors[:2000].tolist()] == expected[:2000].tolist()


def test_evaluate_is_deterministic_and_matches_the_single_environment():
    kwargs = {"model": "improved", "task": "setpoint"}
    a = evaluate(PDPolicy, kwargs, episodes=2, seed=7, max_steps=20, progress=False)
    b = evaluate(PDPolicy, kwargs, episodes=2, seed=7, max_steps=20, progress=False)
    c = evaluate(PDPolicy, kwargs, episodes=2, seed=8, max_steps=20, progress=False)
    for x, y in zip(a.episodes, b.episodes):
        assert x.metrics == y.metrics
        np.testing.assert_array_equal(x.position_error, y.position_error)
    assert a.episodes[0].metrics != c.episodes[0].metrics
    # episode 1 (seed 8) of the run with seed 7 is episode 0 of the run with seed 8
    assert a.episodes[1].metrics == c.episodes[0].metrics
    # and the single environment reset with seed 8 walks the same path
    env = gym.make(ENV_ID, **kwargs)
    policy = PDPolicy(env)
    obs, _ = env.reset(seed=8)
    for _ in range(3):
        obs, *_ = env.step(policy.predict(obs)[0])
    u = env.unwrapped
    np.testing.assert_allclose(
        a.episodes[1].position_error[3], u.target.position - u.state.position, rtol=0, atol=1e-12
    )  # the same arithmetic; batched solves may round differently


def test_report_files(tmp_path):
    result = evaluate(PDPolicy, {"task": "tracking"}, episodes=2, seed=0, max_steps=10, label="PD", progress=False)
    paths = write_report([result], tmp_path)
    table = paths["markdown"].read_text()
    assert "| PD | improved | tracking | 2 |" in table
    assert all(header in table for _, header, _, _ in METRICS)
    with paths["csv"].open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 2 and rows[1]["seed"] == "1"
    assert float(rows[0]["rms_position_error"]) == pytest.approx(result.episodes[0].metrics["rms_position_error"])
    for key in ("error_norms", "trajectory PD improved"):
        assert paths[key].stat().st_size > 10_000  # a real plot, not an empty canvas


def test_evaluate_names_bad_arguments():
    with pytest.raises(ValueError, match="episodes"):
        evaluate(PDPolicy, {}, episodes=0)
    with pytest.raises(ValueError, match="policy"):
        evaluate(42, {})
    with pytest.raises(ValueError, match="final_window"):
        evaluate(PDPolicy, {}, final_window=2.0)


def _decaying_result(label: str, model: str, zero_after: float | None) -> EvaluationResult:
    """Two episodes of an error decaying from 5 cm (and 0.1 rad) to 2.3e-3 mm (4.5e-3 mrad) at 2 s,
    exactly zero after ``zero_after`` s if given."""
    t = np.linspace(0.0, 2.0, 201)
    error = np.outer(np.exp(-5.0 * t), [0.05, 0.0, 0.0])
    if zero_after is not None:
        error[t > zero_after] = 0.0
    episodes = [
        Episode(seed, t, error, 2.0 * error, np.zeros((200, 6)), np.zeros((201, 6)), None, 0.0) for seed in (0, 1)
    ]
    return EvaluationResult(label, {"model": model}, 0, episodes)


def test_error_norm_plot_marks_its_floor_as_a_floor():
    fig = error_norms_figure([_decaying_result("CT", "improved", zero_after=1.5)])
    for ax, unit in zip(fig.axes, ("mm", "mrad")):
        assert [t.get_text() for t in ax.texts] == [f"below 1e-6 {unit}: rounding floor"]
        assert ax.get_ylim()[0] == pytest.approx(ERROR_FLOOR / 2)  # nothing is drawn below the floor
    # errors that stay above the floor draw none
    fig = error_norms_figure([_decaying_result("CT", "improved", zero_after=None)])
    assert all(not ax.texts for ax in fig.axes)


def test_overlapping_results_all_show():
    """Two results with the same curves (as PD on two models that agree): the later one is drawn on
    top, narrower and in another line style, so the one beneath shows around it."""
    fig = error_norms_figure([_decaying_result("PD", "classical", None), _decaying_result("PD", "improved", None)])
    for ax in fig.axes:
        medians = {line.get_label(): line for line in ax.get_lines() if not line.get_label().startswith("_")}
        below, above = medians["PD on classical"], medians["PD on improved"]
        np.testing.assert_array_equal(below.get_ydata(), above.get_ydata())
        assert above.get_zorder() > below.get_zorder()
        assert above.get_linewidth() < below.get_linewidth()
        assert above.get_linestyle() != below.get_linestyle()
        assert above.get_marker() not in ("None", "", None)


def test_figures_leave_the_matplotlib_backend_alone():
    """Writing reports and figures goes through private Agg canvases: the user's backend (here
    'template') stays selected and pyplot is never imported, so render_mode='human' still works."""
    script = """
import sys, matplotlib
matplotlib.use("template")
import numpy as np
from pathlib import Path
import tempfile
from stewart_env.agents.studies import mismatch, reproduce
from stewart_env.agents.evaluation.evaluation import METRICS, Episode, EvaluationResult, write_report
t = np.linspace(0.0, 1.0, 11)
e = np.outer(np.exp(-t), [0.01, 0.0, 0.0])
result = EvaluationResult("PD", {}, 0, [Episode(0, t, e, e, np.zeros((10, 6)), np.zeros((11, 6)), None, 0.0)])
result.episodes[0].metrics = {key: 1.0 for key, *_ in METRICS}
out = Path(tempfile.mkdtemp())
write_report([result], out)
from stewart_env.agents.evaluation.statistics import Interval
rows = [mismatch.Row("PD", "PD", "")]
cell = {key: Interval(v, v, v, 1, 1) for key, v in result.summary().items()}
study = mismatch.MismatchResult(rows, ["improved"], {"PD": {"improved": cell}}, 1)
study.differences = [mismatch.Difference("PD", "C2", "PD", "PD", key, Interval(1.0, 0.5, 2.0, 1, 1), False)
                     for key in mismatch.RANKING_METRICS]
mismatch.heatmap(study, METRICS[0], out / "heatmap.png")
mismatch.forest_figure(study, METRICS).savefig(out / "forest.png")
print(matplotlib.get_backend(), "matplotlib.pyplot" in sys.modules)
"""
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["template", "False"]


def test_no_progress_bar_in_a_log(capsys):
    """Under pytest stderr is captured, not a terminal: a short run writes no bar and no line."""
    evaluate(PDPolicy, {}, episodes=1, max_steps=5, progress=True)
    assert capsys.readouterr().err == ""


class _FullThrust:
    """Every leg pushed to its force limit: the platform leaves the workspace within the episode."""

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        return np.ones((len(observation), 6), np.float32), None


def test_the_table_counts_the_episodes_ended_early_with_their_most_common_reason():
    from stewart_env.agents.evaluation.evaluation import ENDED_EARLY, ended_early

    crashed = evaluate(
        _FullThrust(), {"model": "improved"}, episodes=2, seed=0, label="thrust", max_steps=200, progress=False
    )
    assert [ep.termination for ep in crashed.episodes] == ["leg_stroke", "leg_stroke"]  # within a few steps
    held = evaluate(PDPolicy, {"model": "improved"}, episodes=1, seed=0, label="PD", max_steps=20, progress=False)
    assert ended_early(held) == "0"
    assert ended_early(crashed) == "2 (leg_stroke)"
    from stewart_env.agents import markdown_table

    header, _, *rows = markdown_table([crashed, held]).splitlines()
    columns = [c.strip() for c in header.strip("|").split("|")]
    assert columns[4:6] == ["success", ENDED_EARLY]
    assert [[c.strip() for c in row.strip("|").split("|")][5] for row in rows] == [ended_early(crashed), "0"]


def test_cost_rate_and_limit_hits_are_the_step_infos_costs(tmp_path):
    """Full thrust on the motion simulator: its legs exceed their acceleration and rate bounds.
    The harness's cost rate and limit hits are those the single environment's infos give."""
    import json

    from stewart_env.agents import markdown_table
    from stewart_env.agents.evaluation.evaluation import LIMIT_HITS, limit_hits_cell

    kwargs = {"platform": "motion_simulator"}
    result = evaluate(_FullThrust(), kwargs, episodes=2, seed=4, label="thrust", max_steps=6, progress=False)
    total, steps, hits = 0.0, 0, {}
    for seed in (4, 5):
        env = gym.make("StewartPlatform-v1", **kwargs)
        env.reset(seed=seed)
        for _ in range(6):
            *_, terminated, _, info = env.step(np.ones(6, np.float32))
            total, steps = total + info["cost"], steps + 1
            for key in info:
                if key.startswith("cost_"):
                    hits[key[5:]] = hits.get(key[5:], 0) + int(info[key])
            if terminated:
                break
    assert result.cost_rate() == total / steps
    assert result.limit_hits() == hits and hits["leg_acceleration"] > 0
    header, _, row = markdown_table([result]).splitlines()
    assert header.split("|")[-2].strip() == LIMIT_HITS and row.split("|")[-2].strip() == limit_hits_cell(result)
    assert limit_hits_cell(result).startswith("leg_velocity ") or "leg_acceleration " in limit_hits_cell(result)
    record = json.loads(write_report([result], tmp_path)["json"].read_text())[0]
    assert record["cost_rate"] == result.cost_rate() and record["limit_hits"] == hits
    with (tmp_path / "episodes.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert sum(int(r["hits_leg_acceleration"]) for r in rows) == hits["leg_acceleration"]
