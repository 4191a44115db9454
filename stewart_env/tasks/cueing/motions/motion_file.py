"""The motion file: a vehicle motion recorded by a user (a simulator's log, an IMU) as CSV.

The format (docs/guides/motion-format.md): optional comment lines ``# key: value`` first
(``format``, ``name``, ``source``), then the row of column names, then the row of their units,
then one row per sample::

    # format: stewart-env motion 1
    # name: braking
    time_s,f_x,f_y,f_z,omega_x,omega_y,omega_z
    s,m/s^2,m/s^2,m/s^2,rad/s,rad/s,rad/s
    0.0,0.0,0.0,9.80665,0.0,0.0,0.0
    ...

The channels are the specific force ``f`` (m/s², ``f = a - g``: ``(0, 0, +9.81)`` at rest) and
the angular velocity ``omega`` (rad/s), at the head in the head frame {H} (x forward, y left,
z up).  The columns come in any order, each exactly once.  The time stamps increase with a
uniform step (within :data:`STEP_TOLERANCE` of the median step).

:func:`read_motion` refuses, with a :class:`MotionFileError` naming the file, the row (the
file's line, from 1, as an editor counts it) and the column: a missing or unknown column, a unit
other than the column's, a cell that is not a finite number, a time stamp that does not increase,
a gap or an uneven step, and implausible values for the units (a specific force whose mean
magnitude is far from 1 g, as in a file in g; ``f_z`` negative on average, as in a frame with z
down; an angular velocity beyond :data:`MAX_ANGULAR_VELOCITY`, as in degrees per second).  Files
are read through :func:`stewart_env.files.read_regular` (regular files of at most
:data:`MAX_MOTION_BYTES`); :func:`write_motion` writes the whole file or nothing
(:func:`stewart_env.files.publish`).
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from stewart_env import files
from stewart_env.tasks.cueing.motion import STANDARD_GRAVITY, VehicleMotion

__all__ = [
    "COLUMNS",
    "FORMAT",
    "MAX_ANGULAR_VELOCITY",
    "MAX_MOTION_BYTES",
    "STEP_TOLERANCE",
    "UNITS",
    "MotionFileError",
    "read_motion",
    "write_motion",
]

#: The format's name and version, the first comment line of a file written.
FORMAT = "stewart-env motion 1"
#: The columns, in the order written.
COLUMNS = ("time_s", "f_x", "f_y", "f_z", "omega_x", "omega_y", "omega_z")
#: Each column's unit as written, and the spellings read as the same unit.
UNITS = {"time_s": "s", **{c: "m/s^2" for c in COLUMNS[1:4]}, **{c: "rad/s" for c in COLUMNS[4:]}}
_SPELLINGS = {"s": {"s"}, "m/s^2": {"m/s^2", "m/s2", "m/s²", "m s^-2", "m*s^-2"}, "rad/s": {"rad/s", "rad s^-1"}}
#: The largest file read, bytes: an hour at 1 kHz is about 250 MB of CSV.
MAX_MOTION_BYTES = 1 << 28
#: The largest deviation of a time step from the median step, as a fraction of it: a log with
#: jitter or lost samples is to be resampled first (the task steps at a fixed rate).
STEP_TOLERANCE = 0.05
#: The bounds of the mean magnitude of the specific force, in g0: a vehicle on earth averages near
#: 1 g; a file in g averages near 1 m/s².
MEAN_FORCE_BOUNDS = (0.5, 2.0)
#: The largest angular velocity read, rad/s (573 deg/s, beyond an aerobatic aircraft's roll rate):
#: more is a file in degrees per second.
MAX_ANGULAR_VELOCITY = 10.0


class MotionFileError(files.FileError):
    """A motion file that does not fit the format: the message names the file, the row (the
    file's line, from 1) and the column where there is one.

    Args:
        path: the file.
        problem: what is wrong.
        row: the file's line, from 1, or None.
        column: the column's name, or None.

    Attributes:
        row: the line, or None.
        column: the column's name, or None.
    """

    def __init__(self, path: str | Path, problem: str, row: int | None = None, column: str | None = None):
        super().__init__(path, problem)
        self.row, self.column = row, column

    def __str__(self) -> str:
        where = [part for part in (self.row and f"row {self.row}", self.column and f"column {self.column}") if part]
        return f"{self.path}: {', '.join(where) + ': ' if where else ''}{self.problem}"


def _header_and_table(path: str, text: str) -> tuple[dict[str, str], list[str], np.ndarray, int]:
    """The comment entries, the column names and the table; the line of the first sample."""
    lines = text.split("\n")
    while lines and not lines[-1].strip():  # blank lines at the end
        lines.pop()
    header: dict[str, str] = {}
    k = 0
    while k < len(lines) and (lines[k].startswith("#") or not lines[k].strip()):
        key, sep, value = lines[k].lstrip("#").partition(":")
        if sep:
            header[key.strip()] = value.strip()
        k += 1
    if k >= len(lines):
        raise MotionFileError(path, f"no column names (the format's columns: {','.join(COLUMNS)})", row=k + 1)
    names = [name.strip() for name in lines[k].rstrip("\r").split(",")]
    seen: set[str] = set()
    for name in names:
        if name not in UNITS:
            raise MotionFileError(path, f"unknown column (the format's columns: {','.join(COLUMNS)})", k + 1, name)
        if name in seen:
            raise MotionFileError(path, "the column appears twice", k + 1, name)
        seen.add(name)
    for name in COLUMNS:
        if name not in seen:
            raise MotionFileError(path, "missing (every column of the format is needed)", k + 1, name)
    if k + 1 >= len(lines) or not lines[k + 1].strip():
        raise MotionFileError(path, "no units row after the column names", k + 2)
    units = [unit.strip() for unit in lines[k + 1].rstrip("\r").split(",")]
    if len(units) != len(names):
        raise MotionFileError(path, f"{len(units)} units for {len(names)} columns", k + 2)
    for name, unit in zip(names, units, strict=True):
        if unit not in _SPELLINGS[UNITS[name]]:
            raise MotionFileError(path, f"the unit is {unit!r}; the format's is {UNITS[name]!r}", k + 2, name)
    first = k + 3
    rows = lines[k + 2 :]
    table = np.empty((len(rows), len(names)))
    for r, line in enumerate(rows):
        cells = line.rstrip("\r").split(",")
        if len(cells) != len(names):
            raise MotionFileError(path, f"{len(cells)} values for {len(names)} columns", first + r)
        for c, cell in enumerate(cells):
            try:
                value = float(cell)
            except ValueError:
                raise MotionFileError(path, f"{cell.strip()[:40]!r} is not a number", first + r, names[c]) from None
            if not np.isfinite(value):
                raise MotionFileError(path, f"{cell.strip()!r} is not a finite number", first + r, names[c])
            table[r, c] = value
    return header, names, table, first


def _check_time(path: str, time: np.ndarray, first: int) -> float:
    """The step of uniformly increasing time stamps; the first fault otherwise."""
    if len(time) < 2:
        raise MotionFileError(path, f"{len(time)} samples; a motion needs at least 2", first + len(time))
    step = np.diff(time)
    back = np.flatnonzero(step <= 0.0)
    if back.size:
        k = int(back[0]) + 1
        what = "repeats" if step[k - 1] == 0.0 else "is before"
        raise MotionFileError(
            path,
            f"the time stamp {float(time[k])!r} s {what} the previous row's {float(time[k - 1])!r} s",
            first + k,
            "time_s",
        )
    dt = float(np.median(step))
    uneven = np.flatnonzero(np.abs(step - dt) > STEP_TOLERANCE * dt)
    if uneven.size:
        k = int(uneven[0]) + 1
        what = "a gap" if step[k - 1] > dt else "an uneven step"
        raise MotionFileError(
            path,
            f"{what}: {step[k - 1]:.6g} s after the previous row, the file's step being {dt:.6g} s "
            f"(steps may differ by {STEP_TOLERANCE:.0%}; resample a log with jitter or lost samples)",
            first + k,
            "time_s",
        )
    return (float(time[-1]) - float(time[0])) / (len(time) - 1)


def _check_plausible(path: str, force: np.ndarray, omega: np.ndarray, first: int) -> None:
    """The values' orders of magnitude against the units and the frame."""
    magnitude = np.linalg.norm(force, axis=1)
    low, high = (bound * STANDARD_GRAVITY for bound in MEAN_FORCE_BOUNDS)
    mean = float(magnitude.mean())
    if not low <= mean <= high:
        k = int(np.argmax((magnitude < low) | (magnitude > high)))
        raise MotionFileError(
            path,
            f"the specific force's mean magnitude is {mean:.4g} m/s², not near g0 = {STANDARD_GRAVITY} m/s² "
            f"(a vehicle on earth; values in g rather than m/s^2?)",
            first + k,
            "f_z",
        )
    if float(force[:, 2].mean()) < 0.0:
        k = int(np.argmax(force[:, 2] < 0.0))
        raise MotionFileError(
            path,
            "f_z is negative on average: the head frame's z points up (f = (0, 0, +9.81) at rest)",
            first + k,
            "f_z",
        )
    fast = np.argwhere(np.abs(omega) > MAX_ANGULAR_VELOCITY)
    if fast.size:
        k, c = (int(i) for i in fast[0])
        raise MotionFileError(
            path,
            f"{omega[k, c]:.6g} rad/s is beyond {MAX_ANGULAR_VELOCITY:g} rad/s (values in deg/s rather than rad/s?)",
            first + k,
            COLUMNS[4 + c],
        )


def read_motion(path: str | Path, name: str | None = None) -> VehicleMotion:
    """Read and check a motion file (see the module's docstring for the format and the checks).

    Args:
        path: the CSV file.
        name: the motion's name; by default the header's ``name`` entry, else the file's stem.

    Returns:
        The motion, its ``source`` the path.

    Raises:
        MotionFileError: the first fault, naming the file, the row and the column.
        stewart_env.files.FileError: the file cannot be read, is not a regular file or is larger
            than :data:`MAX_MOTION_BYTES`.
    """
    source = str(path)
    raw = files.read_regular(source, MAX_MOTION_BYTES, "motion file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as err:
        raise MotionFileError(source, f"not UTF-8 text (invalid byte at offset {err.start})") from None
    header, names, table, first = _header_and_table(source, text)
    index = {n: i for i, n in enumerate(names)}
    time = table[:, index["time_s"]]
    dt = _check_time(source, time, first)
    force = table[:, [index[c] for c in COLUMNS[1:4]]]
    omega = table[:, [index[c] for c in COLUMNS[4:]]]
    _check_plausible(source, force, omega, first)
    meta = {key: value for key, value in header.items() if key in ("format", "name", "source")}
    return VehicleMotion(name or header.get("name") or Path(source).stem, dt, force, omega, source=source, meta=meta)


def write_motion(motion: VehicleMotion, path: str | Path) -> Path:
    """Write ``motion`` as a motion file, whole or not at all: every number as the shortest text
    that reads back to the same float, so the same motion always gives the same bytes.

    Args:
        motion: the motion.
        path: the CSV file, replaced whole or left as it was.

    Returns:
        The path written.

    Raises:
        stewart_env.files.WriteError: the file cannot be written (the message names it).
    """
    path = Path(path)
    out = io.StringIO()
    out.write(f"# format: {FORMAT}\n# name: {' '.join(motion.name.split())}\n")
    if motion.source:
        out.write(f"# source: {' '.join(motion.source.split())}\n")
    out.write(",".join(COLUMNS) + "\n" + ",".join(UNITS[c] for c in COLUMNS) + "\n")
    table = np.column_stack([motion.time, motion.specific_force, motion.angular_velocity])
    for row in table:
        out.write(",".join(repr(float(x)) for x in row) + "\n")
    files.publish(path, out.getvalue())
    return path
