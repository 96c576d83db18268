"""Amplitude held within the dwell: the achieved amplitude brought to the target during the hold.

The controller holds a sine dwell's amplitude; the servo's gain, the oil column and the specimen's
load make the displacement differ from it by a few per cent at high frequencies. Rather than
measure the error after the dwell and repeat the point (:mod:`bench.engine.amplitude`), the engine
measures the displacement's amplitude over the first cycles of the hold, while the dwell settles,
and sends the controller a new amplitude: the command scaled by target / achieved, within the same
bounds as a repeat's correction and checked against the soft limits. The controller ramps to it
(its hold sync output low during the ramp) and holds the dwell for its hold time again at the new
amplitude (docs/protocols.md). The first cycles after the ramp are checked the same way, up to
:attr:`AmplitudeHold.max_updates` updates; the dwell's hold is its part after the last ramp (the
excitation's span follows the hold sync bit's last rise), measured after its settling time as any.
A refused update, or none left, leaves the point to the repeat after it: a point is repeated only
when the controller cannot get there.

A window is fitted on its samples' true times (the frame counter), and a command is updated only on a
window with its frames present (:class:`~bench.engine.amplitude.FramesPresent`): a window that lost
frames is measured again at the same command, from the next sample of the same hold segment. An
update's step and the command it reaches are bounded as a repeat's correction is
(:class:`~bench.engine.amplitude.AmplitudeControl`).

:class:`HeldAmplitude` follows one attempt block by block, from the frames' hold sync bit and the
displacement channel: every segment of the hold (from the hold bit rising to its fall) is one
amplitude, its first :meth:`AmplitudeHold.window_s` checked.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace

import numpy as np

from bench.engine.amplitude import AmplitudeControl, FramesPresent, amplitude_mm
from bench.engine.points import hold_runs
from bench.numerics.sine_fit import fit_latest_cycles, frame_offsets


@dataclass(frozen=True)
class AmplitudeHold:
    """How the amplitude is held within a dwell (the bench configuration's ``[amplitude]``).

    ``update_tolerance``: the relative error beyond which the command is updated (below the
    repeat's tolerance, so that an update leaves room for noise and the gain's drift);
    ``max_updates``: updates per attempt; ``ramp_s``: each update's ramp; the amplitude is measured
    over ``window_cycles`` cycles of each hold segment, at least ``window_min_s``, at most the
    dwell's settling time (when that is longer than ``window_min_s``)."""

    update_tolerance: float = 0.005
    max_updates: int = 3
    ramp_s: float = 0.1
    window_cycles: float = 4.0
    window_min_s: float = 0.1

    def window_s(self, freq_hz: float, settle_s: float) -> float:
        """The length of the amplitude's measurement at the start of a hold segment (s)."""
        return max(self.window_min_s, min(settle_s, self.window_cycles / freq_hz))


@dataclass(frozen=True)
class AmplitudeStep:
    """One look at a hold segment's amplitude: the run sample where its window ended, the amplitude
    achieved there under ``command_mm``, and what followed: ``updated_mm`` the new command sent
    (NaN: none), ``refusal`` why an update was not made (empty: none was needed, or it was sent);
    ``frames_missing`` of the window's frames were lost; ``lost`` says why the window was not
    decided on (too many frames lost: the same command is measured again; empty: it was)."""

    sample: int
    achieved_mm: float
    command_mm: float
    updated_mm: float = float("nan")
    refusal: str = ""
    frames_missing: int = 0
    lost: str = ""


#: ``update(amplitude_mm)`` sends the controller a new amplitude: None once sent (or its outcome
#: unknown: the hold sync bit tells), else why it was refused.
UpdateAmplitude = Callable[[float], "str | None"]


class HeldAmplitude:
    """Holds one attempt's amplitude: :meth:`feed` every block of the excitation, then read
    :attr:`updates`, :attr:`command_mm` (the command in force at the hold's end) and :attr:`steps`."""

    def __init__(
        self,
        *,
        freq_hz: float,
        target_mm: float,
        command_mm: float,
        settle_s: float,
        hold_s: float,
        settings: AmplitudeHold,
        control: AmplitudeControl,
        present: FramesPresent,
        sample_rate_hz: float,
        displacement: str,
        hold_bit: int,
        update: UpdateAmplitude,
        on_step: Callable[[AmplitudeStep], None] = lambda step: None,
    ) -> None:
        self.freq_hz = freq_hz
        self.target_mm = target_mm
        self.command_mm = command_mm
        self.settings = settings
        self.control = control
        self.present = present
        self.sample_rate_hz = sample_rate_hz
        self.displacement = displacement
        self.hold_bit = hold_bit
        self._update = update
        self._on_step = on_step
        self._window = max(1, round(settings.window_s(freq_hz, settle_s) * sample_rate_hz))
        self._hold_s = hold_s
        self.updates = 0
        self.steps: list[AmplitudeStep] = []
        self.refusal = ""  # why an update that was due was not made (the point is left to a repeat)
        self._in_hold = False
        self._segment_start: int | None = None  # run sample of the present hold segment's start
        self._segment: list[tuple[np.ndarray, np.ndarray]] = []  # (seq, z) until the window is full
        self._window_start_seq: int | None = None  # the window's first frame counter
        self._checked = False
        self._pending: float | None = None  # an update sent, until its ramp ends

    @property
    def extension_s(self) -> float:
        """How much longer than planned the excitation may last: each update holds the dwell again
        after its ramp (at most the hold plus the ramp)."""
        sent = self.updates + (self._pending is not None)
        return sent * (self._hold_s + self.settings.ramp_s)

    def feed(self, first_sample: int, columns: Mapping[str, np.ndarray]) -> None:
        """One block of the excitation's frames from run sample ``first_sample``."""
        status = columns.get("status")
        if status is None or len(status) == 0:
            return
        z = np.asarray(columns[self.displacement], dtype=float)
        seq = np.asarray(columns["seq"])
        for a, b, holding in hold_runs(status, self.hold_bit):
            if not holding:
                self._in_hold = False
                continue
            if not self._in_hold:
                self._begin_segment(first_sample + a)
            self._in_hold = True
            if not self._checked:
                self._take(first_sample + a, seq[a:b], z[a:b])

    def _begin_segment(self, sample: int) -> None:
        if self._segment_start is not None and self._pending is not None:
            self.command_mm, self._pending = self._pending, None  # the update's ramp has ended
            self.updates += 1
        self._segment_start, self._checked = sample, False
        self._new_window()

    def _new_window(self) -> None:
        self._segment, self._window_start_seq = [], None

    def _take(self, sample: int, seq: np.ndarray, z: np.ndarray) -> None:
        """Add a hold run's frames to the window; check it once it spans its length in sample times
        (frames lost inside it count as time, not as samples)."""
        if len(seq) == 0:
            return
        if self._window_start_seq is None:
            self._window_start_seq = int(seq[0])
        offsets = frame_offsets(seq, self._window_start_seq)
        inside = offsets < self._window
        self._segment.append((offsets[inside], z[inside]))
        if not inside.all():  # the window's time is over: the frames after it wait for the next
            rest = int(np.argmin(inside))
            self._check(sample + rest)
            if not self._checked:  # measured again, from where this window ended
                self._take(sample + rest, seq[rest:], z[rest:])

    def _check(self, sample: int) -> None:
        """The window is full (it ended before run sample ``sample``): measure it, and update the
        command when it is off and its frames were there."""
        offsets = np.concatenate([k for k, _ in self._segment])
        window = np.concatenate([z for _, z in self._segment])
        self._new_window()
        fit = fit_latest_cycles(window, offsets, self.sample_rate_hz, self.freq_hz, start=0, end=self._window)
        achieved = amplitude_mm(fit)
        missing = self._window - len(window) if fit is None else fit.frames_missing
        lost = self.present.refusal(fit)
        if lost:  # the command stays: the same command is measured again over a new window
            self._step(
                AmplitudeStep(
                    sample, achieved, self.command_mm, lost=f"the window {lost}", frames_missing=missing
                )
            )
            return
        self._checked = True
        error = (achieved - self.target_mm) / self.target_mm
        # every update ends in a new hold segment, checked again: no update, no further check
        if abs(error) <= self.settings.update_tolerance or self.updates >= self.settings.max_updates:
            self._step(AmplitudeStep(sample, achieved, self.command_mm, frames_missing=missing))
            return
        if not np.isfinite(achieved) or achieved <= 0:
            self._refuse(AmplitudeStep(sample, achieved, self.command_mm), "no displacement measured")
            return
        updated = self.command_mm * self.control.step(self.target_mm, achieved)
        if cap := self.control.cap_refusal(self.target_mm, updated, called="the update to"):
            self._refuse(AmplitudeStep(sample, achieved, self.command_mm, frames_missing=missing), cap)
            return
        refusal = self._update(updated)
        if refusal is not None:
            self._refuse(
                AmplitudeStep(sample, achieved, self.command_mm, updated, frames_missing=missing), refusal
            )
            return
        self._pending = updated
        self._step(AmplitudeStep(sample, achieved, self.command_mm, updated, frames_missing=missing))

    def _refuse(self, step: AmplitudeStep, reason: str) -> None:
        self.refusal = reason
        self._step(replace(step, refusal=reason))

    def _step(self, step: AmplitudeStep) -> None:
        self.steps.append(step)
        self._on_step(step)
