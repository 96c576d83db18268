"""The simulated WFS acquisition: streams frames of the simulated bench and answers the command set.

Channels: Fz is the plant's WFS force; Fx, Fy, Mx, My, Mz are crosstalk of Fz (seeded factors within
the ±0.5 % specification; moments over a 0.3 m lever) plus seeded noise; aux0/aux1/aux2 carry the
bench displacement, plate force and hub acceleration, sampled in the same frame. With a wheel speed
set, the wheel angle advances and the loads are expressed in the rotating sensor frame, so a host
that applies the rotating-to-non-rotating transformation recovers the wheel-frame loads. The
controller's sync outputs arrive on two digital inputs, sampled at the converter rate and delayed
like the analog channels (:class:`DigitalInputs`), and set the status bits ``EXCITATION_ACTIVE``
and ``AMPLITUDE_HOLD``.

Counters: ``seq`` counts the frames sent since power-up, ``sample`` the samples since the last
START, ``boot`` the power-ups (:meth:`WfsDevice.restart` is one); the command thread and the bench
runner change them under one lock.

The output rate is the bench's: the plant models the acquisition's 10 kHz converter and its
anti-alias decimation, so ``RATE`` changes the plant's oversampling (see :meth:`WfsDevice.valid_rates`).

Backpressure: a block waits at most ``hold_s`` (default :data:`BACKPRESSURE_S`) for the host to
drain the link (it goes out in pieces of whole frames, a command reply or capture after the block);
what is not sent by then is dropped (``frames_dropped``; the sequence counter shows the gap to the
host) and, until the host drains again, later blocks are only offered briefly, so a host that stops
reading never freezes the bench (the bench then runs in real time and the controller's watchdog
fires).

Faults: byte faults on the outgoing stream (:class:`ByteFaults`), a stalled stream (a number of
frames is not sent, the sequence counter runs on), bursts of frames lost at set places of every
hold (:class:`FrameLoss`: deterministic, placed by the frames' own hold sync bit), a disconnect and
reconnect of the link, a restart, commands ignored (neither carried out nor answered).

Commands are dispatched through a table (:attr:`WfsDevice.commands`), one handler per command name.
"""

from __future__ import annotations

import collections
import contextlib
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import serial

from drivers.wfs_capture import MAX_CAPTURE_SAMPLES, encode_capture
from drivers.wfs_commands import UNKNOWN, Reply, parse_command
from drivers.wfs_frame import (
    AUX_FIELDS,
    FORCE_FIELDS,
    FRAME_DTYPE,
    FRAME_SIZE,
    PROTOCOL_VERSION,
    Status,
    encode,
)
from drivers.wfs_transform import rotate_to_wheel_frame
from simulators.bench_sim import BenchBlock, SimulatedBench
from simulators.capture_trigger import BASELINE_SAMPLES, HISTORY_SAMPLES, CaptureTrigger
from simulators.faults import ByteFaults
from simulators.function_generator import AMPLITUDE_HOLD, EXCITATION_ACTIVE
from simulators.worker import Worker

log = logging.getLogger(__name__)

IDENTITY = ("WFSBENCH", "SIM-WFS6", "0001", "2.0", str(PROTOCOL_VERSION))
#: the status bit each digital sync input sets
SYNC_STATUS = {EXCITATION_ACTIVE: Status.EXCITATION_ACTIVE, AMPLITUDE_HOLD: Status.AMPLITUDE_HOLD}
#: measuring range per channel, Fx Fy Fz (N) and Mx My Mz (N m), as the paper's Table 1; beyond it
#: the channel's overload bit is set
LOAD_RANGE = np.array([24_000.0, 15_000.0, 24_000.0, 4_500.0, 7_200.0, 4_500.0])
#: input range of aux0..aux3 (m, N, m/s^2, V): the ±10 V inputs scaled to a ±50 mm displacement
#: transducer, a ±50 kN load cell, a ±50 g accelerometer and the spare input in volts; beyond it on
#: any aux channel the aux overload bit is set
AUX_RANGE = np.array([0.05, 50_000.0, 490.0, 10.0])
CROSSTALK_SPEC = 0.005
LEVER_M = 0.3
_MAX_LINE = 64
#: the lowest output rate RATE accepts (Hz)
MIN_RATE_HZ = 100
#: by default, the longest a block of frames waits for the host to drain the link before it is
#: dropped (s)
BACKPRESSURE_S = 1.0
#: how long a block is offered while the host is not draining (s)
_OVERFLOW_PROBE_S = 0.005
#: frames go out in pieces of this many bytes (whole frames); a command reply after the block's last
_WRITE_PIECE_BYTES = 64 * FRAME_SIZE
#: the longest a command reply waits for the host to drain the link (s)
_REPLY_TIMEOUT_S = 1.0


