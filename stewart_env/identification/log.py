"""The log format: time-stamped leg lengths, poses and leg forces or motor currents, as a
platform's drives record them, in CSV (or HDF5, the extra ``logs``).

A log is one of two kinds (:data:`KINDS`): an ``excitation``, the set points ``stewart-env
excitation`` writes for a machine to follow, or a ``record``, what a machine's drives logged
while following them (``stewart-env record`` writes one from a stand-in plant; ``stewart-env
identify --record`` reads one).  Its columns come in groups (:data:`GROUPS`), each whole or
absent; every number is in SI units, angles in radians, and the pose and its derivatives are of
the platform frame {P} in the base frame {B}.  A short header (:data:`HEADER`) says what the log
is, for which platform and at which rate.

CSV: the header's entries first, one a line as ``# key: value``, then one line of column names,
then one line per sample.  HDF5: the header's entries as the file's attributes, one
one-dimensional float64 dataset per column at the file's root.

:func:`read` checks a log against the schema and names the file, row and column of the first
fault: a column missing or not in the schema, a number that is not one or is not finite, time
stamps that do not increase or leave a gap longer than :data:`MAX_GAP_PERIODS` periods of the
header's rate, a record shorter than asked, leg lengths outside the platform's stroke.
:func:`write` runs the same checks before it writes, and writes the file whole or not at all.
:func:`clipped` finds the samples at the drive's force limit, which :func:`drop_clipped` drops
with a warning that counts them.
"""

from __future__ import annotations

import io
import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stewart_env import files
from stewart_env.errors import UsageError
from stewart_env.params import PlatformParams

__all__ = [
    "FORMAT",
    "GROUPS",
    "HEADER",
    "KINDS",
    "ClippedSamples",
    "Column",
    "Log",
    "LogError",
    "clipped",
    "drop_clipped",
    "read",
    "schema_markdown",
    "write",
]

#: The first header entry of every log: the format and its version.
FORMAT = "stewart-env log 1"
#: The longest gap between two time stamps, in periods of the header's rate: a drive that skips
#: a sample or two is jitter; more is a lost stretch the derivatives' filter would run across.
MAX_GAP_PERIODS = 2.5
#: Largest log read, bytes: an hour at 1 kHz of the widest record is about 200 MB of CSV.
MAX_LOG_BYTES = 1 << 30
#: Suffixes of the HDF5 files.
HDF5_SUFFIXES = (".h5", ".hdf5")
#: Relative distance to the drive's force limit within which a force sample counts as clipped.
CLIP_TOLERANCE = 1e-6


@dataclass(frozen=True)
class Column:
    """One column of the schema: its name, unit and meaning."""

    name: str
    unit: str
    meaning: str


def _six(prefix: str, unit: str, meaning: str) -> tuple[Column, ...]:
    return tuple(Column(f"{prefix}_{i}", unit, meaning.format(i=i)) for i in range(1, 7))


def _vector(names: str, unit: str, meaning: str) -> tuple[Column, ...]:
    return tuple(Column(n, unit, meaning.format(axis=n[-1])) for n in names.split())


#: The column groups, in their order in a file.  A group is present whole or not at all.
GROUPS: dict[str, tuple[Column, ...]] = {
    "time": (Column("time", "s", "time stamp, increasing"),),
    "leg_length": _six("leg_length", "m", "length of leg {i}, from its base joint B_{i} to its platform joint P_{i}"),
    "pose": _vector("x y z", "m", "position of P's origin in {{B}}, {axis}")
    + (
        Column("roll", "rad", "roll angle of {P} in {B} (the package's roll-pitch-yaw convention)"),
        Column("pitch", "rad", "pitch angle of {P} in {B}"),
        Column("yaw", "rad", "yaw angle of {P} in {B}"),
    ),
    "twist": _vector("vx vy vz", "m/s", "velocity of P's origin in {{B}}, {axis}")
    + _vector("wx wy wz", "rad/s", "angular velocity of {{P}} in {{B}}, {axis}"),
    "acceleration": _vector("ax ay az", "m/s^2", "acceleration of P's origin in {{B}}, {axis}")
    + _vector("alphax alphay alphaz", "rad/s^2", "angular acceleration of {{P}} in {{B}}, {axis}"),
    "leg_force": _six("leg_force", "N", "force of leg {i} along its axis, positive pushing the platform away"),
    "motor_current": _six(
        "motor_current", "A", "q-axis current of leg {i}'s motor (the drive constants give the force)"
    ),
}


