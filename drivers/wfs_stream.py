"""Find WFS frames, replies and captures in an arbitrary byte stream, and account for every lost frame.

The parser accepts bytes in chunks of any size (split anywhere), checks sync word and CRC of
candidate frames a block at a time, and after a bad candidate checks every sync word of the bytes
that follow at once (vectorised), so a stream of garbage made of sync words costs no more than a
few numpy passes per read. It keeps the text replies and triggered captures
(``drivers/wfs_capture.py``) that are interleaved with the frames.

Every frame that does not arrive intact is counted through the sequence counter: a jump in ``seq``
is a gap, reported with its position; samples are never interpolated. Restarts are stated by the
device, not guessed: each frame carries the device's power-up count ``boot`` (protocol version 2).

- Same ``boot``: a frame whose ``seq`` is not newer than the newest delivered (unwrapped modulo
  2^32 to within half the counter's range) is a duplicate or a stale copy and is dropped (counted),
  however late it arrives.
- A newer ``boot`` (modulo 2^16, within half its range): the device restarted; reported as a
  :class:`Resync` with its position and counted, and the stream goes on from that frame (the frames
  lost around the restart are not counted missing: nothing can be said about them).
- An older ``boot``: a stale copy from before a restart; dropped as a duplicate.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

from drivers.errors import MalformedReplyError
from drivers.wfs_capture import CAPTURE_SYNC_BYTES, Capture, decode_capture
from drivers.wfs_commands import MAX_REPLY_LEN, REPLY_END, REPLY_START, Reply, parse_reply
from drivers.wfs_frame import FRAME_DTYPE, FRAME_SIZE, SYNC_BYTES, valid, valid_at

_SEQ_MOD = 1 << 32
_BOOT_MOD = 1 << 16
_WINDOW_FRAMES = 1024  # frames checked per vectorised step
_SCAN_BYTES = 4096  # bytes whose sync words are checked per vectorised step after a bad candidate


@dataclass(frozen=True)
class Gap:
    """``missing`` frames absent before position ``index`` of a block (``seq`` from ``first_seq``)."""

    index: int
    first_seq: int
    missing: int


@dataclass(frozen=True)
class Resync:
    """The device restarted before position ``index`` of a block: its power-up count went from
    ``last_boot`` to ``boot`` (``last_seq`` the last frame delivered before, ``seq`` the first after).

    Nothing can be said about the frames lost around the restart, so none are counted as missing;
    the sample clock of the frames from ``index`` on is new.
    """

    index: int
    last_boot: int
    boot: int
    last_seq: int
    seq: int


@dataclass
class LinkCounters:
    """Cumulative link statistics."""

    frames_ok: int = 0
    frames_missing: int = 0  # by sequence counter: dropped or rejected
    gaps: int = 0
    crc_rejects: int = 0  # candidates with a sync word whose CRC failed
    duplicates: int = 0  # duplicates and stale copies, dropped
    resyncs: int = 0  # device restarts (see :class:`Resync`)
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
        self.last_boot: int | None = None

    def reopened(self) -> None:
        """The link was closed and opened again: drop the bytes of the old connection.

        ``last_seq`` and ``last_boot`` are kept, so that frames lost while the link was down show up
        as a gap, and a device that restarted meanwhile as a resync.
        """
        self._buf.clear()

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
                self.counters.bytes_discarded += max(len(buf) - pos - keep, 0)
                pos = max(len(buf) - keep, pos)
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
                # a sync word with a bad CRC: reject it and look for the next intact frame
                self.counters.crc_rejects += 1
                found = self._next_intact_frame(buf, pos + 1)
                self.counters.bytes_discarded += found - pos
                pos = found
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

    def _next_intact_frame(self, buf: bytes, pos: int) -> int:
        """Where parsing goes on after a rejected candidate: the first sync word from ``pos`` on that
        starts an intact frame or a frame not complete yet, or the next reply or capture, whichever comes
        first (else the last byte). The sync words passed over are counted as CRC rejects.

        Every sync word of up to :data:`_SCAN_BYTES` bytes is checked in one vectorised pass.
        """
        messages = [i for i in (buf.find(REPLY_START, pos), buf.find(CAPTURE_SYNC_BYTES, pos)) if i >= 0]
        end = min(messages) if messages else len(buf) - 1
        data = np.frombuffer(buf, np.uint8)
        while pos < end:
            stop = min(end, pos + _SCAN_BYTES)
            pair = data[pos : stop + 1]
            starts = np.flatnonzero((pair[:-1] == SYNC_BYTES[0]) & (pair[1:] == SYNC_BYTES[1])) + pos
            whole = starts[starts + FRAME_SIZE <= len(buf)]
            ok = valid_at(data, whole)
            if ok.any():
                first = int(np.argmax(ok))
                self.counters.crc_rejects += first
                return int(whole[first])
            self.counters.crc_rejects += len(whole)
            if len(whole) < len(starts):
                return int(starts[len(whole)])  # a frame not complete yet: wait for more bytes
            pos = stop
        return end

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
        """Drop duplicates and stale copies, report gaps and restarts against the last frame delivered.

        Vectorised over each run of frames with the same ``boot`` (one numpy pass per run).
        """
        if len(frames) == 0:
            return frames, [], []
        boot = frames["boot"].astype(np.int64)
        bounds = np.concatenate(([0], np.flatnonzero(np.diff(boot)) + 1, [len(boot)]))
        kept: list[np.ndarray] = []
        gaps: list[Gap] = []
        resyncs: list[Resync] = []
        delivered = 0
        for lo, hi in itertools.pairwise(bounds):
            run_boot = int(boot[lo])
            if self.last_boot is not None and run_boot != self.last_boot:
                if _wrapped(run_boot - self.last_boot, _BOOT_MOD) < 0:
                    self.counters.duplicates += int(hi - lo)  # stale copies from before a restart
                    continue
                last_seq, first_seq = int(self.last_seq or 0), int(frames["seq"][lo])
                resyncs.append(Resync(delivered, self.last_boot, run_boot, last_seq, first_seq))
                self.counters.resyncs += 1
                self.last_seq = None
            self.last_boot = run_boot
            idx, run_gaps = self._account_run(frames["seq"][lo:hi].astype(np.int64), delivered)
            gaps += run_gaps
            if len(idx):
                kept.append(idx + lo)
                delivered += len(idx)
        if len(kept) == 1 and len(kept[0]) == len(frames):
            out = frames  # the common case: every frame new, in one power-up
        else:
            out = frames[np.concatenate(kept)] if kept else frames[:0].copy()
        self.counters.frames_ok += len(out)
        self.counters.gaps += len(gaps)
        self.counters.frames_missing += sum(g.missing for g in gaps)
        return out, gaps, resyncs

    def _account_run(self, seq: np.ndarray, delivered: int) -> tuple[np.ndarray, list[Gap]]:
        """The positions of the new frames of one power-up's run and the gaps before them."""
        ref = seq[0] - 1 if self.last_seq is None else self.last_seq
        rel = _wrapped(seq - ref, _SEQ_MOD)  # frames after the last delivered one
        newest = np.maximum.accumulate(np.concatenate(([0], rel)))[:-1]
        fresh = np.flatnonzero(rel > newest)
        self.counters.duplicates += len(seq) - len(fresh)
        step = np.diff(np.concatenate(([0], rel[fresh])))
        gaps = [
            Gap(delivered + int(i), int((seq[fresh[i]] - step[i] + 1) % _SEQ_MOD), int(step[i] - 1))
            for i in np.flatnonzero(step > 1)
        ]
        if len(fresh):
            self.last_seq = int(seq[fresh[-1]])
        return fresh, gaps


def _wrapped(diff, modulus: int):
    """A counter difference unwrapped to ``(-modulus / 2, modulus / 2]``."""
    half = modulus // 2
    return (diff + half - 1) % modulus - half + 1
