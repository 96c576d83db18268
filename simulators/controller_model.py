"""The actuator controller's behaviour, independent of Modbus: states, commands, interlocks, readbacks.

The displacement command comes from a :class:`~simulators.function_generator.FunctionGenerator`
counted in internal samples, so the model runs as fast or as slowly as the bench is advanced. Only
the heartbeat watchdog needs a clock: by default the controller's own sample clock; the simulated
bench passes the wall clock, so that a bench that runs faster than real time does not trip it.

Every stop tapers: a stop command, a finished waveform, a tripped limit and an expired watchdog
taper the excitation out over ``taper_out_s`` and ramp the mean back to zero. Only the e-stop does
not taper: it freezes the command (the valves close and the actuator locks where it is); the reset
that releases it ramps back to rest.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from bench.models.setup import DriveDensity
from drivers.register_map import (
    ALL_POSTS,
    MOVING_STATES,
    Command,
    ControllerState,
    ErrorCode,
    InterlockFlag,
    WaveformCode,
)
from simulators.drive_buffer import DRIVE_REGISTERS, DriveBuffer
from simulators.function_generator import FunctionGenerator
from simulators.plant.excitation import NotchedSweep, SineDwell, Sweep, Waveform

PROTOCOL_VERSION = 1
#: hold time of a dwell that runs until a stop command (about 11 days)
UNTIL_STOPPED_S = 1e6
#: rate of the ``sample_count`` readback (the controller's clock, Hz)
CONTROLLER_CLOCK_HZ = 1000
#: shortest taper the controller accepts (s): a shorter one would be a step
MIN_TAPER_S = 0.05
#: highest excitation frequency the controller accepts (Hz): the servo actuator's bandwidth
MAX_FREQUENCY_HZ = 200.0
#: heartbeat watchdog at power-up (ms): armed, so a host that never beats cannot keep it running
POWER_UP_WATCHDOG_MS = 1500
#: the holding registers at power-up: the values in force until the host writes others
POWER_UP: dict[str, float] = {
    "waveform": WaveformCode.STATIC, "channel_mask": ALL_POSTS, "heartbeat": 0,
    "watchdog_ms": POWER_UP_WATCHDOG_MS, "amplitude_mm": 0.0, "frequency_hz": 1.0, "dwell_s": 0.0,
    "sweep_start_hz": 1.0, "sweep_end_hz": 10.0, "sweep_duration_s": 10.0, "taper_in_s": 1.0,
    "taper_out_s": 1.0, "mean_mm": 0.0, "displacement_limit_mm": 0.0, "force_limit_n": 0.0,
    "amplitude_update_mm": 0.0, "amplitude_ramp_s": 0.1,
    "notch_start_hz": 0.0, "notch_end_hz": 0.0, "notch_amplitude_mm": 0.0, "frequency_update_hz": 0.0,
}  # fmt: skip
_NON_NEGATIVE = (
    "amplitude_update_mm",
    "notch_start_hz",
    "notch_end_hz",
    "notch_amplitude_mm",
    "dwell_s",
    "sweep_duration_s",
    "amplitude_mm",
    "watchdog_ms",
    "displacement_limit_mm",
    "force_limit_n",
)
#: in (0, MAX_FREQUENCY_HZ] when written
_FREQUENCIES = ("frequency_hz", "sweep_start_hz", "sweep_end_hz", "frequency_update_hz")
_TAPERS = ("taper_in_s", "taper_out_s", "amplitude_ramp_s")  # each at least MIN_TAPER_S
#: within the hardware stroke (mm)
_STROKE = (
    "mean_mm",
    "amplitude_mm",
    "displacement_limit_mm",
    "amplitude_update_mm",
    "notch_amplitude_mm",
)
#: a sweep's notch window (Hz): 0 (no notch) up to MAX_FREQUENCY_HZ
_NOTCH_FREQUENCIES = ("notch_start_hz", "notch_end_hz")
_IDLE = (ControllerState.OFF, ControllerState.HYDRAULICS_LOW, ControllerState.HYDRAULICS_HIGH)
#: the states each command is accepted in (a command in another state is refused)
ALLOWED: dict[Command, tuple[ControllerState, ...]] = {
    Command.HYDRAULICS_OFF: _IDLE,
    Command.HYDRAULICS_LOW: _IDLE,
    Command.HYDRAULICS_HIGH: (ControllerState.HYDRAULICS_LOW, ControllerState.HYDRAULICS_HIGH),
    Command.START: (ControllerState.HYDRAULICS_HIGH,),
    Command.STOP: tuple(ControllerState),
    Command.ESTOP: tuple(ControllerState),
    Command.RESET_INTERLOCK: (ControllerState.INTERLOCK, ControllerState.ESTOP),
}


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
    """State machine, interlocks and readbacks of the simulated servo controller.

    ``internal_rate_hz`` is the rate of the displacement command (the plant's internal rate);
    ``clock`` returns seconds for the heartbeat watchdog (None: the controller's sample clock);
    ``posts`` is how many of the controller's channels have an actuator (posts 1..``posts``; the
    simulated plant stands on post 1).
    """

    #: hardware limits (mm from the centre of the stroke, N): always enforced; the interlock limits
    #: the host sets may be tighter, never wider
    HARDWARE_STROKE_MM = 50.0
    HARDWARE_FORCE_N = 50_000.0

    def __init__(
        self, internal_rate_hz: float, clock: Callable[[], float] | None = None, posts: int = 1
    ) -> None:
        self.generator = FunctionGenerator(internal_rate_hz)
        self.existing_posts = (1 << posts) - 1
        self._driven_posts = 0  # the channel mask of the running excitation
        self._clock = clock or (lambda: self.generator.n / internal_rate_hz)
        self.state = ControllerState.OFF
        self.flags = InterlockFlag(0)
        self.error = ErrorCode.NONE
        self.setpoints: dict[str, float] = dict(POWER_UP)
        self.readback = Readback()
        self._last_heartbeat_s = self._clock()
        self._rest_state = ControllerState.HYDRAULICS_HIGH  # where a taper to rest ends
        self._phase_cycles = 0.0
        self._history = np.zeros(0)
        self.drive = DriveBuffer(self.HARDWARE_STROKE_MM)  # the drive file uploaded (docs/protocols.md)

    # -- host side ------------------------------------------------------------------------------

    def write_setpoints(self, values: dict[str, float]) -> ErrorCode | None:
        """Apply written holding registers (other than ``command``); refuse invalid ones, all or none.
        An accepted write clears ``error``, except a write of the heartbeat alone: the host's
        heartbeat runs beside its commands and would otherwise clear the reason of a refusal before
        the host reads it.

        Setpoints take effect at the next start; a running excitation keeps its own, except its
        amplitude: ``amplitude_update_mm`` changes a sine dwell's during its hold
        (:meth:`_update_refusal`), and its frequency: ``frequency_update_hz`` glides it there over
        ``amplitude_ramp_s``, phase-continuously (a write carrying both is refused whole if either is).
        The drive registers upload a drive file (:class:`~simulators.drive_buffer.DriveBuffer`),
        only while nothing moves.
        """
        drive = {name: value for name, value in values.items() if name in DRIVE_REGISTERS}
        values = {name: value for name, value in values.items() if name not in DRIVE_REGISTERS}
        if not all(self._valid(name, value) for name, value in values.items()):
            return self._refuse(ErrorCode.INVALID_SETPOINT)
        if drive and self.state in (*MOVING_STATES, ControllerState.ESTOP):
            return self._refuse(ErrorCode.NOT_ALLOWED_IN_STATE)
        if drive and (reason := self.drive.refusal(drive)) is not None:
            return self._refuse(reason)
        ramp_s = values.get("amplitude_ramp_s", self.setpoints["amplitude_ramp_s"])
        if "frequency_update_hz" in values and not (
            self.state == ControllerState.RUNNING and self.generator.holding()
        ):
            return self._refuse(ErrorCode.NOT_ALLOWED_IN_STATE)
        if "amplitude_update_mm" in values:
            if (reason := self._update_refusal(values["amplitude_update_mm"])) is not None:
                return self._refuse(reason)
            self.generator.update_amplitude(values["amplitude_update_mm"] / 1000, ramp_s)
        if "frequency_update_hz" in values:
            self.generator.update_frequency(values["frequency_update_hz"], ramp_s)
        # only a changed heartbeat proves the host alive: neither a frozen counter nor a rewritten
        # watchdog_ms (a host rewriting its configuration) restarts the watchdog's time
        if "heartbeat" in values and values["heartbeat"] != self.setpoints["heartbeat"]:
            self._last_heartbeat_s = self._clock()
        self.drive.write(drive)
        self.setpoints.update(values)
        if drive or values.keys() - {"heartbeat"}:
            self.error = ErrorCode.NONE
        return None

    def _valid(self, name: str, value: float) -> bool:
        """Whether one setpoint value is acceptable on its own (finite, in range, within the hardware)."""
        if not math.isfinite(value):
            return False
        violated = (
            (name in _NON_NEGATIVE and value < 0)
            or (name in _FREQUENCIES and not 0 < value <= MAX_FREQUENCY_HZ)
            or (name in _NOTCH_FREQUENCIES and value > MAX_FREQUENCY_HZ)
            or (name == "channel_mask" and not int(value) & self.existing_posts)
            or (name in _TAPERS and value < MIN_TAPER_S)
            or (name == "waveform" and value not in tuple(WaveformCode))
            or (name in _STROKE and abs(value) > self.HARDWARE_STROKE_MM)
            or (name == "force_limit_n" and abs(value) > self.HARDWARE_FORCE_N)
        )
        return not violated

    def _update_refusal(self, amplitude_mm: float) -> ErrorCode | None:
        """Why an amplitude update to ``amplitude_mm`` would be refused: no sine dwell holds its
        amplitude now (tapering in or out, a sweep, at rest: not allowed in state), or the new
        amplitude would leave the stroke with the mean or pass the displacement interlock limit
        (invalid setpoint)."""
        if self.state != ControllerState.RUNNING or not self.generator.holding():
            return ErrorCode.NOT_ALLOWED_IN_STATE
        limit_mm = self.setpoints["displacement_limit_mm"] or self.HARDWARE_STROKE_MM
        if self.generator.amplitude_m <= 0 or amplitude_mm > limit_mm:
            return ErrorCode.INVALID_SETPOINT
        if abs(self.generator.mean_m()) * 1000 + amplitude_mm > self.HARDWARE_STROKE_MM:
            return ErrorCode.INVALID_SETPOINT
        return None

    def command_refusal(self, code: int) -> ErrorCode | None:
        """Why the command ``code`` would be refused in the present state (None: it is allowed);
        changes nothing, so a write carrying setpoints and a command can be refused as a whole."""
        try:
            command = Command(code)
        except ValueError:
            return ErrorCode.UNKNOWN_COMMAND
        return None if self.state in ALLOWED[command] else ErrorCode.NOT_ALLOWED_IN_STATE

    def command(self, code: int) -> ErrorCode | None:
        """Execute a command code; return the reason when it is refused."""
        if (reason := self.command_refusal(code)) is not None:
            return self._refuse(reason)
        command = Command(code)
        if command is Command.START:
            return self._start()
        if command is Command.STOP:
            if self.state == ControllerState.RUNNING:
                self._stop()
        elif command is Command.ESTOP:
            self.generator.freeze()
            self.flags |= InterlockFlag.ESTOP
            self.state = ControllerState.ESTOP
        elif command is Command.RESET_INTERLOCK:
            self._reset()
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
        """Start the configured excitation; refused when mean + amplitude (a drive's: its largest
        sample) would leave the stroke, or the drive's upload is not complete."""
        drive = int(self.setpoints["waveform"]) == WaveformCode.DRIVE
        amplitude_mm = self.drive.peak_mm if drive else self.setpoints["amplitude_mm"]
        if abs(self.setpoints["mean_mm"]) + amplitude_mm > self.HARDWARE_STROKE_MM:
            return self._refuse(ErrorCode.INVALID_SETPOINT)
        try:
            waveform = self._waveform()
        except ValueError:
            return self._refuse(ErrorCode.INVALID_SETPOINT)
        self.generator.start(waveform, self.setpoints["mean_mm"] / 1000, self.setpoints["taper_out_s"])
        self._driven_posts = int(self.setpoints["channel_mask"]) & self.existing_posts
        self._phase_cycles = 0.0
        self.readback.cycle_count = 0
        self._rest_state = ControllerState.HYDRAULICS_HIGH
        self.state = ControllerState.RUNNING
        self.error = ErrorCode.NONE
        self._last_heartbeat_s = self._clock()
        return None

    def _waveform(self) -> Waveform | None:
        """The excitation the setpoints describe (None: hold the mean); ValueError if inconsistent."""
        sp = self.setpoints
        amplitude_m = sp["amplitude_mm"] / 1000
        taper_in, taper_out = sp["taper_in_s"], sp["taper_out_s"]
        code = WaveformCode(int(sp["waveform"]))
        if code == WaveformCode.SINE_DWELL:
            hold = sp["dwell_s"] if sp["dwell_s"] > 0 else UNTIL_STOPPED_S
            return SineDwell(sp["frequency_hz"], amplitude_m, hold, taper_in, taper_out)
        if code in (WaveformCode.LINEAR_SWEEP, WaveformCode.LOG_SWEEP):
            spacing = "linear" if code == WaveformCode.LINEAR_SWEEP else "log"
            start, end, duration = sp["sweep_start_hz"], sp["sweep_end_hz"], sp["sweep_duration_s"]
            sweep = Sweep(start, end, duration, amplitude_m, spacing, taper_in, taper_out)
            if sp["notch_end_hz"] <= sp["notch_start_hz"]:
                return sweep
            # a notch outside the sweep's band or deeper than nothing is refused (ValueError)
            notch_m = sp["notch_amplitude_mm"] / 1000
            window = (sp["notch_start_hz"], sp["notch_end_hz"])
            return NotchedSweep(sweep, *window, notch_m, sp["amplitude_ramp_s"])
        if code == WaveformCode.DRIVE:
            return self.drive.waveform(taper_in, taper_out)
        return None

    def _stop(self) -> None:
        """Taper to rest; the state follows the generator (see :meth:`_follow_generator`)."""
        self.generator.stop()
        self.state = ControllerState.TAPERING

    def _reset(self) -> None:
        self.flags = InterlockFlag(0)
        self._rest_state = ControllerState.HYDRAULICS_LOW
        if self.state == ControllerState.ESTOP:
            self.generator.release()
            self.state = ControllerState.TAPERING
            self._follow_generator()
        else:
            self.state = ControllerState.HYDRAULICS_LOW

    def _follow_generator(self) -> None:
        """Move RUNNING -> TAPERING when the generator stops by itself, TAPERING -> rest when at rest."""
        if self.state == ControllerState.RUNNING and self.generator.stopping:
            self.state = ControllerState.TAPERING
        if self.state == ControllerState.TAPERING and self.generator.at_rest:
            self.state = ControllerState.INTERLOCK if self.flags else self._rest_state

    # -- bench side -----------------------------------------------------------------------------

    def check_watchdog(self) -> None:
        """Taper to a stop when the host's heartbeat value has not changed within the watchdog time
        (writing the same value again does not count).

        Watched while RUNNING only: a taper under way reaches rest by itself whatever the host does.
        """
        watchdog_s = self.setpoints["watchdog_ms"] / 1000
        if watchdog_s <= 0 or self.state != ControllerState.RUNNING:
            return
        if self._clock() - self._last_heartbeat_s > watchdog_s:
            self.flags |= InterlockFlag.WATCHDOG
            self._stop()

    def command_block(self, n: int) -> np.ndarray:
        """The displacement command (m) of post 1 for the next ``n`` internal samples."""
        self.check_watchdog()
        out = self.generator.block(n)
        self._follow_generator()
        return self.post_command(1, out)

    def post_command(self, post: int, command_m: np.ndarray) -> np.ndarray:
        """The generator's ``command_m`` as post ``post`` (1-based) receives it: a post the running
        excitation's ``channel_mask`` leaves out stays at rest (zero)."""
        return command_m if self._driven_posts >> (post - 1) & 1 else np.zeros_like(command_m)

    def current_frequency_hz(self) -> float:
        waveform = self.generator.waveform
        if waveform is None or self.state not in MOVING_STATES:
            return 0.0
        return float(waveform.frequency_hz(self.generator.elapsed_s))

    def drive_density(self) -> DriveDensity | None:
        """The running drive file's density (None: no drive runs), for the plant's linearisation."""
        if self.state not in MOVING_STATES:
            return None
        return getattr(self.generator.waveform, "density", None)

    @property
    def amplitude_m(self) -> float:
        """The running excitation's amplitude (an amplitude update's target once one was taken)."""
        return self.generator.amplitude_m

    def observe(self, z_base_m: np.ndarray, f_plate_n: np.ndarray, rate_hz: float) -> None:
        """Update readbacks and the limit interlocks from a block measured at ``rate_hz``.

        The displacement limit applies to the distance from the present mean position.
        """
        rb = self.readback
        g = self.generator
        rb.sample_count = g.n * CONTROLLER_CLOCK_HZ // round(g.rate_hz)
        if len(z_base_m) == 0:
            return
        rb.displacement_mm = float(z_base_m[-1] * 1000)
        rb.force_n = float(f_plate_n[-1])
        rb.frequency_hz = self.current_frequency_hz()
        moving = self.state in MOVING_STATES
        if moving:
            self._phase_cycles += rb.frequency_hz * len(z_base_m) / rate_hz
            rb.cycle_count = int(self._phase_cycles)
        self._check_limits(z_base_m, f_plate_n)

    def measure_amplitude(self, z_m: np.ndarray) -> None:
        """Update ``achieved_amplitude_mm`` from the actuator displacement ``z_m`` (m) of post 1,
        sampled on the controller's own clock (:data:`CONTROLLER_CLOCK_HZ`), whatever the WFS does.

        Half the peak-to-peak displacement over the last two cycles (at least 0.2 s); 0 at rest.
        """
        frequency_hz = self.current_frequency_hz()
        window_s = max(0.2, 2.0 / frequency_hz) if frequency_hz else 0.2
        self._history = np.concatenate([self._history, z_m])[-round(CONTROLLER_CLOCK_HZ * window_s) :]
        moving = self.state in MOVING_STATES and len(self._history)
        self.readback.achieved_amplitude_mm = float(np.ptp(self._history) / 2 * 1000) if moving else 0.0

    def _check_limits(self, z_base_m: np.ndarray, f_plate_n: np.ndarray) -> None:
        """Trip on |z - present mean| beyond the interlock limit, on |z| beyond the hardware stroke
        whatever the mean, and on |force| beyond the interlock (at most the hardware) force."""
        disp_limit_m = (self.setpoints["displacement_limit_mm"] or self.HARDWARE_STROKE_MM) / 1000
        force_limit = self.setpoints["force_limit_n"] or self.HARDWARE_FORCE_N
        tripped = InterlockFlag(0)
        if np.max(np.abs(z_base_m - self.generator.mean_m())) > disp_limit_m:
            tripped |= InterlockFlag.DISPLACEMENT
        if np.max(np.abs(z_base_m)) > self.HARDWARE_STROKE_MM / 1000:
            tripped |= InterlockFlag.DISPLACEMENT
        if np.max(np.abs(f_plate_n)) > force_limit:
            tripped |= InterlockFlag.FORCE
        if tripped and self.state in MOVING_STATES:
            self.flags |= tripped
            if self.state == ControllerState.RUNNING:
                self._stop()
