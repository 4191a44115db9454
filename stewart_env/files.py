"""The package's file machinery: one writer per output folder, atomic publication, safe reading
of files someone else may have put in a folder, the decoding of JSON and YAML, content hashes and
a writability check.

Every command that writes a run (``train``, ``mismatch``, ``evaluate --out``) holds
:func:`lock_folder` on its output folder for as long as it writes: an exclusive ``flock`` on
``.stewart-env.lock`` inside it, which the operating system releases when the process ends,
however it ends, so a killed run never leaves its folder locked.  A second command on the same
folder is refused at once with :class:`FolderBusy`, naming the folder and the holder's PID.  A
command that ends removes the lock file (a killed one leaves it, unlocked, and the next command
takes it over); whoever takes the lock checks that the path still names the file it locked, so
the removal never lets two commands hold one folder.  (On a system without ``flock``, Windows,
folders are not locked.)

Every file is published with :func:`publishing` (or :func:`publish` for bytes and text, and
:func:`publishing_folder` for a folder of files): written under a temporary name unique to the
process in the same directory, flushed to disk, then renamed over the target, so a reader sees
the old file or the whole new one; on any error the temporary file is removed and the error is a
:class:`WriteError` naming the target and the cause (a full disk is "No space left on device").
A published file or folder has the modes the umask gives, as one written with ``open``.

Every file read from a folder the package did not just write goes through :func:`open_regular`
(or :func:`read_regular`, :func:`read_json`, :func:`sha256_file`): regular files only, opened without blocking (a
named pipe would wait for a writer for ever), checked by ``fstat`` after opening (a symbolic link
to ``/dev/zero`` is a device), bounded in size before a byte is read, and read by the size they
have, never by the bound (which may be larger than the machine's memory).

Every JSON or YAML document the package decodes, from a file or a command-line option, goes
through :func:`load_json` or :func:`load_yaml`: a malformed document, or one nested so deeply
that decoding it would exhaust Python's recursion, is a :class:`DocumentError` saying what is
wrong without quoting the text, which the caller raises as its own error naming the file or option.

This module imports nothing from the rest of the package: it sits below every layer.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import os
import secrets
import shutil
import stat
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any, BinaryIO

import yaml

from stewart_env.errors import UsageError

try:
    import fcntl
except ImportError:  # no flock (Windows): folders are not locked there
    fcntl = None

__all__ = [
    "LOCK_FILE",
    "MAX_DEPTH",
    "TMP_PREFIX",
    "DocumentError",
    "FileError",
    "FolderBusy",
    "NotWritable",
    "WriteError",
    "YAMLNestedTooDeep",
    "check_not_busy",
    "check_writable",
    "load_json",
    "load_yaml",
    "lock_folder",
    "open_regular",
    "publish",
    "publishing",
    "publishing_folder",
    "read_json",
    "read_regular",
    "sha256_file",
    "write_error",
]

#: The lock file of an output folder (see :func:`lock_folder`).
LOCK_FILE = ".stewart-env.lock"
#: Prefix of every temporary file and folder: readers of a folder pass over these names.
TMP_PREFIX = ".tmp-"
#: Bytes of the holder's PID read back from a lock file.
_PID_BYTES = 32
#: Tries, and seconds between them, to take a lock that :func:`check_not_busy` of another command
#: may hold for an instant; a lock still held after them belongs to a command that runs.
_LOCK_ATTEMPTS, _LOCK_RETRY_SECONDS = 20, 0.01
#: Deepest nesting of lists and mappings in a JSON or YAML document decoded (the package's own
#: documents nest a few levels; code walking a document recursively fails near a thousand).
MAX_DEPTH = 100
#: Longest piece of a YAML parser's message repeated (a tag or token can be as long as the file).
_PROBLEM_CHARS = 120
#: Bytes read at a time where a file's size is not known in advance.
_READ_CHUNK = 1 << 20
#: Tries to make a temporary file or folder under a name not yet taken.
_NAME_ATTEMPTS = 100


class FileError(UsageError):
    """A file or folder that cannot be read or written as asked; the message names the path and
    the cause.  A ValueError, as every request the command line reports in one line."""

    def __init__(self, path: str | os.PathLike, problem: str):
        super().__init__(path, problem)
        self.path = str(path)
        self.problem = problem

    def __str__(self) -> str:
        return f"{self.path}: {self.problem}"


class WriteError(FileError):
    """Writing ``path`` failed (a full disk, a failing device, no permission)."""

    def __str__(self) -> str:
        return f"cannot write {self.path}: {self.problem}"


class NotWritable(FileError):
    """An output folder that cannot be made, or a file not written in it."""

    def __str__(self) -> str:
        return f"output directory {self.path!r} is not writable: {self.problem}"


class FolderBusy(FileError):
    """Another process holds the folder's lock; ``pid`` is its process id (None if unknown)."""

    def __init__(self, path: str | os.PathLike, pid: int | None):
        holder = f"PID {pid}" if pid is not None else "PID unknown"
        super().__init__(
            path,
            f"in use by another stewart-env command ({holder}); wait for it to end, or choose another output directory",
        )
        self.pid = pid

    def __str__(self) -> str:
        return f"output directory {self.path!r} is {self.problem}"


