"""``stewart-env record`` and ``identify --record``: a stand-in machine's log written and
identified from the file, exactly when the log is exact."""

import json

import numpy as np
import pytest
import yaml

import stewart_env as se
from stewart_env.cli import main
from stewart_env.identification import base as base_mod
from stewart_env.identification import log as logs
from stewart_env.identification import regressor as reg
from stewart_env.params import PlatformParams


def run(argv, capsys):
    try:
        code = main(argv)
    except SystemExit as stop:
        code = stop.code
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture(scope="module")
def excitation(tmp_path_factory):
    path = tmp_path_factory.mktemp("exc") / "exc.csv"
    assert main(["excitation", "--out", str(path), "--duration", "6", "--period", "3", "--random", "--seed", "3"]) == 0
    return path


def truth_beta(truth_file, dasgupta):
    truth = PlatformParams.from_dict(yaml.safe_load(truth_file.read_text()), "truth")
    model = se.make_dynamics("improved", dasgupta)
    base = base_mod.base_parameters(model)
    return base.of_theta(reg.theta_of(truth, model.flags)), base


def wls(report_dir):
    report = json.loads((report_dir / "report.json").read_text())
    return np.array([p["wls"] for p in report["base_parameters"]]), report


@pytest.mark.slow
def test_a_noise_free_log_gives_the_true_base_parameters(tmp_path, capsys, excitation, dasgupta):
    log, truth = tmp_path / "rec.csv", tmp_path / "truth.yaml"
    argv = ["record", "--trajectory", str(excitation), "--out", str(log), "--perturb", "0.3", "--seed", "5"]
    code, _, err = run([*argv, "--derivatives", "exact", "--truth", str(truth)], capsys)
    assert code == 0, err
    assert "twist" in logs.read(log).data and "pose" not in logs.read(log).data  # poses by forward kinematics
    code, text, err = run(
        ["identify", "--record", str(log), "--derivatives", "exact", "--out", str(tmp_path / "id")], capsys
    )
    assert code == 0, err
    beta, report = wls(tmp_path / "id")
    want, base = truth_beta(truth, dasgupta)
    assert report["rank"] == base.rank and report["clipped_samples"] == 0
    # exact data through the file (shortest round-tripping decimals) and forward kinematics to
    # 1e-14 m: rounding, amplified by the regressor's condition number (~1e5), is all that is left
    scale = np.maximum(np.abs(want), 1e-6 * np.abs(want).max())
    assert np.max(np.abs(beta - want) / scale) < 1e-8
    assert report["held_out_force_error"]["wls"] < 1e-8 * report["held_out_rms_force"]
    assert PlatformParams.from_dict(yaml.safe_load((tmp_path / "id" / "platform.yaml").read_text()), "x")


@pytest.mark.slow
def test_motor_currents_through_the_drive_give_the_true_base_parameters(tmp_path, capsys, excitation, dasgupta):
    drive = tmp_path / "d.yaml"
    drive.write_text("lead: 0.01\ntorque_constant: 0.5\nefficiency: 0.9\n")
    (tmp_path / "f").mkdir()
    (tmp_path / "c").mkdir()
    common = ["record", "--trajectory", str(excitation), "--derivatives", "exact", "--truth", str(tmp_path / "t.yaml")]
    assert run([*common, "--out", str(tmp_path / "f" / "rec.csv")], capsys)[0] == 0
    code, _, err = run([*common, "--out", str(tmp_path / "c" / "rec.csv"), "--currents", "--drive", str(drive)], capsys)
    assert code == 0, err
    forces = logs.read(tmp_path / "f" / "rec.csv").data["leg_force"]
    currents = logs.read(tmp_path / "c" / "rec.csv").data["motor_current"]
    k = 2 * np.pi / 0.01
    # f = eta k K_t i, each current one division away from its force: rounding
    assert np.allclose(currents * 0.9 * k * 0.5, forces, rtol=1e-14, atol=0)
    assert yaml.safe_load((tmp_path / "c" / "drive.yaml").read_text())["torque_constant"] == 0.5
    argv = [
        "identify",
        "--record",
        str(tmp_path / "c" / "rec.csv"),
        "--derivatives",
        "exact",
        "--out",
        str(tmp_path / "id"),
    ]
    code, _, err = run(argv, capsys)
    assert code == 0, err
    beta, report = wls(tmp_path / "id")
    assert report["settings"]["forces_from"] == "motor currents" and report["settings"]["drive"]["lead"] == 0.01
    want, _ = truth_beta(tmp_path / "t.yaml", dasgupta)
    # the drive's Coulomb friction and reflected mass, zero here, come out at ~1e-13: a zero is
    # judged against 1e-5 of the largest parameter
    scale = np.maximum(np.abs(want), 1e-5 * np.abs(want).max())
    assert np.max(np.abs(beta - want) / scale) < 1e-8  # as for forces: the currents' rounding adds 1e-16


