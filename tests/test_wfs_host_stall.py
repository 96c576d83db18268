"""A host stall on the paced simulated bench overruns the WFS link's receive buffer, as on real
hardware, and the reader counts the frames lost, says when the bytes after the stall arrived and how
long the port went unread (what an engine needs to record the stall as a host stall).

The stall is injected into the reader itself: its lossless consumer stops taking blocks for 2 s, so
the reader thread is held once the subscription is full and the port goes unread; the device goes
on in real time at 1 kHz over a real pseudo-terminal whose receive buffer holds
``TTY_RX_BUFFER_BYTES`` (docs/protocols.md)."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from drivers.wfs_frame import FRAME_SIZE
from drivers.wfs_reader import WfsReader
from simulators.bench_sim import BenchRunner, SimulatedBench
from simulators.ports import TTY_RX_BUFFER_BYTES, MemoryLink, PtyLink
from simulators.wfs_device import WfsDevice
from tests.waiting import wait_until

STALL_S = 2.0
QUEUE_FRAMES = 100  # the consumer's subscription: full after 0.1 s of frames, then the reader waits


def _paced_rig(link):
    bench = SimulatedBench.paper_shaker(seed=2)
    device = WfsDevice(link, bench, seed=3)
    runner = BenchRunner(bench, paced=True)
    runner.sinks.append(device)
    device.start()
    runner.start()
    return device, runner


def _consume_with_a_stall(reader: WfsReader, device: WfsDevice) -> tuple[list, int]:
    """Take 500 frames, hold for STALL_S (the injected host stall), then take 1000 more frames; the
    blocks taken and the frames the device sent during the stall (about 2000: fewer where a busy
    machine starves the paced device in this process)."""
    blocks = []
    sub = reader.subscribe(lossless=True, max_frames=QUEUE_FRAMES)
    reader.start_stream()
    blocks.append(sub.read_frames(500, timeout_s=20))
    sent_before = device.frames_sent
    threading.Event().wait(STALL_S)  # the host stall itself: nothing taken, the reader is held
    sent_during = device.frames_sent - sent_before
    blocks.extend(sub.get(5) for _ in range(3))
    have = 0
    while have < 1000:
        block = sub.get(5)
        assert block is not None, "the stream did not come back after the stall"
        blocks.append(block)
        have += len(block)
    sub.close()  # first: a full lossless subscription would hold the reader and STOP's reply
    reader.stop_stream()
    return [b for b in blocks if b is not None], sent_during


def test_a_host_stall_overruns_the_paced_link_and_the_lost_frames_are_counted():
    link = PtyLink(rx_buffer_bytes=TTY_RX_BUFFER_BYTES)
    device, runner = _paced_rig(link)
    reader = WfsReader.serial(link.path, baudrate=921600)
    reader.start()
    try:
        assert reader.wait_connected(5)
        blocks, sent_during = _consume_with_a_stall(reader, device)
        counters = reader.counters
    finally:
        reader.close()
        runner.stop()
        device.stop()
        link.close()
    assert runner.error is None
    seq = np.concatenate([b.frames["seq"] for b in blocks]).astype(np.int64)
    missing = sum(b.frames_missing for b in blocks)
    # counters exact: every frame between the first and the last delivered is delivered or missing
    assert np.all(np.diff(seq) > 0)
    assert len(seq) + missing == seq[-1] - seq[0] + 1
    assert counters.frames_missing == missing and counters.frames_rejected == 0
    # what was lost is what overran the link's buffer (each stretch of lost bytes cuts a frame or two)
    assert link.bytes_overrun > 0
    assert abs(missing - link.bytes_overrun / FRAME_SIZE) <= 2 * counters.gaps + 1
    assert device.frames_dropped == 0  # the device never waited: the loss is the host's
    # the first block after the stall says the port went unread for most of the stall; its frames
    # are what the receive buffer held, and the gap comes with the first frame after the overrun,
    # in that read or the next ones
    (after,) = [i for i, b in enumerate(blocks) if b.unread_s > STALL_S / 2]
    stall_missing = sum(b.frames_missing for b in blocks[after : after + 3])
    # the stall lost most of the frames sent meanwhile: all but what the subscription and the port
    # held (a busy machine's own stalls of more than the port's 64 ms may lose a few more elsewhere)
    assert sent_during > STALL_S * 1000 / 4
    assert stall_missing >= sent_during - QUEUE_FRAMES - TTY_RX_BUFFER_BYTES / FRAME_SIZE - 400
    assert blocks[after].arrived_s >= blocks[0].arrived_s + STALL_S / 2
    assert reader.longest_unread_s >= blocks[after].unread_s
    assert reader.last_arrival_s >= blocks[after].arrived_s


@pytest.mark.parametrize(("hold_s", "stall_s"), [(3.0, 0.5), (0.2, 1.0)])
def test_the_unpaced_link_waits_for_its_host_up_to_the_devices_hold(hold_s, stall_s):
    """Without a receive buffer bound (the unpaced bench's link) a stall shorter than the device's
    hold (``[simulation] wfs_hold_s``) loses nothing; a longer one loses what the device could not
    send by then, each frame counted at both ends. The longer stall lasts until the device has
    dropped frames (at least its hold): the unpaced bench shares the test's process, and on a busy
    machine it may take longer than any fixed stall to fill the subscription and the link."""
    link = MemoryLink()
    bench = SimulatedBench.paper_shaker(seed=2)
    device = WfsDevice(link, bench, seed=3, hold_s=hold_s)
    runner = BenchRunner(bench, paced=False, block_s=0.01)
    runner.sinks.append(device)
    device.start()
    runner.start()
    reader = WfsReader(link.open_host)
    reader.start()
    try:
        sub = reader.subscribe(lossless=True, max_frames=QUEUE_FRAMES)
        reader.start_stream()
        first = sub.read_frames(500, timeout_s=20)
        threading.Event().wait(stall_s)  # the host stall: nothing taken, the reader is held
        if stall_s >= hold_s:  # ... until the device gave up waiting for it
            wait_until(lambda: device.frames_dropped > 0, 60, "the device dropped frames")
        # beyond what the link held when the device gave up (64 KiB: 1024 frames), so that the
        # frames after a drop arrive
        second = sub.read_frames(3000, timeout_s=20)
        sub.close()
        reader.stop_stream()
        # counted before the reader closes: the bench runs on, and a device left without a host drops
        counters, dropped = reader.counters, device.frames_dropped
    finally:
        reader.close()
        runner.stop()
        device.stop()
    assert not first.gaps and second.unread_s > 0.2  # the reader was held
    if stall_s < hold_s:
        assert not second.gaps and counters.frames_missing == 0 and dropped == 0
    else:
        assert dropped > 0 and counters.frames_missing == dropped


def test_the_devices_hold_must_be_positive():
    with pytest.raises(ValueError, match="hold_s must be positive"):
        WfsDevice(MemoryLink(), SimulatedBench.paper_shaker(seed=2), hold_s=0.0)
