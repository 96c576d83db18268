"""Transports for the simulated serial devices: an in-memory link, a pseudo-terminal, a pty pair.

The in-memory link and the pty link carry the WFS stream; both can be disconnected and reconnected,
as a USB-serial adapter that is pulled and plugged back: the host's reads fail while the link is
down and the host reopens the same name afterwards. The pty bridge joins two serial ports for a
device that opens its port by name (the Modbus RTU server).

**Backpressure or overrun.** By default the device's writes wait while the host lags (the pty's
kernel buffers, about 16 KiB, then the device's own wait): a simulated bench that runs as fast as
its host reads needs that. A real UART cannot wait: its bytes arrive at the line rate whether the
host reads or not, and what finds the host's receive buffer full is lost (an overrun). With
``rx_buffer_bytes`` the links behave so: the host's buffer holds that many bytes
(:data:`TTY_RX_BUFFER_BYTES` for a real tty), each byte is due at the host when it would have crossed
the wire (10 bits per byte at ``baudrate``) and is dropped if the buffer is full then; the dropped
bytes are counted (``bytes_overrun``) and the host sees the loss as frames missing.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import select
import struct
import tempfile
import termios
import threading
import time
import tty
from pathlib import Path

import serial

#: The host's receive buffer of a real serial port on Linux, in bytes: the N_TTY line discipline's
#: read buffer, ``N_TTY_BUF_SIZE`` = 4096 (include/linux/tty.h), of which ``n_tty_receive_buf_common``
#: (drivers/tty/n_tty.c) keeps one byte free in raw mode, so 4095 bytes wait for the reader (FIONREAD
#: on a raw pty stops at 4095). Once it is full, a USB-serial adapter's driver throttles (stops
#: reading the adapter) and the adapter's own FIFO (FT232R: 256 bytes, FT232H: 1 KiB) overruns
#: within 3-11 ms at 921600 baud: a host that stops reading for longer than 4095 bytes take on the
#: line (44 ms at 921600 baud; 64 ms of 1 kHz frames) loses bytes.
TTY_RX_BUFFER_BYTES = 4095
#: how often a link whose host buffer is full looks again for room (s)
_OVERRUN_POLL_S = 0.001


class _Pipe:
    """A one-way byte pipe with blocking reads (timeout) and a bounded buffer (blocking writes)."""

    def __init__(self, capacity: int, *, overrun: bool = False) -> None:
        self.capacity = capacity
        self.overrun = overrun  # a full buffer drops what does not fit instead of waiting
        self.bytes_overrun = 0
        self.buf = bytearray()
        self.cond = threading.Condition()
        self.closed = False

    def write(self, data: bytes, timeout_s: float | None = None) -> int:
        if self.overrun:
            with self.cond:
                if self.closed:
                    raise serial.SerialException("link is down")
                room = max(self.capacity - len(self.buf), 0)
                self.buf += data[:room]
                self.bytes_overrun += max(len(data) - room, 0)
                self.cond.notify_all()
                return len(data)
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        with self.cond:
            sent = 0
            while sent < len(data):
                if self.closed:
                    raise serial.SerialException("link is down")
                room = self.capacity - len(self.buf)
                if room <= 0:
                    left = None if deadline is None else deadline - time.monotonic()
                    if left is not None and left <= 0:
                        break
                    self.cond.wait(left)
                    continue
                self.buf += data[sent : sent + room]
                sent += min(room, len(data) - sent)
                self.cond.notify_all()
            return sent

    def read(self, size: int, timeout_s: float | None) -> bytes:
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        with self.cond:
            while len(self.buf) < size and not self.closed:
                left = None if deadline is None else deadline - time.monotonic()
                if left is not None and left <= 0:
                    break
                self.cond.wait(left)
            return self._take(size)

    def read_some(self, size: int, timeout_s: float) -> bytes:
        """Whatever is there (at most ``size``) as soon as anything is, or b"" after ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        with self.cond:
            while not self.buf and not self.closed and (left := deadline - time.monotonic()) > 0:
                self.cond.wait(left)
            return self._take(size)

    def _take(self, size: int) -> bytes:
        """Up to ``size`` buffered bytes (the caller holds ``cond``); a closed link raises."""
        if self.closed:
            raise serial.SerialException("link is down")
        out = bytes(self.buf[:size])
        del self.buf[:size]
        self.cond.notify_all()
        return out

    def close(self) -> None:
        with self.cond:
            self.closed = True
            self.cond.notify_all()


