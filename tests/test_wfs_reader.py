"""WFS reader for the run engine: command latency, commands from several threads, subscriptions."""

from __future__ import annotations

import contextlib
import queue
import statistics
import threading
import time

import numpy as np
import pytest

from drivers.errors import ProtocolMismatchError
from drivers.wfs_commands import Reply
from drivers.wfs_frame import encode, new_frames
from drivers.wfs_reader import SampleBlock, Subscription, WfsReader
from drivers.wfs_stream import Gap, Resync
from simulators.bench_sim import BenchRunner, SimulatedBench
from simulators.ports import MemoryLink, PtyLink
from simulators.wfs_device import IDENTITY, WfsDevice


@contextlib.contextmanager
def wfs_rig(link, open_reader):
    """A simulated WFS on ``link``, the bench unpaced, a started reader from ``open_reader(link)``."""
    bench = SimulatedBench.paper_shaker(seed=2)
    device = WfsDevice(link, bench, seed=3)
    runner = BenchRunner(bench, paced=False)
    runner.sinks.append(device)
    device.start()
    runner.start()
    reader = open_reader(link)
    reader.start()
    try:
        yield device, reader
    finally:
        reader.close()
        runner.stop()
        device.stop()
    assert runner.error is None


@pytest.fixture
def pty_rig():
    """The rig on a real pseudo-terminal, the reader on the pty's path."""
    link = PtyLink()
    try:
        with wfs_rig(link, lambda link: WfsReader.serial(link.path)) as (device, reader):
            assert reader.wait_connected(5)
            yield device, reader
    finally:
        link.close()


def test_command_replies_on_a_pty_come_back_within_milliseconds(pty_rig):
    """The reader hands a reply on as soon as its bytes arrive, not after a read timeout (50 ms)."""
    _, reader = pty_rig
    latencies_s = []
    for _ in range(30):
        t0 = time.perf_counter()
        assert reader.identify() == IDENTITY
        latencies_s.append(time.perf_counter() - t0)
    # on an idle machine the median is about 0.3 ms; the bound leaves room for a busy one
    assert statistics.median(latencies_s) < 0.02


def test_commands_of_two_threads_never_take_each_others_replies(pty_rig):
    """Two threads hammer commands on one reader over a real pty while frames stream: every command
    gets its own reply on the first attempt within its timeout."""
    _, reader = pty_rig
    sub = reader.subscribe(lossless=False, max_frames=256)
    reader.start_stream()
    errors: list[BaseException] = []
    answers: dict[str, list[tuple[str, ...]]] = {"IDENT": [], "RATE?": []}

    def hammer(name: str) -> None:
        try:
            for _ in range(150):
                answers[name].append(reader.command(name, timeout_s=1.0, attempts=1).fields)
        except Exception as exc:  # reported by the main thread
            errors.append(exc)

    threads = [threading.Thread(target=hammer, args=(name,)) for name in answers]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    reader.stop_stream()
    sub.close()
    assert errors == []
    assert answers["IDENT"] == [IDENTITY] * 150
    assert answers["RATE?"] == [("1000",)] * 150


def test_a_lossy_view_never_slows_a_lossless_consumer():
    """The lossless consumer gets every frame, paced by its own reading; a live view that is never
    read keeps only its newest frames and counts the blocks it dropped."""
    with wfs_rig(MemoryLink(), lambda link: WfsReader(link.open_host)) as (device, reader):
        engine = reader.subscribe(lossless=True, max_frames=512)
        view = reader.subscribe(lossless=False, max_frames=300)
        reader.start_stream()
        block = engine.read_frames(20_000, timeout_s=30)
        engine.close()  # closed first: a full lossless queue nobody reads would hold the replies up
        newest_seq = int(block.frames["seq"][-1])
        reader.stop_stream()
        kept = []
        while (piece := view.get(0)) is not None:
            kept.append(piece)
        view.close()
        assert view.get(0) is None and view.closed
    seq = block.frames["seq"].astype(np.int64)
    assert np.all(np.diff(seq) == 1) and not block.gaps
    assert reader.counters.frames_missing == 0 and device.frames_dropped == 0
    # the view holds at most 300 frames (or its one newest block), the newest ones, and counted
    # every other block as dropped
    view_seq = np.concatenate([b.frames["seq"] for b in kept]).astype(np.int64)
    assert len(view_seq) <= 300 or len(kept) == 1
    assert np.all(np.diff(view_seq) == 1)
    assert view_seq[-1] >= newest_seq
    assert view.dropped_blocks > 10


