"""Locating an excitation in the acquisition's samples.

The actuator controller drives two digital sync outputs that the WFS acquisition samples with every
frame (status bits): *active* while the generator runs (tapers included) and *hold* during the
constant-amplitude part of a dwell (a sweep between its tapers). An excitation's start, hold and end
are therefore known to the sample, in the same clock as the loads, whatever the link delays.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from drivers.setpoints import DriveSetpoint, DwellSetpoint, SweepSetpoint


@dataclass(frozen=True)
class SyncBits:
    """The frame status bits carrying the controller's sync outputs."""

    active: int
    hold: int


@dataclass(frozen=True)
class ExcitationSpan:
    """Run-sample indices: ``start`` first active sample, ``hold_start`` first hold sample,
    ``hold_end`` one past the last hold sample, ``end`` one past the last active sample."""

    start: int
    hold_start: int
    hold_end: int
    end: int


class SpanTracker:
    """Follows the sync bits block by block until one excitation has started and ended.

    ``feed(first_sample, status)`` with the run-sample index of the block's first sample; ``span``
    is set once the active bit has fallen after rising. A hold that never came (an excitation stopped
    during its taper-in) leaves ``hold_start == hold_end == end``. The hold bit may fall and rise
    again within one excitation (an amplitude update's ramp, a frequency's glide): the hold is the
    last constant-amplitude part, ``hold_start`` its latest rise and ``hold_end`` its fall (None
    while the hold bit is up).
    """

    def __init__(self, active_bit: int, hold_bit: int) -> None:
        self.active_bit = active_bit
        self.hold_bit = hold_bit
        self.start: int | None = None
        self.hold_start: int | None = None
        self.hold_end: int | None = None
        self.span: ExcitationSpan | None = None
        self._held = False  # the hold bit of the last sample fed

    @property
    def started(self) -> bool:
        return self.start is not None

    @property
    def ended(self) -> bool:
        return self.span is not None

    def feed(self, first_sample: int, status: np.ndarray) -> None:
        if self.span is not None or len(status) == 0:
            return
        active = (status & self.active_bit) != 0
        hold = (status & self.hold_bit) != 0
        offset = 0
        if self.start is None:
            rising = np.flatnonzero(active)
            if rising.size == 0:
                return
            offset = int(rising[0])
            self.start = first_sample + offset
        falling = np.flatnonzero(~active[offset:])
        stop = offset + int(falling[0]) if falling.size else len(status)
        part = hold[offset:stop]
        if part.size:
            rising = np.flatnonzero(part & ~np.r_[self._held, part[:-1]])
            if rising.size:  # the latest constant-amplitude part begins here
                self.hold_start = first_sample + offset + int(rising[-1])
            self._held = bool(part[-1])
        if self.hold_start is not None:
            self._follow_hold(first_sample, hold, max(self.hold_start - first_sample, offset), stop)
        if falling.size:
            end = first_sample + stop
            hold_start = self.hold_start if self.hold_start is not None else end
            hold_end = self.hold_end if self.hold_end is not None else end
            self.span = ExcitationSpan(self.start, hold_start, hold_end, end)

    def _follow_hold(self, first_sample: int, hold: np.ndarray, lo: int, hi: int) -> None:
        """Follow the hold bit over ``hold[lo:hi]`` (the block's part after the hold began and
        before the excitation ended): ``hold_end`` its latest fall, None while it is up."""
        part = hold[lo:hi]
        if part.size == 0:
            return
        up = np.flatnonzero(part)
        if up.size == 0:
            if self.hold_end is None:
                self.hold_end = first_sample + lo
        elif up[-1] == part.size - 1 and hi == len(hold):
            self.hold_end = None
        else:
            self.hold_end = first_sample + lo + int(up[-1]) + 1


def excitation_frequency_hz(
    setpoint: DwellSetpoint | SweepSetpoint | DriveSetpoint, t_s: np.ndarray
) -> np.ndarray:
    """The excitation's frequency at ``t_s`` (s from its first active sample): a dwell's, a
    sweep's by its law (clipped to the sweep), as the controller's generator runs it; a drive's
    equivalent sine's (a broadband drive has no single frequency)."""
    t = np.asarray(t_s, dtype=float)
    if isinstance(setpoint, DwellSetpoint):
        return np.full(t.shape, setpoint.freq_hz)
    if isinstance(setpoint, DriveSetpoint):
        return np.full(t.shape, setpoint.equivalent_frequency_hz)
    x = np.clip(t / setpoint.duration_s, 0.0, 1.0)
    if setpoint.spacing == "linear" or setpoint.start_hz == setpoint.end_hz:
        return setpoint.start_hz + (setpoint.end_hz - setpoint.start_hz) * x
    return setpoint.start_hz * (setpoint.end_hz / setpoint.start_hz) ** x


def sweep_time_s(setpoint: SweepSetpoint, freq_hz: float) -> float:
    """When (s from its first active sample) a sweep passes ``freq_hz`` (clipped to the sweep)."""
    if setpoint.start_hz == setpoint.end_hz:
        return 0.0
    if setpoint.spacing == "linear":
        x = (freq_hz - setpoint.start_hz) / (setpoint.end_hz - setpoint.start_hz)
    else:
        x = float(np.log(freq_hz / setpoint.start_hz) / np.log(setpoint.end_hz / setpoint.start_hz))
    return min(max(x, 0.0), 1.0) * setpoint.duration_s


def hold_runs(status: np.ndarray, hold_bit: int) -> Iterator[tuple[int, int, bool]]:
    """The runs of a block's samples over which the hold sync bit stays the same: ``(first, end,
    holding)`` in order, ``end`` exclusive (an amplitude update's ramp, a frequency's glide, end one
    hold run and begin the next)."""
    hold = (np.asarray(status) & hold_bit) != 0
    edges = np.flatnonzero(np.diff(hold.astype(np.int8))) + 1
    for first, end in zip(np.r_[0, edges], np.r_[edges, len(hold)], strict=True):
        yield int(first), int(end), bool(hold[first])
