"""The washout's tuning: its objective's terms, a short tuning that lowers it within the bounds,
deterministically, and the config file it writes."""

import numpy as np
import pytest

from stewart_env.agents.controllers.washout import WashoutParams, load_washout_params
from stewart_env.agents.evaluation.cueing import frequency_response_table, perceive, rms_error
from stewart_env.agents.studies.washout_tuning import (
    TUNED,
    config_text,
    kinematic_chain,
    params_of,
    tune_washout,
    vector_of,
    washout_objective,
)
from stewart_env.errors import UsageError
from stewart_env.tasks.cueing.motion import STANDARD_GRAVITY, VehicleMotion


def braking(n: int = 400, dt: float = 0.01) -> VehicleMotion:
    """A 4 s braking pulse of -3 m/s², smooth at both ends."""
    t = np.arange(n) * dt
    f = np.zeros((n, 3))
    f[:, 2] = STANDARD_GRAVITY
    f[:, 0] = -3.0 * np.sin(np.pi * t / t[-1]) ** 2
    return VehicleMotion("braking", dt, f, np.zeros((n, 3)), source="test")


def test_params_vector_round_trip():
    params = params_of(vector_of(WashoutParams()))
    assert params.force_scale == (0.5, 0.5, 0.5)
    values = np.array([b[0] for _, _, b in TUNED])
    assert np.array_equal(vector_of(params_of(values)), values)


def test_a_still_washout_scores_the_vehicle_motion_alone():
    # a washout that scales everything to nothing leaves the cabin at home: the objective is the
    # RMS of what the vehicle's person feels (no penalty: nothing moves)
    motion = braking()
    still = WashoutParams(force_scale=(0.0, 0.0, 0.0), angular_scale=(0.0, 0.0, 0.0))
    felt, _ = perceive(motion.specific_force, motion.angular_velocity, motion.dt)
    expected = rms_error(felt, np.zeros_like(felt))
    assert expected > 0.5  # the otolith feels most of a 3 m/s² pulse
    assert washout_objective(still, [motion]) == pytest.approx(expected, rel=1e-12)  # the same filters, batched
    # the cabin tilted to the limit of the workspace pays the penalty
    tilted = WashoutParams(
        force_scale=(1.0, 1.0, 1.0), tilt_frequency=(6.0, 6.0), translational_frequency=(0.5, 0.5, 4.0)
    )
    assert washout_objective(tilted, [motion]) > 10.0


@pytest.mark.slow
def test_short_tuning_lowers_the_objective_within_bounds_and_repeats():
    motion = braking()
    first = tune_washout([motion], max_evaluations=40)
    assert first.objective < first.initial_objective
    assert first.evaluations <= 42  # Nelder-Mead may finish its last simplex step
    for value, (_, _, (low, high)) in zip(vector_of(first.params), TUNED):
        assert low <= value <= high
    again = tune_washout([motion], max_evaluations=40)
    assert again.params == first.params  # deterministic


def test_config_text_reads_back(tmp_path):
    motion = braking()
    result = tune_washout([motion], max_evaluations=3)
    path = tmp_path / "washout.yaml"
    path.write_text(config_text(result, [motion], "dasgupta1998", "python -m x"))
    assert path.read_text().startswith("# Classical washout tuned")
    assert load_washout_params(path) == result.params


def test_bad_requests_are_named():
    with pytest.raises(UsageError, match="motions: give at least one training motion"):
        tune_washout([])
    with pytest.raises(UsageError, match="max_evaluations: must be a positive integer"):
        tune_washout([braking()], max_evaluations=0)


def test_gain_and_phase_of_the_washout_alone_in_yaw():
    # yaw has no tilt: the kinematic chain's yaw rate is the scaled high-pass of the vehicle's
    params = WashoutParams(angular_scale=(0.5, 0.5, 0.5), rotational_frequency=(1.0, 1.0, 1.0))
    frequencies = (0.5, 2.0, 8.0)
    rows = frequency_response_table(kinematic_chain(params), channels=("omega_z",), frequencies=frequencies)
    for row, w in zip(rows, frequencies):
        expected = 0.5 * (1j * w) ** 2 / ((1j * w) ** 2 + 2.0 * 1j * w + 1.0)
        # 1 %: Tustin's warping and the central differences, both below 0.3 % up to 8 rad/s at 10 ms
        assert row["gain"] == pytest.approx(abs(expected), rel=0.01)
        assert row["phase"] == pytest.approx(np.degrees(np.angle(expected)), abs=1.0)


def test_command_refuses_options_in_one_line(capsys):
    from stewart_env.agents.studies.washout_tuning import main

    assert main(["--seed", "3"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: python -m stewart_env.agents.studies.washout_tuning [OUT]")
    assert len(err.splitlines()) == 1