def test_a_lossy_view_drops_its_oldest_blocks_to_keep_within_its_frames():
    sub = Subscription(lossless=False, max_frames=100, on_close=lambda s: None)
    never = threading.Event()
    frames = new_frames(250)
    frames["seq"] = np.arange(250)
    for start in (0, 40, 80):
        sub._offer(SampleBlock(frames[start : start + 40]), never)
    # 40 + 40 + 40 frames exceed 100: the oldest block went
    assert np.array_equal(sub.get_all(0).frames["seq"], np.arange(40, 120))
    assert sub.dropped_blocks == 1
    # a block longer than the bound is kept alone, whole
    sub._offer(SampleBlock(frames[120:250]), never)
    assert np.array_equal(sub.get_all(0).frames["seq"], np.arange(120, 250))


def test_identify_refuses_a_device_of_another_protocol_version(pty_rig):
    device, reader = pty_rig
    assert reader.identify()[-1] == "2"
    device.commands["IDENT"] = lambda args: Reply(True, "IDENT", ("WFSBENCH", "SIM-WFS6", "0001", "1.0"))
    with pytest.raises(ProtocolMismatchError, match=r"protocol 1\.0, this reader 2"):
        reader.identify()


def test_get_all_hands_over_every_queued_block_as_one_with_gaps_and_resyncs_reindexed():
    sub = Subscription(lossless=True, max_frames=1000, on_close=lambda s: None)
    never = threading.Event()
    frames = new_frames(30)
    frames["seq"] = np.arange(30)
    sub._offer(SampleBlock(frames[:10]), never)
    sub._offer(SampleBlock(frames[10:25], gaps=(Gap(index=4, first_seq=100, missing=3),)), never)
    restart = Resync(index=2, last_boot=1, boot=2, last_seq=7, seq=0)
    sub._offer(SampleBlock(frames[25:], resyncs=(restart,)), never)
    merged = sub.get_all(0)
    assert np.array_equal(merged.frames["seq"], np.arange(30))
    assert merged.gaps == (Gap(index=14, first_seq=100, missing=3),)
    assert [r.index for r in merged.resyncs] == [27]
    assert sub.get_all(0) is None
    single = SampleBlock(frames[:5])
    sub._offer(single, never)
    assert sub.get_all(0) is single  # nothing to merge: the block itself


@pytest.mark.parametrize(
    ("link", "take", "max_frames", "pause_s", "frames"),
    [("memory", "get", 128, 0.002, 3000), ("pty", "get_all", 4096, 0.0, 20_000)],
    ids=["a-slow-consumer-paces-the-bench", "taking-all-it-is-behind-over-a-pty"],
)
def test_a_lossless_consumer_gets_every_frame_of_an_unpaced_bench(link, take, max_frames, pause_s, frames):
    """A consumer that drains slowly (block by block, pausing between) slows the bench down instead
    of losing frames; one that takes all it is behind at each read (over a real pty) gets them in
    order too: contiguous frames, none lost or doubled."""
    if link == "memory":
        port, open_reader = MemoryLink(capacity=4096), lambda p: WfsReader(p.open_host)
    else:
        port, open_reader = PtyLink(), lambda p: WfsReader.serial(p.path)
    with wfs_rig(port, open_reader) as (device, reader):
        engine = reader.subscribe(lossless=True, max_frames=max_frames)
        reader.start_stream()
        blocks = []
        while sum(len(b) for b in blocks) < frames:
            block = getattr(engine, take)(5)
            assert block is not None
            blocks.append(block)
            if pause_s:
                time.sleep(pause_s)  # a slow consumer: the reader waits for room, the device for the reader
        engine.close()
        reader.stop_stream()
    seq = np.concatenate([b.frames["seq"] for b in blocks]).astype(np.int64)
    assert np.all(np.diff(seq) == 1)
    assert not any(b.gaps for b in blocks) and device.frames_dropped == 0
    assert device.frames_sent >= frames


def test_a_reply_is_handed_on_only_after_the_frames_that_came_before_it():
    """Frames and a STOP reply parsed from one read: when the reply reaches the waiting command,
    every frame sent before it is already queued, so a host that stops the stream has them all."""
    reader = WfsReader(lambda: MemoryLink().open_host())
    sub = reader.subscribe(lossless=True, max_frames=10_000)
    frames = new_frames(500)
    frames["seq"] = np.arange(500)
    queued_at_reply: list[int] = []

    class Replies(queue.Queue):
        def put(self, item, block=True, timeout=None):
            queued_at_reply.append(sub._frames)
            super().put(item, block, timeout)

    reader._replies = Replies()
    reader._consume(encode(frames) + Reply(True, "STOP").encode())
    assert queued_at_reply == [500]
    assert np.array_equal(sub.get_all(0).frames["seq"], np.arange(500))
