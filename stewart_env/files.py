"""The package's file machinery: one writer per output folder, atomic publication, safe reading
of files someone else may have put in a folder, content hashes and a writability check.

Every command that writes a run (``train``, ``mismatch``, ``evaluate --out``) holds
:func:`lock_folder` on its output folder for as long as it writes: an exclusive ``flock`` on
``.stewart-env.lock`` inside it, which the operating system releases when the process ends,
however it ends, so a killed run never leaves its folder locked.  A second command on the same
folder is refused at once with :class:`FolderBusy`, naming the folder and the holder's PID.  (On
a system without ``flock``, Windows, folders are not locked.)

Every file is published with :func:`publishing` (or :func:`publish` for bytes and text, and
:func:`publishing_folder` for a folder of files): written under a temporary name unique to the
process in the same directory, flushed to disk, then renamed over the target, so a reader sees
the old file or the whole new one; on any error the temporary file is removed and the error is a
:class:`WriteError` naming the target and the cause (a full disk is "No space left on device").

Every file read from a folder the package did not just write goes through :func:`open_regular`
(or :func:`read_regular`, :func:`read_json`, :func:`sha256_file`): regular files only, opened without blocking (a
named pipe would wait for a writer for ever), checked by ``fstat`` after opening (a symbolic link
to ``/dev/zero`` is a device), and bounded in size before a byte is read.

This module imports nothing from the rest of the package: it sits below every layer.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import os
import shutil
import stat
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any, BinaryIO

from stewart_env.errors import UsageError

try:
    import fcntl
except ImportError:  # no flock (Windows): folders are not locked there
    fcntl = None

__all__ = ["LOCK_FILE", "TMP_PREFIX", "FileError", "FolderBusy", "NotWritable", "WriteError", "check_not_busy",
           "check_writable", "lock_folder", "open_regular", "publish", "publishing", "publishing_folder", "read_json",
           "read_regular", "sha256_file", "write_error"]

#: The lock file of an output folder (see :func:`lock_folder`).
LOCK_FILE = ".stewart-env.lock"
#: Prefix of every temporary file and folder: readers of a folder pass over these names.
TMP_PREFIX = ".tmp-"
#: Bytes of the holder's PID read back from a lock file.
_PID_BYTES = 32
#: Tries, and seconds between them, to take a lock that :func:`check_not_busy` of another command
#: may hold for an instant; a lock still held after them belongs to a command that runs.
_LOCK_ATTEMPTS, _LOCK_RETRY_SECONDS = 20, 0.01


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
        super().__init__(path, f"in use by another stewart-env command ({holder}); wait for it to end, or choose "
                               "another output directory")
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
    try:
        fd = os.open(lock, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOFOLLOW", 0))
    except (OSError, ValueError):
        return  # no lock file, or one :func:`lock_folder` will report on
    try:
        if stat.S_ISREG(os.fstat(fd).st_mode):
            try:
                fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
            except OSError as err:
                if err.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                    raise FolderBusy(directory, _holder(fd)) from None
    finally:
        os.close(fd)


@contextlib.contextmanager
def lock_folder(directory: str | os.PathLike, create: bool = True) -> Iterator[Path]:
    """Hold the exclusive lock of ``directory`` inside the block.

    A lock file in the folder, locked with ``flock``, which the system releases when the process
    ends however it ends.

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
    try:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0), 0o644)
    except OSError as err:
        raise FileError(lock, f"cannot open the folder's lock file: {_cause(err)}") from None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise FileError(lock, "not a regular file; remove it")
        for attempt in range(_LOCK_ATTEMPTS):
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except OSError as err:
                if err.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                    raise FileError(lock, f"cannot lock the folder: {_cause(err)}") from None
                if attempt == _LOCK_ATTEMPTS - 1:
                    raise FolderBusy(path, _holder(fd)) from None
                time.sleep(_LOCK_RETRY_SECONDS)  # perhaps only another command's check_not_busy, a moment long
        with contextlib.suppress(OSError):  # the PID is for the message of a second command only
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        yield path
    finally:
        os.close(fd)  # closing the descriptor releases the lock


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


@contextlib.contextmanager
def publishing(path: str | os.PathLike) -> Iterator[Path]:
    """A temporary path, unique to this call, next to ``path``, published over ``path`` at the end.

    Whatever the block writes there is flushed and renamed over ``path`` when the block ends, and
    removed if it raises.

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
        fd, name = tempfile.mkstemp(prefix=f"{TMP_PREFIX}{path.stem}-", suffix=path.suffix, dir=path.parent)
        os.close(fd)
    except OSError as err:
        raise write_error(path, err) from None
    with _replacing(path, Path(name)) as tmp:
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
    removed first); if the block raises it is removed.

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
        tmp = Path(tempfile.mkdtemp(prefix=f"{TMP_PREFIX}{path.name}-", dir=path.parent))
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
            data = f.read(limit + 1)
        except OSError as err:
            raise FileError(path, f"cannot read the file: {_cause(err)}") from None
    if len(data) > limit:
        raise FileError(path, f"larger than {limit} bytes")
    return data


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
            for block in iter(lambda: f.read(1 << 20), b""):
                digest.update(block)
        except OSError as err:
            raise FileError(path, f"cannot read the file: {_cause(err)}") from None
    return digest.hexdigest()


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
        return json.loads(data.decode("utf-8"))
    except UnicodeDecodeError as err:
        raise FileError(path, f"not valid JSON (not UTF-8 text: invalid byte at offset {err.start})") from None
    except json.JSONDecodeError as err:
        raise FileError(path, f"not valid JSON ({err})") from None
