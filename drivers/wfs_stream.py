"""Find WFS frames, replies and captures in an arbitrary byte stream, and account for every lost frame.

The parser accepts bytes in chunks of any size (split anywhere) and finds everything in a chunk with
a few vectorised passes, whatever the bytes are:

- **frames**: every sync word (``A5 5A``) whose 64 bytes are in hand has its CRC checked at once;
- **replies**: a ``$`` starts a reply only if printable ASCII other than ``$`` follows it up to a
  ``\r\n`` within :data:`~drivers.wfs_commands.MAX_REPLY_LEN` bytes, which is decided for every
  ``$`` at once; only those lines are parsed (checksum) one by one;
- **captures** (``drivers/wfs_capture.py``): every capture sync word (``3C C3``) has its header CRC
  checked at once; only a header that passes makes the parser wait for the message's samples.

The intact pieces are then taken in the order they lie in the stream. A run of back-to-back frames,
a reply or a capture hides what lies inside it (a sync word in a frame's payload is payload); a lone
frame (garbage on both sides) hides nothing, so a CRC-valid fake made of garbage cannot swallow the
real frame it overlaps: both go on to the accounting below, which tells them apart. Bytes that may
still become something (a frame whose 64 bytes are not all in hand, a ``$`` line not ended yet, a
last byte that may begin a sync word) are kept for the next chunk only while nothing intact lies
behind them: garbage never holds back a frame behind it.

**Accounting.** Every intact frame is accounted against the stream delivered so far (the *believed*
stream: its power-up count ``boot`` and newest ``seq``), so that every frame that does not arrive
intact is counted through the sequence counter; samples are never interpolated.

- A frame that continues the believed stream (same ``boot``, ``seq`` one more than the newest) is
  delivered at once. One that is not newer (same ``boot``, ``seq`` at or before the newest,
  unwrapped modulo 2^32 to within half the counter's range) is a duplicate or a stale copy and is
  dropped (counted), however late it arrives.
- Anything else breaks the believed stream's continuity: a jump forward of ``seq`` (frames lost), a
  newer ``boot`` (the device restarted), and at start-up the first frame. A single frame cannot
  prove that: garbage made of sync words next to real frames yields CRC-valid fakes (one in 65,536
  candidates) with wild counters. So such frames are held as a *candidate stream* and believed
  only when :data:`EVIDENCE_FRAMES` frames agree on it (the same ``boot``, ``seq`` rising by at
  most :data:`CHAIN_STEP` from one to the next), which is what a real restart or gap looks like: the
  device numbers every frame it sends, so the frames after a jump go on from it one by one. A fake
  is followed by the real stream, not by frames that continue its counters: as soon as a frame
  continues the believed stream the candidates are dropped and counted (``frames_rejected``).
  Once believed, the candidate's frames are delivered with a :class:`Gap` (frames lost before the
  jump) or a :class:`Resync` (a restart: the frames lost around it are not counted, nothing can be
  said about them); a candidate lying between the believed stream and the confirmed one (frames
  of the lost stretch that arrived intact) is delivered with it.
- A counter that goes back (an older ``boot``, or ``seq`` behind the newest in the same ``boot``)
  is a stale copy: dropped and counted as a duplicate. Only when :data:`STALE_EVIDENCE_FRAMES`
  frames agree on such a stream (a device swapped, a counter reset) is it believed, reported as a
  :class:`Resync`: no state of the parser drops valid frames indefinitely.

Frames held as a candidate are delivered as soon as the evidence arrives (:data:`EVIDENCE_FRAMES`
frames after the jump: 2 ms at 1 kHz), or dropped and counted when the believed stream goes on;
:attr:`StreamParser.pending_frames` says how many are held.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

from drivers.errors import MalformedReplyError
from drivers.wfs_capture import CAPTURE_SYNC_BYTES, HEADER_SIZE, Capture, decode_capture
from drivers.wfs_commands import MAX_REPLY_LEN, REPLY_END, REPLY_START, Reply, parse_reply
from drivers.wfs_frame import FRAME_DTYPE, FRAME_SIZE, SYNC_BYTES, crc16_rows, valid, valid_at

_SEQ_MOD = 1 << 32
_BOOT_MOD = 1 << 16
#: frames that must agree before a jump of the counters (a gap, a restart) is believed
EVIDENCE_FRAMES = 3
#: frames that must agree before a counter that went back (a device swapped, a counter reset) is
#: believed; until then they are stale copies
STALE_EVIDENCE_FRAMES = 64
#: the largest step of ``seq`` between two frames of one candidate stream (frames lost between them)
CHAIN_STEP = 256
#: candidate streams held at once (the oldest is dropped beyond)
MAX_CHAINS = 4

_SYNC0, _SYNC1 = SYNC_BYTES
_CAP0, _CAP1 = CAPTURE_SYNC_BYTES
_DOLLAR = REPLY_START[0]
_CR, _LF = REPLY_END
_EMPTY = np.zeros(0, FRAME_DTYPE)
#: the value of an upper-case hex digit by byte (anything else: 4096, which no checksum equals)
_HEX_VALUE = np.full(256, 4096, np.int32)
_HEX_VALUE[np.frombuffer(b"0123456789ABCDEF", np.uint8)] = np.arange(16)


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
    Also reported, with the same ``boot``, when a counter that went back was believed (a device
    swapped, a counter reset: see the module docstring).

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
    frames_rejected: int = 0  # CRC-valid frames that broke the stream and no later frame confirmed
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
        self._wait_for = 0  # bytes the buffer must hold before it is parsed again (a capture arriving)
        self.counters = LinkCounters()
        self.last_seq: int | None = None
        self.last_boot: int | None = None
        self._chains: list[_Chain] = []
        self._arrivals = itertools.count()

    @property
    def pending_frames(self) -> int:
        """Frames held until later frames confirm or refute them (see the module docstring)."""
        return sum(chain.count for chain in self._chains)

    def reopened(self) -> None:
        """The link was closed and opened again: drop the bytes of the old connection.

        ``last_seq`` and ``last_boot`` are kept, so that frames lost while the link was down show up
        as a gap, and a device that restarted meanwhile as a resync.
        """
        self._buf.clear()
        self._wait_for = 0

    def feed(self, data: bytes) -> ParseResult:
        """Add ``data`` to the stream; return the frames, gaps and replies completed by it."""
        self._buf += data
        if len(self._buf) < self._wait_for:
            return ParseResult(_EMPTY)
        self._wait_for = 0
        buf = bytes(self._buf)
        # the common case first: intact frames back to back from the start (a run hides what lies
        # inside it, so only the bytes after it need the search)
        lead = 0
        if len(buf) >= 2 * FRAME_SIZE and buf.startswith(SYNC_BYTES):
            ok = valid(np.frombuffer(buf, FRAME_DTYPE, count=len(buf) // FRAME_SIZE))
            lead = len(ok) if ok.all() else int(np.argmin(ok))
            lead = lead if lead > 1 else 0
        rest = buf[lead * FRAME_SIZE :] if lead else buf
        cut, starts, replies, captures = self._scan(rest)
        del self._buf[: lead * FRAME_SIZE + cut]
        parts = [np.frombuffer(buf, FRAME_DTYPE, count=lead)] if lead else []
        if len(starts):
            rows = np.lib.stride_tricks.sliding_window_view(np.frombuffer(rest, np.uint8), FRAME_SIZE)[starts]
            parts.append(np.ascontiguousarray(rows).view(FRAME_DTYPE).reshape(-1))
        good = np.concatenate(parts) if len(parts) > 1 else parts[0].copy() if parts else _EMPTY
        frames, gaps, resyncs = self._account(good)
        return ParseResult(frames, gaps, replies, resyncs, captures)

    # -- finding frames, replies and captures --------------------------------------------------

    def _scan(self, buf: bytes) -> tuple[int, np.ndarray, list[Reply], list[Capture]]:
        """Where the bytes kept for the next chunk begin, the frame starts taken, the replies and the
        captures, in stream order; counts CRC rejects and discarded bytes."""
        n = len(buf)
        d = np.frombuffer(buf, np.uint8)
        if n < 2:
            keep = n == 1 and int(d[0]) in (_SYNC0, _CAP0, _DOLLAR)
            return (0 if keep else n), np.zeros(0, np.intp), [], []
        found = _Found(buf, d)
        found.frames()
        found.replies()
        found.captures()
        walk = _Walk(found)
        cut = walk.wait_at
        if d[-1] in (_SYNC0, _CAP0):
            found.undecided.append(n - 1)  # may begin a sync word
        soft = [u for u in found.undecided if walk.taken_end <= u < cut]
        if soft:
            cut = min(soft)
        if cut == walk.wait_at and walk.wait_size:
            self._wait_for = walk.wait_size
        # every sync word passed over: its CRC failed, or its frame could not be complete (something
        # intact lies inside it); none inside what was taken
        passed = np.concatenate((found.bad, found.incomplete)) if len(found.incomplete) else found.bad
        rejected = passed[passed < cut]
        if len(rejected) and walk.hard_spans:
            spans = np.array(walk.hard_spans)
            where = np.searchsorted(spans[:, 0], rejected, side="right") - 1
            inside = (where >= 0) & (rejected < spans[np.maximum(where, 0), 1])
            rejected = rejected[~inside]
        self.counters.crc_rejects += len(rejected)
        self.counters.bytes_discarded += max(cut - walk.covered, 0)
        self.counters.replies += len(walk.replies)
        self.counters.captures += len(walk.captures)
        starts = np.concatenate(walk.taken) if walk.taken else np.zeros(0, np.intp)
        return cut, starts, walk.replies, walk.captures

    # -- accounting ----------------------------------------------------------------------------

    def _account(self, frames: np.ndarray) -> tuple[np.ndarray, list[Gap], list[Resync]]:
        """Deliver the frames that continue the believed stream or are confirmed, hold candidates,
        drop duplicates and fakes (counted); report gaps and restarts (see the module docstring)."""
        n = len(frames)
        if n == 0:
            return frames, [], []
        seq = frames["seq"].astype(np.int64)
        boot = frames["boot"]
        steps = np.diff(seq) % _SEQ_MOD
        if (
            not self._chains
            and self.last_boot is not None
            and (seq[0] - self.last_seq) % _SEQ_MOD == 1
            and bool(np.all(boot == self.last_boot))
            and bool(np.all(steps == 1))
        ):
            self.last_seq = int(seq[-1])  # the common case: the believed stream goes on
            self.counters.frames_ok += n
            return frames, [], []
        out = _Delivery()
        breaks = np.flatnonzero((steps != 1) | (np.diff(boot) != 0)) + 1
        for lo, hi in itertools.pairwise([0, *breaks.tolist(), n]):
            self._take_run(frames[lo:hi], out)
        if len(out.frames) == 1:
            delivered = out.frames[0]
        else:
            delivered = np.concatenate(out.frames) if out.frames else _EMPTY
        self.counters.frames_ok += len(delivered)
        self.counters.gaps += len(out.gaps)
        self.counters.frames_missing += sum(g.missing for g in out.gaps)
        self.counters.resyncs += len(out.resyncs)
        return delivered, out.gaps, out.resyncs

    def _take_run(self, run: np.ndarray, out: _Delivery) -> None:
        """One run of frames numbered one after the other in one power-up."""
        boot, first = int(run["boot"][0]), int(run["seq"][0])
        if self.last_boot is None:
            kind = _FORWARD  # start-up: the first frames are believed on evidence too
        elif boot == self.last_boot:
            rel_first = _wrapped(first - self.last_seq, _SEQ_MOD)
            rel_last = rel_first + len(run) - 1
            if rel_first <= 1 <= rel_last:  # the believed stream goes on (after stale copies)
                stale = 1 - rel_first
                self.counters.duplicates += stale
                self._reject_all()
                self._commit(run[stale:], out)
                return
            kind = _STALE if rel_last <= 0 else _FORWARD
        else:
            kind = _FORWARD if _wrapped(boot - self.last_boot, _BOOT_MOD) > 0 else _STALE
        for chain in reversed(self._chains):
            if chain.follows(kind, boot, first):
                chain.add(run)
                break
        else:
            chain = _Chain(kind, boot, next(self._arrivals), run)
            self._chains.append(chain)
            if len(self._chains) > MAX_CHAINS:
                self._reject(self._chains.pop(0))
        if chain.count >= (EVIDENCE_FRAMES if kind == _FORWARD else STALE_EVIDENCE_FRAMES):
            self._confirm(chain, out)

    def _confirm(self, chain: _Chain, out: _Delivery) -> None:
        """Believe ``chain``: deliver it (and the candidates lying between it and the believed stream)."""
        others = [c for c in self._chains if c is not chain]
        self._chains = []
        parts = [c for c in others if self._between(c, chain)]
        for c in others:
            if not any(c is p for p in parts):
                self._reject(c)
        if chain.kind == _STALE:
            first = chain.frames[0]
            out.resyncs.append(
                Resync(out.count, int(self.last_boot), chain.boot, int(self.last_seq), int(first["seq"][0]))
            )
            self.last_boot = self.last_seq = None
        for c in sorted([*parts, chain], key=lambda c: c.arrival):
            for frames in c.frames:
                self._commit(frames, out)

    def _between(self, c: _Chain, chain: _Chain) -> bool:
        """Whether candidate ``c`` lies between the believed stream and the confirmed ``chain``: frames
        of the stretch the jump passed over that arrived intact."""
        if self.last_boot is None:
            return False  # at start-up nothing is believed yet: nothing lies between
        if c.kind != _FORWARD or chain.kind != _FORWARD or c.arrival > chain.arrival:
            return False
        if c.boot == chain.boot:
            after_believed = self.last_boot != c.boot or _wrapped(c.first - self.last_seq, _SEQ_MOD) > 0
            return after_believed and _wrapped(chain.first - c.last, _SEQ_MOD) > 0
        # the last frames of the believed stream before a restart
        return c.boot == self.last_boot and 0 < _wrapped(c.first - self.last_seq, _SEQ_MOD) <= CHAIN_STEP

    def _commit(self, frames: np.ndarray, out: _Delivery) -> None:
        """Deliver frames of one power-up, numbered upwards, with the gap or restart before them and
        the gaps between them."""
        if len(frames) == 0:
            return
        seq = frames["seq"].astype(np.int64)
        boot = int(frames["boot"][0])
        if self.last_boot is not None:
            if boot != self.last_boot:
                out.resyncs.append(Resync(out.count, self.last_boot, boot, int(self.last_seq), int(seq[0])))
            else:
                missing = _wrapped(int(seq[0]) - self.last_seq, _SEQ_MOD) - 1
                if missing > 0:
                    out.gaps.append(Gap(out.count, (self.last_seq + 1) % _SEQ_MOD, missing))
        steps = np.diff(seq) % _SEQ_MOD
        for i in np.flatnonzero(steps > 1).tolist():
            out.gaps.append(Gap(out.count + i + 1, int(seq[i] + 1) % _SEQ_MOD, int(steps[i]) - 1))
        out.frames.append(frames)
        out.count += len(frames)
        self.last_boot, self.last_seq = boot, int(seq[-1])

    def _reject(self, chain: _Chain) -> None:
        if chain.kind == _FORWARD:
            self.counters.frames_rejected += chain.count
        else:
            self.counters.duplicates += chain.count

    def _reject_all(self) -> None:
        for chain in self._chains:
            self._reject(chain)
        self._chains = []


# kinds of the pieces found in the bytes
_RUN, _LONE, _REPLY, _CAPTURE, _WAIT = range(5)
# kinds of candidate streams
_FORWARD, _STALE = "forward", "stale"


class _Found:
    """Everything intact in a buffer, found with a few vectorised passes: ``events`` (start, end,
    kind, what), the sync words whose CRC failed (``bad``) and the positions of what may still
    become something when more bytes come (``undecided``)."""

    def __init__(self, buf: bytes, d: np.ndarray) -> None:
        self.buf, self.d, self.n = buf, d, len(d)
        self.events: list[tuple[int, int, int, object]] = []
        self.undecided: list[int] = []
        self.valid = self.bad = self.incomplete = np.zeros(0, np.intp)

    def frames(self) -> None:
        """Frames: every sync word whose 64 bytes are in hand has its CRC checked at once; the intact
        ones are grouped in runs of back-to-back frames (``_RUN``, or ``_LONE`` for one alone)."""
        d, n = self.d, self.n
        sync = np.flatnonzero((d[:-1] == _SYNC0) & (d[1:] == _SYNC1))
        n_whole = int(np.searchsorted(sync, n - FRAME_SIZE, side="right"))
        whole = sync[:n_whole]
        ok = valid_at(d, whole) if n_whole else np.zeros(0, bool)
        self.valid, self.bad = whole[ok], whole[~ok]
        self.incomplete = sync[n_whole:]
        self.undecided += self.incomplete.tolist()  # frames not complete yet (the last 63 bytes)
        valid = self.valid
        if len(valid) == 0:
            return
        breaks = np.flatnonzero(np.diff(valid) != FRAME_SIZE) + 1
        lo = [0, *breaks.tolist()]
        hi = [*breaks.tolist(), len(valid)]
        ends = (valid[np.array(hi) - 1] + FRAME_SIZE).tolist()
        for a, b, start, end in zip(lo, hi, valid[lo].tolist(), ends, strict=True):
            self.events.append((start, end, _RUN if b - a > 1 else _LONE, (a, b)))

    def replies(self) -> None:
        """Reply lines: a ``$``, then printable ASCII other than ``$`` up to ``\r\n``, all within
        MAX_REPLY_LEN bytes; decided for every ``$`` at once, only such lines parsed one by one."""
        d, n = self.d, self.n
        dollars = np.flatnonzero(d == _DOLLAR)
        if len(dollars) == 0:
            return
        stops = np.flatnonzero((d < 0x20) | (d > 0x7E) | (d == _DOLLAR))
        after = stops[np.minimum(np.searchsorted(stops, dollars + 1), len(stops) - 1)]
        after = np.where(after > dollars, after, n)  # the first byte that cannot be in the line
        length = after + len(REPLY_END) - dollars
        fits = length <= MAX_REPLY_LEN
        padded = np.concatenate((d, [0, 0]))
        ended = fits & (after + 1 < n) & (padded[after] == _CR) & (padded[after + 1] == _LF)
        waiting = fits & ((after == n) | ((after == n - 1) & (padded[after] == _CR)))
        if waiting.any():
            self.undecided.append(int(dollars[np.argmax(waiting)]))
        if ended.any():  # the checksum of every ended line at once: "*HH" with HH the XOR of the body
            ends = np.where(ended, after, np.minimum(dollars + 3, n - 1))  # any index in range if not ended
            star_ok = d[np.maximum(ends - 3, 0)] == ord("*")
            digits = _HEX_VALUE[d[np.maximum(ends - 2, 0)]] * 16 + _HEX_VALUE[d[np.maximum(ends - 1, 0)]]
            xor = np.bitwise_xor.accumulate(d)
            body = xor[np.maximum(ends - 4, 0)] ^ xor[dollars]
            ended &= star_ok & (digits == body) & (ends - 3 > dollars)
        for p, size in zip(dollars[ended].tolist(), length[ended].tolist(), strict=True):
            try:
                reply = parse_reply(self.buf[p : p + size])
            except MalformedReplyError:
                continue
            self.events.append((p, p + size, _REPLY, reply))

    def captures(self) -> None:
        """Capture messages: every capture sync word's header CRC checked at once; a message whose
        header passes is decoded, or waited for (a ``_WAIT`` event) until its samples are in hand."""
        d, n = self.d, self.n
        found = np.flatnonzero((d[:-1] == _CAP0) & (d[1:] == _CAP1))
        if len(found) == 0:
            return
        n_whole = int(np.searchsorted(found, n - HEADER_SIZE, side="right"))
        self.undecided += found[n_whole:].tolist()  # headers not complete yet (the last 23 bytes)
        whole = found[:n_whole]
        if n_whole == 0:
            return
        rows = np.lib.stride_tricks.sliding_window_view(d, HEADER_SIZE)[whole]
        stored = rows[:, -2].astype(np.uint16) | (rows[:, -1].astype(np.uint16) << 8)
        intact = crc16_rows(rows[:, 2 : HEADER_SIZE - 2]) == stored
        for p in whole[intact].tolist():
            consumed, capture = decode_capture(self.buf, p)
            if capture is not None:
                self.events.append((p, p + consumed, _CAPTURE, capture))
            elif consumed == 0:
                size = HEADER_SIZE + 4 * int.from_bytes(self.buf[p + 2 : p + 6], "little") + 2
                self.events.append((p, n, _WAIT, size))


class _Walk:
    """The pieces found, taken in stream order. A run of frames, a reply or a capture hides what
    starts inside it (a run partly inside a reply or capture keeps its frames after it); a lone frame
    hides nothing. A capture still arriving ends the walk (``wait_at``, its size ``wait_size``)."""

    def __init__(self, found: _Found) -> None:
        self.taken: list[np.ndarray] = []
        self.replies: list[Reply] = []
        self.captures: list[Capture] = []
        self.hard_spans: list[tuple[int, int]] = []
        self.taken_end = 0  # end of everything taken
        self.covered = 0  # bytes taken (overlaps counted once)
        self.wait_at, self.wait_size = found.n, 0
        events = found.events
        if len(events) > 1:
            events.sort(key=lambda e: e[0])
        hard_end = 0
        for start, end, kind, what in events:
            if kind == _WAIT:
                if start >= hard_end:
                    self.wait_at, self.wait_size = start, int(what)
                    break
                continue
            if end <= hard_end or (start < hard_end and kind != _RUN):
                continue
            begin = start
            if kind in (_RUN, _LONE):
                a, b = what
                if start < hard_end:
                    a += int(np.searchsorted(found.valid[a:b], hard_end))
                    begin = int(found.valid[a])
                self.taken.append(found.valid[a:b])
            elif kind == _REPLY:
                self.replies.append(what)
            else:
                self.captures.append(what)
            if end > self.taken_end:
                self.covered += end - max(begin, self.taken_end)
                self.taken_end = end
            if kind != _LONE:
                hard_end = end
                self.hard_spans.append((begin, end))


class _Chain:
    """A candidate stream: frames of one ``boot`` numbered upwards, held until believed or refuted."""

    def __init__(self, kind: str, boot: int, arrival: int, run: np.ndarray) -> None:
        self.kind, self.boot, self.arrival = kind, boot, arrival
        self.frames: list[np.ndarray] = []
        self.count = 0
        self.first = int(run["seq"][0])
        self.last = self.first
        self.add(run)

    def follows(self, kind: str, boot: int, seq: int) -> bool:
        """Whether a frame of this ``kind``, ``boot`` and ``seq`` goes on from this candidate."""
        step = _wrapped(seq - self.last, _SEQ_MOD)
        return kind == self.kind and boot == self.boot and 0 < step <= CHAIN_STEP

    def add(self, run: np.ndarray) -> None:
        self.frames.append(run)
        self.count += len(run)
        self.last = int(run["seq"][-1])


@dataclass
class _Delivery:
    """What one feed delivers, in order."""

    frames: list[np.ndarray] = field(default_factory=list)
    gaps: list[Gap] = field(default_factory=list)
    resyncs: list[Resync] = field(default_factory=list)
    count: int = 0


def _wrapped(diff, modulus: int):
    """A counter difference unwrapped to ``(-modulus / 2, modulus / 2]``."""
    half = modulus // 2
    return (diff + half - 1) % modulus - half + 1