def test_a_current_log_without_drive_constants_is_refused(tmp_path, capsys, dasgupta):
    n = 401
    time = np.arange(n) / 200.0
    lengths, _ = se.inverse_kinematics(dasgupta, dasgupta.home_position, np.eye(3))
    header = {"format": logs.FORMAT, "kind": "record", "platform": "dasgupta1998", "rate_hz": "200"}
    log = logs.Log(header, {"time": time, "leg_length": np.tile(lengths, (n, 1)), "motor_current": np.ones((n, 6))})
    path = logs.write(tmp_path / "rec.csv", log)
    code, _, err = run(["identify", "--record", str(path), "--out", str(tmp_path / "id")], capsys)
    assert code == 2
    assert f"{path}: motor currents need the drive constants: a drive.yaml beside the log" in err
    (tmp_path / "drive.yaml").write_text("lead: 0.01\npitch: 3\n")
    code, _, err = run(["identify", "--record", str(path), "--out", str(tmp_path / "id")], capsys)
    assert code == 2 and "drive.yaml: pitch: not a drive constant (the keys are lead, gear_ratio" in err
    assert not (tmp_path / "id").exists()


def test_a_motionless_log_names_the_base_parameters_it_cannot_identify(tmp_path, capsys, dasgupta):
    n = 801
    time = np.arange(n) / 200.0
    lengths, _ = se.inverse_kinematics(dasgupta, dasgupta.home_position, np.eye(3))
    header = {"format": logs.FORMAT, "kind": "record", "platform": "dasgupta1998", "rate_hz": "200"}
    log = logs.Log(header, {"time": time, "leg_length": np.tile(lengths, (n, 1)), "leg_force": np.full((n, 6), 200.0)})
    path = logs.write(tmp_path / "rec.csv", log)
    code, _, err = run(["identify", "--record", str(path), "--out", str(tmp_path / "id")], capsys)
    assert code == 2
    assert "the excitation does not excite" in err and "of 81 base parameters" in err
    assert "a longer record of the same motion does not help; a richer one does" in err
    assert not (tmp_path / "id").exists()


def test_a_bad_log_is_refused_by_identify_naming_file_row_and_column(tmp_path, capsys, excitation):
    log = tmp_path / "rec.csv"
    assert run(["record", "--trajectory", str(excitation), "--out", str(log)], capsys)[0] == 0
    lines = log.read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    lines[head + 50] = lines[head + 50].replace(lines[head + 50].split(",")[3], "nan", 1)
    log.write_text("\n".join(lines) + "\n")
    code, _, err = run(["identify", "--record", str(log), "--out", str(tmp_path / "id")], capsys)
    assert code == 2 and f"{log}: row 50, column leg_length_3: nan is not a finite number" in err
    assert not (tmp_path / "id").exists()


def test_record_refuses_a_log_that_is_not_an_excitation(tmp_path, capsys, excitation):
    log = tmp_path / "rec.csv"
    assert run(["record", "--trajectory", str(excitation), "--out", str(log)], capsys)[0] == 0
    code, _, err = run(["record", "--trajectory", str(log), "--out", str(tmp_path / "again.csv")], capsys)
    assert code == 2 and f"{log}: a record log, not an excitation" in err
    code, _, err = run(
        ["record", "--trajectory", str(excitation), "--out", str(tmp_path / "x.csv"), "--currents"], capsys
    )
    assert code == 2 and "--currents and --drive go together" in err