@dataclass(frozen=True)
class Kind:
    """What a kind of log holds: the groups it must have, those it may have, and the groups of
    which it has exactly one."""

    meaning: str
    required: tuple[str, ...]
    optional: tuple[str, ...] = ()
    one_of: tuple[str, ...] = ()


#: The kinds of log.
KINDS: dict[str, Kind] = {
    "excitation": Kind(
        "set points for a machine to follow: leg lengths and poses, with the set points' twist and acceleration",
        required=("time", "leg_length", "pose"),
        optional=("twist", "acceleration"),
    ),
    "record": Kind(
        "what a machine's drives logged: leg lengths and leg forces or motor currents; poses, twists and "
        "accelerations where a measurement (or a simulation) gives them",
        required=("time", "leg_length"),
        optional=("pose", "twist", "acceleration"),
        one_of=("leg_force", "motor_current"),
    ),
}

#: The header's entries: each key and what it holds (``format``, ``kind``, ``platform`` and
#: ``rate_hz`` are required; a log may carry other entries, which are kept).
HEADER: dict[str, str] = {
    "format": f"the format and its version, `{FORMAT}`",
    "kind": "`excitation` or `record`",
    "platform": "the platform's name (a shipped config) or its config file",
    "rate_hz": "the nominal sampling rate, Hz (the gap bound is in its periods)",
    "what": "one line on what the log is (optional)",
}
_REQUIRED_HEADER = ("format", "kind", "platform", "rate_hz")


class LogError(UsageError):
    """A log that does not fit the schema; the message names the file, and the row and column
    where there is one (rows count the samples from 1, the column-name line not counted).

    Attributes:
        path: the file.
        row: the sample's row (from 1), or None.
        column: the column's name, or None.
    """

    def __init__(self, path: str | Path, problem: str, row: int | None = None, column: str | None = None):
        where = ", ".join(
            part
            for part in (None if row is None else f"row {row}", None if column is None else f"column {column}")
            if part
        )
        super().__init__(f"{path}: {where + ': ' if where else ''}{problem}", argument=None, problem=problem)
        self.path, self.row, self.column = str(path), row, column


class ClippedSamples(UserWarning):
    """Force samples at the drive's limit were dropped (the message counts them)."""


@dataclass(frozen=True)
class Log:
    """A checked log: its header and its columns by group.

    Attributes:
        header: the header's entries (strings), ``format``, ``kind``, ``platform`` and ``rate_hz`` among them.
        data: each present group's samples, (T,) for ``time``, (T, k) for the others.
        source: the file read, or ``""`` for a log made in memory.
    """

    header: dict[str, str]
    data: dict[str, np.ndarray]
    source: str = ""

    @property
    def kind(self) -> str:
        """The log's kind, a key of :data:`KINDS`."""
        return self.header["kind"]

    @property
    def rate(self) -> float:
        """The nominal sampling rate, Hz."""
        return float(self.header["rate_hz"])

    @property
    def time(self) -> np.ndarray:
        """The time stamps (T,), s."""
        return self.data["time"]

    def columns(self) -> list[str]:
        """The column names, in the file's order."""
        return [c.name for g in GROUPS if g in self.data for c in GROUPS[g]]


def schema_markdown() -> str:
    """Markdown: the header's entries, then each kind's groups and every column with its unit and
    meaning (the log-format page shows it)."""
    lines = ["| header key | holds |", "|---|---|"]
    lines += [f"| `{k}` | {v} |" for k, v in HEADER.items()]
    lines += ["", "| kind | holds | groups required | groups optional | exactly one of |", "|---|---|---|---|---|"]
    for name, kind in KINDS.items():
        groups = [", ".join(f"`{g}`" for g in gs) or "-" for gs in (kind.required, kind.optional, kind.one_of)]
        lines.append(f"| `{name}` | {kind.meaning} | {' | '.join(groups)} |")
    lines += ["", "| group | column | unit | meaning |", "|---|---|---|---|"]
    for group, columns in GROUPS.items():
        for c in columns:
            lines.append(f"| `{group}` | `{c.name}` | {c.unit} | {c.meaning} |")
    return "\n".join(lines)


