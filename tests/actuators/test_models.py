"""The actuator models (docs/physics.md section 10): hand cases to rounding, the current loop's and
the leg servo's bandwidths measured by frequency sweeps, the hydraulic natural frequency of a
simulated free oscillation and the step the oil's stiffness needs, determinism across batch
sizes and pickling."""

import dataclasses
import math
import pickle

import numpy as np
import pytest

from stewart_env.actuators import (
    ElectricActuator,
    HydraulicActuator,
    IdealActuator,
    LagActuator,
    LegServo,
    load_actuators,
)
from stewart_env.errors import UsageError

SETS = load_actuators("motion_simulator")
ELECTRIC = SETS.electric
HYDRAULIC = SETS.hydraulic
# the motion simulator's electric set by hand: k = 2 pi / 25 mm
K = 2 * math.pi / 0.025


def sine_amplitude(t, x, omega):
    """Amplitude of the omega-component of x(t) (one series per column), by least squares on
    sin, cos and a constant."""
    basis = np.stack([np.sin(omega * t), np.cos(omega * t), np.ones_like(t)], axis=1)
    coef = np.linalg.lstsq(basis, x, rcond=None)[0]
    return math.hypot(coef[0], coef[1])


def minus_3db(omegas, gains):
    """The frequency where the gain first falls through 1/sqrt(2), interpolated in log-log."""
    below = np.nonzero(gains < 1 / math.sqrt(2))[0][0]
    lo, hi = below - 1, below
    s = (math.log(1 / math.sqrt(2)) - math.log(gains[lo])) / (math.log(gains[hi]) - math.log(gains[lo]))
    return math.exp(math.log(omegas[lo]) + s * (math.log(omegas[hi]) - math.log(omegas[lo])))


# ---- lag ------------------------------------------------------------------------------------------


def test_the_lag_s_step_response_is_exact():
    lag = LagActuator(n=2, tau=0.05)
    dt, u = 1e-3, 1000.0
    for k in range(1, 201):
        force = lag.step(np.full((2, 6), u), dt)
        # k products of the same factor: rounding grows like k eps
        assert force[1, 3] == pytest.approx(u * -math.expm1(-k * dt / 0.05), rel=1e-12)


def test_the_ideal_actuator_passes_the_command():
    command = np.arange(12.0).reshape(2, 6)
    assert np.array_equal(LagActuator(n=2, tau=0.0).step(command, 1e-3), command)
    assert np.array_equal(IdealActuator(n=2).step(command, 1e-3), command)


# ---- electric -------------------------------------------------------------------------------------


def test_reflected_mass_stall_force_and_no_load_speed_by_hand():
    drive = ElectricActuator(ELECTRIC)
    # k^2 J_m = (2 pi / 0.025)^2 0.015 kg
    assert drive.reflected_mass == pytest.approx(K**2 * 0.015, rel=1e-14)  # rounding
    assert drive.reflected_mass == pytest.approx(947.4820225045784, rel=1e-14)
    # eta k K_t i_max = 0.9 k 1.95 90
    assert drive.stall_force == pytest.approx(0.9 * K * 1.95 * 90.0, rel=1e-14)
    # omega_0 = U / K_e = 560 / 1.95 rad/s, l_dot = omega_0 / k
    assert drive.no_load_speed == pytest.approx(560.0 / 1.95 / K, rel=1e-14)


def run_electric(drive, command, l_dot, steps=60, dt=1e-3):
    for _ in range(steps):
        force = drive.step(command, l_dot, dt)
    return force


def test_the_drive_at_rest_stalls_at_its_current_limit():
    drive = ElectricActuator(ELECTRIC)
    # 60 steps of exp(-pi) each: the current has converged to its limit
    force = run_electric(drive, np.array([[1e4, -1e4, 90.0, 45.0, 0.0, 1e9]]), 0.0)
    stall = 0.9 * K * 1.95 * 90.0
    expected = [stall, -stall, stall, stall / 2, 0.0, stall]
    assert force[0] == pytest.approx(expected, rel=1e-12, abs=1e-9)  # rounding of a converged lag


def test_the_voltage_envelope_ends_at_the_no_load_speed():
    params = ELECTRIC
    speed0 = 560.0 / 1.95 / K
    friction = lambda v: params.coulomb_friction * math.tanh(v / params.friction_speed)  # noqa: E731
    drive = ElectricActuator(params)
    l_dot = np.array([[0.0, 0.5, 0.999, 1.0 + 1e-9, 1.5, -0.999]]) * speed0
    run_electric(drive, 1e4, l_dot)
    current = drive.current[0]
    # motoring (legs 0-4): (U - K_e k |l_dot|) / R, capped at i_max: 90 A, 90 A, 1.6 A, 0, 0; leg 5
    # moves against the current (braking): i_max alone, 90 A
    assert current == pytest.approx([90.0, 90.0, 0.001 * 560 / 0.35, 0.0, 0.0, 90.0], rel=1e-6)
    # beyond the no-load speed the motor gives nothing: the leg feels only the friction
    assert drive.force[0, 3] == pytest.approx(-friction(l_dot[0, 3]), rel=1e-12)


