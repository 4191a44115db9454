"""The drive-log format: the schema, the CSV and HDF5 round trips, and every bad log refused with
its file, row and column (stewart_env.identification.log, docs/guides/log-format.md)."""

from pathlib import Path

import numpy as np
import pytest

from stewart_env.identification import log as logs
from stewart_env.identification.log import LogError


@pytest.fixture
def record(dasgupta):
    """A small record log: 2 s at 200 Hz of leg lengths around the home pose and leg forces."""
    n = 401
    time = np.arange(n) / 200.0
    from stewart_env.kinematics import inverse_kinematics

    home, _ = inverse_kinematics(dasgupta, dasgupta.home_position, np.eye(3))
    lengths = home + 0.01 * np.sin(time)[:, None] * np.arange(1, 7)[None, :] / 6
    forces = 100 + 10 * np.cos(time)[:, None] * np.ones(6)
    header = {"format": logs.FORMAT, "kind": "record", "platform": "dasgupta1998", "rate_hz": "200"}
    return logs.Log(header, {"time": time, "leg_length": lengths, "leg_force": forces})


def written(tmp_path: Path, record, name="log.csv") -> Path:
    return logs.write(tmp_path / name, record)


def edit(path: Path, row: int, column: str, text: str) -> None:
    """Replace one cell of a CSV log (row counted from 1 after the column names)."""
    lines = path.read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    names = lines[head].split(",")
    cells = lines[head + row].split(",")
    cells[names.index(column)] = text
    lines[head + row] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")


def test_a_csv_log_reads_back_bit_for_bit(tmp_path, record, dasgupta):
    back = logs.read(written(tmp_path, record), dasgupta)
    assert back.kind == "record" and back.rate == 200.0
    for group, values in record.data.items():
        assert np.array_equal(back.data[group], values)  # repr of a float reads back to the same float
    assert back.columns()[:2] == ["time", "leg_length_1"] and back.columns()[-1] == "leg_force_6"


def test_an_hdf5_log_reads_back_bit_for_bit(tmp_path, record, dasgupta):
    pytest.importorskip("h5py", reason="HDF5 logs need the extra logs (h5py)")
    back = logs.read(written(tmp_path, record, "log.h5"), dasgupta)
    assert back.header["platform"] == "dasgupta1998"
    for group, values in record.data.items():
        assert np.array_equal(back.data[group], values)


def test_the_schema_page_lists_every_column_with_its_unit():
    text = logs.schema_markdown()
    for columns in logs.GROUPS.values():
        for c in columns:
            assert f"| `{c.name}` | {c.unit} |" in text
    page = (Path(__file__).parents[2] / "docs" / "guides" / "log-format.md").read_text()
    assert "<!-- generated: log format -->" in page


@pytest.mark.parametrize(
    ("row", "column", "text", "message"),
    [
        (5, "leg_force_3", "nan", "row 5, column leg_force_3: nan is not a finite number"),
        (7, "leg_length_2", "inf", "row 7, column leg_length_2: inf is not a finite number"),
        (9, "leg_length_1", "1.2.3", "row 9, column leg_length_1: '1.2.3' is not a number"),
        (4, "time", "0.01", "row 4, column time: time stamp 0.01 s repeats row 3's 0.01 s"),
        (4, "time", "0.005", "row 4, column time: time stamp 0.005 s is before row 3's 0.01 s"),
        (4, "leg_length_4", "1261.3", "row 4, column leg_length_4: leg length 1261.3 m is outside the stroke"),
    ],
)
def test_a_bad_cell_is_named_by_file_row_and_column(tmp_path, record, dasgupta, row, column, text, message):
    path = written(tmp_path, record)
    edit(path, row, column, text)
    with pytest.raises(LogError) as err:
        logs.read(path, dasgupta)
    assert str(err.value).startswith(f"{path}: {message}")


def test_millimetres_are_suspected(tmp_path, record, dasgupta):
    path = written(tmp_path, record)
    edit(path, 2, "leg_length_1", "1261.3")
    with pytest.raises(LogError, match=r"in mm or cm\? the log's unit is m"):
        logs.read(path, dasgupta)


def test_a_gap_beyond_the_bound_is_refused(tmp_path, record):
    time = record.data["time"].copy()
    time[200:] += 3 / 200  # three samples lost: a gap of four periods
    gappy = logs.Log(record.header, {**record.data, "time": time})
    with pytest.raises(
        LogError, match=r"row 201, column time: a gap of 0.02 s after row 200, longer than the bound 0.0125 s"
    ):
        logs.check(gappy, path="g.csv")
    time[200:] -= 2 / 200  # one lost: two periods, inside the bound
    logs.check(logs.Log(record.header, {**record.data, "time": time}))


def test_too_short_a_record_is_refused(tmp_path, record):
    with pytest.raises(LogError, match=r"401 samples over 2 s; at least 5 s are needed"):
        logs.read(written(tmp_path, record), min_duration=5.0)


def test_a_missing_or_extra_column_is_named(tmp_path, record):
    path = written(tmp_path, record)
    text = path.read_text()
    path.write_text(text.replace(",leg_length_6,", ",leg_length_7,"))
    with pytest.raises(LogError, match=r"column leg_length_7: not in the schema"):
        logs.read(path)
    lines = text.splitlines()
    head = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    trimmed = [",".join(line.split(",")[:-1]) if i >= head else line for i, line in enumerate(lines)]
    path.write_text("\n".join(trimmed) + "\n")
    with pytest.raises(LogError, match=r"column leg_force_6: missing \(the group leg_force has"):
        logs.read(path)
    path.write_text(text.replace("leg_force_", "motor_current_", 1))
    with pytest.raises(LogError, match=r"column leg_force_1: missing"):
        logs.read(path)


def test_a_row_of_the_wrong_width_and_a_bad_header_are_named(tmp_path, record):
    path = written(tmp_path, record)
    text = path.read_text()
    lines = text.splitlines()
    lines[7] += ",1.0"  # the header's four lines, the names, then row 3
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(LogError, match=r"row 3: 14 values for 13 columns"):
        logs.read(path)
    path.write_text(text.replace("# rate_hz: 200\n", ""))
    with pytest.raises(LogError, match=r"the header has no 'rate_hz' entry"):
        logs.read(path)
    path.write_text(text.replace("kind: record", "kind: diary"))
    with pytest.raises(LogError, match=r"kind 'diary' is not one of excitation, record"):
        logs.read(path)


def test_the_writer_refuses_a_bad_log_and_writes_nothing(tmp_path, record):
    forces = record.data["leg_force"].copy()
    forces[10, 2] = np.nan
    with pytest.raises(LogError, match=r"row 11, column leg_force_3: nan is not a finite number"):
        logs.write(tmp_path / "bad.csv", logs.Log(record.header, {**record.data, "leg_force": forces}))
    assert list(tmp_path.iterdir()) == []


def test_clipped_samples_are_dropped_with_a_warning_that_counts_them(record):
    forces = record.data["leg_force"].copy()
    forces[[3, 4, 9], 1] = 1500.0  # the drive's limit
    forces[20, 5] = -1500.0
    with pytest.warns(logs.ClippedSamples, match=r"f.csv: 4 of 401 samples have a leg force at the drive's limit"):
        keep = logs.drop_clipped("f.csv", forces, (-1500.0, 1500.0))
    assert np.flatnonzero(~keep).tolist() == [3, 4, 9, 20]
