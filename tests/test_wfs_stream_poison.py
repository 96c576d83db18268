"""Nothing poisons the WFS stream: CRC-valid fake frames made of garbage (sync words next to real
frames) are never delivered, never taken for a restart or a jump of the counter, and every real
frame after them is delivered; garbage never holds back a frame behind it.

A restart or a jump is believed only when ``EVIDENCE_FRAMES`` frames agree on it (docs/protocols.md,
*Parsing, counters and restarts*). Every case is fed whole and in seeded random chunks."""

from __future__ import annotations

import binascii

import numpy as np
import pytest

from drivers.wfs_capture import CAPTURE_SYNC_BYTES
from drivers.wfs_commands import Reply
from drivers.wfs_frame import FRAME_DTYPE, FRAME_SIZE, SYNC_BYTES, encode, new_frames, valid
from drivers.wfs_stream import EVIDENCE_FRAMES, STALE_EVIDENCE_FRAMES, Gap, Resync, StreamParser


def _frames(n: int, first_seq: int = 0, boot: int = 7) -> np.ndarray:
    f = new_frames(n)
    f["seq"] = (np.arange(n) + first_seq) % 2**32
    f["sample"] = f["seq"]
    f["boot"] = boot
    f["fz"] = 1000 + np.arange(n)
    return np.frombuffer(encode(f), dtype=FRAME_DTYPE).copy()


def _fake(seq: int, boot: int, fz: float = 2.3e16) -> bytes:
    """A CRC-valid frame with wild values, as garbage next to real frames happens to form."""
    f = new_frames(1)
    f["seq"], f["sample"], f["boot"], f["fz"] = seq, seq, boot, fz
    return encode(f)


def _feed(parser: StreamParser, data: bytes, chunks: np.random.Generator | None):
    """Feed ``data`` whole or in random chunks; the frames, gaps (re-indexed) and resyncs delivered."""
    sizes = [len(data)] if chunks is None else []
    while chunks is not None and sum(sizes) < len(data):
        sizes.append(int(chunks.integers(1, 700)))
    frames, gaps, resyncs, replies, done, pos = [], [], [], [], 0, 0
    for size in sizes:
        result = parser.feed(data[pos : pos + size])
        pos += size
        gaps += [Gap(g.index + done, g.first_seq, g.missing) for g in result.gaps]
        resyncs += [(r.index + done, r.last_boot, r.boot) for r in result.resyncs]
        replies += result.replies
        frames.append(result.frames)
        done += len(result.frames)
    return np.concatenate(frames), gaps, resyncs, replies


CHUNKS = [None, 1, 2]


def _sync_words(data: bytes) -> int:
    d = np.frombuffer(data, np.uint8)
    return int(np.count_nonzero((d[:-1] == SYNC_BYTES[0]) & (d[1:] == SYNC_BYTES[1])))


def _chunks(seed):
    return None if seed is None else np.random.default_rng(seed)


@pytest.mark.parametrize("seed", CHUNKS)
@pytest.mark.parametrize(
    ("what", "seq", "boot"),
    [
        ("a wild counter", 0xDEADBEEF, 0x5AA5),  # a newer boot: once taken for a device restart
        ("a jump forward in the same power-up", 105, 7),
        ("a jump far forward", 2**31 - 1, 7),
        ("an older boot", 50, 3),
        ("the counter gone back", 10, 7),
    ],
)
def test_a_fake_frame_among_sync_word_garbage_is_never_delivered_and_the_stream_goes_on(
    seed, what, seq, boot
):
    sent = _frames(400)
    garbage = SYNC_BYTES * 300
    stream = encode(sent[:100]) + garbage + _fake(seq, boot) + garbage + encode(sent[100:])
    parser = StreamParser()
    got, gaps, resyncs, _ = _feed(parser, stream, _chunks(seed))
    assert np.array_equal(got, sent), what  # every real frame once, no fake
    assert gaps == [] and resyncs == []
    c = parser.counters
    assert (c.frames_ok, c.frames_missing, c.resyncs) == (400, 0, 0)
    assert c.frames_rejected + c.duplicates == 1  # the fake, counted
    assert c.crc_rejects == 600 + _sync_words(_fake(seq, boot)[2:])  # every sync word passed over
    assert c.bytes_discarded == 2 * len(garbage)
    assert parser.pending_frames == 0