def test_the_current_loop_s_bandwidth_is_its_configured_one():
    omega_c = ELECTRIC.current_bandwidth
    omegas = omega_c * np.geomspace(0.25, 4.0, 25)
    n, dt, steps = len(omegas), 2e-6, 10000  # 20 ms: 2.5 periods of the slowest sine after 10 ms
    drive = ElectricActuator(ELECTRIC, n=n)
    times = np.arange(1, steps + 1) * dt
    currents = np.empty((steps, n))
    for j in range(steps):
        # the set point held over the step from its start
        command = np.repeat((10.0 * np.sin(omegas * (times[j] - dt)))[:, None], 6, axis=1)
        drive.step(command, 0.0, dt)
        currents[j] = drive.current[:, 0]
    settled = times > 0.01
    gains = np.array([sine_amplitude(times[settled], currents[settled, r], omegas[r]) / 10.0 for r in range(n)])
    # a first-order loop at 10 A, far inside the limits: its -3 dB point is omega_c; the grid's
    # log-log interpolation and the held set point: a few 1e-3
    assert minus_3db(omegas, gains) == pytest.approx(omega_c, rel=0.1)
    assert minus_3db(omegas, gains) == pytest.approx(omega_c, rel=0.01)


# ---- the leg servo on an electric leg -------------------------------------------------------------


@pytest.mark.parametrize("zeta", [0.7, 1.0])
def test_the_leg_servo_s_measured_bandwidth_is_its_configured_one(zeta):
    drive_mass = 8000.0 / 6 + 300.0  # kg: a leg's share of the cab and a leg's own mass
    mass = drive_mass + ElectricActuator(ELECTRIC).reflected_mass
    omega_b = 2 * math.pi * 5.0
    omegas = omega_b * np.geomspace(0.3, 3.0, 21)
    n, dt, steps = len(omegas), 1e-3, 6000  # the physics step; 6 s: 2 s of transient, 4 s fitted
    drive = ElectricActuator(ELECTRIC, n=n)
    servo = LegServo.from_bandwidth(
        omega_b, zeta, mass, ELECTRIC.viscous_friction, drive.screw.efficiency * K * 1.95, n=n
    )
    length, rate = np.zeros((n, 6)), np.zeros((n, 6))
    times = np.arange(steps) * dt
    lengths = np.empty((steps, n))
    amplitude = 0.005  # m: the servo's force stays within the current limit
    for j in range(steps):
        setpoint = np.repeat((amplitude * np.sin(omegas * times[j]))[:, None], 6, axis=1)
        command = servo.step(setpoint, length, rate, dt)
        force = drive.step(command, rate, dt)
        rate += force / mass * dt  # semi-implicit Euler of the leg on its mass
        length += rate * dt
        lengths[j] = length[:, 0]
    assert np.abs(drive.current).max() < ELECTRIC.current_limit
    fitted = times > 2.0
    gains = np.array([sine_amplitude(times[fitted], lengths[fitted, r], omegas[r]) / amplitude for r in range(n)])
    # the current loop's lag (500 Hz), the screw's Coulomb friction and the 1 ms step: a few %
    assert minus_3db(omegas, gains) == pytest.approx(omega_b, rel=0.1)


def test_servo_gains_by_hand():
    # zeta = 1/sqrt(2): omega_b = omega_n
    servo = LegServo.from_bandwidth(10.0, 1 / math.sqrt(2), 100.0, 20.0, 2.0)
    assert servo.gains == pytest.approx([100.0 * 100.0, 2 / math.sqrt(2) * 10.0 * 100.0 - 20.0, 0.0, 2.0], rel=1e-14)


# ---- hydraulic ------------------------------------------------------------------------------------


def free_oscillation(params, mass, dt, duration, v0=0.01, substeps=1):
    """A mass on one closed-valve cylinder at mid-stroke, pushed off balance with speed v0: its
    leg rates over time (legs are independent: every leg runs the same case)."""
    cylinder = HydraulicActuator(params, substeps=substeps)
    l_mid = params.retracted_length + params.stroke / 2
    cylinder.state[..., 0] = 0.0
    cylinder.state[..., 2] = 1e7
    cylinder.state[..., 1] = 1e7 * params.area_b / params.area_a  # the piston's forces balance
    length, rate = np.full((1, 6), l_mid), np.full((1, 6), v0)
    steps = int(round(duration / dt))
    rates = np.empty(steps)
    for j in range(steps):
        force = cylinder.step(0.0, length, rate, dt)
        rate = rate + force / mass * dt
        length = length + rate * dt
        rates[j] = rate[0, 0]
    return cylinder, l_mid, rates