class MemoryEnd:
    """One end of a :class:`MemoryLink`, with the ``read``/``write``/``close`` of a serial port."""

    def __init__(self, rx: _Pipe, tx: _Pipe, timeout: float | None) -> None:
        self._rx, self._tx = rx, tx
        self.timeout = timeout

    def read(self, size: int = 1) -> bytes:
        return self._rx.read(size, self.timeout)

    def write(self, data: bytes) -> int:
        return self._tx.write(bytes(data))

    @property
    def in_waiting(self) -> int:
        return len(self._rx.buf)

    def close(self) -> None:
        self._rx.close()
        self._tx.close()


class MemoryLink:
    """A bidirectional in-memory serial link between a device and a host, for fast unit tests.

    ``rx_buffer_bytes``: the host's receive buffer overruns at that size instead of holding up the
    device (no wire timing: what does not fit when written is dropped at once)."""

    def __init__(self, capacity: int = 65536, *, rx_buffer_bytes: int | None = None) -> None:
        self.capacity = capacity if rx_buffer_bytes is None else rx_buffer_bytes
        self.overrun = rx_buffer_bytes is not None
        self._overrun_before = 0
        self._lock = threading.Lock()
        self._connect()

    @property
    def bytes_overrun(self) -> int:
        """Bytes dropped because the host's receive buffer was full (every connection so far)."""
        return self._overrun_before + self._to_host.bytes_overrun

    def _connect(self) -> None:
        if hasattr(self, "_to_host"):
            self._overrun_before += self._to_host.bytes_overrun
        self._to_host = _Pipe(self.capacity, overrun=self.overrun)
        self._to_device = _Pipe(self.capacity)
        self.device_end = MemoryEnd(self._to_device, self._to_host, timeout=0.05)
        self._host_taken = False

    def open_host(self, timeout_s: float = 0.05) -> MemoryEnd:
        """The host's end (what the reader opens); fails while the link is down."""
        with self._lock:
            if self._to_host.closed or self._host_taken:
                raise serial.SerialException("memory link is down")
            self._host_taken = True
            return MemoryEnd(self._to_host, self._to_device, timeout=timeout_s)

    def device_read(self, size: int, timeout_s: float) -> bytes:
        """What the host sent (up to ``size`` bytes, waiting at most ``timeout_s``); raises while down."""
        return self._to_device.read_some(size, timeout_s)

    def device_write(self, data: bytes, timeout_s: float) -> int:
        """Queue bytes for the host; blocks while the host lags (backpressure); raises while down."""
        return self._to_host.write(data, timeout_s)

    def disconnect(self) -> None:
        with self._lock:
            self._to_host.close()
            self._to_device.close()

    def reconnect(self) -> None:
        with self._lock:
            self._connect()


#: The directories that hold the pty symlinks are named after their process, so that those of a
#: killed process (no cleanup ran) are recognised and removed by the next one.
_LINK_DIR_PREFIX = "wfs-pty-"