class DeviceLink(Protocol):
    """The device's side of a transport (:class:`MemoryLink`, :class:`PtyLink`)."""

    def device_read(self, size: int, timeout_s: float) -> bytes: ...

    def device_write(self, data: bytes, timeout_s: float) -> int: ...

    def disconnect(self) -> None: ...

    def reconnect(self) -> None: ...


@dataclass(frozen=True)
class FrameLoss:
    """A burst of ``frames`` frames lost on the link, beginning ``after_hold_frames`` frames into a
    hold of the excitation (from a rise of the amplitude-hold sync input, as the frames' status
    shows it): every hold, or those numbered in ``holds`` (0: the first hold the device streams,
    each in-dwell amplitude update's hold counting as one). A link that loses bytes (a USB
    adapter's hiccup, a cable, noise), placed where a test wants it whatever the host's speed. The
    counter runs on over the lost frames."""

    after_hold_frames: int
    frames: int
    holds: tuple[int, ...] | None = None


class DigitalInputs:
    """The acquisition's digital inputs: sampled at the converter rate, and each output sample takes
    the inputs at the instant its analog channels describe (``latency`` output samples earlier, the
    anti-alias filter's delay), so that an edge lines up with the analog channels."""

    def __init__(self) -> None:
        self._history = np.zeros(0, np.uint8)  # the latest converter samples, for the delay

    def sample(self, flags: np.ndarray, n_out: int, latency_samples: int) -> np.ndarray:
        """The inputs of ``n_out`` output samples from the block's converter-rate ``flags``."""
        if len(flags) == 0:
            return np.zeros(n_out, np.uint8)
        factor = len(flags) // n_out
        delay = latency_samples * factor
        past = self._history[-delay:] if delay else self._history[:0]
        past = np.concatenate([np.zeros(delay - len(past), np.uint8), past])  # inputs low at power-up
        data = np.concatenate([past, flags])
        self._history = data[len(data) - delay :]
        return data[: n_out * factor : factor]


#: The simulated bench's wiring of the aux inputs: displacement, plate force, hub acceleration, open.
DEFAULT_AUX_WIRING = ("z_base_m", "f_plate_n", "a_hub_m_s2", None)