def _cause(err: OSError) -> str:
    return err.strerror or str(err) or type(err).__name__


def write_error(path: str | os.PathLike, err: OSError) -> WriteError:
    """The :class:`WriteError` of an OSError met while writing ``path``.

    Args:
        path: the file being written.
        err: the OSError met.

    Returns:
        The WriteError, naming ``path`` and the cause.
    """
    return WriteError(path, _cause(err))


# -- the folder lock ------------------------------------------------------------------------------


def _holder(fd: int) -> int | None:
    """The PID written into a held lock file (None if the holder has not written it yet)."""
    try:
        text = os.pread(fd, _PID_BYTES, 0).decode("ascii", "replace").strip()
    except OSError:
        return None
    return int(text) if text.isdigit() else None


def _same_file(fd: int, path: Path) -> bool:
    """Whether ``path`` still names the file open as ``fd`` (a finished holder unlinks its lock
    file: a lock taken on the unlinked file locks nothing)."""
    try:
        named, held = os.stat(path, follow_symlinks=False), os.fstat(fd)
    except OSError:
        return False
    return (named.st_dev, named.st_ino) == (held.st_dev, held.st_ino)


def check_not_busy(directory: str | os.PathLike) -> None:
    """Raise :class:`FolderBusy` if another process holds the lock of ``directory``, changing nothing.

    A missing lock file is nobody's.  A command calls it before its first look at the folder, so
    that a busy folder is reported as such and not by what a run in progress left.

    Args:
        directory: the output folder.

    Raises:
        FolderBusy: another process holds the folder's lock.
    """
    lock = Path(directory) / LOCK_FILE
    if fcntl is None:
        return
    for _ in range(_LOCK_ATTEMPTS):
        try:
            fd = os.open(lock, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOFOLLOW", 0))
        except (OSError, ValueError):
            return  # no lock file, or one :func:`lock_folder` will report on
        try:
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                return
            try:
                fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
            except OSError as err:
                if err.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                    raise FolderBusy(directory, _holder(fd)) from None
                return
            if _same_file(fd, lock):
                return
            # the file a holder unlinked as it ended: the path may name a newer lock file by now
        finally:
            os.close(fd)


@contextlib.contextmanager
def lock_folder(directory: str | os.PathLike, create: bool = True) -> Iterator[Path]:
    """Hold the exclusive lock of ``directory`` inside the block.

    A lock file in the folder, locked with ``flock``, which the system releases when the process
    ends however it ends.  When the block ends the lock file is removed, still locked, then
    closed; a process that opened it meanwhile finds, once it has the lock, that the path no
    longer names that file, and starts again with a new one.

    Args:
        directory: the output folder.
        create: make the folder if it is missing; without it, it must exist.

    Yields:
        The folder's path.

    Raises:
        FolderBusy: another process holds it; nothing in the folder was changed.
        FileError: the folder cannot be made or written (see :func:`check_writable`).
    """
    check_not_busy(directory)
    path = check_writable(directory, create=create)
    if fcntl is None:
        yield path
        return
    lock = path / LOCK_FILE
    fd = _locked(path, lock)
    try:
        with contextlib.suppress(OSError):  # the PID is for the message of a second command only
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        yield path
    finally:
        # unlinked while still locked, so no other process can hold the lock on this path meanwhile
        if _same_file(fd, lock):
            with contextlib.suppress(OSError):
                os.unlink(lock)
        os.close(fd)  # closing the descriptor releases the lock


def _locked(folder: Path, lock: Path) -> int:
    """A descriptor of ``lock``, the lock file ``folder`` holds, exclusively locked by this process."""
    for attempt in range(_LOCK_ATTEMPTS):
        try:
            fd = os.open(
                lock, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0), 0o644
            )
        except OSError as err:
            raise FileError(lock, f"cannot open the folder's lock file: {_cause(err)}") from None
        try:
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                raise FileError(lock, "not a regular file; remove it")
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as err:
                if err.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                    raise FileError(lock, f"cannot lock the folder: {_cause(err)}") from None
                if attempt == _LOCK_ATTEMPTS - 1:
                    raise FolderBusy(folder, _holder(fd)) from None
                time.sleep(_LOCK_RETRY_SECONDS)  # perhaps only another command's check_not_busy, a moment long
                os.close(fd)
                continue
        except BaseException:
            os.close(fd)
            raise
        if _same_file(fd, lock):
            return fd
        os.close(fd)  # the file its last holder unlinked as it ended: open the path again
    raise FolderBusy(folder, None)


