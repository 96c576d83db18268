"""One master per device and one writer per campaign file: advisory locks that die with their process.

Every resource a run uses exclusively (the WFS port, the actuator controller's serial port or its
Modbus TCP address, the campaign file it writes) has a lock file in the lock directory
(``$WFSBENCH_LOCK_DIR``, else ``wfsbench-locks`` in the system's temporary directory, e.g.
``/tmp/wfsbench-locks``: one directory for every user of the PC, since two users may reach for the
same bench). The holder takes ``fcntl.flock(LOCK_EX | LOCK_NB)`` on that file and writes into it its
pid, its command line and what it holds. The kernel releases a flock when its process ends, however
it ends (kill -9 included), so a lock file left behind holds nothing and is simply taken by the next
process; lock files are never deleted (deleting one another process is about to lock would let two
processes hold "the same" lock). A process that finds the lock held is refused with
:class:`InUseError`, naming the holder from the file, before it opens, sends or reads anything.

Keys: a serial port by its real path (``/dev/serial/by-id/...`` and the ``/dev/ttyUSB0`` it points
at are one port), a Modbus TCP controller by host and port (the host resolved to its address where
the resolver answers at once, so ``localhost`` and ``127.0.0.1`` are one controller), a campaign file
by its real path. Within one process a lock is re-entrant (the run and its file writer share the
campaign file's).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import hashlib
import json
import os
import re
import shlex
import socket
import sys
import tempfile
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

#: The environment variable naming the lock directory.
LOCK_DIR_ENV = "WFSBENCH_LOCK_DIR"
_COMMAND_CHARS = 200  # of the holder's command line recorded


def lock_dir() -> Path:
    """Where the lock files are: ``$WFSBENCH_LOCK_DIR``, else ``<tmp>/wfsbench-locks``."""
    return Path(os.environ.get(LOCK_DIR_ENV) or Path(tempfile.gettempdir()) / "wfsbench-locks")


def serial_key(device: str) -> str:
    """The key of a serial port (a device path, or a pyserial URL such as ``socket://h:p``)."""
    if "://" in device:
        return f"serial:{device}"
    return f"serial:{os.path.realpath(device)}"


def tcp_key(host: str, port: int) -> str:
    """The key of a Modbus TCP controller."""
    with contextlib.suppress(OSError, UnicodeError):
        host = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0][4][0]
    return f"modbus-tcp:{host}:{port}"


def file_key(path: str | Path) -> str:
    """The key of a file written exclusively (a campaign file)."""
    return f"file:{os.path.realpath(path)}"


@dataclass(frozen=True)
class Holder:
    """Who holds a lock: its process id, command line and what it said it holds."""

    pid: int
    command: str
    what: str

    def __str__(self) -> str:
        if self.pid <= 0:
            return "another process"
        return f"process {self.pid} ({self.command})" if self.command else f"process {self.pid}"


class InUseError(RuntimeError):
    """``what`` is held by another process (``holder``: who, when its lock file says)."""

    def __init__(self, what: str, holder: Holder | None) -> None:
        self.what, self.holder = what, holder
        super().__init__(f"{what} is in use by {holder or 'another process'}")


class LockDirError(ValueError):
    """The lock directory cannot be used (``$WFSBENCH_LOCK_DIR`` names a file, a place under one, or
    a directory this user may not write): nothing was opened."""

    def __init__(self, directory: Path, reason: str) -> None:
        super().__init__(
            f"the lock directory {directory} cannot be used ({reason}): set {LOCK_DIR_ENV} to a"
            " directory every user of the bench may write, or leave it unset"
        )


def _lock_path(key: str) -> Path:
    readable = re.sub(r"[^A-Za-z0-9._-]+", "_", key).strip("_")[-80:]
    digest = hashlib.sha256(key.encode()).hexdigest()[:12]
    return lock_dir() / f"{readable}-{digest}.lock"


def _open_lock_file(path: Path) -> tuple[int, bool]:
    """An fd on the lock file (created readable and writable by every user), and whether it can be
    written (a file another user created before may be read-only to us: flock works on it all the
    same)."""
    directory = path.parent
    try:
        if not directory.is_dir():
            with contextlib.suppress(FileExistsError):
                directory.mkdir(parents=True)
                with contextlib.suppress(OSError):
                    os.chmod(directory, 0o1777)  # shared like /tmp: every user may add lock files
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)
        except PermissionError:
            return os.open(path, os.O_RDONLY | os.O_CLOEXEC), False
    except OSError as exc:
        raise LockDirError(directory, exc.strerror or str(exc)) from None
    with contextlib.suppress(OSError):
        os.fchmod(fd, 0o666)
    return fd, True


def _command_line() -> str:
    argv = [Path(sys.argv[0]).name, *sys.argv[1:]] if sys.argv and sys.argv[0] else ["python"]
    text = shlex.join(argv)
    return text if len(text) <= _COMMAND_CHARS else text[: _COMMAND_CHARS - 3] + "..."


def _read_holder(fd: int) -> Holder | None:
    try:
        data = json.loads(os.pread(fd, 4096, 0).decode("utf-8"))
        return Holder(int(data["pid"]), str(data.get("command", "")), str(data.get("what", "")))
    except (OSError, ValueError, KeyError, TypeError):
        return None  # empty (the holder is writing it now) or not ours


_held: dict[str, list[int]] = {}  # key -> [fd, count] of the locks this process holds
_held_guard = threading.Lock()


def acquire(key: str, what: str) -> None:
    """Take the lock of ``key`` (``what`` describes the resource to a person, e.g. "the WFS port
    /dev/ttyUSB0"); :class:`InUseError` naming the holder if another process has it. Re-entrant
    within a process: each acquire needs its :func:`release`."""
    with _held_guard:
        if key in _held:
            _held[key][1] += 1
            return
        path = _lock_path(key)
        fd, writable = _open_lock_file(path)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            holder = _read_holder(fd)
            os.close(fd)
            if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise InUseError(what, holder) from None
            raise
        if writable:
            record = {"pid": os.getpid(), "command": _command_line(), "what": what}
            os.ftruncate(fd, 0)
            os.pwrite(fd, json.dumps(record).encode("utf-8"), 0)
        _held[key] = [fd, 1]


def release(key: str) -> None:
    """Give back one :func:`acquire` of ``key``; the last one unlocks it."""
    with _held_guard:
        entry = _held.get(key)
        if entry is None:
            return
        entry[1] -= 1
        if entry[1] == 0:
            del _held[key]
            with contextlib.suppress(OSError):
                os.ftruncate(entry[0], 0)  # nobody holds it: no holder to name
            os.close(entry[0])  # closing the last fd of the file releases the flock


@contextlib.contextmanager
def holding(key: str, what: str) -> Iterator[None]:
    """:func:`acquire` for the ``with`` block."""
    acquire(key, what)
    try:
        yield
    finally:
        release(key)


def holder_of(key: str) -> Holder | None:
    """Who holds ``key``'s lock now (None: nobody, or this process; a holder of pid 0 when the lock is
    held but its file names nobody). Only looks: takes nothing."""
    with _held_guard:
        if key in _held:
            return None
    path = _lock_path(key)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_CLOEXEC)
    except OSError:
        return None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except OSError:
            return _read_holder(fd) or Holder(0, "", "")
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)