# -- the checks -------------------------------------------------------------------------------------


def _check_header(path: str, header: dict[str, str]) -> None:
    for key in _REQUIRED_HEADER:
        if key not in header:
            raise LogError(path, f"the header has no {key!r} entry (a line '# {key}: ...' before the column names)")
    if header["format"] != FORMAT:
        raise LogError(path, f"format {header['format']!r} is not {FORMAT!r}")
    if header["kind"] not in KINDS:
        raise LogError(path, f"kind {header['kind']!r} is not one of {', '.join(KINDS)}")
    try:
        rate = float(header["rate_hz"])
    except ValueError:
        rate = math.nan
    if not (math.isfinite(rate) and 0 < rate <= 1e6):
        raise LogError(path, f"rate_hz {header['rate_hz']!r} is not a rate in (0, 1e6] Hz")


def _groups_of(path: str, kind: str, names: list[str]) -> list[str]:
    """The groups the column names make, checked against the kind: every name in the schema and
    once, every group whole, the kind's required groups and one of its alternatives there."""
    spec = KINDS[kind]
    allowed = spec.required + spec.optional + spec.one_of
    owner = {c.name: g for g in allowed for c in GROUPS[g]}
    seen: set[str] = set()
    for name in names:
        if name in seen:
            raise LogError(path, "the column appears twice", column=name)
        seen.add(name)
        if name not in owner:
            known = {c.name for cs in GROUPS.values() for c in cs}
            why = "not in a log of this kind" if name in known else "not in the schema"
            raise LogError(path, f"{why} (a {kind} log has the groups {', '.join(allowed)})", column=name)
    present = [g for g in GROUPS if g in allowed and any(c.name in seen for c in GROUPS[g])]
    for group in present:
        for c in GROUPS[group]:
            if c.name not in seen:
                raise LogError(
                    path, f"missing (the group {group} has {', '.join(x.name for x in GROUPS[group])})", column=c.name
                )
    for group in spec.required:
        if group not in present:
            raise LogError(path, f"missing (a {kind} log has the group {group})", column=GROUPS[group][0].name)
    if spec.one_of:
        chosen = [g for g in spec.one_of if g in present]
        if len(chosen) != 1:
            problem = "both" if chosen else "neither"
            raise LogError(
                path,
                f"a {kind} log has one of the groups {' or '.join(spec.one_of)}, this one {problem}",
                column=GROUPS[spec.one_of[0]][0].name,
            )
    return present


def _check_samples(path: str, header: dict[str, str], data: dict[str, np.ndarray], min_duration: float) -> None:
    for group, values in data.items():
        bad = ~np.isfinite(values)
        if bad.any():
            flat = values.reshape(values.shape[0], -1)
            row, col = np.argwhere(~np.isfinite(flat))[0]
            raise LogError(
                path, f"{flat[row, col]} is not a finite number", row=int(row) + 1, column=GROUPS[group][col].name
            )
    time = data["time"]
    if time.size == 0:
        raise LogError(path, "no samples")
    step = np.diff(time)
    back = np.flatnonzero(step <= 0)
    if back.size:
        k = int(back[0]) + 1
        what = "repeats" if step[k - 1] == 0 else "is before"
        raise LogError(
            path, f"time stamp {float(time[k])!r} s {what} row {k}'s {float(time[k - 1])!r} s", row=k + 1, column="time"
        )
    bound = MAX_GAP_PERIODS / float(header["rate_hz"])
    gap = np.flatnonzero(step > bound)
    if gap.size:
        k = int(gap[0]) + 1
        raise LogError(
            path,
            f"a gap of {step[k - 1]:.6g} s after row {k}, longer than the bound {bound:.6g} s "
            f"({MAX_GAP_PERIODS:g} periods of rate_hz {header['rate_hz']})",
            row=k + 1,
            column="time",
        )
    length = float(time[-1] - time[0])
    if length < min_duration:
        raise LogError(path, f"{time.size} samples over {length:.6g} s; at least {min_duration:g} s are needed")


