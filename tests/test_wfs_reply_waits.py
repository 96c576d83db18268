"""A command's reply on a line busy with frames, on both ends.

The device sends a reply before its next piece of frames, however the threads that stream frames
and answer commands are scheduled. The host counts a reply late only once it has read what arrived
at the port by the deadline: a reply waiting unread behind frames (the reader held by a full
lossless subscription, or not scheduled on a busy machine) is the host's delay, not the device's."""

from __future__ import annotations

import contextlib
import queue
import threading
import time

import pytest
import serial

from drivers.errors import CommandOutcomeUnknownError
from drivers.wfs_frame import FRAME_SIZE
from drivers.wfs_reader import WfsReader
from simulators.bench_sim import BenchRunner, SimulatedBench
from simulators.ports import MemoryLink, PtyLink
from simulators.wfs_device import WfsDevice
from tests.waiting import wait_until

TIMEOUT_S = 30.0


class HandDrainedLink:
    """A device link whose host takes each write only when the test lets it (:meth:`drain`)."""

    def __init__(self) -> None:
        self.writes: list[bytes] = []
        self.writers_waiting = 0
        self.commands: queue.Queue[bytes] = queue.Queue()
        self._room = threading.Semaphore(0)

    def drain(self, writes: int) -> None:
        """Let the host take ``writes`` more writes, and wait until it has."""
        expected = len(self.writes) + writes
        for _ in range(writes):
            self._room.release()
        wait_until(lambda: len(self.writes) >= expected, TIMEOUT_S, f"{expected} writes")

    def device_read(self, size: int, timeout_s: float) -> bytes:
        try:
            return self.commands.get(timeout=timeout_s)
        except queue.Empty:
            return b""

    def device_write(self, data: bytes, timeout_s: float) -> int:
        """Waits for the test's leave, whatever ``timeout_s``: the order of the writes is the test."""
        self.writers_waiting += 1
        taken = self._room.acquire(timeout=TIMEOUT_S)
        self.writers_waiting -= 1
        if not taken:
            return 0
        self.writes.append(bytes(data))
        return len(data)

    def disconnect(self) -> None:
        pass

    def reconnect(self) -> None:
        pass


def test_a_reply_goes_out_after_the_block_being_written_and_before_the_next():
    """The frames made before a command come before its reply (a host that stops the stream has
    every frame made before STOP), and the reply waits for no block made after it, however the
    streaming thread and the command thread are scheduled."""
    link = HandDrainedLink()
    bench = SimulatedBench.paper_shaker(seed=2)
    device = WfsDevice(link, bench, seed=3)
    device.execute("START", [])
    device.start()  # serves commands
    try:
        streaming = threading.Thread(target=device.deliver, args=(bench.advance(4 * 64),))
        streaming.start()  # four pieces of 64 frames
        wait_until(lambda: link.writers_waiting == 1, TIMEOUT_S, "the first piece on the line")
        link.commands.put(b"IDENT\n")
        wait_until(lambda: device.replies_waiting, TIMEOUT_S, "the reply queued")
        link.drain(4)  # the block's four pieces
        link.drain(1)  # then the reply
        streaming.join(TIMEOUT_S)
        assert link.writes[4].startswith(b"$OK,IDENT,"), link.writes[4][:20]
        assert [len(w) for w in link.writes[:4]] == [64 * FRAME_SIZE] * 4
        assert device.frames_sent == 4 * 64 and not device.replies_waiting
    finally:
        device.stop()


@contextlib.contextmanager
def held_reader(catch_up_limit_s: float):
    """A paced bench streaming to a reader held by a full lossless subscription: the frames, and any
    reply behind them, wait unread in the link (1 MiB, about 16 s of frames)."""
    link = MemoryLink(capacity=1 << 20)
    bench = SimulatedBench.paper_shaker(seed=2)
    device = WfsDevice(link, bench, seed=3)
    device.start()
    runner = BenchRunner(bench, paced=True)
    runner.sinks.append(device)
    runner.start()
    reader = WfsReader(link.open_host, catch_up_limit_s=catch_up_limit_s)
    reader.start()
    held = reader.subscribe(lossless=True, max_frames=10)
    try:
        reader.start_stream()
        assert held.get(TIMEOUT_S) is not None
        # the reader waits on the full subscription: nothing read for 0.2 s of a 1 kHz stream
        wait_until(lambda: time.monotonic() - reader.last_arrival_s > 0.2, TIMEOUT_S, "the reader held")
        yield device, reader, held
    finally:
        held.close()
        reader.close()
        runner.stop()
        device.stop()


def _command_in_thread(reader: WfsReader, name: str, timeout_s: float) -> tuple[threading.Thread, dict]:
    outcome: dict = {}

    def send() -> None:
        try:
            outcome["reply"] = reader.command(name, timeout_s=timeout_s)
        except Exception as exc:
            outcome["error"] = exc

    thread = threading.Thread(target=send)
    thread.start()
    return thread, outcome


def test_a_reply_waiting_unread_behind_frames_is_not_late():
    with held_reader(catch_up_limit_s=10.0) as (device, reader, held):
        thread, outcome = _command_in_thread(reader, "TARE", timeout_s=0.2)
        wait_until(lambda: bool(device.tare_offset.any()), TIMEOUT_S, "the device tared")  # and replied
        thread.join(0.5)  # past the deadline: the reply waits unread behind frames
        assert thread.is_alive(), outcome
        held.close()  # the reader reads on
        thread.join(TIMEOUT_S)
    assert "error" not in outcome and outcome["reply"].ok


def test_a_reader_that_never_catches_up_gives_up_after_its_limit():
    with (
        held_reader(catch_up_limit_s=0.3) as (_device, reader, _held),
        pytest.raises(CommandOutcomeUnknownError, match="TARE"),
    ):
        reader.command("TARE", timeout_s=0.2)


def test_a_device_write_made_after_its_deadline_still_goes_out_where_the_port_has_room():
    """A writer not scheduled until after its deadline (a busy machine) has not waited for the host:
    what fits in the pty's buffer now is written, not dropped as if the host had stopped reading."""
    link = PtyLink()
    try:
        with serial.serial_for_url(link.path, timeout=1.0) as host:
            assert link.device_write(b"$OK,TARE*00\r\n", timeout_s=-0.5) == 13
            assert host.read(13) == b"$OK,TARE*00\r\n"
    finally:
        link.close()