# -- writing --------------------------------------------------------------------------------------


def check_writable(directory: str | os.PathLike, create: bool = True) -> Path:
    """Prove ``directory`` writable by creating it and writing a file in it.

    Without ``create`` nothing is left behind: the probe file and every directory the probe made
    are removed again.  (Permission bits alone cannot tell: root passes them on a read-only or
    virtual file system.)  The probe's name is unique, so processes probing one folder at once do
    not remove each other's.

    Args:
        directory: the folder to probe.
        create: keep the folder (and the folders above it) the probe made.

    Returns:
        The folder's path.

    Raises:
        FileError: the folder cannot be made or written (the message names it).
    """
    path = Path(directory)
    made = []
    missing = path
    while not missing.exists() and missing != missing.parent:
        made.append(missing)
        missing = missing.parent
    try:
        path.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=f"{TMP_PREFIX}write-test-", dir=path)
        os.close(fd)
        os.unlink(probe)
    except OSError as err:
        raise NotWritable(path, _cause(err)) from None
    finally:
        if not create:
            for folder in made:  # innermost first
                with contextlib.suppress(OSError):
                    folder.rmdir()
    return path


def _fsync(path: Path) -> None:
    """Flush a file's or a directory's entries to disk: a rename is durable only after both."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    except OSError:
        if not path.is_dir():
            raise  # some file systems cannot sync a directory: its rename is then as durable as they make it
    finally:
        os.close(fd)


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(OSError):
            path.unlink()


@contextlib.contextmanager
def _replacing(path: Path, tmp: Path) -> Iterator[Path]:
    """Yield ``tmp`` (a file or a folder of files); when the block ends, flush it and rename it
    over ``path`` (a folder replacing a folder removes the old one first); on any error remove
    it, an OSError raised as :class:`WriteError` naming ``path``."""
    try:
        yield tmp
        for name in os.listdir(tmp) if tmp.is_dir() else ():
            _fsync(tmp / name)
        _fsync(tmp)
        if tmp.is_dir() and path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        os.replace(tmp, path)
        _fsync(path.parent)
    except OSError as err:
        _remove(tmp)
        raise write_error(path, err) from None
    except BaseException:
        _remove(tmp)
        raise


def _made_unique(parent: Path, prefix: str, suffix: str, folder: bool) -> Path:
    """A new, empty file or folder in ``parent`` under a name no other process has taken, made
    with the modes the umask gives (0666 or 0777 less the umask), as a file the user writes
    with ``open`` gets: :mod:`tempfile` would make it private (0600, 0700), and so the file it
    becomes once renamed."""
    for _ in range(_NAME_ATTEMPTS):
        name = parent / f"{prefix}{secrets.token_hex(6)}{suffix}"
        try:
            if folder:
                os.mkdir(name, 0o777)
            else:
                os.close(os.open(name, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0), 0o666))
        except FileExistsError:
            continue
        return name
    raise FileExistsError(errno.EEXIST, f"no unused temporary name after {_NAME_ATTEMPTS} tries", str(parent))


@contextlib.contextmanager
def publishing(path: str | os.PathLike) -> Iterator[Path]:
    """A temporary path, unique to this call, next to ``path``, published over ``path`` at the end.

    Whatever the block writes there is flushed and renamed over ``path`` when the block ends, and
    removed if it raises.  The file is made with the modes the umask gives (0666 less the umask).

    Args:
        path: the file to publish.

    Yields:
        The temporary path to write.

    Raises:
        WriteError: an OSError of the block or of the publication, naming ``path``.
    """
    path = Path(path)
    try:
        # the target's suffix kept: some writers (SB3's save) append theirs to a name without it
        name = _made_unique(path.parent, f"{TMP_PREFIX}{path.stem}-", path.suffix, folder=False)
    except OSError as err:
        raise write_error(path, err) from None
    with _replacing(path, name) as tmp:
        yield tmp


def publish(path: str | os.PathLike, data: bytes | str) -> None:
    """Write ``data`` to ``path`` atomically (see :func:`publishing`).

    Args:
        path: the file to write.
        data: bytes, or text (written as UTF-8).

    Raises:
        WriteError: the file cannot be written (the message names it).

    Examples:
        >>> import tempfile, pathlib
        >>> from stewart_env.files import publish
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     publish(pathlib.Path(folder) / "note.txt", "hello")
        ...     print((pathlib.Path(folder) / "note.txt").read_text())
        hello
    """
    with publishing(path) as tmp:
        tmp.write_bytes(data.encode() if isinstance(data, str) else data)


@contextlib.contextmanager
def publishing_folder(path: str | os.PathLike) -> Iterator[Path]:
    """A temporary folder, unique to this call, next to ``path``, published over ``path`` at the end.

    When the block ends its files are flushed and the folder replaces ``path`` (an existing one is
    removed first); if the block raises it is removed.  The folder is made with the modes the umask
    gives (0777 less the umask).

    Args:
        path: the folder to publish.

    Yields:
        The temporary folder to fill.

    Raises:
        WriteError: an OSError, naming ``path``.
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = _made_unique(path.parent, f"{TMP_PREFIX}{path.name}-", "", folder=True)
    except OSError as err:
        raise write_error(path, err) from None
    with _replacing(path, tmp) as tmp:
        yield tmp


