"""A tracked resonance dwell: the resonance found from a search, then followed by phase.

**The resonance** (:func:`find_resonance`): a single-mode resonance ``H = G / (1 - r^2 + 2 i zeta
r)``, ``r = f / f_n``, has ``1 / |H|^2 = (x^2 / f_n^4 + (4 zeta^2 - 2) x / f_n^2 + 1) / G^2`` in
``x = f^2``: the parabola through the search's largest ``|H|`` and its two neighbours gives the
peak (``x = -b / 2a``), ``f_n^2 = sqrt(c / a)`` and ``zeta = sqrt((b / sqrt(ac) + 2) / 4)``. The
phase to hold is the measured phase interpolated at the peak; the phase's slope there, ``1 /
(zeta f_n)`` rad/Hz, signed as the measured phase runs across the peak.

**The track** (:class:`TrackWatch`): one dwell at the resonance. After each change of frequency
(the controller glides there with its hold sync output low) the response settles for three of the
mode's time constants ``1 / (2 pi zeta f)`` (at least two cycles), then every ``update_s`` the
output, the input and the displacement are fitted at the drive frequency (offset, sine, cosine)
and the ratio ``output / (input + m w^2 z)`` formed. Its phase's difference from the held phase
over the slope is how far the resonance lies from the drive: ``f_res = f - dphi / slope``. The
damping ratio is the search's scaled by the peak's height, ``zeta_0 |H_0| / |H|`` (a single mode's
peak is inversely proportional to its damping at a fixed static gain). When the resonance lies
further than :data:`DEADBAND` from the drive, the drive is moved to it. The track ends after its
length, or when the resonance leaves ``freq_band_pct`` of the one found, or the ratio's magnitude
``ratio_band_pct`` of the one found (stop rules, with the reason).

Each window is fitted on its samples' true times (the frame counter's: frames lost on the link are
a gap, not a shift) and spans ``update_s`` of sample time; a window that lost more of its frames
than :class:`~bench.engine.amplitude.FramesPresent` allows is not looked at (no estimate, no move
of the drive): the next window is measured at the same frequency.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from bench.engine.amplitude import FramesPresent
from bench.engine.points import hold_runs
from bench.numerics.sine_fit import fit_sine, frame_offsets
from sequences import TrackedDwell

#: The glide (s) of each change of the drive's frequency (the controller's ramp, docs/protocols.md).
GLIDE_S = 0.1
#: The drive is moved when the resonance lies further from it than this fraction of its frequency.
DEADBAND = 2e-4
#: The response settles for this many of the mode's time constants after a change of frequency.
SETTLE_TIME_CONSTANTS = 3.0


@dataclass(frozen=True)
class Resonance:
    """A resonance of the ratio: its peak frequency, the ratio there, its damping ratio, the phase
    to hold (rad) and the phase's slope there (rad/Hz)."""

    freq_hz: float
    ratio: complex
    damping_ratio: float
    phase_rad: float
    slope_rad_per_hz: float


def find_resonance(freqs_hz: np.ndarray, frf: np.ndarray) -> Resonance | None:
    """The single-mode resonance through the largest ``|frf|`` and its neighbours (None: the largest
    lies at an end of the search, or the three points show no resonance)."""
    f = np.asarray(freqs_hz, float)
    h = np.asarray(frf, complex)
    mag = np.abs(h)
    i = int(np.argmax(mag))
    if i == 0 or i == len(mag) - 1:
        return None
    x = f[i - 1 : i + 2] ** 2
    a, b, c = np.polyfit(x, 1.0 / mag[i - 1 : i + 2] ** 2, 2)
    if a <= 0 or c <= 0 or not x[0] < -b / (2 * a) < x[2]:
        return None
    peak_hz = float(np.sqrt(-b / (2 * a)))
    natural_hz = float((c / a) ** 0.25)
    zeta = math.sqrt(max(b / math.sqrt(a * c) + 2.0, 1e-12) / 4.0)
    phase = np.unwrap(np.angle(h[i - 1 : i + 2]))
    held = float(np.interp(peak_hz, f[i - 1 : i + 2], phase))
    magnitude = float(1.0 / np.sqrt(a * peak_hz**4 + b * peak_hz**2 + c))
    sign = 1.0 if phase[2] > phase[0] else -1.0
    return Resonance(peak_hz, magnitude * np.exp(1j * held), zeta, held, sign / (zeta * natural_hz))


