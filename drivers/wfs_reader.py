"""Serial reader of the WFS acquisition: a thread with blocking reads, off the event loop.

The thread reads whatever the port has as soon as it has anything (``in_waiting``, at least one
byte), feeds the stream parser, and hands each :class:`SampleBlock` to every :class:`Subscription`:

- a *lossless* subscription (the run engine, the recorder) has a queue bounded in frames; when it
  is full the reader waits, so a device that is paced by its host slows down (a device whose
  buffers overflow meanwhile drops frames and the sequence counter reports the loss);
- a *lossy* subscription (a live view) never slows the reader: when its queue is full its oldest
  blocks are dropped and counted (:attr:`Subscription.dropped_blocks`).

Blocks that arrive while nobody subscribes are not kept. Replies to text commands are routed to
:meth:`WfsReader.command`, which serialises the commands of several threads. A port error closes
the port and the thread reopens it until stopped: a disconnect and reconnect resume the stream,
the frames lost in between show up as a gap; a device that restarted meanwhile (a new boot count)
shows up as a :class:`~drivers.wfs_stream.Resync`.
"""

from __future__ import annotations

import collections
import contextlib
import logging
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from typing import Protocol

import numpy as np
import serial

from drivers.errors import (
    CommandOutcomeUnknownError,
    CommandRejectedError,
    ConnectionLostError,
    LinkTimeoutError,
    ProtocolMismatchError,
)
from drivers.wfs_capture import Capture
from drivers.wfs_commands import Reply, format_command
from drivers.wfs_frame import PROTOCOL_VERSION
from drivers.wfs_stream import Gap, LinkCounters, Resync, StreamParser

log = logging.getLogger(__name__)

#: how often a command past its deadline looks again whether the reader has caught up (s)
_CATCH_UP_LOOK_S = 0.02
#: commands never re-sent on timeout: START restarts the sample clock, TARE re-zeroes the loads
NOT_RESENT = frozenset({"START", "TARE"})
#: How long past its port's read timeout a read may return and still be taken as having waited for
#: the line (s): a woken thread's wait for a processor on a loaded host. A read that returns later
#: than that was held by the host (see :meth:`WfsReader._unread_s`).
HELD_READ_MARGIN_S = 0.02
#: How long a consumer whose wait for blocks the host held past its timeout waits further, at most,
#: for the reader to read what the port holds (s; see :meth:`Subscription.get_all`)
CATCH_UP_AFTER_HOLD_S = 0.5


class SerialLike(Protocol):
    """The part of ``serial.Serial`` the reader uses (a pty, a USB adapter or an in-memory port)."""

    def read(self, size: int = 1) -> bytes: ...

    @property
    def in_waiting(self) -> int: ...

    def write(self, data: bytes) -> int | None: ...

    def close(self) -> None: ...


@dataclass(frozen=True)
class SampleBlock:
    """Consecutive frames as delivered (FRAME_DTYPE array), the gaps and the resynchronisations
    (device restarts: the sample clock starts over) before some of them.

    ``arrived_s``: when the bytes that completed the block arrived at the host (``time.monotonic()``
    when the port's read returned them), not when a consumer got round to the block. ``unread_s``:
    how long the port went unread before that read (the reader thread busy or held: waiting for a
    full lossless subscription, descheduled, or the whole process stopped, even inside the read:
    see :meth:`WfsReader._unread_s`); a host stall longer than the port's receive buffer lasts at
    the line rate (4095 bytes: 44 ms at 921600 baud) loses frames: the first read after it returns
    what the buffer held, and the gap comes with the first frame after the overrun, in that read's
    block or the next ones (:attr:`frames_missing`)."""

    frames: np.ndarray
    gaps: tuple[Gap, ...] = ()
    resyncs: tuple[Resync, ...] = ()
    arrived_s: float = 0.0
    unread_s: float = 0.0

    def __len__(self) -> int:
        return len(self.frames)

    @property
    def frames_missing(self) -> int:
        """Frames lost before frames of this block (the sum of its gaps)."""
        return sum(g.missing for g in self.gaps)