# -- reading --------------------------------------------------------------------------------------


def _check_regular(info: os.stat_result, path: str, limit: int, what: str) -> None:
    if stat.S_ISDIR(info.st_mode):
        raise FileError(path, f"a directory, not a {what}")
    if not stat.S_ISREG(info.st_mode):
        raise FileError(path, "not a regular file (a FIFO, socket or device)")
    if info.st_size > limit:
        raise FileError(path, f"larger than {limit} bytes ({info.st_size} bytes)")


@contextlib.contextmanager
def open_regular(path: str | os.PathLike, limit: int, what: str = "file") -> Iterator[BinaryIO]:
    """``path`` opened for reading in binary, if it is a regular file of at most ``limit`` bytes.

    FIFOs, sockets, devices (a symbolic link to one included) and directories are refused before
    they are opened, and again after (``fstat`` of the open file, should the path have changed
    since): opened with ``O_NONBLOCK``, a FIFO never blocks.

    Args:
        path: the file to open.
        limit: its largest size, bytes.
        what: the expected kind of file, named in the message about a directory.

    Yields:
        The open binary file.

    Raises:
        FileError: naming ``path``: missing, unreadable, not a regular file or too large.
    """
    source = str(path)
    try:
        _check_regular(os.stat(path), source, limit, what)
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    except (OSError, ValueError) as err:  # ValueError: a NUL character in the path
        if isinstance(err, FileError):
            raise
        raise FileError(source, f"cannot read the file: {getattr(err, 'strerror', None) or err}") from None
    with os.fdopen(fd, "rb") as f:
        _check_regular(os.fstat(fd), source, limit, what)
        yield f


