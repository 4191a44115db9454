"""The cueing metrics on synthetic signals: a known delay recovered, a known correlation, false cues
counted by hand, the perception's rest, and the gain and phase table of known chains."""

import math

import gymnasium as gym
import numpy as np
import pytest

from stewart_env.agents.evaluation.cueing import (
    CUEING_METRICS,
    OMCT_FREQUENCIES,
    correlation,
    cueing_metrics,
    delay,
    false_cues,
    fit_harmonic,
    frequency_response_table,
    kinematic_head_motion,
    perceive,
    rms_error,
    sine_motion,
    table_markdown,
)
from stewart_env.errors import UsageError
from stewart_env.rotations import rpy_to_matrix
from stewart_env.tasks.cueing.motion import STANDARD_GRAVITY
from stewart_env.tasks.cueing.vestibular import THRESHOLDS

DT = 0.01


def test_known_delay_is_recovered_to_the_sample_and_between_samples():
    t = np.arange(3000) * DT
    signal = np.stack([np.sin(1.3 * t) + 0.5 * np.sin(3.1 * t), np.cos(0.7 * t), 0 * t], axis=1)
    late = np.roll(signal, 17, axis=0)  # 170 ms later
    assert delay(signal[100:], late[100:], DT) == pytest.approx(
        0.17, abs=1e-3
    )  # the parabola's refinement of an exact peak
    assert delay(late[100:], signal[100:], DT) == pytest.approx(-0.17, abs=1e-3)
    # 45 ms: between samples, the parabola through the peak recovers it within a tenth of a sample
    smooth = np.sin(0.9 * (t - 0.045))[:, None]
    assert delay(np.sin(0.9 * t)[:, None], smooth, DT) == pytest.approx(0.045, abs=1e-3)
    assert math.isnan(delay(np.ones((50, 1)), signal[:50, :1], DT))


def test_known_correlation():
    rng = np.random.default_rng(1)
    a = rng.normal(size=(20000, 3))
    noise = rng.normal(size=(20000, 3))
    # b = a + noise: cov = var(a) = 1, var(b) = 2, so r = 1 / sqrt(2)
    assert correlation(a, a + noise) == pytest.approx(
        1 / math.sqrt(2), abs=0.01
    )  # the sample's spread, 1/sqrt(N)-sized
    assert correlation(a, 3.0 * a + 5.0) == pytest.approx(1.0, abs=1e-12)
    assert correlation(a, -a) == pytest.approx(-1.0, abs=1e-12)
    assert math.isnan(correlation(a, np.zeros_like(a)))


def test_false_cues_counted_by_hand():
    threshold = np.array([0.17, 0.17, 0.28])
    vehicle = np.zeros((8, 3))
    platform = np.zeros((8, 3))
    vehicle[:, 0] = [1, 1, 1, 1, -1, -1, -1, -1]
    platform[:, 0] = [0.1, -0.5, -0.5, 0.2, 0.3, -0.2, 0.5, 0.5]  # x: wrong sign above 0.17 at 1-2 and 4, 6-7: 3 runs
    platform[:, 1] = [0.0, 0.18, 0.0, 0.0, 0.0, 0.0, 0.0, 0.1]  # y: felt where the vehicle is 0: 1 run
    platform[:, 2] = [0.27, -0.27, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]  # z: below 0.28: none
    count, mask = false_cues(vehicle, platform, threshold)
    assert count == 4
    assert mask[:, 0].tolist() == [False, True, True, False, True, False, True, True]
    assert mask.sum() == 6


def test_perception_of_rest_is_zero_and_metrics_of_identical_motions():
    n = 500
    t = np.arange(n) * DT
    f = np.zeros((n, 3))
    f[:, 2] = STANDARD_GRAVITY
    f[:, 0] = np.sin(2.0 * t)
    w = np.zeros((n, 3))
    w[:, 2] = 0.2 * np.sin(1.5 * t)
    rest_f, rest_w = perceive(np.tile([0.0, 0.0, STANDARD_GRAVITY], (n, 1)), np.zeros((n, 3)), DT)
    assert np.abs(rest_f).max() == 0.0 and np.abs(rest_w).max() == 0.0
    m = cueing_metrics(DT, f, w, f, w, pose_fraction=np.full((n, 6), 0.25), leg_fraction=np.full((n, 6), -0.5))
    assert list(m) == list(CUEING_METRICS)
    assert m["rms_specific_force_error"] == 0.0 and m["rms_angular_velocity_error"] == 0.0
    assert m["specific_force_correlation"] == pytest.approx(1.0, abs=1e-12)
    assert m["specific_force_delay"] == pytest.approx(0.0, abs=1e-9)
    assert m["false_specific_force_cues"] == 0.0 and m["false_cue_time"] == 0.0
    assert (m["workspace_use"], m["stroke_use"]) == (0.25, 0.5)
    # the platform standing still: the error is the vehicle's perceived motion, every sample felt by none
    still_f, still_w = np.tile([0.0, 0.0, STANDARD_GRAVITY], (n, 1)), np.zeros((n, 3))
    m = cueing_metrics(DT, f, w, still_f, still_w)
    vf, _ = perceive(f, w, DT)
    assert m["rms_specific_force_error"] == pytest.approx(rms_error(vf, 0 * vf), rel=1e-12)
    assert math.isnan(m["specific_force_correlation"]) and math.isnan(m["workspace_use"])
    # the platform's cue reversed: false cues wherever it is felt
    m = cueing_metrics(DT, f, w, 2 * still_f - f, -w)
    assert m["false_specific_force_cues"] >= 2 and m["specific_force_correlation"] == pytest.approx(-1.0, abs=1e-12)


