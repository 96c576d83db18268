"""The actuator controller's behaviour, independent of Modbus: states, function generator, interlocks.

The function generator evaluates the excitation waveform objects (:mod:`simulators.plant.excitation`)
at the internal sample instants of each block. Run time is counted in samples, so the model runs as
fast or as slowly as the bench is advanced; only the heartbeat watchdog reads the wall clock.

Every stop tapers: a stop command, a finished waveform, a tripped limit and an expired watchdog
all multiply the running output by a raised-cosine ramp of ``taper_out_s``. Only the e-stop does
not taper: it freezes the command (the valves close and the actuator locks where it is).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from drivers.register_map import Command, ControllerState, ErrorCode, InterlockFlag, WaveformCode
from simulators.plant.excitation import SineDwell, Sweep, Waveform, taper_envelope

PROTOCOL_VERSION = 1
#: hold time of a dwell that runs until a stop command (about 11 days)
UNTIL_STOPPED_S = 1e6
_MOVING = (ControllerState.RUNNING, ControllerState.TAPERING)
_NON_NEGATIVE = ("taper_in_s", "taper_out_s", "dwell_s", "sweep_duration_s", "amplitude_mm", "watchdog_ms")
_POSITIVE = ("frequency_hz", "sweep_start_hz", "sweep_end_hz")


@dataclass
class Readback:
    """What the controller measures, refreshed by :meth:`ControllerModel.observe`."""

    displacement_mm: float = 0.0
    force_n: float = 0.0
    achieved_amplitude_mm: float = 0.0
    frequency_hz: float = 0.0
    cycle_count: int = 0
    sample_count: int = 0


class ControllerModel:
    """State machine and function generator of the simulated servo controller."""

    #: hardware limits that apply when the host has not set its own (mm, N)
    HARDWARE_STROKE_MM = 50.0
    HARDWARE_FORCE_N = 50_000.0

    def __init__(self, internal_rate_hz: float, output_rate_hz: float, clock: Callable[[], float]) -> None:
        self.internal_rate_hz = internal_rate_hz
        self.output_rate_hz = output_rate_hz
        self._clock = clock
        self.state = ControllerState.OFF
        self.flags = InterlockFlag(0)
        self.error = ErrorCode.NONE
        self.setpoints: dict[str, float] = {
            "waveform": 0, "channel_mask": 0x000F, "heartbeat": 0, "watchdog_ms": 0, "amplitude_mm": 0.0,
            "frequency_hz": 1.0, "dwell_s": 0.0, "sweep_start_hz": 1.0, "sweep_end_hz": 10.0,
            "sweep_duration_s": 10.0, "taper_in_s": 1.0, "taper_out_s": 1.0, "mean_mm": 0.0,
            "displacement_limit_mm": 0.0, "force_limit_n": 0.0,
        }  # fmt: skip
        self.readback = Readback()
        self._last_heartbeat_s = clock()
        # function generator
        self._waveform: Waveform | None = None
        self._mean_m = 0.0
        self._taper_in_s = 1.0
        self._taper_out_s = 1.0
        self._k = 0  # internal samples since the start of the run
        self._stop_at_s: float | None = None
        self._frozen_m: float | None = None
        self._running_source = False
        self._last_command_m = 0.0
        self._phase_cycles = 0.0
        self._history = np.zeros(0)

    # -- host side ------------------------------------------------------------------------------

    def write_setpoints(self, values: dict[str, float]) -> ErrorCode | None:
        """Apply written holding registers (other than ``command``); refuse invalid ones."""
        for name, value in values.items():
            if not math.isfinite(value):
                return self._refuse(ErrorCode.INVALID_SETPOINT)
            if name in _NON_NEGATIVE and value < 0:
                return self._refuse(ErrorCode.INVALID_SETPOINT)
            if name in _POSITIVE and value <= 0:
                return self._refuse(ErrorCode.INVALID_SETPOINT)
            if name == "waveform" and value not in tuple(WaveformCode):
                return self._refuse(ErrorCode.INVALID_SETPOINT)
        if "heartbeat" in values:
            self._last_heartbeat_s = self._clock()
        if "watchdog_ms" in values:
            self._last_heartbeat_s = self._clock()
        self.setpoints.update(values)
        return None

    def command(self, code: int) -> ErrorCode | None:
        """Execute a command code; return the reason when it is refused."""
        try:
            command = Command(code)
        except ValueError:
            return self._refuse(ErrorCode.UNKNOWN_COMMAND)
        s = self.state
        allowed = {
            Command.HYDRAULICS_OFF: s in (ControllerState.OFF, ControllerState.HYDRAULICS_LOW,
                                          ControllerState.HYDRAULICS_HIGH),
            Command.HYDRAULICS_LOW: s in (ControllerState.OFF, ControllerState.HYDRAULICS_LOW,
                                          ControllerState.HYDRAULICS_HIGH),
            Command.HYDRAULICS_HIGH: s in (ControllerState.HYDRAULICS_LOW, ControllerState.HYDRAULICS_HIGH),
            Command.START: s == ControllerState.HYDRAULICS_HIGH,
            Command.STOP: True,
            Command.ESTOP: True,
            Command.RESET_INTERLOCK: s in (ControllerState.INTERLOCK, ControllerState.ESTOP),
        }[command]  # fmt: skip
        if not allowed:
            return self._refuse(ErrorCode.NOT_ALLOWED_IN_STATE)
        if command is Command.START:
            return self._start()
        if command is Command.STOP:
            if s == ControllerState.RUNNING:
                self._begin_stop(ControllerState.TAPERING)
        elif command is Command.ESTOP:
            self._frozen_m = self._last_command_m
            self.flags |= InterlockFlag.ESTOP
            self.state = ControllerState.ESTOP
        elif command is Command.RESET_INTERLOCK:
            self.flags = InterlockFlag(0)
            self.state = ControllerState.HYDRAULICS_LOW
            if self._frozen_m is not None:  # return from the frozen position with a taper
                frozen, self._frozen_m = self._frozen_m, None
                self._start_source(None, frozen, 0.0, self._taper_out_s)
                self._begin_stop(ControllerState.HYDRAULICS_LOW)
        else:
            self.state = {
                Command.HYDRAULICS_OFF: ControllerState.OFF,
                Command.HYDRAULICS_LOW: ControllerState.HYDRAULICS_LOW,
                Command.HYDRAULICS_HIGH: ControllerState.HYDRAULICS_HIGH,
            }[command]
        self.error = ErrorCode.NONE
        return None

    def _refuse(self, reason: ErrorCode) -> ErrorCode:
        self.error = reason
        return reason

    def _start(self) -> ErrorCode | None:
        sp = self.setpoints
        amplitude_m = sp["amplitude_mm"] / 1000
        taper_in, taper_out = sp["taper_in_s"], sp["taper_out_s"]
        code = WaveformCode(int(sp["waveform"]))
        try:
            if code == WaveformCode.SINE_DWELL:
                hold = sp["dwell_s"] if sp["dwell_s"] > 0 else UNTIL_STOPPED_S
                waveform: Waveform | None = SineDwell(
                    sp["frequency_hz"], amplitude_m, hold, taper_in, taper_out
                )
            elif code in (WaveformCode.LINEAR_SWEEP, WaveformCode.LOG_SWEEP):
                spacing = "linear" if code == WaveformCode.LINEAR_SWEEP else "log"
                waveform = Sweep(
                    sp["sweep_start_hz"], sp["sweep_end_hz"], sp["sweep_duration_s"], amplitude_m,
                    spacing, taper_in, taper_out,
                )  # fmt: skip
            else:
                waveform = None
        except ValueError:
            return self._refuse(ErrorCode.INVALID_SETPOINT)
        self._start_source(waveform, sp["mean_mm"] / 1000, taper_in, taper_out)
        self._phase_cycles = 0.0
        self.readback.cycle_count = 0
        self.state = ControllerState.RUNNING
        self.error = ErrorCode.NONE
        self._last_heartbeat_s = self._clock()
        return None

    def _start_source(
        self, waveform: Waveform | None, mean_m: float, taper_in_s: float, taper_out_s: float
    ) -> None:
        self._waveform = waveform
        self._mean_m = mean_m
        self._taper_in_s = taper_in_s
        self._taper_out_s = taper_out_s
        self._k = 0
        self._stop_at_s = None
        self._running_source = True

    def _begin_stop(self, state: ControllerState) -> None:
        """Taper the output to zero over ``taper_out_s`` from now."""
        if self._stop_at_s is None:
            self._stop_at_s = self._k / self.internal_rate_hz
        self.state = state

    # -- bench side -----------------------------------------------------------------------------

    def check_watchdog(self) -> None:
        """Taper to a stop when the host's heartbeat has not changed within the watchdog time."""
        watchdog_s = self.setpoints["watchdog_ms"] / 1000
        if watchdog_s <= 0 or self.state not in _MOVING:
            return
        if self._clock() - self._last_heartbeat_s > watchdog_s:
            self.flags |= InterlockFlag.WATCHDOG
            self._begin_stop(ControllerState.TAPERING)

    def command_block(self, n: int) -> np.ndarray:
        """The displacement command (m) for the next ``n`` internal samples."""
        self.check_watchdog()
        if self._frozen_m is not None:
            out = np.full(n, self._frozen_m)
        elif not self._running_source:
            out = np.zeros(n)
        else:
            out = self._generate(n)
        if n:
            self._last_command_m = float(out[-1])
        return out

    def _generate(self, n: int) -> np.ndarray:
        t = (self._k + np.arange(n)) / self.internal_rate_hz
        self._k += n
        mean_env = taper_envelope(t, math.inf, self._taper_in_s, 0.0) if self._taper_in_s > 0 else 1.0
        out = self._mean_m * mean_env
        if self._waveform is not None:
            out = out + self._waveform.value(t)
            if self._stop_at_s is None and t[-1] >= self._waveform.duration_s:
                self._begin_stop(ControllerState.TAPERING)
        if self._stop_at_s is not None:
            tau = t - self._stop_at_s
            if self._taper_out_s > 0:
                out = out * taper_envelope(tau, self._taper_out_s, 0.0, self._taper_out_s)
            else:
                out = np.where(tau < 0, out, 0.0)
            if tau[-1] >= self._taper_out_s:
                self._running_source = False
                self._waveform = None
                if self.state in _MOVING:
                    self.state = ControllerState.INTERLOCK if self.flags else ControllerState.HYDRAULICS_HIGH
        return np.asarray(out, dtype=float)

    def current_frequency_hz(self) -> float:
        if self._waveform is None or self.state not in _MOVING:
            return 0.0
        return float(self._waveform.frequency_hz(self._k / self.internal_rate_hz))

    @property
    def amplitude_m(self) -> float:
        return float(self._waveform.amplitude) if self._waveform is not None else 0.0

    def observe(self, z_base_m: np.ndarray, f_plate_n: np.ndarray) -> None:
        """Update readbacks, achieved amplitude, cycle count and the limit interlocks from a block."""
        rb = self.readback
        rb.sample_count += len(z_base_m)
        if len(z_base_m) == 0:
            return
        rb.displacement_mm = float(z_base_m[-1] * 1000)
        rb.force_n = float(f_plate_n[-1])
        rb.frequency_hz = self.current_frequency_hz()
        # achieved amplitude: half the peak-to-peak over the last two cycles (at least 0.2 s)
        window = int(self.output_rate_hz * max(0.2, 2.0 / rb.frequency_hz if rb.frequency_hz else 0.2))
        self._history = np.concatenate([self._history, z_base_m])[-window:]
        moving = self.state in _MOVING
        rb.achieved_amplitude_mm = float(np.ptp(self._history) / 2 * 1000) if moving else 0.0
        if moving:
            self._phase_cycles += rb.frequency_hz * len(z_base_m) / self.output_rate_hz
            rb.cycle_count = int(self._phase_cycles)
        self._check_limits(z_base_m, f_plate_n)

    def _check_limits(self, z_base_m: np.ndarray, f_plate_n: np.ndarray) -> None:
        disp_limit = self.setpoints["displacement_limit_mm"] or self.HARDWARE_STROKE_MM
        force_limit = self.setpoints["force_limit_n"] or self.HARDWARE_FORCE_N
        tripped = InterlockFlag(0)
        if np.max(np.abs(z_base_m * 1000 - self.setpoints["mean_mm"])) > disp_limit:
            tripped |= InterlockFlag.DISPLACEMENT
        if np.max(np.abs(f_plate_n)) > force_limit:
            tripped |= InterlockFlag.FORCE
        if tripped and self.state in _MOVING:
            self.flags |= tripped
            self._begin_stop(ControllerState.TAPERING)