def read_regular(path: str | os.PathLike, limit: int, what: str = "file") -> bytes:
    """The bytes of ``path`` through :func:`open_regular`.

    Args:
        path: the file to read.
        limit: its largest size, bytes; a file grown past it since its check is refused too.
        what: the expected kind of file, named in the message about a directory.

    Returns:
        The file's bytes.

    Raises:
        FileError: not a regular file, too large, or unreadable (the message names it).
    """
    with open_regular(path, limit, what) as f:
        try:
            # as many bytes as the file holds, not ``limit``: a read of n bytes allocates n first,
            # and the bound of an agent's files is larger than many a machine's memory
            parts = [f.read(os.fstat(f.fileno()).st_size)]
            total = len(parts[0])
            while total <= limit:  # the file grown since its fstat (or a size the system does not report)
                block = f.read(min(_READ_CHUNK, limit + 1 - total))
                if not block:
                    break
                parts.append(block)
                total += len(block)
        except OSError as err:
            raise FileError(path, f"cannot read the file: {_cause(err)}") from None
    if total > limit:
        raise FileError(path, f"larger than {limit} bytes")
    return parts[0] if len(parts) == 1 else b"".join(parts)


def sha256_file(path: str | os.PathLike, limit: int) -> str:
    """The hex sha256 of a regular file's bytes (read through :func:`open_regular`).

    Args:
        path: the file.
        limit: its largest size, bytes.

    Returns:
        The digest, 64 hex digits.

    Raises:
        FileError: not a regular file, too large, or unreadable (the message names it).
    """
    digest = hashlib.sha256()
    with open_regular(path, limit) as f:
        try:
            for block in iter(lambda: f.read(_READ_CHUNK), b""):
                digest.update(block)
        except OSError as err:
            raise FileError(path, f"cannot read the file: {_cause(err)}") from None
    return digest.hexdigest()


# -- decoding -------------------------------------------------------------------------------------


class DocumentError(UsageError):
    """Text that is not a document of its format (JSON or YAML), or one nested deeper than
    :data:`MAX_DEPTH`; ``problem`` says what is wrong and quotes no more of the text than a
    parser's token, ``nested`` whether the depth was the problem.  The caller raises it as its own
    error, naming the file or option."""

    def __init__(self, problem: str, nested: bool = False):
        super().__init__(problem)
        self.problem = problem
        self.nested = nested

    def __str__(self) -> str:
        return self.problem


def _too_deep(document: Any, limit: int) -> bool:
    """Whether a decoded JSON document nests lists and objects more than ``limit`` levels deep
    (iterative: the check must not itself run out of recursion)."""
    stack = [(document, 1)]
    while stack:
        value, depth = stack.pop()
        if depth > limit:
            return True
        if isinstance(value, dict):
            stack.extend((item, depth + 1) for item in value.values() if isinstance(item, (dict, list)))
        elif isinstance(value, list):
            stack.extend((item, depth + 1) for item in value if isinstance(item, (dict, list)))
    return False