@pytest.mark.parametrize("seed", CHUNKS)
def test_fakes_before_the_first_real_frame_do_not_set_the_counters(seed):
    """At start-up the first frames too are believed on evidence: a fake first does not make the
    real frames look like stale copies."""
    sent = _frames(50, first_seq=1000)
    stream = SYNC_BYTES * 40 + _fake(2**32 - 1, 7) + _fake(0xFFFF0000, 0xFFFF) + encode(sent)
    parser = StreamParser()
    got, gaps, resyncs, _ = _feed(parser, stream, _chunks(seed))
    assert np.array_equal(got, sent) and gaps == [] and resyncs == []
    assert parser.counters.frames_rejected == 2 and parser.counters.duplicates == 0


def _overlapping_fake(real: bytes, k: int) -> bytes:
    """Bytes that end in a CRC-valid fake frame whose last ``k`` bytes are the first ``k`` bytes of the
    frame ``real``: the fake's CRC field is the real frame's bytes ``k-2, k-1``, so a free field of
    the fake (its ``seq``) is searched until the CRC matches."""
    head = bytearray(_fake(0, 0x1234)[: FRAME_SIZE - k])
    target = int.from_bytes(real[k - 2 : k], "little")
    for guess in range(1 << 16):
        head[2:4] = guess.to_bytes(2, "little")
        body = bytes(head[2:]) + real[: k - 2]
        if binascii.crc_hqx(body, 0xFFFF) == target:
            fake = bytes(head) + real[:k]
            assert valid(np.frombuffer(fake, FRAME_DTYPE))[0]
            return fake[: FRAME_SIZE - k]
    raise AssertionError("no CRC-valid overlap found")


@pytest.mark.parametrize("seed", CHUNKS)
@pytest.mark.parametrize("k", [10, 33, 58])
def test_a_fake_overlapping_the_next_real_frame_does_not_swallow_it(seed, k):
    sent = _frames(30)
    real = encode(sent[10:11])
    stream = encode(sent[:10]) + SYNC_BYTES * 5 + _overlapping_fake(real, k) + encode(sent[10:])
    parser = StreamParser()
    got, gaps, resyncs, _ = _feed(parser, stream, _chunks(seed))
    assert np.array_equal(got, sent) and gaps == [] and resyncs == []
    c = parser.counters
    assert (c.frames_rejected + c.duplicates, c.frames_missing, c.bytes_discarded) == (1, 0, 10)


@pytest.mark.parametrize("seed", CHUNKS)
def test_a_real_restart_after_fakes_is_believed_on_its_frames(seed):
    """Fakes with newer boots before a real restart: the restart is reported once, where it is."""
    before, after = _frames(100), _frames(60, boot=8)
    stream = encode(before) + _fake(5, 8) + SYNC_BYTES * 33 + _fake(9, 9) + encode(after)
    parser = StreamParser()
    got, gaps, resyncs, _ = _feed(parser, stream, _chunks(seed))
    assert np.array_equal(got, np.concatenate([before, after]))
    assert resyncs == [(100, 7, 8)] and gaps == []
    assert parser.counters.frames_rejected == 2 and parser.counters.resyncs == 1


def test_a_jump_is_held_until_enough_frames_agree_then_delivered_with_its_gap():
    sent = _frames(120)
    parser = StreamParser()
    assert len(parser.feed(encode(sent[:100])).frames) == 100
    held = parser.feed(encode(sent[105 : 105 + EVIDENCE_FRAMES - 1]))
    assert len(held.frames) == 0 and parser.pending_frames == EVIDENCE_FRAMES - 1
    result = parser.feed(encode(sent[105 + EVIDENCE_FRAMES - 1 :]))
    assert np.array_equal(result.frames, sent[105:])
    assert result.gaps == [Gap(0, 100, 5)] and parser.pending_frames == 0
    assert parser.counters.frames_missing == 5 and parser.counters.frames_rejected == 0


