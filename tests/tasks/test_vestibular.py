"""The vestibular models against their transfer functions: step, frequency, discretisation, batches."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.signal

from stewart_env.errors import UsageError
from stewart_env.tasks.cueing.motion import STANDARD_GRAVITY
from stewart_env.tasks.cueing.vestibular import THRESHOLDS, Otolith, SemicircularCanal

MODELS = [Otolith(), SemicircularCanal()]
DT = 0.01


@pytest.mark.parametrize("model", MODELS, ids=lambda m: type(m).__name__)
def test_step_response_is_the_transfer_functions_to_one_percent(model):
    numerator, denominator = model.transfer_function()
    time = np.arange(0.0, 60.0, DT)
    _, expected = scipy.signal.step((numerator, denominator), T=time)
    perceived = model.perceive(np.ones((len(time), 3)), DT, start="rest")
    peak = np.max(np.abs(expected))
    for axis in range(3):
        # 1 %: the bound; the hold is exact here, so the error is rounding
        assert np.max(np.abs(perceived[:, axis] - expected)) < 0.01 * peak
        assert np.max(np.abs(perceived[:, axis] - expected)) < 1e-9 * peak


def _fitted_gain(model, frequency_hz: float) -> complex:
    """The filter's complex gain at one frequency: a sine from rest, fitted with its transient.

    The response from rest is the steady sine plus one exponential per pole, so a linear least
    squares fit on those regressors gives the steady part's gain exactly, without waiting the
    canal's 80 s adaptation out.
    """
    _, denominator = model.transfer_function()
    poles = np.roots(denominator).real
    omega = 2 * math.pi * frequency_hz
    time = np.arange(0.0, max(20.0, 3.0 / frequency_hz), DT)
    perceived = model.perceive(np.repeat(np.sin(omega * time)[:, None], 3, axis=1), DT, start="rest")
    regressors = np.column_stack([np.sin(omega * time), np.cos(omega * time), *[np.exp(p * time) for p in poles]])
    coefficients, *_ = np.linalg.lstsq(regressors, perceived[:, 0], rcond=None)
    return complex(coefficients[0], coefficients[1])


@pytest.mark.parametrize("model", MODELS, ids=lambda m: type(m).__name__)
@pytest.mark.parametrize("frequency_hz", [0.01, 0.05, 0.2, 1.0, 2.0])
def test_frequency_response_is_the_transfer_functions_to_one_percent(model, frequency_hz):
    numerator, denominator = model.transfer_function()
    omega = 2 * math.pi * frequency_hz
    _, expected = scipy.signal.freqs(numerator, denominator, worN=[omega])
    fitted = _fitted_gain(model, frequency_hz)
    # 1 %: the bound; what is left is the straight lines between samples of the sine,
    # (1 - sinc^2) < 0.2 % up to 2 Hz at 100 Hz sampling
    assert abs(fitted - expected[0]) < 0.01 * abs(expected[0])


@pytest.mark.parametrize("model", MODELS, ids=lambda m: type(m).__name__)
def test_discretisation_is_exact_for_inputs_linear_between_samples(model):
    # scipy's lsim joins the samples linearly too: the same continuous input, solved its own way
    numerator, denominator = model.transfer_function()
    time = np.arange(0.0, 30.0, DT)
    signal = np.random.default_rng(7).normal(size=(len(time), 3))
    expected = np.column_stack(
        [scipy.signal.lsim((numerator, denominator), signal[:, axis], time)[1] for axis in range(3)]
    )
    perceived = model.perceive(signal, DT, start="rest")
    # 1e-10: rounding of two exact solutions of the same linear ODE over 3000 steps
    assert np.max(np.abs(perceived - expected)) < 1e-10


@pytest.mark.parametrize("model", MODELS, ids=lambda m: type(m).__name__)
def test_a_batch_is_its_elements_one_by_one_bit_for_bit(model):
    rng = np.random.default_rng(3)
    signal = rng.normal(size=(50, 4, 5, 3))
    batch = model.discretize(DT)
    batch.reset(signal[0])
    together = np.stack([batch.step(sample) for sample in signal])
    for i in range(4):
        for j in range(5):
            one = model.discretize(DT)
            one.reset(signal[0, i, j])
            alone = np.stack([one.step(sample[i, j]) for sample in signal])
            assert np.array_equal(alone, together[:, i, j])


def test_hand_case_canal_step_and_otolith_at_rest():
    canal = SemicircularCanal()
    tau_l, tau_a = canal.long_time_constant, canal.adaptation_time_constant
    time = np.arange(0.0, 20.0, DT)
    perceived = canal.perceive(np.tile([0.0, 0.0, 0.1], (len(time), 1)), DT, start="rest")
    # the step response of tau_L tau_a s^2 / ((tau_L s + 1)(tau_a s + 1)) by partial fractions
    by_hand = 0.1 * (tau_a * np.exp(-time / tau_l) - tau_l * np.exp(-time / tau_a)) / (tau_a - tau_l)
    assert perceived[0, 2] == pytest.approx(0.1, abs=1e-15)  # the canal feeds a step through at once
    assert perceived[1000, 2] == pytest.approx(by_hand[1000], rel=1e-9)  # 10 s: 0.1*(80 e^-1.745 - 5.73 e^-0.125)/74.27
    assert np.max(np.abs(perceived[:, :2])) == 0.0
    # the otolith adapted to gravity at rest reads K g, with no transient
    resting = Otolith().perceive(np.tile([0.0, 0.0, STANDARD_GRAVITY], (200, 1)), DT)
    assert np.allclose(resting[:, 2], 0.4 * STANDARD_GRAVITY, rtol=1e-12, atol=0.0)
    # and from rest it starts at 0: the model is strictly proper
    fresh = Otolith().perceive(np.tile([0.0, 0.0, STANDARD_GRAVITY], (200, 1)), DT, start="rest")
    assert fresh[0, 2] == 0.0


def test_mid_band_gains_are_near_one():
    # the parameters' design: a mid-band motion is felt near its size (Telban and Cardullo)
    frequencies = np.logspace(-3, 2, 2001)
    _, otolith = scipy.signal.freqs(*Otolith().transfer_function(), worN=frequencies)
    assert np.abs(otolith).max() == pytest.approx(0.891, abs=1e-3)  # at 0.50 rad/s
    assert frequencies[np.abs(otolith).argmax()] == pytest.approx(0.50, abs=0.01)
    assert abs(otolith[0]) == pytest.approx(0.4, abs=1e-3)  # 1e-3 rad/s: the gain at rest
    _, canal = scipy.signal.freqs(*SemicircularCanal().transfer_function(), worN=[1.0])
    assert abs(canal[0]) == pytest.approx(0.985, abs=1e-3)


def test_thresholds_are_the_published_ones_and_read_only():
    assert THRESHOLDS["specific_force"].tolist() == [0.17, 0.17, 0.28]
    assert np.degrees(THRESHOLDS["angular_velocity"]) == pytest.approx([3.0, 3.6, 2.6])
    with pytest.raises(ValueError):
        THRESHOLDS["specific_force"][0] = 1.0


def test_bad_arguments_name_themselves():
    with pytest.raises(UsageError, match=r"^dt: must be a finite positive"):
        Otolith().discretize(0.0)
    with pytest.raises(UsageError, match=r"^dt: "):
        Otolith().perceive(np.zeros((3, 3)), float("nan"))
    with pytest.raises(UsageError, match=r"^signal: has a non-finite value at sample 1"):
        Otolith().perceive([[0, 0, 0], [0, np.inf, 0]], DT)
    with pytest.raises(UsageError, match=r"^signal: must have shape \(T, 3\)"):
        Otolith().perceive(np.zeros((4, 2)), DT)
    with pytest.raises(UsageError, match=r"^start: "):
        Otolith().perceive(np.zeros((4, 3)), DT, start="cold")
    with pytest.raises(UsageError, match=r"^long_time_constant: "):
        SemicircularCanal(long_time_constant=-1.0)
    sensor = Otolith().discretize(DT)
    sensor.step(np.zeros((2, 3)))
    with pytest.raises(UsageError, match=r"^u: has shape \(3,\)"):
        sensor.step(np.zeros(3))


def test_starting_rows_adapted_is_a_fresh_filter_for_those_rows():
    rng = np.random.default_rng(5)
    signal = rng.normal(size=(30, 4, 3))
    batch = Otolith().discretize(DT)
    batch.reset(np.zeros((4, 3)))
    for sample in signal[:10]:
        batch.step(sample)
    steady = np.array([[0.0, 0.0, 9.81], [1.0, 2.0, 3.0]])
    batch.start_rows([1, 3], steady)
    after = np.stack([batch.step(sample) for sample in signal[10:]])
    fresh = Otolith().discretize(DT)
    fresh.reset(steady)
    alone = np.stack([fresh.step(sample[[1, 3]]) for sample in signal[10:]])
    assert np.array_equal(after[:, [1, 3]], alone)
    with pytest.raises(UsageError, match=r"^steady_input: must have shape \(2, 3\)"):
        batch.start_rows([0, 1], np.zeros((3, 3)))
    with pytest.raises(UsageError, match=r"^rows: the filter holds no batch yet"):
        Otolith().discretize(DT).start_rows([0], np.zeros((1, 3)))