def test_jittered_stamps_are_resampled_onto_the_rate_grid(dasgupta):
    from stewart_env.identification import logged

    rng = np.random.default_rng(0)
    n, rate = 401, 200.0
    grid = np.arange(n) / rate
    stamps = grid + rng.uniform(-0.2, 0.2, n) / rate  # a fifth of a period of jitter
    stamps[0], stamps[-1] = grid[0], grid[-1]

    def pose(t):
        position = dasgupta.home_position + 0.01 * np.stack([np.sin(t), np.cos(t) - 1, 0.5 * np.sin(2 * t)], axis=1)
        return position, se.rpy_to_matrix(0.02 * np.stack([np.sin(t), np.sin(3 * t), 0 * t], axis=1))

    t, R = pose(stamps)
    forces = np.stack([100 + np.sin(stamps + i) for i in range(6)], axis=1)
    header = {"format": logs.FORMAT, "kind": "record", "platform": "dasgupta1998", "rate_hz": "200"}
    lengths, _ = se.inverse_kinematics(dasgupta, t, R)
    log = logs.Log(header, {"time": stamps, "leg_length": lengths, "leg_force": forces})
    time, t_grid, R_grid, F_grid, resampled = logged._resampled(log, t, R, forces)
    assert resampled is not None and np.abs(time - grid).max() < 1e-15  # k / rate against k * (1 / rate)
    want_t, want_R = pose(grid)
    # cubic splines of a motion smooth on the scale of the samples: errors of order (dt)^4 f''''
    assert np.abs(t_grid - want_t).max() < 1e-9
    assert np.abs(R_grid - want_R).max() < 1e-9
    # linear interpolation of the forces: h^2 / 8 of their second derivative (1 N/s^2) over stamps
    # up to h = 1.4 periods apart, 6e-6 N
    assert np.abs(F_grid - np.stack([100 + np.sin(grid + i) for i in range(6)], axis=1)).max() < 1e-5


def test_without_a_drive_file_the_platform_config_s_electric_drive_is_used(tmp_path, simulator):
    from stewart_env.identification import logged

    log = logs.Log({"kind": "record"}, {}, str(tmp_path / "rec.csv"))
    drive = logged.drive_for(log, None, simulator)  # motion_simulator's actuators.electric
    assert (drive.lead, drive.torque_constant, drive.efficiency) == (0.025, 1.95, 0.9)
    (tmp_path / "drive.yaml").write_text("lead: 0.01\n")
    assert logged.drive_for(log, None, simulator).lead == 0.01  # the file beside the log first


def test_identify_passes_forces_and_prior_weight_to_the_log_settings(tmp_path, capsys, dasgupta, monkeypatch):
    from stewart_env.identification import logged

    n = 401
    lengths, _ = se.inverse_kinematics(dasgupta, dasgupta.home_position, np.eye(3))
    header = {"format": logs.FORMAT, "kind": "record", "platform": "dasgupta1998", "rate_hz": "200"}
    data = {"time": np.arange(n) / 200.0, "leg_length": np.tile(lengths, (n, 1)), "leg_force": np.ones((n, 6))}
    path = logs.write(tmp_path / "rec.csv", logs.Log(header, data))
    seen = []

    def identify_log(record, nominal, settings):
        seen.append(settings)
        raise base_mod.IdentificationError("stopped here")

    monkeypatch.setattr(logged, "identify_log", identify_log)
    argv = ["identify", "--record", str(path), "--out", str(tmp_path / "id")]
    assert run([*argv, "--forces", "held", "--prior-weight", "0.01"], capsys)[0] == 2
    assert (seen[-1].forces, seen[-1].prior_weight) == ("held", 0.01)
    assert run(argv, capsys)[0] == 2
    assert (seen[-1].forces, seen[-1].prior_weight) == ("sampled", logged.est.PRIOR_WEIGHT)
    code, _, err = run([*argv, "--prior-weight", "-1"], capsys)
    assert code == 2 and "--prior-weight" in err and len(seen) == 2
    code, _, err = run([*argv, "--forces", "late"], capsys)
    assert code == 2 and "--forces" in err and "held" in err