def _new_link_dir() -> Path:
    """A fresh directory for pty symlinks, after removing those of processes that are gone."""
    for stale in Path(tempfile.gettempdir()).glob(f"{_LINK_DIR_PREFIX}*-*"):
        pid = stale.name[len(_LINK_DIR_PREFIX) :].split("-", 1)[0]
        if pid.isdigit() and not _process_alive(int(pid)):
            for entry in stale.iterdir():
                if entry.is_symlink():  # only what a link dir holds; anything else keeps the dir
                    entry.unlink(missing_ok=True)
            with contextlib.suppress(OSError):
                stale.rmdir()
    return Path(tempfile.mkdtemp(prefix=f"{_LINK_DIR_PREFIX}{os.getpid()}-"))


def _process_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process
        return True
    return True


class PtyLink:
    """A pseudo-terminal: the device holds the master, the host opens ``path`` like a serial port.

    ``path`` is a stable symlink to the current slave (as udev's /dev/serial/by-id names): a
    reconnect creates a fresh pty and moves the link, and the host reopens the same name.
    """

    def __init__(
        self, link_dir: str | None = None, *, rx_buffer_bytes: int | None = None, baudrate: int = 921600
    ) -> None:
        """``rx_buffer_bytes``: overrun like a UART whose host buffer holds that many bytes (at most
        :data:`TTY_RX_BUFFER_BYTES`, what a pty's line discipline holds), bytes crossing the wire at
        ``baudrate``; None: the device waits for the host (backpressure)."""
        if rx_buffer_bytes is not None and not 0 < rx_buffer_bytes <= TTY_RX_BUFFER_BYTES:
            raise ValueError(f"rx_buffer_bytes must be 1..{TTY_RX_BUFFER_BYTES}, got {rx_buffer_bytes}")
        self._dir = Path(link_dir) if link_dir else _new_link_dir()
        self.path = str(self._dir / "wfs")
        self.master_fd = -1
        self._slave_fd = -1
        self.rx_buffer_bytes = rx_buffer_bytes
        self.byte_s = 10 / baudrate  # 8N1
        self.bytes_overrun = 0  # dropped because the host's buffer was full
        self._wire_free_s = 0.0  # when the wire has carried every byte written so far
        self._connect()

    def _connect(self) -> None:
        master, slave = os.openpty()
        tty.setraw(master)
        tty.setraw(slave)  # no echo, no line discipline: a binary link
        os.set_blocking(master, False)
        self.master_fd, self._slave_fd = master, slave
        tmp = self.path + ".new"
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        os.symlink(os.ttyname(slave), tmp)
        os.replace(tmp, self.path)

    def device_read(self, size: int, timeout_s: float) -> bytes:
        """What the host sent, or b"" after ``timeout_s``; raises OSError while down."""
        fd = self.master_fd
        if fd < 0:
            raise OSError("pty link is down")
        ready, _, _ = select.select([fd], [], [], timeout_s)
        return os.read(fd, size) if ready else b""

    def device_write(self, data: bytes, timeout_s: float) -> int:
        """Write to the host; waits while the pty buffer is full (backpressure), up to ``timeout_s``.
        With a receive buffer (``rx_buffer_bytes``), bytes the host's buffer has no room for when they
        arrive are dropped instead (see the module docstring): every byte counts as sent."""
        fd = self.master_fd
        if fd < 0:
            raise OSError("pty link is down")
        if self.rx_buffer_bytes is not None:
            return self._write_overrunning(fd, data)
        deadline = time.monotonic() + timeout_s
        sent = 0
        view = memoryview(data)
        while sent < len(data):
            left = deadline - time.monotonic()
            # looked at even past the deadline: a writer not scheduled until after it has not waited
            # for the host, whose buffer may have room by now
            _, ready, _ = select.select([], [fd], [], max(left, 0.0))
            written = 0
            if ready:
                with contextlib.suppress(BlockingIOError):
                    written = os.write(fd, view[sent:])
            sent += written
            if not written and left <= 0:
                break
        return sent

    def _waiting(self) -> int:
        """Bytes the host's line discipline holds for it (FIONREAD on the slave); OSError while down."""
        fd = self._slave_fd
        if fd < 0:
            raise OSError("pty link is down")
        return struct.unpack("i", fcntl.ioctl(fd, termios.FIONREAD, b"\0\0\0\0"))[0]

    def _write_overrunning(self, fd: int, data: bytes) -> int:
        """Put ``data`` on the wire: each byte is due at the host ``byte_s`` after the one before
        (from when the wire is free); bytes written as soon as the host's buffer has room, and a byte
        still without room when it is due is dropped (``bytes_overrun``)."""
        now = time.monotonic()
        start = max(now, self._wire_free_s)
        self._wire_free_s = start + len(data) * self.byte_s
        view = memoryview(data)
        done = 0  # bytes written or dropped
        while done < len(data):
            waiting = self._waiting()
            room = self.rx_buffer_bytes - waiting
            if room > 0:
                try:
                    written = os.write(fd, view[done : done + room])
                except BlockingIOError:
                    written = 0
                if written:
                    done += written
                    self._settle(waiting)
                    continue
            # no room: the bytes due by now are lost
            due = min(len(data), int((time.monotonic() - start) / self.byte_s) + 1)
            if due > done:
                self.bytes_overrun += due - done
                done = due
                continue
            time.sleep(max(min(_OVERRUN_POLL_S, start + (done + 1) * self.byte_s - time.monotonic()), 0.0))
        return len(data)

    def _settle(self, before: int) -> None:
        """Wait (at most 2 ms) until written bytes reach the line discipline, which the pty does
        asynchronously (about 10 us), so that the next look at the host's buffer counts them."""
        deadline = time.monotonic() + 0.002
        while self._waiting() == before and time.monotonic() < deadline:
            pass

    def disconnect(self) -> None:
        """Close both sides: the host's reads fail, as when an adapter is pulled."""
        for fd in (self.master_fd, self._slave_fd):
            with contextlib.suppress(OSError):
                os.close(fd)
        self.master_fd = self._slave_fd = -1
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self.path)

    def reconnect(self) -> None:
        self._connect()

    def close(self) -> None:
        self.disconnect()
        with contextlib.suppress(OSError):
            self._dir.rmdir()


