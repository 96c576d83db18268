"""Stream parser: frames found in any byte stream, bad ones rejected, every loss counted."""

import numpy as np
import pytest

from drivers.wfs_commands import Reply
from drivers.wfs_frame import FRAME_DTYPE, FRAME_SIZE, SYNC_BYTES, encode, new_frames
from drivers.wfs_stream import Resync, StreamParser
from simulators.faults import ByteFaults, FaultLog


def _frames(n: int, first_seq: int = 0, boot: int = 1) -> np.ndarray:
    f = new_frames(n)
    f["seq"] = (np.arange(n) + first_seq) % 2**32
    f["sample"] = f["seq"]
    f["boot"] = boot
    f["fz"] = np.sin(np.arange(n) * 0.1) * 1000
    return np.frombuffer(encode(f), dtype=FRAME_DTYPE).copy()


def _feed_in_chunks(parser: StreamParser, data: bytes, rng: np.random.Generator):
    frames, gaps, replies, pos, delivered = [], [], [], 0, 0
    while pos < len(data):
        step = int(rng.integers(1, 700))
        result = parser.feed(data[pos : pos + step])
        pos += step
        frames.append(result.frames)
        gaps.extend((g.index + delivered, g.missing) for g in result.gaps)
        delivered += len(result.frames)
        replies.extend(result.replies)
    return np.concatenate(frames), gaps, replies


def test_clean_stream_split_anywhere():
    sent = _frames(3000)
    got, gaps, _ = _feed_in_chunks(StreamParser(), encode(sent), np.random.default_rng(0))
    assert np.array_equal(got, sent)
    assert gaps == []


def test_leading_garbage_and_partial_frame_are_skipped():
    parser = StreamParser()
    data = encode(_frames(10))
    result = parser.feed(b"\x5a\xa5\x00garbage$$\xa5" + data[30:FRAME_SIZE] + data)
    assert result.frames["seq"].tolist() == list(range(10))
    # the partial first frame shows up as discarded bytes, not as a frame
    assert parser.counters.bytes_discarded >= FRAME_SIZE - 30
    assert parser.counters.frames_missing == 0


def test_gap_reported_where_frames_are_missing():
    sent = _frames(100)
    data = encode(np.concatenate([sent[:40], sent[47:]]))
    parser = StreamParser()
    result = parser.feed(data)
    assert [(g.index, g.first_seq, g.missing) for g in result.gaps] == [(40, 40, 7)]
    assert parser.counters.frames_missing == 7
    assert len(result.frames) == 93


def test_duplicated_frames_are_dropped_and_counted():
    sent = _frames(20)
    data = encode(np.concatenate([sent[:10], sent[8:12], sent[12:]]))
    parser = StreamParser()
    result = parser.feed(data)
    assert result.frames["seq"].tolist() == list(range(20))
    assert parser.counters.duplicates == 2


def test_device_restart_is_a_resync_and_the_new_stream_is_delivered():
    """After 100 000 frames the device restarts (boot 1 -> 2) and counts from 0 again."""
    parser = StreamParser()
    assert len(parser.feed(encode(_frames(100_000))).frames) == 100_000
    restarted = _frames(50_000, boot=2)
    result = parser.feed(encode(restarted[:20_000]) + encode(restarted[20_000:30_000]))
    assert np.array_equal(result.frames, restarted[:30_000])
    assert result.resyncs == [Resync(0, 1, 2, 99_999, 0)]
    assert result.gaps == []
    assert parser.counters.resyncs == 1 and parser.counters.duplicates == 0
    # the new stream is then checked for gaps and duplicates as usual
    result = parser.feed(encode(np.concatenate([restarted[29_990:40_000], restarted[40_005:]])))
    assert parser.counters.duplicates == 10
    assert [(g.index, g.first_seq, g.missing) for g in result.gaps] == [(10_000, 40_000, 5)]


def test_restart_inside_a_block_is_reported_where_it_happens():
    parser = StreamParser()
    result = parser.feed(encode(np.concatenate([_frames(5000), _frames(300, boot=2)])))
    assert len(result.frames) == 5300
    assert result.resyncs == [Resync(5000, 1, 2, 4999, 0)]


def test_restart_within_256_frames_of_power_up_delivers_every_new_frame():
    parser = StreamParser()
    parser.feed(encode(_frames(100)))
    result = parser.feed(encode(_frames(100, boot=2)))
    assert result.frames["seq"].tolist() == list(range(100))
    assert result.resyncs == [Resync(0, 1, 2, 99, 0)]
    assert parser.counters.duplicates == 0 and parser.counters.frames_missing == 0


def test_restart_after_the_counter_passed_half_its_range_is_no_gap():
    parser = StreamParser()
    parser.feed(encode(_frames(50, first_seq=2**31 + 5)))
    result = parser.feed(encode(_frames(50, boot=2)))
    assert len(result.frames) == 50 and result.gaps == []
    assert result.resyncs == [Resync(0, 1, 2, 2**31 + 54, 0)]
    assert parser.counters.frames_missing == 0 and parser.counters.gaps == 0