def load_json(text: str | bytes) -> Any:
    """The JSON document in ``text``.

    Args:
        text: the document; bytes are decoded as UTF-8.

    Returns:
        The decoded document.

    Raises:
        DocumentError: not UTF-8, not valid JSON, or nested more than :data:`MAX_DEPTH` levels.
    """
    if isinstance(text, (bytes, bytearray)):
        try:
            text = bytes(text).decode("utf-8")
        except UnicodeDecodeError as err:
            raise DocumentError(f"not valid JSON (not UTF-8 text: invalid byte at offset {err.start})") from None
    try:
        document = json.loads(text)
        deep = _too_deep(document, MAX_DEPTH)
    except json.JSONDecodeError as err:
        raise DocumentError(f"not valid JSON ({err})") from None
    except RecursionError:  # the decoder recurses once per level, before any bound of ours can look
        deep = True
    if deep:
        raise DocumentError(f"not valid JSON (nested more than {MAX_DEPTH} levels deep)", nested=True)
    return document


class YAMLNestedTooDeep(yaml.composer.ComposerError):
    """A YAML document nested deeper than a bounded loader allows: what such a loader raises, so
    that :func:`load_yaml` tells the depth from the other errors by the type
    (:attr:`DocumentError.nested`), not by the message's words.

    Args:
        limit: the loader's bound, levels.
        mark: where the level beyond it starts (a YAML mark).
    """

    def __init__(self, limit: int, mark: yaml.Mark | None):
        super().__init__(None, None, f"nested more than {limit} levels deep", mark)


class _BoundedLoader(yaml.SafeLoader):
    """YAML's safe loader, nesting at most :data:`MAX_DEPTH` levels: its composer recurses once
    per level, so the bound comes before Python's recursion limit."""

    def __init__(self, stream):
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent, index):
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                raise YAMLNestedTooDeep(MAX_DEPTH, self.peek_event().start_mark)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


def _shortened(text: str) -> str:
    return text if len(text) <= _PROBLEM_CHARS else text[: _PROBLEM_CHARS - 3] + "..."


def _yaml_problem(err: yaml.YAMLError) -> str:
    """Where and what went wrong, without PyYAML's snippet of the offending line."""
    if isinstance(err, yaml.reader.ReaderError):
        return f"position {err.position + 1}: character #x{err.character:04x} is not allowed"
    if isinstance(err, yaml.MarkedYAMLError):
        mark = err.problem_mark or err.context_mark
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        return where + "; ".join(_shortened(part) for part in (err.context, err.problem) if part)
    return type(err).__name__


def load_yaml(text: str | bytes, loader: type[yaml.SafeLoader] | None = None) -> Any:
    """The YAML document in ``text``, by YAML's safe loader bounded in depth (or ``loader``).

    Args:
        text: the document; bytes are read as YAML reads them (UTF-8 or UTF-16).
        loader: a loader class derived from ``yaml.SafeLoader`` with bounds of its own (a
            platform config's), which raises :class:`YAMLNestedTooDeep` beyond its depth; by
            default the safe loader nesting at most :data:`MAX_DEPTH` levels.

    Returns:
        The decoded document.

    Raises:
        DocumentError: not valid YAML, or beyond the loader's bounds.
    """
    try:
        return yaml.load(text, Loader=loader or _BoundedLoader)
    except yaml.YAMLError as err:
        raise DocumentError(
            f"not valid YAML: {_yaml_problem(err)}", nested=isinstance(err, YAMLNestedTooDeep)
        ) from None
    except RecursionError:  # a loader without a depth bound
        raise DocumentError("not valid YAML: nested too deeply", nested=True) from None


def read_json(path: str | os.PathLike, limit: int, what: str = "JSON file") -> Any:
    """The JSON document in ``path``, read through :func:`read_regular`.

    Args:
        path: the file.
        limit: its largest size, bytes.
        what: the expected kind of file, named in messages.

    Returns:
        The decoded document.

    Raises:
        FileError: not a regular UTF-8 JSON file of at most ``limit`` bytes (the message names it).
    """
    data = read_regular(path, limit, what)
    try:
        return load_json(data)
    except DocumentError as err:
        raise FileError(path, err.problem) from None