@dataclass(frozen=True)
class TrackWindow:
    """One look at the tracked resonance: the window's end (run sample), the drive frequency, the
    resonance estimated there, the ratio (magnitude and phase) and the damping ratio."""

    sample: int
    drive_hz: float
    resonance_hz: float
    ratio: complex
    damping_ratio: float


#: ``update(freq_hz)`` sends the controller a new frequency: None once sent, else why it was refused.
UpdateFrequency = Callable[[float], "str | None"]


class TrackWatch:
    """Follows one tracked dwell's hold block by block (:meth:`feed`); :attr:`done` once the track
    ended, :attr:`reason` why it stopped early (empty: it ran its length)."""

    def __init__(
        self,
        step: TrackedDwell,
        resonance: Resonance,
        *,
        sample_rate_hz: float,
        channels: tuple[str, str, str],
        hold_bit: int,
        update: UpdateFrequency,
        present: FramesPresent | None = None,
        on_window: Callable[[TrackWindow], None] = lambda window: None,
    ) -> None:
        """``channels``: the output, the input and the displacement (m); ``present``: how much of a
        window's frames a look needs."""
        self.present = present or FramesPresent()
        self.step = step
        self.found = resonance
        self.rate_hz = sample_rate_hz
        self.channels = channels
        self.hold_bit = hold_bit
        self._update = update
        self._on_window = on_window
        self.drive_hz = resonance.freq_hz
        self.windows: list[TrackWindow] = []
        self.done = False
        self.reason = ""
        self._in_hold = False
        self._pending: float | None = None  # a frequency sent, until its glide ends
        self._held = 0  # hold sample times so far (frames lost count)
        self._cycles = 0.0  # cycles held so far
        self._skip = 0  # samples still to settle
        # (first run sample, true offsets from the window's first frame, rows) of the window
        self._window: list[tuple[int, np.ndarray, np.ndarray]] = []
        self._window_seq: int | None = None  # the window's first frame counter
        self._last_seq: int | None = None  # the counter of the last hold frame seen

    def _settle_samples(self) -> int:
        tau_s = 1.0 / (2 * math.pi * self.found.damping_ratio * self.drive_hz)
        return round(max(SETTLE_TIME_CONSTANTS * tau_s, 2.0 / self.drive_hz) * self.rate_hz)

    def feed(
        self,
        first_sample: int,
        columns: Mapping[str, np.ndarray],
        hold_start: int | None = None,
        hold_end: int | None = None,
    ) -> None:
        """One block of the excitation's frames from run sample ``first_sample`` (the hold is read
        from the frames' sync bit: each glide of the frequency interrupts it)."""
        status = columns.get("status")
        if self.done or status is None or len(status) == 0:
            return
        data = np.column_stack([np.asarray(columns[name], float) for name in self.channels])
        seq = np.asarray(columns["seq"])
        for a, b, holding in hold_runs(status, self.hold_bit):
            if not holding:
                self._in_hold = False
                continue
            if not self._in_hold:
                self._segment_begins()
            self._in_hold = True
            self._hold(first_sample + a, seq[a:b], data[a:b])
            if self.done:
                return

    def _segment_begins(self) -> None:
        if self._pending is not None:
            self.drive_hz, self._pending = self._pending, None
        self._skip = self._settle_samples()
        self._window, self._window_seq, self._last_seq = [], None, None

    def _hold(self, sample: int, seq: np.ndarray, rows: np.ndarray) -> None:
        """A run of hold frames from run sample ``sample``: its sample times (frames lost among them
        included) count towards the settling, the window and the track's length."""
        times = frame_offsets(seq, self._last_seq) if self._last_seq is not None else frame_offsets(seq) + 1
        self._last_seq = int(seq[-1])
        elapsed = int(times[-1])  # sample times since the last hold frame seen
        self._held += elapsed
        self._cycles += elapsed * self.drive_hz / self.rate_hz
        settled = times > self._skip  # the settling counts sample times too
        self._skip = max(self._skip - elapsed, 0)
        if self._pending is None and settled.any():
            first = int(np.argmax(settled))
            self._take(sample + first, seq[first:], rows[first:])
        if not self.done and self._length_reached():
            self.done = True

    def _take(self, sample: int, seq: np.ndarray, rows: np.ndarray) -> None:
        """Add settled frames to the window; look once it spans ``update_s`` of sample time."""
        if self._window_seq is None:
            self._window_seq = int(seq[0])
        n = round(self.step.update_s * self.rate_hz)
        offsets = frame_offsets(seq, self._window_seq)
        inside = offsets < n
        self._window.append((sample, offsets[inside], rows[inside]))
        if inside.all():
            return
        rest = int(np.argmin(inside))
        self._look(n)
        if not self.done and self._pending is None:  # the next window begins where this one ended
            self._take(sample + rest, seq[rest:], rows[rest:])

    def _length_reached(self) -> bool:
        if self.step.track_cycles is not None:
            return self._cycles >= self.step.track_cycles
        return self._held >= self.step.track_s * self.rate_hz

    def _look(self, n: int) -> None:
        """Fit the window (``n`` sample times) at the drive frequency, estimate the resonance, apply
        the stop rules and move the drive when the resonance lies beyond the deadband; a window that
        lost too many of its frames is passed over."""
        first = self._window[0][0]
        offsets = np.concatenate([k for _, k, _ in self._window])
        rows = np.concatenate([r for _, _, r in self._window])
        self._window, self._window_seq = [], None
        if self.present.refusal_of(len(offsets), n, self.drive_hz, self.rate_hz) or len(offsets) < 4:
            return
        w = 2 * math.pi * self.drive_hz
        output, input_, z = fit_sine(rows, offsets, self.rate_hz, self.drive_hz).phasors
        ratio = output / (input_ + self.step.plate_mass_kg * w**2 * z)
        off = (np.angle(ratio) - self.found.phase_rad + math.pi) % (2 * math.pi) - math.pi
        resonance_hz = self.drive_hz - off / self.found.slope_rad_per_hz
        zeta = self.found.damping_ratio * abs(self.found.ratio) / abs(ratio)
        window = TrackWindow(first + len(offsets), self.drive_hz, resonance_hz, ratio, zeta)
        self.windows.append(window)
        self._on_window(window)
        self._stop_rules(window)
        if not self.done and abs(resonance_hz - self.drive_hz) > DEADBAND * self.drive_hz:
            refusal = self._update(resonance_hz)
            if refusal is not None:
                self.done, self.reason = True, f"frequency update refused: {refusal}"
            else:
                self._pending = resonance_hz

    def _stop_rules(self, window: TrackWindow) -> None:
        f0, band = self.found.freq_hz, self.step.freq_band_pct / 100
        if abs(window.resonance_hz / f0 - 1) > band:
            self.done = True
            self.reason = (
                f"the resonance at {window.resonance_hz:.3f} Hz left its band {f0 * (1 - band):.3f}-"
                f"{f0 * (1 + band):.3f} Hz after {self._held / self.rate_hz:.1f} s"
            )
            return
        h0, band = abs(self.found.ratio), self.step.ratio_band_pct / 100
        if abs(abs(window.ratio) / h0 - 1) > band:
            self.done = True
            self.reason = (
                f"the ratio {abs(window.ratio):.3g} left its band {h0 * (1 - band):.3g}-{h0 * (1 + band):.3g}"
                f" after {self._held / self.rate_hz:.1f} s"
            )
