"""Find WFS frames, replies and captures in an arbitrary byte stream, and account for every lost frame.

The parser accepts bytes in chunks of any size (split anywhere), checks sync word and CRC of
candidate frames a block at a time, resynchronises byte by byte after a bad candidate, and keeps the
text replies and triggered captures (``drivers/wfs_capture.py``) interleaved with the frames. Every
frame that does not arrive intact is counted through the sequence counter: a jump in ``seq`` is a
gap, reported with its position; samples are never interpolated. A frame whose ``seq`` lies at most
:data:`DUPLICATE_WINDOW` frames behind the newest one delivered is a duplicate and is dropped (and
counted). A frame further behind (the device restarted and counts from 0 again, or the counter
jumped by half its range) is a resynchronisation: reported as a :class:`Resync` with its position,
counted, and the stream goes on from that frame. The first frame after :meth:`StreamParser.reopened`
that is not newer than the last one delivered is a resynchronisation too, however small the step
back.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from drivers.errors import MalformedReplyError
from drivers.wfs_capture import CAPTURE_SYNC_BYTES, Capture, decode_capture
from drivers.wfs_commands import MAX_REPLY_LEN, REPLY_END, REPLY_START, Reply, parse_reply
from drivers.wfs_frame import FRAME_DTYPE, FRAME_SIZE, SYNC_BYTES, valid

_SEQ_MOD = 1 << 32
_SEQ_HALF = _SEQ_MOD // 2
#: how far (frames) behind the newest delivered ``seq`` a frame is still a duplicate, not a restart
DUPLICATE_WINDOW = 256
_WINDOW_FRAMES = 1024  # frames checked per vectorised step


@dataclass(frozen=True)
class Gap:
    """``missing`` frames absent before position ``index`` of a block (``seq`` from ``first_seq``)."""

    index: int
    first_seq: int
    missing: int


@dataclass(frozen=True)
class Resync:
    """The sequence counter went back from ``last_seq`` to ``seq`` before position ``index`` of a block.

    The device restarted (or the counter is corrupt): nothing can be said about the frames lost in
    between, so none are counted as missing; the sample clock of the frames from ``index`` on is new.
    """

    index: int
    last_seq: int
    seq: int


@dataclass
class LinkCounters:
    """Cumulative link statistics."""

    frames_ok: int = 0
    frames_missing: int = 0  # by sequence counter: dropped or rejected
    gaps: int = 0
    crc_rejects: int = 0  # candidates with a sync word whose CRC failed
    duplicates: int = 0
    resyncs: int = 0  # the sequence counter went back: device restart (see :class:`Resync`)
    bytes_discarded: int = 0  # bytes that belonged to no intact frame or reply
    replies: int = 0
    reconnects: int = 0
    captures: int = 0  # triggered-capture messages received intact


@dataclass
class ParseResult:
    """What one :meth:`StreamParser.feed` produced."""

    frames: np.ndarray
    gaps: list[Gap] = field(default_factory=list)
    replies: list[Reply] = field(default_factory=list)
    resyncs: list[Resync] = field(default_factory=list)
    captures: list[Capture] = field(default_factory=list)


class StreamParser:
    """Incremental frame/reply parser with loss accounting (not thread-safe: one reader owns it)."""

    def __init__(self) -> None:
        self._buf = bytearray()
        self.counters = LinkCounters()
        self.last_seq: int | None = None
        self._after_reopen = False

    def reopened(self) -> None:
        """The link was closed and opened again: drop the bytes of the old connection, and take the
        first frame that is not newer than the last one delivered as a device restart (a resync).

        ``last_seq`` is kept, so that frames lost while the link was down still show up as a gap.
        """
        self._buf.clear()
        self._after_reopen = True

    def feed(self, data: bytes) -> ParseResult:
        """Add ``data`` to the stream; return the frames, gaps and replies completed by it."""
        self._buf += data
        buf = bytes(self._buf)
        chunks: list[np.ndarray] = []
        replies: list[Reply] = []
        captures: list[Capture] = []
        pos = 0
        while True:
            start = self._next_candidate(buf, pos)
            if start < 0:
                # keep a trailing byte that may begin a sync word or a reply
                keep = 1 if buf[-1:] in (SYNC_BYTES[:1], REPLY_START, CAPTURE_SYNC_BYTES[:1]) else 0
                self.counters.bytes_discarded += len(buf) - pos - keep
                pos = len(buf) - keep
                break
            self.counters.bytes_discarded += start - pos
            pos = start
            if buf.startswith(REPLY_START, pos) or buf.startswith(CAPTURE_SYNC_BYTES, pos):
                consumed = self._take_message(buf, pos, replies, captures)
                if consumed == 0:
                    break  # incomplete reply or capture: wait for more bytes
                pos += consumed
                continue
            n = min((len(buf) - pos) // FRAME_SIZE, _WINDOW_FRAMES)
            if n == 0:
                break  # incomplete frame: wait for more bytes
            frames = np.frombuffer(buf, dtype=FRAME_DTYPE, count=n, offset=pos)
            ok = valid(frames)
            n_good = n if ok.all() else int(np.argmin(ok))
            if n_good:
                chunks.append(frames[:n_good])
                pos += n_good * FRAME_SIZE
            if n_good < n and buf.startswith(SYNC_BYTES, pos):
                # a sync word with a bad CRC: reject it and resynchronise from the next byte
                self.counters.crc_rejects += 1
                self.counters.bytes_discarded += 1
                pos += 1
        del self._buf[:pos]
        good = np.concatenate(chunks) if chunks else np.zeros(0, FRAME_DTYPE)
        frames, gaps, resyncs = self._account(good)
        return ParseResult(frames, gaps, replies, resyncs, captures)

    @staticmethod
    def _next_candidate(buf: bytes, pos: int) -> int:
        """Position of the next frame sync word, reply or capture (-1: none)."""
        sync = buf.find(SYNC_BYTES, pos)
        limit = sync if sync >= 0 else len(buf)
        messages = (buf.find(REPLY_START, pos, limit), buf.find(CAPTURE_SYNC_BYTES, pos, limit))
        found = [i for i in messages if i >= 0]
        return min(found) if found else sync

    def _take_message(self, buf: bytes, pos: int, replies: list[Reply], captures: list[Capture]) -> int:
        """Take the reply or capture starting at ``pos``; return the bytes consumed (0: incomplete).

        Bytes that only looked like the start of one are discarded one at a time (resynchronisation).
        """
        if buf.startswith(REPLY_START, pos):
            consumed, reply = self._try_reply(buf, pos)
            if reply is not None:
                replies.append(reply)
                self.counters.replies += 1
                return consumed
        else:
            consumed, capture = decode_capture(buf, pos)
            if capture is not None:
                captures.append(capture)
                self.counters.captures += 1
                return consumed
        self.counters.bytes_discarded += consumed
        return consumed

    @staticmethod
    def _try_reply(buf: bytes, pos: int) -> tuple[int, Reply | None]:
        """``(bytes consumed, reply)``; ``(0, None)`` when the line may still be incomplete."""
        end = buf.find(REPLY_END, pos, pos + MAX_REPLY_LEN)
        if end < 0:
            return (0, None) if len(buf) - pos < MAX_REPLY_LEN else (1, None)
        line = buf[pos : end + len(REPLY_END)]
        try:
            return len(line), parse_reply(line)
        except MalformedReplyError:
            return 1, None

    def _account(self, frames: np.ndarray) -> tuple[np.ndarray, list[Gap], list[Resync]]:
        """Drop duplicates, report gaps and resynchronisations against the last frame delivered.

        Vectorised between resynchronisations (one numpy pass per segment, no per-frame loop).
        """
        seq = frames["seq"].astype(np.int64)
        kept: list[np.ndarray] = []
        gaps: list[Gap] = []
        resyncs: list[Resync] = []
        delivered = 0
        start = 0
        while start < len(seq):
            ref = seq[start] - 1 if self.last_seq is None else self.last_seq
            # position relative to the last delivered frame, unwrapped to (-2^31, 2^31]
            rel = (seq[start:] - ref + _SEQ_HALF - 1) % _SEQ_MOD - _SEQ_HALF + 1
            newest = np.maximum.accumulate(np.concatenate(([0], rel)))[:-1]
            back = rel < newest - DUPLICATE_WINDOW
            if self._after_reopen and rel[0] <= 0:
                back[0] = True
            self._after_reopen = False
            end = int(np.argmax(back)) if back.any() else len(rel)
            if end == 0:
                # the counter went back: start over from this frame
                resyncs.append(Resync(delivered, int(ref % _SEQ_MOD), int(seq[start])))
                self.counters.resyncs += 1
                self.last_seq = None
                continue
            fresh = rel[:end] > newest[:end]
            self.counters.duplicates += int(end - np.count_nonzero(fresh))
            idx = np.flatnonzero(fresh) + start
            step = np.diff(np.concatenate(([0], rel[idx - start])))
            for i in np.flatnonzero(step > 1):
                gaps.append(
                    Gap(delivered + int(i), int((seq[idx[i]] - step[i] + 1) % _SEQ_MOD), int(step[i] - 1))
                )
            if len(idx):
                kept.append(idx)
                delivered += len(idx)
                self.last_seq = int(seq[idx[-1]])
            start += end
        out = frames[np.concatenate(kept)] if kept else frames[:0].copy()
        self.counters.frames_ok += len(out)
        self.counters.gaps += len(gaps)
        self.counters.frames_missing += sum(g.missing for g in gaps)
        return out, gaps, resyncs
