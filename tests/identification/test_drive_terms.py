"""The legs' friction and the drive's reflected mass among the identified parameters: their
regressor columns against the leg motion they stand for, their round trip through a recorded log
of motor currents, and where the identified values are written."""

import json

import numpy as np
import pytest
import yaml

import stewart_env as se
from stewart_env.actuators.transmission import BallScrew
from stewart_env.identification import base as base_mod
from stewart_env.identification import excitation as exc
from stewart_env.identification import log as logs
from stewart_env.identification import logged, recording
from stewart_env.identification import regressor as reg
from stewart_env.kinematics import inverse_kinematics, jacobian
from stewart_env.params import PlatformParams


def leg_rows(params, t, R, column):
    """J^-T of a wrench column (N, 6): the leg forces it stands for."""
    return np.linalg.solve(np.swapaxes(jacobian(params, t, R), 1, 2), column[..., None])[..., 0]


def test_the_drive_columns_are_the_leg_motion_they_stand_for(simulator):
    model = se.make_dynamics("improved", simulator)
    series = exc.random_excitation(simulator, model, np.random.default_rng(1), period=6.0, harmonics=3)
    times = np.linspace(0.5, 5.5, 40)
    h = 1e-4
    q, qd, qdd = series.sample(np.concatenate([times - h, times, times + h]))
    t, R, v, w, a, alpha = exc.task_states(q, qd, qdd)
    L, _ = inverse_kinematics(simulator, t, R)
    n = times.size
    lddot = (L[:n] - 2 * L[n : 2 * n] + L[2 * n :]) / h**2
    mid = slice(n, 2 * n)
    Y = reg.regressor_matrix(model, t[mid], R[mid], v[mid], w[mid], a[mid], alpha[mid])
    ldot = np.einsum("nij,nj->ni", jacobian(simulator, t[mid], R[mid]), np.concatenate([v[mid], w[mid]], 1))
    assert reg.friction_speed(simulator) == 0.005  # motion_simulator's actuators.electric
    cp, fc, mr = (
        leg_rows(simulator, t[mid], R[mid], Y[..., k]) for k in (reg.OFF_DAMPING + 1, reg.OFF_DRIVE, reg.OFF_DRIVE + 1)
    )
    assert np.max(np.abs(cp - ldot)) < 1e-12  # the same products, rounding apart
    assert np.max(np.abs(fc - np.tanh(ldot / 0.005))) < 1e-12
    # central second difference at h = 1e-4 s: truncation ~h^2 L'''' and rounding ~1e-16 L / h^2
    assert np.max(np.abs(mr - lddot)) < 1e-5 * np.abs(lddot).max()
    other = reg.regressor_matrix(model, t[mid], R[mid], v[mid], w[mid], a[mid], alpha[mid], speed_scale=0.05)
    assert np.max(np.abs(leg_rows(simulator, t[mid], R[mid], other[..., reg.OFF_DRIVE]) - np.tanh(ldot / 0.05))) < 1e-12
    base = base_mod.base_parameters(model)
    assert {"drive.coulomb_friction", "drive.reflected_mass"} <= set(base.names)  # each identifiable alone


def test_theta_holds_the_drive_only_when_the_forces_are_the_drives(simulator, dasgupta):
    drive = BallScrew.from_params(simulator.actuators.electric)
    theta = reg.theta_of(simulator, drive=True)
    e = simulator.actuators.electric
    assert theta[reg.OFF_DRIVE] == e.coulomb_friction == 300.0
    assert theta[reg.OFF_DRIVE + 1] == drive.reflected_mass
    assert theta[reg.OFF_DAMPING + 1] == simulator.damping.prismatic + e.viscous_friction
    assert np.all(reg.theta_of(simulator)[reg.OFF_DRIVE :] == 0.0)
    assert np.all(reg.theta_of(dasgupta, drive=True)[reg.OFF_DRIVE :] == 0.0)  # no electric section