def frictionless(params, **changes):
    return dataclasses.replace(params, coulomb_friction=0.0, viscous_friction=0.0, **changes)


def test_the_hydraulic_natural_frequency_of_a_free_oscillation():
    params = frictionless(HYDRAULIC)
    mass = 1600.0
    dt = 1e-5
    cylinder, l_mid, rates = free_oscillation(params, mass, dt, 0.3)
    # by hand: V_A = V_A0 + A_A s / 2, V_B = V_B0 + A_B s / 2, omega_h^2 = beta (A_A^2 / V_A + A_B^2 / V_B) / m
    A_A, A_B = math.pi * 0.08**2 / 4, math.pi * (0.08**2 - 0.05**2) / 4
    V_A, V_B = 0.0005 + A_A * 0.75, 0.0005 + A_B * 0.75
    omega_h = math.sqrt(1.4e9 * (A_A**2 / V_A + A_B**2 / V_B) / mass)
    assert cylinder.natural_frequency(mass, l_mid) == pytest.approx(omega_h, rel=1e-14)  # rounding
    # upward zero crossings of the rate, interpolated: the period
    up = np.nonzero((rates[:-1] < 0) & (rates[1:] >= 0))[0]
    crossings = (up + rates[up] / (rates[up] - rates[up + 1])) * dt
    period = np.mean(np.diff(crossings))
    assert len(crossings) >= 3
    # backward-Euler pressures at omega_h dt ~ 1e-3: the frequency within 1e-4; the brief's bound 2 %
    assert 2 * math.pi / period == pytest.approx(omega_h, rel=0.02)
    assert 2 * math.pi / period == pytest.approx(omega_h, rel=1e-3)


def test_the_oil_s_stiffness_is_stable_at_the_physics_step():
    """The pressures' backward-Euler step is stable at any step; the explicit coupling with the
    leg's motion is stable while omega_h dt < 2 (as a symplectic Euler step of a spring): at the
    environment's 1 ms the motion simulator's cylinder (omega_h ~ 90 rad/s) is far inside it, and
    a light mass with omega_h dt = 1.5 still oscillates without growing; at omega_h dt = 2.2 it grows."""
    params = frictionless(HYDRAULIC)
    dt = 1e-3
    _, _, rates = free_oscillation(params, 1600.0, dt, 5.0)
    assert np.all(np.isfinite(rates)) and np.abs(rates).max() <= 0.01 * (1 + 1e-9)
    stiffness = HydraulicActuator(params).natural_frequency(1.0, params.retracted_length + params.stroke / 2) ** 2
    for product, bounded in ((1.5, True), (2.2, False)):
        _, _, rates = free_oscillation(params, stiffness / (product / dt) ** 2, dt, 0.05)
        # the symplectic step keeps the amplitude within 1 / sqrt(1 - (omega dt / 2)^2) = 1.51 v0
        # at 1.5; at 2.2 it grows 2.4-fold a step
        assert bool(np.abs(rates).max() < 0.0152) == bounded


def test_an_open_valve_drives_the_leg_and_the_pressures_stay_physical():
    cylinder = HydraulicActuator(HYDRAULIC, substeps=4)
    length, rate, mass = np.full((1, 6), 2.96), np.zeros((1, 6)), 1600.0
    for _ in range(500):
        force = cylinder.step(np.array([[1.0, -1.0, 0.5, -0.5, 0.0, 1.0]]), length, rate, 1e-3)
        rate = rate + force / mass * 1e-3
        length = np.clip(length + rate * 1e-3, 2.26, 3.66)
    pressures = cylinder.state[0, :, 1:]
    assert np.all(pressures >= 0.0) and np.all(pressures <= HYDRAULIC.supply_pressure * 1.01)
    assert rate[0, 0] > 0.1 and rate[0, 1] < -0.1  # the spool's sign is the leg's direction
    assert cylinder.state[0, 0, 0] == pytest.approx(HYDRAULIC.valve_max_opening, rel=1e-9)  # spool settled


# ---- batches, copies, refusals --------------------------------------------------------------------