def test_intact_frames_inside_a_long_lost_stretch_are_delivered_with_the_stream_after_it():
    """One frame came through a long overrun alone: it is delivered, not rejected, once the stream
    after the overrun is believed; both gaps are counted."""
    sent = _frames(600)
    stream = encode(sent[:100]) + encode(sent[102:103]) + encode(sent[500:])
    parser = StreamParser()
    result = parser.feed(stream)
    assert result.frames["seq"].tolist() == [*range(100), 102, *range(500, 600)]
    assert result.gaps == [Gap(100, 100, 2), Gap(101, 103, 397)]
    assert parser.counters.frames_missing == 399 and parser.counters.frames_rejected == 0


def test_a_counter_that_goes_back_for_good_is_believed_after_enough_frames():
    """A device swapped for one whose counters are lower: stale copies at first, then a resync; no
    frame of the new device is lost."""
    old, new = _frames(500, first_seq=10_000), _frames(STALE_EVIDENCE_FRAMES + 20, first_seq=3, boot=5)
    parser = StreamParser()
    parser.feed(encode(old))
    result = parser.feed(encode(new))
    assert np.array_equal(result.frames, new)
    assert result.resyncs == [Resync(0, 7, 5, 10_499, 3)]
    assert parser.counters.duplicates == 0


@pytest.mark.parametrize(
    "garbage",
    [b"$", b"$" * 50, b"$OK,STOP", b"$OK,IDENT,X*5", b"\xa5", SYNC_BYTES * 3, CAPTURE_SYNC_BYTES * 4, b"<"],
    ids=["dollar", "dollars", "unended reply", "unended checksum", "a5", "sync words", "capture syncs", "3c"],
)
def test_garbage_never_holds_back_the_frame_behind_it(garbage):
    """The frame after the garbage comes out of the same read, and the garbage is discarded."""
    sent = _frames(20)
    parser = StreamParser()
    parser.feed(encode(sent[:10]))
    result = parser.feed(garbage + encode(sent[10:]))
    assert np.array_equal(result.frames, sent[10:])
    assert parser.counters.bytes_discarded == len(garbage)


def test_a_reply_after_garbage_and_frames_is_handed_on_at_once():
    sent = _frames(10)
    reply = Reply(True, "STOP").encode()
    parser = StreamParser()
    result = parser.feed(encode(sent) + b"$$\x3c" + reply)
    assert np.array_equal(result.frames, sent) and result.replies == [Reply(True, "STOP")]


GARBAGE_PIECES = [
    SYNC_BYTES, CAPTURE_SYNC_BYTES, b"$", b"$OK,STOP*00\r\n", b"$OK,STOP*", b"\r\n", b"*", b"A",
    Reply(True, "STOP").encode(), b"\xa5", b"\x5a", b"\x3c", b"\xc3", b"\x00",
]  # fmt: skip


@pytest.mark.parametrize("seed", range(6))
def test_any_mix_of_garbage_pieces_split_anywhere_delivers_every_real_frame(seed):
    """Frames between seeded random garbage made of the pieces every rule looks at (sync words,
    capture sync words, reply starts and ends, bad and good replies), fed in random chunks."""
    rng = np.random.default_rng(seed)
    sent = _frames(300)
    stream = b"".join(
        encode(sent[i : i + 1])
        + b"".join(GARBAGE_PIECES[int(k)] for k in rng.integers(0, len(GARBAGE_PIECES), rng.integers(0, 30)))
        for i in range(300)
    )
    stream += encode(_frames(3, first_seq=300))  # the stream goes on: the last frames are confirmed
    whole = StreamParser()
    _feed(whole, stream, None)
    parser = StreamParser()
    got, gaps, resyncs, replies = _feed(parser, stream, rng)
    assert np.array_equal(got[:300], sent) and gaps == [] and resyncs == []
    assert parser.counters.frames_missing == 0 and parser.counters.frames_rejected == 0
    assert all(r == Reply(True, "STOP") for r in replies) and replies
    assert parser.counters == whole.counters  # split anywhere, the same count of everything