def test_fit_harmonic_of_a_known_sine():
    t = np.arange(2000) * DT
    y = 0.7 * np.cos(1.1 * t - 0.4) + 3.0
    assert fit_harmonic(y, DT, 1.1) == pytest.approx(0.7 * np.exp(-0.4j), abs=1e-9)


def test_table_of_known_chains():
    def lag_chain(motion):
        # the cue delayed by 5 samples at half the gain: gain 0.5, phase -w 0.05 rad
        f = motion.specific_force.copy()
        f[:, :2] = 0.5 * np.roll(f[:, :2], 5, axis=0)
        return f, 0.5 * np.roll(motion.angular_velocity, 5, axis=0)

    rows = frequency_response_table(lag_chain, channels=("f_x", "omega_z"), frequencies=(0.5, 2.0))
    for row in rows:
        assert row["gain"] == pytest.approx(0.5, rel=1e-6)  # an exact delay of a sine: the fit's rounding
        assert row["phase"] == pytest.approx(-math.degrees(row["frequency"] * 0.05), abs=1e-4)
    text = table_markdown(rows)
    assert text.splitlines()[0] == "| w (rad/s) | f_x gain | f_x phase (deg) | omega_z gain | omega_z phase (deg) |"
    assert "| 0.5 | 0.5 | -1.4 | 0.5 | -1.4 |" in text
    assert OMCT_FREQUENCIES[0] == 0.1 and OMCT_FREQUENCIES[-1] == 15.849


def test_kinematic_head_motion_of_a_tilt_and_a_sway():
    n = 400
    t = np.arange(n) * DT
    displacement = np.zeros((n, 3))
    displacement[:, 1] = 0.1 * np.sin(2.0 * t)
    rpy = np.zeros((n, 3))
    rpy[:, 0] = 0.05
    rpy[:, 2] = 0.3 * t  # a constant yaw rate
    f, w = kinematic_head_motion(displacement, rpy, DT)
    inner = slice(2, n - 2)
    # the exact motion: lateral acceleration -0.4 sin(2t) and gravity, seen in the cabin R^T (a + g)
    acceleration = np.zeros((n, 3))
    acceleration[:, 1] = -0.4 * np.sin(2.0 * t)
    acceleration[:, 2] = STANDARD_GRAVITY
    rotation = rpy_to_matrix(rpy)
    expected = np.einsum("tji,tj->ti", rotation, acceleration)
    assert np.abs(f[inner] - expected[inner]).max() < 1e-4  # central differences: 0.4 (2 dt)² / 12 = 1.3e-5
    # a yaw rate about the vertical seen in a cabin rolled by 0.05 rad: (0, sin, cos) 0.3
    np.testing.assert_allclose(w[inner], np.tile([0.0, 0.3 * np.sin(0.05), 0.3 * np.cos(0.05)], (n - 4, 1)), atol=1e-4)


def test_sine_motion_refuses_bad_channels():
    with pytest.raises(UsageError, match="channel: must be one of"):
        sine_motion("heave", 1.0, 1.0, DT)
    with pytest.raises(UsageError, match="frequency: must be a finite positive number"):
        sine_motion("f_x", 0.0, 1.0, DT)
    with pytest.raises(UsageError, match="channels: unknown channel 'heave'"):
        frequency_response_table(lambda m: (m.specific_force, m.angular_velocity), channels=("heave",))
    assert THRESHOLDS["specific_force"].shape == (3,)


def test_evaluate_on_the_cueing_task_reports_the_cueing_metrics(tmp_path):
    from stewart_env.agents import WashoutPolicy, evaluate

    kwargs = {"task": "cueing", "action_mode": "pose", "task_options": {"motions": ("braking",)}}
    result = evaluate(WashoutPolicy, kwargs, episodes=2, seed=0, max_steps=60, out=tmp_path, progress=False)
    assert result.cueing_keys() == list(CUEING_METRICS)
    for ep in result.episodes:
        assert 0.0 <= ep.metrics["workspace_use"] <= 1.0 and 0.0 < ep.metrics["stroke_use"] <= 1.0
        assert ep.metrics["rms_specific_force_error"] >= 0.0
    header = (tmp_path / "episodes.csv").read_text().splitlines()[0].split(",")
    assert header[-len(CUEING_METRICS) :] == list(CUEING_METRICS)
    assert "## Cueing" in (tmp_path / "results.md").read_text()
    # the same policy object evaluated twice starts its filters over: the same numbers
    policy = WashoutPolicy(gym.make("StewartPlatform-v1", **kwargs))
    first = evaluate(policy, kwargs, episodes=2, seed=0, max_steps=60, progress=False)
    second = evaluate(policy, kwargs, episodes=2, seed=0, max_steps=60, progress=False)
    assert [ep.metrics for ep in first.episodes] == [ep.metrics for ep in second.episodes]
    assert [ep.metrics for ep in first.episodes] == [ep.metrics for ep in result.episodes]


def test_evaluate_elsewhere_has_no_cueing_metrics():
    from stewart_env.agents import PDPolicy, evaluate

    result = evaluate(PDPolicy, {"task": "setpoint"}, episodes=1, seed=0, max_steps=5, progress=False)
    assert result.cueing_keys() == []
    assert "rms_specific_force_error" not in result.summary()
