"""An in-memory bench for the engine's unit tests: actuator and acquisition in one deterministic fake.

It implements the engine's contracts and nothing else. Frames are produced only when the engine
asks for the next block, so a test runs at the engine's speed with no thread and no clock. An
excitation follows its setpoint in samples: taper in, hold, taper out, with the sync bits set as
the controller's outputs would be; the displacement reaches ``gain(freq_hz)`` times the command,
so the amplitude control has an error to correct.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from drivers.errors import CommandRejectedError, ConnectionLostError
from drivers.setpoints import DriveSetpoint, DwellSetpoint, SweepSetpoint
from drivers.wfs_capture import Capture
from drivers.wfs_frame import FRAME_DTYPE, Status
from drivers.wfs_stream import Gap
from sequences.limits import BenchLimits

ACTIVE_BIT = 1 << 9
HOLD_BIT = 1 << 10


@dataclass
class FakeStatus:
    moving: bool
    interlock_reason: str | None
    sample_count: int


@dataclass
class FakeBlock:
    frames: np.ndarray
    gaps: tuple = ()
    resyncs: tuple = ()
    unread_s: float = 0.0
    arrived_s: float = 0.0


@dataclass
class FakeBench:
    """``gain(freq_hz)``: achieved over commanded amplitude; ``block`` frames per block."""

    rate_hz: float = 1000.0
    block: int = 100
    gain: Callable[[float], float] = lambda f: 1.0
    force_per_m: float = 0.0  # plate force per metre of displacement (for the force interlock)
    log: list[str] = field(default_factory=list)
    setpoint: DwellSetpoint | SweepSetpoint | DriveSetpoint | None = None
    drive_files: bool = True  # the controller plays drive files (a road replay)
    drive: DriveSetpoint | None = None  # the drive it holds
    streaming: bool = False
    hydraulics: str = "off"
    estopped: bool = False
    link_down: bool = False
    silent: bool = False  # the WFS stops sending (a pulled serial cable)
    on_block: Callable[[FakeBench], None] | None = None  # a test's hook, called before each block
    # a test's hook, called as a command (configure, start, set_hydraulics, tare, start_stream,
    # arm_capture, wait_capture) begins, with the command's name
    on_call: Callable[[FakeBench, str], None] | None = None
    # command name -> (the call that fails, counted from 1, and the error it raises)
    faults: dict[str, tuple[int, Exception]] = field(default_factory=dict)
    calls: Counter = field(default_factory=Counter)
    limits: BenchLimits | None = None  # configure refuses what these refuse, as the client does
    overload: bool = False  # the WFS reports Fz beyond its range
    offset_m: float = 0.0  # added to the displacement (a drifted actuator)
    stuck_active: bool = False  # the controller's active output stays up
    unread_s: float = 0.0  # the next block's bytes waited this long at the port unread (a host stall)
    lost_in_stall: int = 0  # frames the next block misses (they overran the port meanwhile)
    _silent_for_s: float = 0.0  # how long the engine has waited on the silent port
    _wave: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    _capture: tuple[float, int, int] = (0.0, 0, 1)
    _seq: int = 0
    _sample: int = 0

    # -- actuator -----------------------------------------------------------------------------

    def read_status(self) -> FakeStatus:
        self._check_link()
        reason = "estop" if self.estopped else None  # the flags by name, as the controller's readback
        return FakeStatus(len(self._wave) > 0, reason, self._sample)

    def load_drive(self, drive: DriveSetpoint) -> None:
        self._command("load_drive")
        self._check_link()
        if self.limits is not None:
            drive.check(self.limits)
        self.log.append(f"load drive of {drive.n_samples} samples")
        self.drive = drive

    def configure(self, setpoint: DwellSetpoint | SweepSetpoint | DriveSetpoint) -> None:
        self._command("configure")
        self._check_link()
        if self.limits is not None:
            setpoint.registers(self.limits)
        if isinstance(setpoint, DriveSetpoint) and (self.drive is None or self.drive.crc32 != setpoint.crc32):
            raise CommandRejectedError("the controller does not hold the drive to play")
        self.log.append(f"configure {setpoint}")
        self.setpoint = setpoint

    def start(self) -> None:
        self._command("start")
        self._check_link()
        self.log.append("start")
        self._wave = self._excitation(self.setpoint)

    def stop(self) -> None:
        self._check_link()
        self.log.append("stop")
        if len(self._wave):  # taper out from here within 0.1 s
            n = min(len(self._wave), round(0.1 * self.rate_hz))
            taper = np.linspace(1, 0, n)
            self._wave = np.column_stack([self._wave[:n, 0] * taper, np.zeros(n)])

    def estop(self) -> None:
        self.log.append("estop")
        self.estopped = True
        self._wave = np.zeros((0, 2))

    def set_hydraulics(self, level: str) -> None:
        self._command("set_hydraulics")
        self.log.append(f"hydraulics {level}")
        self.hydraulics = level

    def reset_interlock(self) -> None:
        self.log.append("reset")
        self.estopped = False

    def link_fault(self) -> str | None:
        return "connection dropped" if self.link_down else None

    def _check_link(self) -> None:
        if self.link_down:
            raise ConnectionLostError("fake link down")

    def _command(self, name: str) -> None:
        """Count the command, call the test's hook, and raise the error due at this call."""
        self.calls[name] += 1
        if self.on_call is not None:
            self.on_call(self, name)
        call, error = self.faults.get(name, (0, None))
        if call == self.calls[name]:
            raise error

    def clear_faults(self) -> None:
        """The cause of a stop cleared, and the actuator at rest (as before a reset)."""
        self.link_down = self.silent = self.overload = self.stuck_active = False
        self.offset_m = 0.0
        self.limits = None
        self.faults.clear()
        self.on_block = self.on_call = None
        self._wave = np.zeros((0, 2))

    def _excitation(self, sp: DwellSetpoint | SweepSetpoint | DriveSetpoint) -> np.ndarray:
        """(displacement m, hold flag) per sample of the whole excitation."""
        fs = self.rate_hz
        if isinstance(sp, DriveSetpoint):  # the drive at the bench's rate, linear between samples
            t = np.arange(round(sp.duration_s * fs) + 1) / fs
            z = np.interp(t * sp.sample_rate_hz, np.arange(sp.n_samples), sp.samples_mm) / 1e3
            hold = ((t >= sp.taper_in_s) & (t < sp.duration_s - sp.taper_out_s)).astype(float)
            envelope = np.clip(np.minimum(t / sp.taper_in_s, (sp.duration_s - t) / sp.taper_out_s), 0, 1)
            return np.column_stack([z * (0.5 - 0.5 * np.cos(np.pi * envelope)), hold])
        if isinstance(sp, DwellSetpoint):
            n_in, n_hold, n_out = (round(x * fs) for x in (sp.taper_in_s, sp.dwell_s, sp.taper_out_s))
            freq = np.full(n_in + n_hold + n_out, sp.freq_hz)
        else:
            n_in, n_out = round(sp.taper_in_s * fs), round(sp.taper_out_s * fs)
            n_hold = round(sp.duration_s * fs) - n_in - n_out
            freq = np.linspace(sp.start_hz, sp.end_hz, n_in + n_hold + n_out)
        n = n_in + n_hold + n_out
        envelope = np.ones(n)
        envelope[:n_in] = 0.5 - 0.5 * np.cos(np.pi * np.arange(n_in) / n_in)
        envelope[n - n_out :] = 0.5 + 0.5 * np.cos(np.pi * np.arange(n_out) / n_out)
        phase = 2 * np.pi * np.cumsum(freq) / fs
        amplitude_m = sp.amplitude_mm / 1e3 * np.array([self.gain(f) for f in freq])
        hold = np.zeros(n)
        hold[n_in : n_in + n_hold] = 1
        return np.column_stack([envelope * amplitude_m * np.sin(phase), hold])

    # -- acquisition --------------------------------------------------------------------------

    def subscribe(self, *, lossless: bool, max_frames: int) -> FakeBench:
        return self

    def close(self) -> None:
        pass

    def start_stream(self) -> None:
        self._command("start_stream")
        self.log.append("stream start")
        self.streaming = True
        self._sample = 0

    def stop_stream(self) -> None:
        self.log.append("stream stop")
        self.streaming = False

    def tare(self) -> None:
        self._command("tare")
        self.log.append("tare")

    def arm_capture(self, trigger_level_n: float, pre_trigger_s: float, length_s: float) -> tuple[int, int]:
        self._command("arm_capture")
        self.log.append("arm capture")
        self._capture = (trigger_level_n, round(pre_trigger_s * self.rate_hz), round(length_s * self.rate_hz))
        return self._capture[1], self._capture[2]

    def wait_capture(self, timeout_s: float) -> Capture:
        """The armed capture: a blow's decaying ring at its trigger."""
        self._command("wait_capture")
        level, pre, n = self._capture
        t = np.arange(n - pre) / self.rate_hz
        ring = 10 * level * np.exp(-50 * t) * np.cos(2 * np.pi * 200 * t)
        samples = np.concatenate([np.zeros(pre), ring])
        return Capture(samples, self.rate_hz, pre, level, 0.0)

    def link_counters(self) -> dict[str, int]:
        return {"frames_ok": self._seq}

    def link_silence_s(self) -> float:
        """The port's silence: the time the engine has waited on it since it went silent."""
        return self._silent_for_s

    def get_all(self, timeout_s: float) -> FakeBlock | None:
        if self.on_block is not None:
            self.on_block(self)
        if not self.streaming or self.silent:
            self._silent_for_s += timeout_s if self.silent else 0.0
            return None
        self._silent_for_s = 0.0
        frames = np.zeros(self.block, dtype=FRAME_DTYPE)
        take = self._wave[: self.block]
        self._wave = self._wave[self.block :]
        z = np.zeros(self.block)
        z[: len(take)] = take[:, 0]
        status = np.zeros(self.block, dtype=np.uint16)
        status[: len(take)] |= ACTIVE_BIT
        status[: len(take)][take[:, 1] > 0] |= HOLD_BIT
        frames["seq"] = np.arange(self._seq, self._seq + self.block)
        frames["sample"] = np.arange(self._sample, self._sample + self.block)
        if self.stuck_active:
            status |= ACTIVE_BIT
        if self.overload:
            status |= int(Status.OVERLOAD_FZ)
        frames["aux0"] = z + self.offset_m
        frames["aux1"] = self.force_per_m * z
        frames["fz"] = 0.5 * self.force_per_m * z
        frames["status"] = status
        self._seq += self.block
        self._sample += self.block
        stall, self.unread_s = self.unread_s, 0.0
        lost, self.lost_in_stall = self.lost_in_stall, 0
        return FakeBlock(
            frames, (Gap(0, int(frames["seq"][0]) - lost, lost),) if lost else (), unread_s=stall
        )
