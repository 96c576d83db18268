"""A host stopped inside the reader's read is told apart from a quiet line.

A process stopped (SIGSTOP, a debugger, a suspended machine) while its reader thread waits in the
port's read system call comes back with the read returning at once and the port full of what
arrived meanwhile, though nothing was waiting when the read was called. The reader counts such a
read's wait as unread time (the host's stall), where a read that waited for a quiet line counts
none. On a real pseudo-terminal, the stop played by a port whose read the test holds, as the
operating system holds a stopped process's; and a consumer whose own wait the host held past its
timeout is handed what the reader then reads from the port, not an empty wait."""

from __future__ import annotations

import itertools
import os
import threading
import time
import tty

import numpy as np
import pytest
import serial

from drivers.wfs_frame import encode, new_frames
from drivers.wfs_reader import CATCH_UP_AFTER_HOLD_S, SampleBlock, Subscription, WfsReader
from tests.waiting import wait_until

#: The port's read timeout (s): the reader's default.
READ_TIMEOUT_S = 0.02
#: How long the test holds the reader inside its read (s): the host's stop.
HOLD_S = 0.4
#: How long the line stays quiet in the test of a quiet line (s).
QUIET_S = 0.4


def frames(first: int, n: int) -> bytes:
    """``n`` valid frames numbered from ``first``, as the device sends them."""
    block = new_frames(n)
    block["seq"] = np.arange(first, first + n)
    block["sample"] = block["seq"]
    return encode(block)


class HeldPort:
    """A pyserial port on a pty whose reads the test can hold: once ``armed``, the next read called
    with nothing waiting at the port sets ``entered`` and blocks until ``released``, as a process
    stopped inside the read's system call does; then it reads the port as it finds it."""

    def __init__(self, path: str) -> None:
        self.port = serial.serial_for_url(path, baudrate=921600, timeout=READ_TIMEOUT_S)
        self.timeout = self.port.timeout
        self.armed, self.entered, self.released = threading.Event(), threading.Event(), threading.Event()

    def read(self, size: int = 1) -> bytes:
        if self.armed.is_set() and self.port.in_waiting == 0:
            self.armed.clear()
            self.entered.set()
            self.released.wait(10)
        return self.port.read(size)

    @property
    def in_waiting(self) -> int:
        return self.port.in_waiting

    def write(self, data: bytes) -> int | None:
        return self.port.write(data)

    def close(self) -> None:
        self.port.close()


@pytest.fixture
def pty_port():
    """A raw pty: its master (the device's end) and a held port on its slave (the host's)."""
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    port = HeldPort(os.ttyname(slave))
    try:
        yield master, port
    finally:
        port.released.set()
        for fd in (master, slave):
            os.close(fd)


def test_a_read_held_while_bytes_fill_the_port_counts_the_hold_as_unread(pty_port):
    master, port = pty_port
    with WfsReader(lambda: port) as reader:
        sub = reader.subscribe(lossless=True, max_frames=100_000)
        os.write(master, frames(0, 10))
        first = sub.read_frames(10, timeout_s=5)
        port.armed.set()
        assert port.entered.wait(5), "the reader did not call a read"
        held_from = time.monotonic()  # the reader waits in its read, nothing at the port
        data = frames(10, 50)  # 3,200 bytes: the port's buffer (4,095) keeps them all
        os.write(master, data)
        wait_until(lambda: port.in_waiting == len(data), 5, "the bytes at the port")
        assert reader.link_silence_s() == 0.0  # bytes wait at the port: the host's delay, no silence
        threading.Event().wait(HOLD_S)  # the host stays stopped
        released_at = time.monotonic()
        port.released.set()
        after = sub.read_frames(50, timeout_s=5)
        done_at = time.monotonic()
    assert len(after) == 50 and not after.gaps  # nothing lost: the port kept them
    assert after.unread_s >= max(HOLD_S, released_at - held_from)
    assert after.unread_s <= done_at - first.arrived_s  # from the read before the hold at the earliest
    assert reader.longest_unread_s >= after.unread_s
    assert reader.largest_backlog_bytes >= len(data)


def test_a_read_that_waited_for_a_quiet_line_counts_no_unread_time(pty_port):
    """The line's silence is not the host's: the reader read all along, its reads timing out."""
    master, port = pty_port
    with WfsReader(lambda: port) as reader:
        sub = reader.subscribe(lossless=True, max_frames=100_000)
        os.write(master, frames(0, 10))
        sub.read_frames(10, timeout_s=5)
        threading.Event().wait(QUIET_S)  # the device says nothing
        assert reader.link_silence_s() >= QUIET_S
        os.write(master, frames(10, 10))
        after = sub.read_frames(10, timeout_s=5)
    assert not after.gaps
    assert after.unread_s < QUIET_S / 2


def _held_clock():
    """A clock for which a wait took a second longer than it did: the host held the waiting thread
    (its first reading is the wait's start, the later ones a second on)."""
    calls = itertools.count()
    return lambda: time.monotonic() + (1.0 if next(calls) else 0.0)


def test_a_wait_the_host_held_past_its_timeout_gets_the_block_the_reader_then_reads():
    """The consumer's wait ends, held, with nothing queued: the reader, held with it, has not read
    the port since before. It waits on until the reader hands over what the port held."""
    looked = threading.Event()

    def parsed_through() -> float:
        looked.set()
        return float("-inf")  # the reader has not parsed the port since before the hold

    sub = Subscription(
        lossless=True,
        max_frames=1000,
        on_close=lambda s: None,
        parsed_through=parsed_through,
        clock=_held_clock(),
    )
    got: list[SampleBlock | None] = []
    consumer = threading.Thread(target=lambda: got.append(sub.get_all(0.05)))
    consumer.start()
    assert looked.wait(5), "the consumer did not wait for the reader"
    block = SampleBlock(new_frames(64), unread_s=1.0)
    sub._offer(block, threading.Event())  # the reader hands over the stall's block
    consumer.join(5)
    assert len(got) == 1 and got[0] is block


def test_a_held_wait_ends_empty_once_the_reader_has_read_the_port():
    """The reader has parsed everything that arrived by the wait's end: the line was quiet."""
    sub = Subscription(
        lossless=True,
        max_frames=1000,
        on_close=lambda s: None,
        parsed_through=lambda: float("inf"),
        clock=_held_clock(),
    )
    started = time.monotonic()
    assert sub.get_all(0.05) is None
    assert time.monotonic() - started < 0.05 + CATCH_UP_AFTER_HOLD_S


def test_a_wait_within_its_timeout_ends_empty_without_looking_at_the_reader():
    """A wait that ended at its timeout saw the reader hand over nothing: the line was quiet."""
    consulted = []
    sub = Subscription(
        lossless=True,
        max_frames=1000,
        on_close=lambda s: None,
        parsed_through=lambda: consulted.append(True) or float("-inf"),
        clock=lambda: 0.0,  # the wait took no longer than its timeout, however loaded the machine
    )
    assert sub.get_all(0.05) is None
    assert consulted == []