class WfsDevice:
    """A WFS acquisition on a serial link, fed blocks by the bench runner (a :class:`BenchSink`).

    ``boot`` is the number of power-ups so far (kept in the device's non-volatile memory).
    """

    #: :meth:`deliver` waits for the host to drain the link: the bench runner feeds it from a thread
    #: of its own, so that the bench's clock never waits for the host
    waits_for_host = True

    def __init__(
        self,
        link: DeviceLink,
        bench: SimulatedBench,
        *,
        seed: int = 0,
        baudrate: int = 921600,
        faults: ByteFaults | None = None,
        noise_n: float = 1.0,
        speed_rad_s: float = 0.0,
        angle_rad: float = 0.0,
        boot: int = 1,
        aux_wiring: tuple[str | None, ...] = DEFAULT_AUX_WIRING,
        hold_s: float = BACKPRESSURE_S,
    ) -> None:
        """``aux_wiring``: the bench channel each aux input (aux0..aux3) carries, None for an input
        left open (it reads 0); ``hold_s``: the longest a block waits for a host that stops reading
        before it is dropped (the device's buffer, in seconds of frames)."""
        if not hold_s > 0:
            raise ValueError(f"hold_s must be positive, got {hold_s}")
        self.link = link
        self.hold_s = hold_s
        self.aux_wiring = aux_wiring
        self.bench = bench
        self.baudrate = baudrate
        self.faults = faults or ByteFaults(seed=seed)
        self.noise_n = noise_n
        self.speed_rad_s = speed_rad_s
        self.angle_rad = angle_rad
        self._rng = np.random.default_rng(seed)
        # crosstalk of Fz into Fx, Fy (N/N) and Mx, My, Mz (N m / N)
        scale = np.array([1.0, 1.0, LEVER_M, LEVER_M, LEVER_M])
        self.crosstalk = self._rng.uniform(-CROSSTALK_SPEC, CROSSTALK_SPEC, 5) * scale
        self.tare_offset = np.zeros(6)
        self._recent = np.zeros((0, 6))
        self._write_lock = threading.Lock()  # the line: one writer at a time
        #: replies and captures waiting for the line (see :meth:`_send_after_frames`)
        self._outbox: collections.deque[bytes] = collections.deque()
        self._counter_lock = threading.Lock()  # seq, sample, boot, streaming: bench and command threads
        self._streaming = False
        self._seq = 0
        self._sample = 0
        self.boot = boot % (1 << 16)
        self._inputs = DigitalInputs()
        self._stall_frames = 0
        #: bursts lost in every hold (:class:`FrameLoss`), and where the stream is in them
        self.frame_losses: tuple[FrameLoss, ...] = ()
        self._hold_position = -1  # frames into the present hold (-1: not in a hold)
        self._holds_begun = 0  # holds begun since the device started
        self._losing = 0  # frames of a burst still to lose
        self.frames_lost_in_holds = 0
        self._link_up = True
        #: command name (as parsed, e.g. ``RATE?``) -> handler of its arguments
        self.commands: dict[str, Callable[[list[str]], Reply]] = {
            "IDENT": _no_arguments("IDENT", lambda: Reply(True, "IDENT", IDENTITY)),
            "START": _no_arguments("START", self._start),
            "STOP": _no_arguments("STOP", self._stop_streaming),
            "TARE": _no_arguments("TARE", self._tare),
            "RATE": self._set_rate,
            "RATE?": _no_arguments("RATE", lambda: Reply(True, "RATE", (str(self.rate_hz),))),
            "CAPTURE": self._arm_capture,
        }
        #: commands received and ignored, neither carried out nor answered (a fault: a device that
        #: does not answer TARE, say)
        self.ignored_commands: set[str] = set()
        self._worker = Worker(self._serve_commands, "wfs-device")
        self._stop = self._worker.stopping
        self.frames_sent = 0
        self.frames_unsent = 0  # produced while stalled or disconnected (the host sees a gap)
        self.frames_dropped = 0  # not sent because the host did not drain the link (a gap too)
        self._overflowing = False  # the last block did not fit: the host is not draining
        self._capture_lock = threading.Lock()
        self._fast_history = np.zeros(0)  # the latest converter samples of Fz (tare applied)
        self._trigger: CaptureTrigger | None = None

    @property
    def rate_hz(self) -> int:
        """The output rate (frames per second) of the acquisition."""
        return round(self.bench.output_rate_hz)

    def valid_rates(self) -> list[int]:
        """Rates ``RATE`` accepts: a whole oversampling of the converter, from
        :data:`MIN_RATE_HZ` up to the frames per second the serial line carries (10 bits per byte).
        """
        converter_hz = round(self.bench.plant.internal_rate_hz)
        line_max = self.baudrate // (10 * FRAME_SIZE)
        return [r for r in range(MIN_RATE_HZ, min(line_max, converter_hz) + 1) if converter_hz % r == 0]

    # -- life cycle -----------------------------------------------------------------------------

    @property
    def streaming(self) -> bool:
        return self._streaming

    @property
    def replies_waiting(self) -> int:
        """Replies and captures queued for the line, not yet written."""
        return len(self._outbox)

    @property
    def paces_bench(self) -> bool:
        """Streaming to a host that drains the link (an unpaced bench runs as fast as it reads)."""
        return self._streaming and self._link_up and not self._overflowing

    def start(self) -> None:
        self._worker.start()

    def stop(self) -> None:
        self._worker.stop()

    # -- faults ---------------------------------------------------------------------------------

    def stall(self, frames: int) -> None:
        """Send nothing while the next ``frames`` frames are produced (they are lost)."""
        self._stall_frames = frames

    def restart(self) -> None:
        """A power cycle: the boot count goes up, ``seq`` and ``sample`` start from 0, streaming stops,
        the tare is lost (the output rate, a setting of the bench, stays)."""
        with self._counter_lock:
            self.boot = (self.boot + 1) % (1 << 16)
            self._seq = self._sample = 0
            self._streaming = False
            self.tare_offset = np.zeros(6)

    def disconnect(self) -> None:
        with self._write_lock:
            self._link_up = False
            self._outbox.clear()  # replies to the lost connection are lost with it
            self.link.disconnect()

    def reconnect(self) -> None:
        with self._write_lock:
            self.link.reconnect()
            self._link_up = True
        self._flush_outbox()

    # -- streaming ------------------------------------------------------------------------------

    def deliver(self, block: BenchBlock) -> None:
        """Turn a bench block into frames and send them (called by the bench runner)."""
        self._feed_capture(block)
        frames = self._frames(block)
        if len(frames) == 0:
            return
        if self.frame_losses:
            frames = self._lose(frames)
        if self._stall_frames:
            stalled = min(self._stall_frames, len(frames))
            self._stall_frames -= stalled
            self.frames_unsent += stalled
            frames = frames[stalled:]
        if not self._link_up or len(frames) == 0:
            self.frames_unsent += len(frames)
            return
        data = self.faults.apply(encode(frames))
        deadline = time.monotonic() + (_OVERFLOW_PROBE_S if self._overflowing else self.hold_s)
        sent, link_lost = 0, False
        # written a piece of whole frames at a time, so that a reply waits for one piece at most
        for start in range(0, len(data), _WRITE_PIECE_BYTES):
            piece = data[start : start + _WRITE_PIECE_BYTES]
            with self._write_lock:
                if not self._link_up:
                    link_lost = True
                    break
                try:
                    written = self._write_all(piece, deadline - time.monotonic())
                except (serial.SerialException, OSError) as exc:
                    log.debug("WFS device write failed: %s", exc)
                    link_lost = True
                    break
            sent += written
            if written < len(piece):
                break
        self._flush_outbox()  # what was queued while the block went out: after its frames
        whole = min(sent // FRAME_SIZE, len(frames))
        self.frames_sent += whole
        if link_lost:
            self.frames_unsent += len(frames) - whole
        else:
            self._overflowing = sent < len(data)
            self.frames_dropped += len(frames) - whole

    def _lose(self, frames: np.ndarray) -> np.ndarray:
        """The frames that survive the :attr:`frame_losses` bursts (the lost ones count as unsent)."""
        hold = (frames["status"] & int(Status.AMPLITUDE_HOLD)) != 0
        keep = np.ones(len(frames), bool)
        for i, holding in enumerate(hold.tolist()):
            if holding and self._hold_position < 0:
                self._holds_begun += 1
            self._hold_position = self._hold_position + 1 if holding else -1
            for loss in self.frame_losses:
                applies = loss.holds is None or self._holds_begun - 1 in loss.holds
                if applies and self._hold_position == loss.after_hold_frames:
                    self._losing = max(self._losing, loss.frames)
            if self._losing:
                keep[i] = False
                self._losing -= 1
        lost = len(frames) - int(keep.sum())
        self.frames_unsent += lost
        self.frames_lost_in_holds += lost
        return frames[keep]

    def _write_all(self, data: bytes, timeout_s: float) -> int:
        """Write as much of ``data`` as the host drains within ``timeout_s``; return the bytes sent
        (a frame cut short is rejected by the host's CRC check)."""
        deadline = time.monotonic() + timeout_s
        sent = 0
        while sent < len(data) and self._link_up and not self._stop.is_set():
            # offered at least once, however late: a thread not scheduled until after its deadline
            # has not waited for the host
            sent += self.link.device_write(data[sent:], max(deadline - time.monotonic(), 0.0))
            if time.monotonic() >= deadline:
                break
        return sent

    def _frames(self, block: BenchBlock) -> np.ndarray:
        """Frames for the samples of ``block`` (the bench's output is the acquisition's, filtered)."""
        ch = block.channels
        fz = ch["fz_wfs_n"]
        m = len(block)
        loads = np.empty((m, 6))
        loads[:, 2] = fz
        noise = self.noise_n * self._rng.standard_normal((m, 5))
        loads[:, [0, 1, 3, 4, 5]] = fz[:, None] * self.crosstalk + noise
        # the instants the (delayed) analog channels describe
        t = block.start_s + (np.arange(m) - block.latency_samples) / block.rate_hz
        angle = np.mod(self.angle_rad + self.speed_rad_s * t, 2 * np.pi)
        loads = rotate_to_wheel_frame(loads, -angle)  # the sensor turns with the wheel
        inputs = self._inputs.sample(block.sync_flags, m, block.latency_samples)
        self._recent = np.concatenate([self._recent, loads])[-100:]
        frames = np.zeros(m, FRAME_DTYPE)
        with self._counter_lock:
            # a block made before a RATE change (queued behind the bench) is never sent: the
            # acquisition's output after the change is at the new rate only
            if not self._streaming or block.rate_hz != self.bench.output_rate_hz:
                return frames[:0]
            frames["seq"] = (self._seq + np.arange(m)) % (1 << 32)
            frames["sample"] = (self._sample + np.arange(m)) % (1 << 32)
            frames["boot"] = self.boot
            self._seq += m
            self._sample += m
            out = loads - self.tare_offset
            tared = Status.TARED if self.tare_offset.any() else 0
        for i, name in enumerate(FORCE_FIELDS):
            frames[name] = out[:, i]
        frames["angle_rad"] = angle
        frames["speed_rad_s"] = self.speed_rad_s
        for field, channel in zip(AUX_FIELDS, self.aux_wiring, strict=True):
            if channel is not None:
                frames[field] = ch[channel]
        aux = np.column_stack([frames[field] for field in AUX_FIELDS])
        with np.errstate(invalid="ignore"):  # a NaN is no overload: it is an ADC fault
            overload = (np.abs(loads) > LOAD_RANGE) * (1 << np.arange(6))
            aux_overload = np.any(np.abs(aux) > AUX_RANGE, axis=1)
        # the converter flags a conversion it could not complete: here, a non-finite sample
        fault = ~(np.all(np.isfinite(loads), axis=1) & np.all(np.isfinite(aux), axis=1))
        status = overload.sum(axis=1) | tared
        status |= np.where(aux_overload, int(Status.OVERLOAD_AUX), 0)
        status |= np.where(fault, int(Status.ADC_FAULT), 0)
        for bit, flag in SYNC_STATUS.items():
            status |= np.where(inputs & bit, int(flag), 0)
        frames["status"] = status
        return frames

    # -- triggered capture ----------------------------------------------------------------------

    def _feed_capture(self, block: BenchBlock) -> None:
        """Keep the converter's Fz and feed an armed capture; send the capture when it is complete."""
        fast = block.fast.get("fz_wfs_n")
        if fast is None:
            return
        fz = fast - self.tare_offset[2]
        with self._capture_lock:
            self._fast_history = np.concatenate([self._fast_history, fz])[-HISTORY_SAMPLES:]
            capture = self._trigger.feed(fz) if self._trigger is not None else None
            if capture is not None:
                self._trigger = None
        if capture is not None:
            self._send_after_frames(encode_capture(capture))

    def _arm_capture(self, args: list[str]) -> Reply:
        """``CAPTURE <trigger_level_n> <pre_trigger_s> <length_s>``: arm (replacing an armed capture)."""
        rate_hz = self.bench.plant.internal_rate_hz
        if len(args) != 3:
            return Reply(False, "CAPTURE", ("bad arguments",))
        try:
            level_n, pre_s, length_s = (float(a) for a in args)
        except ValueError:
            return Reply(False, "CAPTURE", ("level pre length must be numbers",))
        longest_pre_s = (HISTORY_SAMPLES - BASELINE_SAMPLES) / rate_hz
        if not (0 < level_n < np.inf and 0 <= pre_s <= longest_pre_s and pre_s < length_s):
            limits = f"level > 0 N; 0 <= pre < length; pre <= {longest_pre_s:g} s"
            return Reply(False, "CAPTURE", (f"{level_n:g} N {pre_s:g} s {length_s:g} s not possible", limits))
        if not length_s * rate_hz <= MAX_CAPTURE_SAMPLES:
            longest_s = MAX_CAPTURE_SAMPLES / rate_hz
            return Reply(False, "CAPTURE", (f"length {length_s:g} s beyond {longest_s:g} s",))
        length, pre = round(length_s * rate_hz), round(pre_s * rate_hz)
        if pre >= length:
            return Reply(False, "CAPTURE", (f"pre-trigger {pre_s:g} s leaves no sample after the trigger",))
        with self._capture_lock:
            self._trigger = CaptureTrigger(
                self._fast_history,
                rate_hz=rate_hz,
                trigger_level_n=level_n,
                pre_trigger_samples=pre,
                length_samples=length,
            )
        return Reply(True, "CAPTURE", (str(length), str(pre), f"{rate_hz:g}"))

    # -- commands -------------------------------------------------------------------------------

    def _serve_commands(self) -> None:
        line = bytearray()
        too_long = False  # an over-long line is refused once and skipped up to its end
        while not self._stop.is_set():
            try:
                data = self.link.device_read(256, 0.05) if self._link_up else b""
            except (serial.SerialException, OSError):
                data = b""
            if not data:
                if not self._link_up:
                    self._stop.wait(0.05)
                continue
            for byte in data:
                if byte == 0x0A:
                    if too_long:
                        self._reply(Reply(False, UNKNOWN, ("line too long",)))
                    else:
                        self._answer(bytes(line))
                    line.clear()
                    too_long = False
                elif len(line) < _MAX_LINE:
                    line.append(byte)
                else:
                    too_long = True

    def _answer(self, line: bytes) -> None:
        try:
            name, args = parse_command(line)
        except ValueError:
            self._reply(Reply(False, UNKNOWN, ("unknown command",)))
            return
        if name in self.ignored_commands:
            return
        self._reply(self.execute(name, args))

    def execute(self, name: str, args: list[str]) -> Reply:
        """Carry out one command (a name of :attr:`commands`) and return the reply."""
        handler = self.commands.get(name)
        if handler is None:
            return Reply(False, UNKNOWN, ("unknown command",))
        return handler(args)

    def _start(self) -> Reply:
        with self._counter_lock:
            self._sample = 0
            self._streaming = True
        return Reply(True, "START")

    def _stop_streaming(self) -> Reply:
        with self._counter_lock:
            self._streaming = False
        return Reply(True, "STOP")

    def _tare(self) -> Reply:
        if len(self._recent) == 0:
            return Reply(False, "TARE", ("no samples yet",))
        with self._counter_lock:
            self.tare_offset = self._recent.mean(axis=0)
        return Reply(True, "TARE")

    def _set_rate(self, args: list[str]) -> Reply:
        if len(args) != 1:
            return Reply(False, "RATE", ("bad arguments",))
        text = args[0]
        if self._streaming:
            return Reply(False, "RATE", ("stop first",))
        valid = self.valid_rates()
        choices = "valid rates " + " ".join(map(str, valid)) + " Hz"
        try:
            rate = int(text)
        except ValueError:
            return Reply(False, "RATE", (f"{text[:12]!r} is not a whole number of Hz", choices))
        if rate not in valid:
            return Reply(False, "RATE", (f"{rate} Hz not possible", choices))
        self.bench.set_output_rate(rate)
        return Reply(True, "RATE", (str(self.rate_hz),))

    def _reply(self, reply: Reply) -> None:
        self._send_after_frames(reply.encode())

    # -- the line -------------------------------------------------------------------------------

    def _send_after_frames(self, data: bytes) -> None:
        """Send a reply or a capture after the frames made before it, before any made after: queued,
        and written by this thread if the line is free, else by the thread streaming a block once
        the block is out. A lock is not fair: a streaming thread takes the line back piece after
        piece and block after block while another thread waits for it, so a reply waited for
        blocks made after its command (a second or more on a busy host)."""
        self._outbox.append(data)
        self._flush_outbox()

    def _flush_outbox(self) -> None:
        """Write what waits in the outbox unless another thread holds the line (it writes it then);
        dropped while the link is down."""
        while self._outbox and self._write_lock.acquire(blocking=False):
            try:
                while self._outbox:
                    data = self._outbox.popleft()
                    if self._link_up:
                        with contextlib.suppress(serial.SerialException, OSError):
                            self._write_all(data, _REPLY_TIMEOUT_S)
            finally:
                self._write_lock.release()


def _no_arguments(name: str, handler: Callable[[], Reply]) -> Callable[[list[str]], Reply]:
    """A command handler that refuses arguments (``$ERR,<name>,bad arguments``)."""
    return lambda args: Reply(False, name, ("bad arguments",)) if args else handler()