def _check_stroke(path: str, lengths: np.ndarray, platform: PlatformParams) -> None:
    lo, hi = platform.limits.leg_length
    out = (lengths < lo) | (lengths > hi)
    if out.any():
        row, col = np.argwhere(out)[0]
        value = lengths[row, col]
        hint = " (lengths in mm or cm? the log's unit is m)" if value > 10 * hi else ""
        raise LogError(
            path,
            f"leg length {value:.6g} m is outside the stroke [{lo:g}, {hi:g}] m of {platform.name}{hint}",
            row=int(row) + 1,
            column=GROUPS["leg_length"][col].name,
        )


def check(log: Log, platform: PlatformParams | None = None, min_duration: float = 0.0, path: str | None = None) -> Log:
    """Check a log against the schema (and, given the platform, its leg lengths against the
    stroke); the log itself.

    Args:
        log: the log.
        platform: the platform whose stroke bounds the leg lengths, or None for no such check.
        min_duration: the shortest time the stamps may span, s.
        path: the file named in the errors (default the log's source).

    Returns:
        ``log``.

    Raises:
        LogError: the first fault, naming the file, row and column.
    """
    where = path or log.source or "log"
    header = {k: str(v) for k, v in log.header.items()}
    _check_header(where, header)
    names = [c.name for g in GROUPS if g in log.data for c in GROUPS[g]]
    _groups_of(where, header["kind"], names)
    n = np.asarray(log.data["time"]).shape[0]
    for group, values in log.data.items():
        want = (n,) if group == "time" else (n, len(GROUPS[group]))
        if np.shape(values) != want:
            raise LogError(where, f"the group {group} has shape {np.shape(values)}, not {want}")
    _check_samples(where, header, log.data, min_duration)
    if platform is not None:
        _check_stroke(where, log.data["leg_length"], platform)
    return log


# -- reading ------------------------------------------------------------------------------------------


def _parse_csv(path: str, text: str) -> tuple[dict[str, str], list[str], np.ndarray]:
    header: dict[str, str] = {}
    lines = text.splitlines()
    k = 0
    while k < len(lines) and (lines[k].startswith("#") or not lines[k].strip()):
        entry = lines[k].lstrip("#").strip()
        if entry:
            key, sep, value = entry.partition(":")
            if not sep:
                raise LogError(path, f"header line {k + 1} {entry[:60]!r} is not 'key: value'")
            header[key.strip()] = value.strip()
        k += 1
    _check_header(path, header)
    if k == len(lines):
        raise LogError(path, "no column names after the header")
    names = [n.strip() for n in lines[k].split(",")]
    _groups_of(path, header["kind"], names)
    rows = [line for line in lines[k + 1 :]]
    while rows and not rows[-1].strip():
        rows.pop()
    values = np.empty((len(rows), len(names)))
    for r, line in enumerate(rows):
        cells = line.split(",")
        if len(cells) != len(names):
            raise LogError(path, f"{len(cells)} values for {len(names)} columns", row=r + 1)
        for c, cell in enumerate(cells):
            try:
                values[r, c] = float(cell)
            except ValueError:
                raise LogError(path, f"{cell.strip()[:40]!r} is not a number", row=r + 1, column=names[c]) from None
    return header, names, values


def _read_hdf5(path: str) -> tuple[dict[str, str], list[str], np.ndarray]:
    from stewart_env.extras import require

    require("logs", f"reading the HDF5 log {path}")
    import h5py

    with files.open_regular(path, MAX_LOG_BYTES, "log") as raw:
        try:
            with h5py.File(io.BytesIO(raw.read()), "r") as f:
                header = {k: (v.decode() if isinstance(v, bytes) else str(v)) for k, v in f.attrs.items()}
                _check_header(path, header)
                names = list(f.keys())
                _groups_of(path, header["kind"], names)
                sizes = {f[n].shape for n in names}
                if len(sizes) != 1 or len(next(iter(sizes))) != 1:
                    raise LogError(path, "the columns are not one-dimensional datasets of one length")
                ordered = [c.name for g in GROUPS for c in GROUPS[g] if c.name in names]
                values = np.stack([np.asarray(f[n], dtype=float) for n in ordered], axis=1)
        except OSError as err:
            raise LogError(path, f"not an HDF5 file ({err})") from None
    return header, ordered, values