class PtyBridge:
    """Two pseudo-terminals joined back to back, as a null-modem cable between two serial ports.

    A program opens ``device_path`` (the simulated controller's serial port) and another opens
    ``host_path`` (the host's): bytes written to one arrive at the other. Both are raw (no echo, no
    line discipline); a pty carries no parity or modem lines, so use 8N1 and leave RTS/DTR alone.
    A thread copies between the two masters until :meth:`close`.
    """

    def __init__(self, name: str, link_dir: str | None = None) -> None:
        self._dir = Path(link_dir) if link_dir else _new_link_dir()
        self.host_path = str(self._dir / name)
        self.device_path = str(self._dir / f"{name}-device")
        self._fds: list[int] = []
        masters = []
        for path in (self.host_path, self.device_path):
            master, slave = os.openpty()
            tty.setraw(master)
            tty.setraw(slave)
            os.symlink(os.ttyname(slave), path)
            self._fds += [master, slave]  # the slave stays open so the master never reads EIO
            masters.append(master)
        self._masters = masters
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._copy, name=f"pty-bridge-{name}", daemon=True)
        self._thread.start()

    def _copy(self) -> None:
        host, device = self._masters
        peer = {host: device, device: host}
        while not self._stop.is_set():
            ready, _, _ = select.select(self._masters, [], [], 0.05)
            for fd in ready:
                try:
                    data = os.read(fd, 4096)
                except OSError:
                    continue
                view = memoryview(data)
                while view:
                    view = view[os.write(peer[fd], view) :]

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        for fd in self._fds:
            with contextlib.suppress(OSError):
                os.close(fd)
        for path in (self.host_path, self.device_path):
            with contextlib.suppress(FileNotFoundError):
                os.unlink(path)
        with contextlib.suppress(OSError):
            self._dir.rmdir()