def test_the_identified_drive_goes_to_actuators_electric(simulator, dasgupta):
    model = se.make_dynamics("improved", simulator)
    theta = reg.theta_of(simulator, model.flags, drive=True)
    theta[reg.OFF_DRIVE] = 123.0
    theta[reg.OFF_DRIVE + 1] = 500.0
    theta[reg.OFF_DAMPING + 1] = simulator.damping.prismatic + 40.0
    out = base_mod.params_from_theta(theta, simulator, model.flags, drive=True)
    ratio = BallScrew.from_params(simulator.actuators.electric).ratio
    assert out.actuators.electric.coulomb_friction == 123.0
    assert out.actuators.electric.rotor_inertia == pytest.approx(500.0 / ratio**2, rel=1e-15)  # one division
    assert out.actuators.electric.viscous_friction == pytest.approx(40.0, rel=1e-12)  # a difference of sums
    assert out.damping.prismatic == simulator.damping.prismatic
    # load cells (no drive) or no electric section: the platform keeps its drive, C_p takes the viscous
    plain = base_mod.params_from_theta(theta, simulator, model.flags)
    assert plain.actuators == simulator.actuators and plain.damping.prismatic == theta[reg.OFF_DAMPING + 1]
    theta[reg.OFF_DRIVE] = -1.0
    with pytest.raises(base_mod.IdentificationError, match="Coulomb friction -1 N"):
        base_mod.params_from_theta(theta, simulator, model.flags, drive=True)


@pytest.mark.slow
def test_a_noise_free_log_of_motor_currents_gives_friction_and_reflected_mass_exactly(tmp_path, simulator):
    excitation, _ = recording.excitation_log(simulator, "motion_simulator", duration=8, period=6, random=True, seed=3)
    drive = BallScrew.from_params(simulator.actuators.electric)
    settings = recording.RecordSettings(plant="improved", perturb=0.3, seed=5, drive=drive, exact=True)
    record, truth = recording.record_log(excitation, simulator, settings)
    logs.write(tmp_path / "rec.csv", record, simulator)
    result = logged.identify_log(
        logs.read(tmp_path / "rec.csv", simulator), simulator, logged.LogSettings(derivatives="exact")
    )
    model = se.make_dynamics("improved", simulator)
    base = base_mod.base_parameters(model)
    want = base.of_theta(reg.theta_of(truth, model.flags, drive=True))
    report = result["report"]
    beta = np.array([p["wls"] for p in report["base_parameters"]])
    names = [p["name"] for p in report["base_parameters"]]
    # the drive's terms are in the forces: 300 N of Coulomb friction, ~950 kg of reflected mass
    assert want[names.index("drive.coulomb_friction")] == 300.0
    assert want[names.index("drive.reflected_mass")] == pytest.approx(947.48, rel=1e-5)
    # exact data through the file and forward kinematics to 1e-14 m: rounding, amplified by the
    # regressor's condition number, is all that is left
    scale = np.maximum(np.abs(want), 1e-6 * np.abs(want).max())
    assert np.max(np.abs(beta - want) / scale) < 1e-8
    assert report["leg_friction_and_drive"]["written_to"] == "actuators.electric"
    logged.write(result, tmp_path / "id")
    written = PlatformParams.from_dict(yaml.safe_load((tmp_path / "id" / "platform.yaml").read_text()), "x")
    # the consistent fit: exact data, so its constraint and weak prior leave the drive near the truth
    assert written.actuators.electric.coulomb_friction == pytest.approx(300.0, rel=1e-3)
    assert written.actuators.electric.rotor_inertia == pytest.approx(drive.rotor_inertia, rel=1e-3)
    assert "Coulomb" in (tmp_path / "id" / "report.md").read_text()
    assert json.loads((tmp_path / "id" / "report.json").read_text())["n_theta"] == reg.N_THETA