def test_stale_copy_arriving_late_is_dropped_without_a_resync():
    """A copy of frame 100 arrives 900 frames late, then one from before a restart: both dropped."""
    sent = _frames(1100)
    parser = StreamParser()
    data = encode(sent[:1000]) + encode(sent[100:101]) + encode(sent[1000:])
    got = parser.feed(data).frames
    assert got["seq"].tolist() == list(range(1100))  # each frame once, none missing
    assert parser.counters.duplicates == 1
    assert parser.counters.resyncs == 0 and parser.counters.frames_missing == 0
    after_restart = _frames(20, boot=2)
    result = parser.feed(encode(after_restart[:10]) + encode(sent[500:501]) + encode(after_restart[10:]))
    assert result.frames["seq"].tolist() == list(range(20))
    assert len(result.resyncs) == 1 and parser.counters.duplicates == 2


def test_boot_count_wraps_and_stays_a_restart():
    parser = StreamParser()
    parser.feed(encode(_frames(10, boot=0xFFFF)))
    result = parser.feed(encode(_frames(10, boot=0)))
    assert result.resyncs == [Resync(0, 0xFFFF, 0, 9, 0)] and len(result.frames) == 10


def test_after_a_reopen_lost_frames_are_a_gap_and_a_restart_a_resync():
    parser = StreamParser()
    parser.feed(encode(_frames(300)))
    parser.feed(encode(_frames(1))[:30])  # half a frame of the old connection
    parser.reopened()
    result = parser.feed(encode(_frames(5, first_seq=320)))
    assert [(g.first_seq, g.missing) for g in result.gaps] == [(300, 20)]
    assert parser.counters.resyncs == 0 and parser.counters.bytes_discarded == 0
    parser.reopened()
    result = parser.feed(encode(_frames(10, first_seq=3, boot=2)))
    assert result.frames["seq"].tolist() == list(range(3, 13))
    assert result.resyncs == [Resync(0, 1, 2, 324, 3)] and result.gaps == []


def test_garbage_of_sync_words_is_skipped_and_every_sync_word_rejected():
    sent = _frames(200)
    garbage = SYNC_BYTES * 5000 + b"\xa5"
    stream = encode(sent[:100]) + garbage + encode(sent[100:])
    parser = StreamParser()
    got, gaps, _ = _feed_in_chunks(parser, stream, np.random.default_rng(7))
    assert np.array_equal(got, sent) and gaps == []
    assert parser.counters.crc_rejects == 5000
    assert parser.counters.bytes_discarded == len(garbage)


def test_sequence_counter_wraps_without_a_gap():
    parser = StreamParser()
    result = parser.feed(encode(_frames(10, first_seq=2**32 - 5)[:5]) + encode(_frames(5, first_seq=0)))
    assert len(result.frames) == 10
    assert result.gaps == []


def test_replies_interleaved_with_frames_are_extracted():
    sent = _frames(50)
    data = encode(sent)
    reply = Reply(True, "IDENT", ("SIM", "WFS-6", "0001", "1.0")).encode()
    stream = data[: 20 * FRAME_SIZE] + reply + data[20 * FRAME_SIZE :] + b"$OK,STOP*00\r\n"
    got, gaps, replies = _feed_in_chunks(StreamParser(), stream, np.random.default_rng(5))
    assert np.array_equal(got, sent)
    # the reply with a bad checksum is dropped
    assert replies == [Reply(True, "IDENT", ("SIM", "WFS-6", "0001", "1.0"))]
    assert gaps == []


@pytest.mark.parametrize(
    "seed", [1, pytest.param(2, marks=pytest.mark.validation), pytest.param(3, marks=pytest.mark.validation)]
)
def test_bit_errors_drops_duplicates_and_garbage_every_intact_frame_delivered(seed):
    n = 20_000
    sent = _frames(n + 5)
    log = FaultLog()
    faults = ByteFaults(
        seed=seed, bit_error_rate=1e-3, drop_rate=2e-4, duplicate_rate=1e-4, garbage_rate=2e-4, log=log
    )
    data = encode(sent[:n])
    corrupted = b"".join(faults.apply(data[i : i + 997]) for i in range(0, len(data), 997))
    # the stream goes on intact for a few frames: the frames after the last gap are confirmed by them
    corrupted += encode(sent[n:])
    parser = StreamParser()
    got, gaps, _ = _feed_in_chunks(parser, corrupted, np.random.default_rng(seed))
    intact = (set(range(n)) - log.damaged_frames(FRAME_SIZE)) | set(range(n, n + 5))
    assert 0.4 * n < len(intact) < 0.9 * n  # the faults really bite
    delivered = got["seq"].tolist()
    # every frame that went out intact is delivered; whatever is delivered is bit-exact
    # (a fault may by chance leave a frame's bytes unchanged, so delivered may exceed intact)
    assert intact <= set(delivered)
    assert np.array_equal(got, sent[delivered])
    assert delivered == sorted(set(delivered))
    # every frame between the first and the last delivered one that is missing is counted
    missing = (delivered[-1] - delivered[0] + 1) - len(delivered)
    assert parser.counters.frames_missing == missing == sum(m for _, m in gaps)
    assert parser.counters.crc_rejects > 0