def read(path: str | Path, platform: PlatformParams | None = None, min_duration: float = 0.0) -> Log:
    """Read and check a log (CSV, or HDF5 by the suffix ``.h5`` or ``.hdf5``).

    Args:
        path: the file.
        platform: the platform whose stroke bounds the leg lengths, or None for no such check.
        min_duration: the shortest time the stamps may span, s.

    Returns:
        The checked log.

    Raises:
        LogError: the first fault, naming the file, row and column.
        stewart_env.files.FileError: the file cannot be read.
        stewart_env.extras.MissingExtra: an HDF5 log without the extra ``logs``.
    """
    source = str(path)
    if Path(source).suffix.lower() in HDF5_SUFFIXES:
        header, names, values = _read_hdf5(source)
    else:
        raw = files.read_regular(source, MAX_LOG_BYTES, "log")
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError:
            raise LogError(source, "not UTF-8 text (a CSV log; HDF5 logs end in .h5 or .hdf5)") from None
        header, names, values = _parse_csv(source, text)
    index = {n: i for i, n in enumerate(names)}
    data = {}
    for group, columns in GROUPS.items():
        if columns[0].name in index:
            block = values[:, [index[c.name] for c in columns]]
            data[group] = block[:, 0].copy() if group == "time" else np.ascontiguousarray(block)
    return check(Log(header, data, source), platform, min_duration)


# -- writing ------------------------------------------------------------------------------------------


def write(path: str | Path, log: Log, platform: PlatformParams | None = None) -> Path:
    """Check a log and write it whole (CSV, or HDF5 by the suffix ``.h5`` or ``.hdf5``): every
    number as the shortest text that reads back to the same float.

    Args:
        path: the file, replaced whole or left as it was.
        log: the log.
        platform: the platform whose stroke bounds the leg lengths, or None for no such check.

    Returns:
        The path written.

    Raises:
        LogError: the log does not fit the schema (nothing is written).
        stewart_env.files.WriteError: the file cannot be written.
        stewart_env.extras.MissingExtra: an HDF5 log without the extra ``logs``.
    """
    path = Path(path)
    header = {"format": FORMAT, **{k: str(v) for k, v in log.header.items() if k != "format"}}
    log = check(Log(header, log.data, log.source), platform, path=str(path))
    names = log.columns()
    table = np.column_stack([log.data[g] for g in GROUPS if g in log.data])
    if path.suffix.lower() in HDF5_SUFFIXES:
        from stewart_env.extras import require

        require("logs", f"writing the HDF5 log {path}")
        import h5py

        with files.publishing(path) as tmp:
            with h5py.File(tmp, "w") as f:
                for key, value in header.items():
                    f.attrs[key] = value
                for k, name in enumerate(names):
                    f.create_dataset(name, data=table[:, k])
        return path
    out = io.StringIO()
    for key, value in header.items():
        out.write(f"# {key}: {value}\n")
    out.write(",".join(names) + "\n")
    for row in table:
        out.write(",".join(repr(float(x)) for x in row) + "\n")
    files.publish(path, out.getvalue())
    return path


# -- clipped samples -----------------------------------------------------------------------------------


def clipped(forces: np.ndarray, limits: tuple[float, float]) -> np.ndarray:
    """The samples (T,) where some leg's force sits at the drive's limit (within
    :data:`CLIP_TOLERANCE` of it, or beyond): a saturated drive reports its limit, not the force
    the motion needed.

    Args:
        forces: the leg forces (T, 6), N.
        limits: the drive's (lowest, highest) leg force, N.
    """
    lo, hi = limits
    margin = CLIP_TOLERANCE * max(abs(lo), abs(hi))
    return np.any((forces <= lo + margin) | (forces >= hi - margin), axis=1)


def drop_clipped(source: str, forces: np.ndarray, limits: tuple[float, float]) -> np.ndarray:
    """The samples to keep (T,) bool: all but the clipped ones (:func:`clipped`), with a
    :class:`ClippedSamples` warning that counts the dropped ones.

    Args:
        source: the log's file, named in the warning.
        forces: the leg forces (T, 6), N.
        limits: the drive's (lowest, highest) leg force, N.
    """
    cut = clipped(forces, limits)
    if cut.any():
        warnings.warn(
            f"{source}: {int(cut.sum())} of {cut.size} samples have a leg force at the drive's limit "
            f"[{limits[0]:g}, {limits[1]:g}] N and are dropped (first at row {int(np.argmax(cut)) + 1})",
            ClippedSamples,
            stacklevel=2,
        )
    return ~cut
