"""The actuator controller's function generator: excitation, tapers and mean position, in samples.

The displacement command is the sum of two parts, both evaluated at the controller's internal
sample instants (time is counted in samples, never read from a clock):

- the *excitation*, a waveform of :mod:`simulators.plant.excitation` (it carries its own raised-
  cosine taper in and out); an early stop multiplies it by a raised cosine falling from 1 to 0 over
  ``taper_out_s``;
- the *mean position*, which never steps: every change (to the setpoint at a start, back to zero at
  a stop, from the frozen position back to zero after an e-stop) follows a raised cosine whose
  length is the distance over :data:`MEAN_RATE_MM_S` (so the mean moves at that rate on average
  and at pi/2 times it at most, with zero velocity at both ends).

A sine dwell's amplitude may be changed during its hold (:meth:`FunctionGenerator.update_amplitude`,
the controller's amplitude update): the excitation is scaled along a raised cosine to the new
amplitude and the dwell then holds for its hold time again.

An e-stop freezes the command at its last value; :meth:`FunctionGenerator.release` returns from
there to rest along a mean-position ramp.

Two digital sync outputs accompany the command, sample by sample (:func:`sync_flags`):
:data:`EXCITATION_ACTIVE` while the excitation runs (its tapers included) and
:data:`AMPLITUDE_HOLD` during its constant-amplitude part (a dwell's hold, a sweep or a drive
between its tapers; not during an amplitude update's ramp); they are wired to digital inputs of the WFS
acquisition, which locates each point in its samples with them.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from simulators.plant.excitation import (
    NotchedSweep,
    RetunedDwell,
    SampledDrive,
    SineDwell,
    Sweep,
    Waveform,
    taper_envelope,
)

#: average speed of every change of the mean position (mm/s); the peak speed is pi/2 times this
MEAN_RATE_MM_S = 10.0
#: sync output bits (uint8 per internal sample): the excitation runs / its amplitude is held constant
EXCITATION_ACTIVE = 0x01
AMPLITUDE_HOLD = 0x02


def hold_window_s(waveform: Waveform) -> tuple[float, float]:
    """Start and end (s from the excitation's start) of the waveform's constant-amplitude part."""
    if isinstance(waveform, NotchedSweep):
        waveform = waveform.sweep
    if isinstance(waveform, RetunedDwell):
        waveform = waveform.dwell
    if isinstance(waveform, SineDwell):
        return waveform.taper_in_s, waveform.taper_in_s + waveform.hold_s
    if isinstance(waveform, Sweep):
        return waveform.taper_in_s, waveform.sweep_s - waveform.taper_out_s
    if isinstance(waveform, SampledDrive):
        return waveform.taper_in_s, waveform.duration_s - waveform.taper_out_s
    return 0.0, 0.0


def sync_flags(
    t_s: np.ndarray, waveform: Waveform, stop_s: float | None = None, taper_out_s: float = 0.0
) -> np.ndarray:
    """The sync outputs (uint8 bits) at times ``t_s`` (s from the excitation's start) of ``waveform``
    stopped early at ``stop_s`` (None: not stopped) with a taper of ``taper_out_s``."""
    end_s = waveform.duration_s if stop_s is None else min(waveform.duration_s, stop_s + taper_out_s)
    hold_start_s, hold_end_s = hold_window_s(waveform)
    if stop_s is not None:
        hold_end_s = min(hold_end_s, stop_s)
    active = (t_s >= 0) & (t_s < end_s)
    hold = (t_s >= hold_start_s) & (t_s < hold_end_s)
    return (active * EXCITATION_ACTIVE | hold * AMPLITUDE_HOLD).astype(np.uint8)


class MeanRamp:
    """A value that moves between targets along raised cosines: the mean position (m), at
    :data:`MEAN_RATE_MM_S` on average, or an amplitude's scale over a stated length."""

    def __init__(self, rate_hz: float) -> None:
        self.rate_hz = rate_hz
        self._from_m = 0.0
        self._to_m = 0.0
        self._start_n = 0
        self._length_s = 0.0

    @property
    def target_m(self) -> float:
        return self._to_m

    def values(self, n: np.ndarray) -> np.ndarray:
        """The position (m) at the absolute sample indices ``n``."""
        t = (np.asarray(n, dtype=float) - self._start_n) / self.rate_hz
        return self._from_m + (self._to_m - self._from_m) * taper_envelope(t, math.inf, self._length_s, 0.0)

    def move(self, n: int, from_m: float, to_m: float, length_s: float | None = None) -> None:
        """Start at sample ``n`` a ramp from ``from_m`` to ``to_m`` lasting ``length_s`` (None: a
        mean position's, at :data:`MEAN_RATE_MM_S`)."""
        self._from_m, self._to_m, self._start_n = from_m, to_m, n
        self._length_s = abs(to_m - from_m) * 1000 / MEAN_RATE_MM_S if length_s is None else length_s

    @property
    def span(self) -> tuple[int, int]:
        """The samples ``[start, end)`` of the last ramp."""
        return self._start_n, self._start_n + math.ceil(self._length_s * self.rate_hz)

    def settled(self, n: int) -> bool:
        """True if sample ``n`` is on the target (always, for a ramp of no length)."""
        return self._length_s == 0 or (n - self._start_n) / self.rate_hz >= self._length_s


class FunctionGenerator:
    """Produces the displacement command (m) block by block at ``rate_hz`` internal samples per second."""

    def __init__(self, rate_hz: float) -> None:
        self.rate_hz = rate_hz
        self.n = 0  # internal samples generated since power-up
        self.last_m = 0.0  # the last command sample
        self._mean = MeanRamp(rate_hz)
        self._waveform: Waveform | None = None
        self._start_n = 0
        self._taper_out_s = 0.0
        self._stop_n: int | None = None
        self._stopping = False
        self._frozen_m: float | None = None
        self._scale = MeanRamp(rate_hz)  # the excitation's amplitude over the waveform's own
        self._scale.move(0, 1.0, 1.0, 0.0)
        self._dwell_hold_s = 0.0  # the running dwell's hold as started (an update holds it again)
        self._glide = (0, 0)  # the samples of the last frequency glide
        self._sync: list[np.ndarray] = []  # sync outputs of the blocks generated since the last take

    # -- control ------------------------------------------------------------------------------

    def start(self, waveform: Waveform | None, mean_m: float, taper_out_s: float) -> None:
        """Run ``waveform`` from the next sample on ``mean_m`` (reached along a mean ramp).

        ``taper_out_s`` (> 0) is the length of the taper of an early :meth:`stop`.
        """
        if taper_out_s <= 0:
            raise ValueError(f"taper_out_s must be > 0, got {taper_out_s}")
        self._waveform, self._start_n, self._taper_out_s = waveform, self.n, taper_out_s
        self._stop_n, self._stopping = None, False
        self._scale.move(self.n, 1.0, 1.0, 0.0)
        self._dwell_hold_s = waveform.hold_s if isinstance(waveform, SineDwell) else 0.0
        self._mean.move(self.n, self.mean_m(), mean_m)

    def holding(self) -> bool:
        """A sine dwell runs in its hold (an amplitude ramp or a frequency glide included), not
        stopping."""
        waveform = self._waveform
        if not isinstance(waveform, SineDwell | RetunedDwell) or self._stopping or self._frozen_m is not None:
            return False
        hold_start_s, hold_end_s = hold_window_s(waveform)
        return hold_start_s <= self.elapsed_s < hold_end_s

    def update_amplitude(self, amplitude_m: float, ramp_s: float) -> None:
        """Ramp the holding sine dwell's amplitude from where it is to ``amplitude_m`` along a raised
        cosine of ``ramp_s`` from the next sample, then hold it for the dwell's hold time again (the
        hold sync output is low during the ramp). Only while :meth:`holding` (ValueError otherwise)."""
        if not self.holding():
            raise ValueError("no sine dwell holds its amplitude")
        waveform = self._waveform
        dwell = waveform.dwell if isinstance(waveform, RetunedDwell) else waveform
        assert isinstance(dwell, SineDwell)
        if dwell.amplitude <= 0:
            raise ValueError("a dwell of no amplitude has none to change")
        scale_now = float(self._scale.values(np.array([self.n]))[0])
        self._scale.move(self.n, scale_now, amplitude_m / dwell.amplitude, ramp_s)
        held = replace(dwell, hold_s=self.elapsed_s - dwell.taper_in_s + ramp_s + self._dwell_hold_s)
        self._waveform = replace(waveform, dwell=held) if isinstance(waveform, RetunedDwell) else held

    def update_frequency(self, freq_hz: float, glide_s: float) -> None:
        """Glide the holding sine dwell's frequency linearly to ``freq_hz`` over ``glide_s`` from the
        next sample, its phase continuous (the hold sync output is low during the glide); the hold
        goes on. Only while :meth:`holding` (ValueError otherwise)."""
        if not self.holding():
            raise ValueError("no sine dwell holds its frequency")
        waveform = self._waveform
        retuned = waveform if isinstance(waveform, RetunedDwell) else RetunedDwell(waveform)
        change = (self.elapsed_s, float(freq_hz), float(glide_s))
        self._waveform = replace(retuned, changes=(*retuned.changes, change))
        self._glide = (self.n, self.n + math.ceil(glide_s * self.rate_hz))

    @property
    def amplitude_m(self) -> float:
        """The excitation's amplitude, an update's target once one was made (0 without excitation)."""
        waveform = self._waveform
        return float(waveform.amplitude) * self._scale.target_m if waveform is not None else 0.0

    def stop(self) -> None:
        """Taper the excitation out over ``taper_out_s`` from the next sample; the mean ramps to 0."""
        if self._frozen_m is not None or self._stopping:
            return
        self._stopping = True
        if self._waveform is not None:
            self._stop_n = self.n
        self._mean.move(self.n, self.mean_m(), 0.0)

    def freeze(self) -> None:
        """E-stop: hold the last command sample (no taper: the valves close where they are)."""
        self._frozen_m = self.last_m
        self._waveform, self._stop_n = None, None

    def release(self) -> None:
        """Leave an e-stop: ramp from the frozen position back to rest."""
        if self._frozen_m is None:
            return
        frozen, self._frozen_m = self._frozen_m, None
        self._stopping = True
        self._mean.move(self.n, frozen, 0.0)

    # -- state --------------------------------------------------------------------------------

    @property
    def stopping(self) -> bool:
        """A stop (commanded, or the excitation's natural end, or a release) is under way or done."""
        return self._stopping

    @property
    def at_rest(self) -> bool:
        """No excitation, not frozen, and the last sample put the mean at zero."""
        return (
            self._waveform is None
            and self._frozen_m is None
            and self._mean.target_m == 0.0
            and self._mean.settled(self.n - 1)
        )

    @property
    def waveform(self) -> Waveform | None:
        return self._waveform

    @property
    def elapsed_s(self) -> float:
        """Time since the last start (s), in samples of the internal rate."""
        return (self.n - self._start_n) / self.rate_hz

    def mean_m(self) -> float:
        """The mean position (m) at the next sample (the frozen command during an e-stop)."""
        if self._frozen_m is not None:
            return self._frozen_m
        return float(self._mean.values(np.array([self.n]))[0])

    # -- generation ---------------------------------------------------------------------------

    def block(self, count: int) -> np.ndarray:
        """The command (m) for the next ``count`` internal samples (their sync outputs are kept for
        :meth:`take_sync_flags`)."""
        n = self.n + np.arange(count)
        self._sync.append(self._sync_flags(n))
        if self._frozen_m is not None:
            out = np.full(count, self._frozen_m)
        else:
            out = self._mean.values(n)
            if self._waveform is not None:
                out = out + self._excitation(n)
        self.n += count
        if count:
            self.last_m = float(out[-1])
            self._end_excitation(self.n - 1)
        return out

    def take_sync_flags(self) -> np.ndarray:
        """The sync outputs (uint8 bits) of every internal sample generated since the last call."""
        flags = np.concatenate(self._sync) if self._sync else np.zeros(0, np.uint8)
        self._sync = []
        return flags

    def _sync_flags(self, n: np.ndarray) -> np.ndarray:
        if self._waveform is None or self._frozen_m is not None:
            return np.zeros(len(n), np.uint8)
        stop_s = None if self._stop_n is None else (self._stop_n - self._start_n) / self.rate_hz
        flags = sync_flags((n - self._start_n) / self.rate_hz, self._waveform, stop_s, self._taper_out_s)
        for first, end in (self._scale.span, self._glide):  # an amplitude ramps, a frequency glides
            flags[(n >= first) & (n < end)] &= ~np.uint8(AMPLITUDE_HOLD)
        return flags

    def _excitation(self, n: np.ndarray) -> np.ndarray:
        assert self._waveform is not None
        value = self._waveform.value((n - self._start_n) / self.rate_hz) * self._scale.values(n)
        if self._stop_n is not None:
            tau = (n - self._stop_n) / self.rate_hz
            value = value * taper_envelope(tau, self._taper_out_s, 0.0, self._taper_out_s)
        return value

    def _end_excitation(self, last_n: int) -> None:
        """Drop the excitation once it is zero for good: its stop taper or its own end is complete."""
        waveform = self._waveform
        if waveform is None:
            return
        if self._stop_n is not None:
            if (last_n - self._stop_n) / self.rate_hz >= self._taper_out_s:
                self._waveform, self._stop_n = None, None
        elif (last_n - self._start_n) / self.rate_hz >= waveform.duration_s:
            self._waveform = None
            self.stop()