def merge_blocks(blocks: list[SampleBlock]) -> SampleBlock:
    """Consecutive blocks as one, the gaps and resyncs re-indexed to the merged frames; arrived when
    the last arrived, with the longest time the port went unread before any of them."""
    gaps: list[Gap] = []
    resyncs: list[Resync] = []
    first = 0
    for block in blocks:
        gaps.extend(replace(g, index=g.index + first) for g in block.gaps)
        resyncs.extend(replace(r, index=r.index + first) for r in block.resyncs)
        first += len(block)
    return SampleBlock(
        np.concatenate([b.frames for b in blocks]),
        tuple(gaps),
        tuple(resyncs),
        arrived_s=blocks[-1].arrived_s,
        unread_s=max(b.unread_s for b in blocks),
    )


class Subscription:
    """One consumer's queue of sample blocks (see :meth:`WfsReader.subscribe`)."""

    def __init__(
        self,
        *,
        lossless: bool,
        max_frames: int,
        on_close: Callable[[Subscription], None],
        parsed_through: Callable[[], float] | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        """``parsed_through()``: the ``time.monotonic()`` up to which the reader has parsed every byte
        that arrived at the port (None: not known; a wait the host held then ends at its timeout);
        ``clock``: what tells how long a wait took (``time.monotonic``)."""
        if max_frames < 1:
            raise ValueError(f"max_frames must be >= 1, got {max_frames}")
        self.lossless = lossless
        self.max_frames = max_frames
        self.dropped_blocks = 0  # lossy only: oldest blocks dropped because the queue was full
        self._blocks: collections.deque[SampleBlock] = collections.deque()
        self._frames = 0  # frames queued
        self._cond = threading.Condition()
        self._closed = False
        self._on_close = on_close
        self._parsed_through = parsed_through
        self._clock = clock

    @property
    def closed(self) -> bool:
        return self._closed

    def get(self, timeout_s: float | None = None) -> SampleBlock | None:
        """The next block, or None if none arrived within ``timeout_s`` (or the subscription is closed);
        a wait the host held past ``timeout_s`` waits for the reader as :meth:`get_all` says."""
        with self._cond:
            self._wait(timeout_s)
            if not self._blocks:
                return None
            block = self._blocks.popleft()
            self._frames -= len(block)
            self._cond.notify_all()
            return block

    def get_all(self, timeout_s: float | None = None) -> SampleBlock | None:
        """Every block queued since the last call, merged into one (gaps and resyncs re-indexed), or
        None if none arrived within ``timeout_s``.

        A consumer that has fallen behind catches up in one step: its cost per call is paid once for
        all the queued frames instead of once per block the port happened to deliver.

        None means that nothing arrived at the port within the wait, also when the host held the
        wait past ``timeout_s`` (the process stopped, the thread starved): the reader was held with
        it, and what arrived meanwhile waits in the port unread, so such a wait goes on until the
        reader has parsed every byte that had arrived by the wait's end, or a block comes (at most
        :data:`CATCH_UP_AFTER_HOLD_S` longer). Its consumer then sees the host stall's block first,
        not an empty wait that would read as a quiet link."""
        with self._cond:
            self._wait(timeout_s)
            if not self._blocks:
                return None
            blocks = list(self._blocks)
            self._blocks.clear()
            self._frames = 0
            self._cond.notify_all()
        return blocks[0] if len(blocks) == 1 else merge_blocks(blocks)

    def _wait(self, timeout_s: float | None) -> None:
        """Wait, holding the condition, for a block or the close, up to ``timeout_s``; a wait held
        past it by more than :data:`HELD_READ_MARGIN_S` goes on until the reader has caught up with
        the port (see :meth:`get_all`)."""
        ready = lambda: bool(self._blocks) or self._closed  # noqa: E731 - the condition's predicate
        start = self._clock()
        if self._cond.wait_for(ready, timeout_s) or timeout_s is None or self._parsed_through is None:
            return
        ended = self._clock()
        if ended - start <= timeout_s + HELD_READ_MARGIN_S:
            return
        limit = ended + CATCH_UP_AFTER_HOLD_S
        while not ready() and self._parsed_through() < ended and (left := limit - self._clock()) > 0:
            self._cond.wait(min(left, _CATCH_UP_LOOK_S))

    def read_frames(self, n: int, timeout_s: float) -> SampleBlock:
        """Collect at least ``n`` frames (whole blocks) within ``timeout_s``, gaps and resyncs re-indexed.

        On a lossy subscription the blocks it dropped meanwhile are missing without a gap: compare
        :attr:`dropped_blocks` before and after.
        """
        deadline = time.monotonic() + timeout_s
        blocks: list[SampleBlock] = []
        have = 0
        while have < n:
            block = self.get(max(deadline - time.monotonic(), 0.0))
            if block is None:
                raise LinkTimeoutError(f"{have} of {n} frames within {timeout_s} s")
            blocks.append(block)
            have += len(block)
        return merge_blocks(blocks)

    def close(self) -> None:
        """Stop receiving blocks; a reader waiting for room in this queue goes on."""
        with self._cond:
            self._closed = True
            self._blocks.clear()
            self._frames = 0
            self._cond.notify_all()
        self._on_close(self)

    def __enter__(self) -> Subscription:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _offer(self, block: SampleBlock, stopping: threading.Event) -> None:
        """Reader side: queue ``block``. A lossless queue holding ``max_frames`` frames or more waits
        until its consumer takes them; a lossy one drops its oldest blocks until the new one fits
        (the newest block is always kept, however long)."""
        with self._cond:
            if self.lossless:
                while self._frames >= self.max_frames and not self._closed and not stopping.is_set():
                    self._cond.wait(0.1)
            else:
                while self._blocks and self._frames + len(block) > self.max_frames:
                    self._frames -= len(self._blocks.popleft())
                    self.dropped_blocks += 1
            if not self._closed:
                self._blocks.append(block)
                self._frames += len(block)
                self._cond.notify_all()


class WfsReader:
    """Owns the serial port, the reader thread and the stream parser."""

    def __init__(
        self,
        open_port: Callable[[], SerialLike],
        *,
        read_size: int = 65536,
        reconnect_interval_s: float = 0.1,
        catch_up_limit_s: float = 10.0,
    ) -> None:
        """``catch_up_limit_s``: how long past a command's deadline its reply is still awaited while
        the reader has not yet read what arrived at the port by the deadline (see :meth:`command`)."""
        self._open_port = open_port
        self.read_size = read_size
        self.reconnect_interval_s = reconnect_interval_s
        self.catch_up_limit_s = catch_up_limit_s
        self._subscriptions: list[Subscription] = []
        self._subscriptions_lock = threading.Lock()
        self._replies: queue.Queue[Reply] = queue.Queue()
        self._captures: queue.Queue[Capture] = queue.Queue()
        self._command_lock = threading.Lock()
        self._parser = StreamParser()
        self._lock = threading.Lock()
        self._port: SerialLike | None = None
        self._stop = threading.Event()
        self._connected = threading.Event()
        self._thread: threading.Thread | None = None
        self.last_error: str | None = None
        #: ``time.monotonic()`` when bytes were last seen at the port: a read returned them, or they
        #: were waiting there as the reader took them (None: none yet)
        self.last_arrival_s: float | None = None
        #: the longest the port went unread since the reader started (s): the ``unread_s`` of every
        #: read, bytes or none
        self.longest_unread_s = 0.0
        #: the most bytes one read took from the port since the reader started: how full its receive
        #: buffer got
        self.largest_backlog_bytes = 0
        self._read_returned_s: float | None = None
        #: ``time.monotonic()`` up to which every byte that arrived at the port has been parsed (its
        #: replies queued): the call of the last read that left the port empty, once parsed
        self._parsed_through_s = float("-inf")

    @classmethod
    def serial(cls, url: str, *, baudrate: int = 921600, timeout_s: float = 0.02, **kwargs) -> WfsReader:
        """A reader on a serial port or pyserial URL (``/dev/ttyUSB0``, a pty path, ``socket://...``).

        ``timeout_s`` bounds a read on an idle line (how often the thread looks at its stop flag);
        bytes are handed on as soon as they arrive, whatever it is. It also bounds how long the host
        can hold a read unseen: a read that outlasts it by :data:`HELD_READ_MARGIN_S` was held by the
        host (:meth:`_unread_s`), so the default with its margin (40 ms) stays within the time a
        real port's receive buffer lasts (4095 bytes: 44 ms at 921600 baud): a host stall that loses
        frames is always told as one.
        """
        return cls(lambda: serial.serial_for_url(url, baudrate=baudrate, timeout=timeout_s), **kwargs)

    # -- life cycle ---------------------------------------------------------------------------

    def start(self) -> None:
        if self._thread is not None:
            raise RuntimeError("reader already started")
        self._thread = threading.Thread(target=self._run, name="wfs-reader", daemon=True)
        self._thread.start()

    def close(self) -> None:
        """Stop the thread and close the port."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
            self._thread = None
        self._close_port()

    def __enter__(self) -> WfsReader:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    @property
    def thread_id(self) -> int | None:
        """The reader thread's operating-system id while it runs (for CPU accounting), else None."""
        return self._thread.native_id if self.running else None

    def wait_connected(self, timeout_s: float) -> bool:
        return self._connected.wait(timeout_s)

    def link_silence_s(self) -> float:
        """How long (s) no byte has arrived at the port: since bytes were last seen there
        (:attr:`last_arrival_s`), or 0 while bytes wait in the port unread (the host is behind: the
        reader thread was not scheduled, or the whole process was stopped, not the link went quiet).
        Infinite before any byte arrived.

        The reader stamps :attr:`last_arrival_s` before it takes bytes it found waiting, so a port
        emptied by a read that has not returned yet (the process resumed after a stop, the reader
        taking the backlog) never reads as a silence that lasted since before the stop."""
        port = self._port
        try:
            if port is not None and port.in_waiting > 0:
                return 0.0
        except (serial.SerialException, OSError, TypeError, AttributeError):
            pass  # a port closed under the question: judged by the last arrival
        arrived = self.last_arrival_s
        return float("inf") if arrived is None else max(0.0, time.monotonic() - arrived)

    def link_counters(self) -> dict[str, int]:
        """The link counters by name (what a run records beside its samples)."""
        return asdict(self.counters)

    @property
    def counters(self) -> LinkCounters:
        """A consistent snapshot of the link counters."""
        with self._lock:
            return replace(self._parser.counters)

    # -- data ---------------------------------------------------------------------------------

    def subscribe(self, *, lossless: bool, max_frames: int = 4096) -> Subscription:
        """A new consumer of the sample stream, from the next block on (see the module docstring).

        Close it when done: a lossless subscription nobody reads stops the reader, and with it the
        replies to commands, so its consumer reads in a thread of its own.
        """
        sub = Subscription(
            lossless=lossless,
            max_frames=max_frames,
            on_close=self._unsubscribe,
            parsed_through=lambda: self._parsed_through_s,
        )
        with self._subscriptions_lock:
            self._subscriptions.append(sub)
        return sub

    def _unsubscribe(self, sub: Subscription) -> None:
        with self._subscriptions_lock, contextlib.suppress(ValueError):
            self._subscriptions.remove(sub)

    # -- commands -----------------------------------------------------------------------------

    def command(
        self, name: str, argument: str | float | None = None, *, timeout_s: float = 1.0, attempts: int = 3
    ) -> Reply:
        """Send a text command and wait up to ``timeout_s`` (s) for its reply, sending it up to
        ``attempts`` times; a command of :data:`NOT_RESENT` is sent once.

        A reply is late only once the reader has parsed every byte that arrived at the port by the
        deadline: one waiting unread behind frames (the reader held by a full lossless subscription,
        or not scheduled on a busy machine) is the host's delay, not the device's, and is awaited
        up to ``catch_up_limit_s`` longer.

        Commands of several threads are serialised (one command on the line at a time), and only a
        reply naming the command answers it.

        Raises CommandRejectedError on an ``ERR`` reply, LinkTimeoutError when no reply arrives,
        CommandOutcomeUnknownError when a command of :data:`NOT_RESENT` got no reply (it may have
        been carried out: check the frames' ``sample`` clock or status bits).
        """
        line = format_command(name, argument)
        with self._command_lock:
            return self._command_locked(line, name.rstrip("?").upper(), timeout_s, attempts)

    def _command_locked(self, line: bytes, answered: str, timeout_s: float, attempts: int) -> Reply:
        once = answered in NOT_RESENT
        for _ in range(1 if once else attempts):
            self._drain_replies()
            self._write(line, timeout_s)
            deadline = time.monotonic() + timeout_s
            while True:
                left = self._reply_wait_s(deadline)
                try:  # late: only what the reader has queued by now
                    reply = self._replies.get(timeout=left) if left > 0 else self._replies.get_nowait()
                except queue.Empty:
                    if left > 0:
                        continue
                    break
                if reply.command != answered:
                    continue
                if not reply.ok:
                    reason = ",".join(reply.fields)
                    raise CommandRejectedError(f"WFS refused {line.decode().strip()}: {reason}")
                return reply
            log.warning("no reply to %r within %s s", line, timeout_s)
        if once:
            raise CommandOutcomeUnknownError(
                f"no reply to {line.decode().strip()!r} within {timeout_s} s; not re-sent, it may have run"
            )
        raise LinkTimeoutError(f"no reply to {line.decode().strip()!r} after {attempts} attempts")

    def _reply_wait_s(self, deadline_s: float) -> float:
        """How long to wait for a reply next (s); 0: it is late. Past ``deadline_s``, a short look
        again while the reader is behind the port (within :attr:`catch_up_limit_s`)."""
        now = time.monotonic()
        if now < deadline_s:
            return deadline_s - now
        if self._parsed_through_s >= deadline_s or now >= deadline_s + self.catch_up_limit_s:
            return 0.0
        return _CATCH_UP_LOOK_S

    def identify(self) -> tuple[str, ...]:
        """The device's identity (vendor, model, serial, firmware, protocol version); raises
        ProtocolMismatchError when it speaks another protocol version than this reader."""
        fields = self.command("IDENT").fields
        if not fields or fields[-1] != str(PROTOCOL_VERSION):
            raise ProtocolMismatchError(
                f"WFS speaks protocol {fields[-1] if fields else '?'}, this reader {PROTOCOL_VERSION}"
            )
        return fields

    def start_stream(self) -> None:
        self.command("START")

    def stop_stream(self) -> None:
        self.command("STOP")

    def tare(self) -> None:
        self.command("TARE")

    def set_rate(self, rate_hz: int) -> int:
        return int(self.command("RATE", int(rate_hz)).fields[0])

    def rate_hz(self) -> int:
        """The frame rate the device streams at (Hz), as it reports it."""
        return int(self.command("RATE?").fields[0])

    def capture(
        self, trigger_level_n: float, pre_trigger_s: float, length_s: float, timeout_s: float
    ) -> Capture:
        """Arm a triggered capture of Fz at the converter rate and wait up to ``timeout_s`` for it
        (:meth:`arm_capture` then :meth:`wait_capture`)."""
        self.arm_capture(trigger_level_n, pre_trigger_s, length_s)
        return self.wait_capture(timeout_s)

    def arm_capture(self, trigger_level_n: float, pre_trigger_s: float, length_s: float) -> tuple[int, int]:
        """Send ``CAPTURE``; return the block's samples and pre-trigger samples the device confirmed.

        A capture that arrived before is discarded. A refusal raises CommandRejectedError naming
        the limits. Once this returns the device is armed: a blow from now on fires the trigger.
        """
        with contextlib.suppress(queue.Empty):
            while True:
                self._captures.get_nowait()
        reply = self.command("CAPTURE", f"{trigger_level_n:g} {pre_trigger_s:g} {length_s:g}")
        return int(reply.fields[0]), int(reply.fields[1])

    def wait_capture(self, timeout_s: float) -> Capture:
        """The armed capture's block, once the trigger fired and it arrived (LinkTimeoutError if it
        did not within ``timeout_s``; the device stays armed)."""
        try:
            return self._captures.get(timeout=timeout_s)
        except queue.Empty:
            message = f"no triggered capture within {timeout_s} s: nothing beyond the level"
            raise LinkTimeoutError(message) from None

    def _drain_replies(self) -> None:
        with contextlib.suppress(queue.Empty):
            while True:
                self._replies.get_nowait()

    def _write(self, data: bytes, timeout_s: float) -> None:
        if not self._connected.wait(timeout_s):
            raise ConnectionLostError(f"WFS port not open ({self.last_error})")
        port = self._port
        try:
            if port is None:
                raise ConnectionLostError("WFS port closed")
            port.write(data)
        except (serial.SerialException, OSError) as exc:
            raise ConnectionLostError(f"writing to the WFS port failed: {exc}") from exc

    # -- thread -------------------------------------------------------------------------------

    def _run(self) -> None:
        opened_before = False
        while not self._stop.is_set():
            if self._port is None:
                self._parsed_through_s = time.monotonic()  # a closed port holds nothing to read
                if not self._try_open(opened_before):
                    self._stop.wait(self.reconnect_interval_s)
                    continue
                opened_before = True
            port = self._port
            called = time.monotonic()
            try:
                waiting = port.in_waiting
                data, first_s, held_between_s = self._read_available(port)
            except (serial.SerialException, OSError, TypeError, AttributeError) as exc:
                # pyserial raises TypeError/AttributeError when the port is closed under a read
                self.last_error = f"read failed: {exc}"
                log.warning("WFS %s; reopening", self.last_error)
                self._close_port()
                self._read_returned_s = None
                continue
            returned = time.monotonic()
            held = bool(data) and _read_held(port, first_s - called)
            unread = max(self._unread_s(called, returned, waiting > 0 or held), held_between_s)
            self._read_returned_s = returned
            self.longest_unread_s = max(self.longest_unread_s, unread)
            self.largest_backlog_bytes = max(self.largest_backlog_bytes, len(data))
            if data:
                self.last_arrival_s = returned
                self._consume(data, returned, unread)
            if len(data) < self.read_size:  # the port was empty after the call: all read by then
                self._parsed_through_s = called

    def _unread_s(self, called_s: float, returned_s: float, held: bool) -> float:
        """How long the port went unread before the read called at ``called_s`` returned at
        ``returned_s``: from the previous read's return to this one's when the host ``held`` the
        port's bytes, else to the call (the read then waited for the line, not the host).

        The host held them when bytes were waiting at the call (the reader thread busy, waiting for
        a full lossless subscription, descheduled), or when the read came back with bytes later than
        the port's own read timeout allows (:func:`_read_held`). The second is a host stopped or
        starved *inside* the read: a process stopped (SIGSTOP, a debugger, a machine suspended)
        while its reader waits in the read's system call finds, when it resumes, the read returning
        at once with what the port kept meanwhile, and nothing was waiting when the read was called.
        Unread time counted only up to the call would read ~0 s for the whole stop, with a full
        buffer behind it and the frames lost to the overrun booked as the link's.

        A read that waited for the line returns as soon as a byte arrives, and on an idle line empty
        at its timeout: returning with bytes later than the timeout allows, it was held for part of
        its wait at least. When its bytes arrived within that wait is not known, so the whole wait
        is counted: an upper bound, off by at most the read timeout while the line streams (bytes
        arrive within it), which it does through any stop long enough to overrun the port's buffer;
        a line quiet for part of the stop (a reply arriving at its end) makes it longer than the
        bytes waited, which costs a stall recorded without frames lost, never frames booked wrong."""
        since = self._read_returned_s
        if since is None:
            return 0.0
        return (returned_s if held else called_s) - since

    def _read_available(self, port: SerialLike) -> tuple[bytes, float, float]:
        """What the port holds, as soon as it holds anything: wait (up to the port's timeout) for one
        byte, then take whatever else has arrived meanwhile, up to ``read_size`` bytes, without
        waiting for more. A pty hands over at most 4 KiB per read: the reads go on while bytes are
        waiting, so a fast stream is parsed in large pieces.

        Returns the bytes, when the first read returned (``time.monotonic()``), and the longest time
        between the returns of two reads that took bytes found waiting (each returns at once unless
        the host held the thread: that time the waiting bytes went unread). Bytes found waiting are
        seen at the port (:attr:`last_arrival_s`) before they are taken."""
        if waiting := min(port.in_waiting, self.read_size):
            self.last_arrival_s = time.monotonic()
        data = port.read(waiting or 1)
        first = last = time.monotonic()
        held = 0.0
        while data and (waiting := min(port.in_waiting, self.read_size - len(data))) > 0:
            self.last_arrival_s = time.monotonic()
            data += port.read(waiting)
            now = time.monotonic()
            held, last = max(held, now - last), now
        return data, first, held

    def _try_open(self, reopening: bool) -> bool:
        try:
            port = self._open_port()
        except (serial.SerialException, OSError, ValueError) as exc:
            self.last_error = f"open failed: {exc}"
            return False
        self._port = port
        if reopening:
            with self._lock:
                self._parser.counters.reconnects += 1
                self._parser.reopened()
        self._connected.set()
        return True

    def _close_port(self) -> None:
        self._connected.clear()
        port, self._port = self._port, None
        if port is not None:
            with contextlib.suppress(serial.SerialException, OSError):
                port.close()

    def _consume(self, data: bytes, arrived_s: float = 0.0, unread_s: float = 0.0) -> None:
        """Parse ``data`` (arrived at ``arrived_s``, the port unread for ``unread_s`` before); hand its
        frames to the subscriptions first, then its replies and captures to whoever awaits them: a
        command's reply is seen only once the frames that came before it on the line are queued (a
        host that stops the stream has every frame sent before STOP)."""
        with self._lock:
            result = self._parser.feed(data)
        if len(result.frames) or result.gaps or result.resyncs:
            gaps, resyncs = tuple(result.gaps), tuple(result.resyncs)
            block = SampleBlock(result.frames, gaps, resyncs, arrived_s=arrived_s, unread_s=unread_s)
            with self._subscriptions_lock:
                subscriptions = sorted(self._subscriptions, key=lambda sub: sub.lossless)  # lossy first
            for sub in subscriptions:
                sub._offer(block, self._stop)
        for reply in result.replies:
            self._replies.put(reply)
        for capture in result.captures:
            self._captures.put(capture)


def _read_held(port: SerialLike, wait_s: float) -> bool:
    """Whether a read that came back with bytes after waiting ``wait_s`` for its first one was held
    by the host: it waited longer than ``port``'s read timeout (pyserial's ``timeout``) allows,
    with :data:`HELD_READ_MARGIN_S` for the wake-up of its thread. A read that waits for the line
    returns as soon as a byte arrives and, on a quiet line, empty at its timeout; one that returns
    with bytes later was not running when it could have returned. A port without a timeout waits
    for the line as long as it is quiet: nothing tells its held reads apart (False)."""
    timeout = getattr(port, "timeout", None)
    return isinstance(timeout, int | float) and wait_s > timeout + HELD_READ_MARGIN_S
