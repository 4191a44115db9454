"""``stewart-env excitation``: the excitation as set points in the drive-log format."""

import json

import numpy as np
import pytest

import stewart_env as se
from stewart_env.cli import main
from stewart_env.identification import excitation as exc
from stewart_env.identification import log as logs
from stewart_env.identification import recording


def run(argv, capsys):
    try:
        code = main(argv)
    except SystemExit as stop:
        code = stop.code
    out = capsys.readouterr()
    return code, out.out, out.err


def test_the_set_points_are_the_series_sampled_at_the_rate(tmp_path, capsys, dasgupta):
    out = tmp_path / "exc.csv"
    code, text, err = run(
        ["excitation", "--out", str(out), "--rate", "100", "--duration", "4", "--period", "2", "--random"], capsys
    )
    assert code == 0, err
    assert "401 set points over 4 s at 100 Hz" in text
    log = logs.read(out, dasgupta)
    assert log.kind == "excitation" and log.header["platform"] == "dasgupta1998" and log.rate == 100.0
    assert np.array_equal(log.time, np.arange(401) / 100.0)
    series = recording.series_of(log)
    q, qd, qdd = series.sample(log.time)
    assert np.array_equal(log.data["pose"], q)  # the same compiled series, written exactly
    lengths, _ = se.inverse_kinematics(dasgupta, q[:, :3], se.rpy_to_matrix(q[:, 3:]))
    assert np.array_equal(log.data["leg_length"], lengths)
    model = se.make_dynamics("improved", dasgupta)
    assert np.all(exc.margins(series, model, log.time) >= 0)  # inside every limit at every sample
    assert json.loads(log.header["series"])["wf"] == pytest.approx(np.pi)  # period 2 s


def test_too_fast_set_points_and_a_rate_off_the_plant_steps_are_refused(tmp_path, capsys):
    out = tmp_path / "exc.csv"
    base = ["excitation", "--out", str(out), "--duration", "4", "--period", "2", "--random"]
    code, _, err = run([*base, "--max-leg-speed", "0.01"], capsys)
    assert code == 2
    assert "stewart-env excitation: error: --max-leg-speed: the set points' legs reach" in err
    assert "above 0.01 m/s (--max-leg-speed); a longer --period slows them" in err
    code, _, err = run([*base, "--rate", "300"], capsys)
    assert code == 2 and "--rate: 300 Hz: its period must be a whole number of the plant's 0.001 s steps" in err
    assert not out.exists()


def test_an_hdf5_excitation_reads_back(tmp_path, capsys, dasgupta):
    pytest.importorskip("h5py", reason="HDF5 logs need the extra logs (h5py)")
    code, _, err = run(
        ["excitation", "--out", str(tmp_path / "e.h5"), "--duration", "2", "--period", "2", "--random"], capsys
    )
    assert code == 0, err
    assert logs.read(tmp_path / "e.h5", dasgupta).time.size == 401