def run_all(n, rng_seed=7, steps=30):
    rng = np.random.default_rng(rng_seed)
    commands = rng.normal(size=(steps, 64, 6))
    rates = rng.normal(scale=0.2, size=(steps, 64, 6))
    lengths = 2.96 + rng.normal(scale=0.2, size=(steps, 64, 6))
    rows = slice(0, n) if n == 64 else slice(17, 18)
    electric, hydraulic = ElectricActuator(ELECTRIC, n=n), HydraulicActuator(HYDRAULIC, n=n, substeps=3)
    servo, lag = LegServo(1e5, 2e3, 10.0, 50.0, n=n), LagActuator(n=n, tau=0.02)
    out = []
    for j in range(steps):
        out.append(electric.step(50 * commands[j, rows], rates[j, rows], 1e-3).copy())
        out.append(hydraulic.step(commands[j, rows], lengths[j, rows], rates[j, rows], 1e-3).copy())
        out.append(servo.step(lengths[j, rows] + 0.01, lengths[j, rows], rates[j, rows], 1e-3).copy())
        out.append(lag.step(commands[j, rows], 1e-3).copy())
    return out


def test_a_row_s_numbers_do_not_depend_on_its_batch():
    alone, batch = run_all(1), run_all(64)
    for one, many in zip(alone, batch):
        assert np.array_equal(one[0], many[17])


def test_the_models_pickle_with_their_state():
    rng = np.random.default_rng(3)
    models = [ElectricActuator(ELECTRIC, n=2), HydraulicActuator(HYDRAULIC, n=2), LagActuator(n=2, tau=0.01)]
    steps = [
        lambda m, u: m.step(u, 0.1, 1e-3),
        lambda m, u: m.step(u, 2.9, 0.1, 1e-3),
        lambda m, u: m.step(u, 1e-3),
    ]
    for model, step in zip(models, steps):
        step(model, rng.normal(size=(2, 6)))
        copy = pickle.loads(pickle.dumps(model))
        u = rng.normal(size=(2, 6))
        assert np.array_equal(step(copy, u), step(model, u))
    servo = LegServo.from_bandwidth(30.0, 0.7, 2000.0, n=2)
    servo.step(0.01, 0.0, 0.0, 1e-3)
    copy = pickle.loads(pickle.dumps(servo))
    assert np.array_equal(copy.step(0.02, 0.0, 0.0, 1e-3), servo.step(0.02, 0.0, 0.0, 1e-3))


@pytest.mark.parametrize(
    "make, argument",
    [
        (lambda: LagActuator(n=0), "n"),
        (lambda: LagActuator(tau=-1.0), "tau"),
        (lambda: HydraulicActuator(HYDRAULIC, substeps=0), "substeps"),
        (lambda: LegServo.from_bandwidth(0.0, 0.7, 1.0), "bandwidth"),
        (lambda: LegServo.from_bandwidth(1.0, 0.7, -1.0), "mass"),
    ],
)
def test_bad_arguments_are_refused_by_name(make, argument):
    with pytest.raises(UsageError) as err:
        make()
    assert err.value.argument == argument


def test_bad_arrays_and_steps_are_refused_by_name():
    drive = ElectricActuator(ELECTRIC, n=2)
    with pytest.raises(ValueError, match="command: expected shape"):
        drive.step(np.zeros((3, 6)), 0.0, 1e-3)
    with pytest.raises(ValueError, match="dt: expected a finite step"):
        drive.step(np.zeros((2, 6)), 0.0, 0.0)
    with pytest.raises(TypeError, match="params: expected an ElectricParams"):
        ElectricActuator(HYDRAULIC)


def test_resets_set_the_rows_they_name():
    cylinder = HydraulicActuator(HYDRAULIC, n=3)
    pressure_force = cylinder.state[..., 1] * HYDRAULIC.area_a - cylinder.state[..., 2] * HYDRAULIC.area_b
    # at first no net pressure force: differences of ~5e4 N products, rounding
    assert np.abs(pressure_force).max() < 1e-9
    cylinder.reset(rows=[1], force=2e4)
    pressure_force = cylinder.state[..., 1] * HYDRAULIC.area_a - cylinder.state[..., 2] * HYDRAULIC.area_b
    assert pressure_force[:, 0] == pytest.approx([0.0, 2e4, 0.0], abs=1e-9)  # rounding, as above
    # a centred spool holds the pressures: over 1 ms only the piston's leakage moves them (~2 N)
    assert cylinder.step(0.0, 2.96, 0.0, 1e-3)[:, 0] == pytest.approx([0.0, 2e4, 0.0], abs=5.0)
    drive = ElectricActuator(ELECTRIC, n=2)
    drive.step(50.0, 0.0, 1e-3)
    drive.reset(rows=[0])
    assert np.array_equal(drive.current[0], np.zeros(6)) and np.all(drive.current[1] > 0)
    with pytest.raises(IndexError, match="rows: expected indices of a batch of 2"):
        drive.reset(rows=[2])
