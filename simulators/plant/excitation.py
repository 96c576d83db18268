"""Excitation waveforms as pure functions of time.

The same objects serve the offline plant simulation and the simulated actuator controller's
function generator, which evaluates them block by block at the sample instants it needs. Each
waveform knows its instantaneous frequency and amplitude, which a non-linear plant uses to choose
its operating point.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from scipy import signal

from bench.models.setup import DriveDensity, drive_density
from bench.models.taper import taper_envelope
from drivers.setpoints import equivalent_sine


class Waveform(Protocol):
    """A finite excitation starting at t = 0."""

    @property
    def duration_s(self) -> float: ...

    def value(self, t_s: np.ndarray) -> np.ndarray:
        """The excitation (displacement in m, or force in N) at times ``t_s``; zero outside."""
        ...

    def frequency_hz(self, t_s: float) -> float:
        """Instantaneous excitation frequency at ``t_s``."""
        ...

    @property
    def amplitude(self) -> float: ...


def _check_taper(total_s: float, taper_in_s: float, taper_out_s: float) -> None:
    if taper_in_s < 0 or taper_out_s < 0 or taper_in_s + taper_out_s > total_s:
        raise ValueError(
            f"tapers ({taper_in_s} s in, {taper_out_s} s out) must be >= 0 and fit in {total_s} s"
        )


@dataclass(frozen=True)
class SineDwell:
    """A sine at one frequency: taper in, hold, taper out (sine phase zero at t = 0)."""

    freq_hz: float
    amplitude: float
    hold_s: float
    taper_in_s: float = 1.0
    taper_out_s: float = 1.0

    def __post_init__(self) -> None:
        if self.freq_hz <= 0 or self.amplitude < 0 or self.hold_s < 0:
            raise ValueError(f"invalid dwell {self}")
        _check_taper(self.duration_s, self.taper_in_s, self.taper_out_s)

    @property
    def duration_s(self) -> float:
        return self.taper_in_s + self.hold_s + self.taper_out_s

    def value(self, t_s: np.ndarray) -> np.ndarray:
        t = np.asarray(t_s, dtype=float)
        env = taper_envelope(t, self.duration_s, self.taper_in_s, self.taper_out_s)
        return self.amplitude * env * np.sin(2 * np.pi * self.freq_hz * t)

    def frequency_hz(self, t_s: float) -> float:
        return self.freq_hz


@dataclass(frozen=True)
class Sweep:
    """A sine sweep from ``start_hz`` to ``end_hz`` over ``sweep_s``, linear or logarithmic in frequency.

    The tapers lie inside the sweep: the first ``taper_in_s`` and the last ``taper_out_s`` seconds
    are ramped.
    """

    start_hz: float
    end_hz: float
    sweep_s: float
    amplitude: float
    spacing: str = "linear"
    taper_in_s: float = 1.0
    taper_out_s: float = 1.0

    def __post_init__(self) -> None:
        if self.start_hz <= 0 or self.end_hz <= 0 or self.sweep_s <= 0 or self.amplitude < 0:
            raise ValueError(f"invalid sweep {self}")
        if self.spacing not in ("linear", "log"):
            raise ValueError(f"sweep spacing must be 'linear' or 'log', got {self.spacing!r}")
        _check_taper(self.sweep_s, self.taper_in_s, self.taper_out_s)

    @property
    def duration_s(self) -> float:
        return self.sweep_s

    def value(self, t_s: np.ndarray) -> np.ndarray:
        """The tapered sweep, ``A sin(phase)`` with the phase of :func:`scipy.signal.chirp` (its
        cosine shifted by -90 degrees): zero phase at the start, frequency as :meth:`frequency_hz`."""
        t = np.asarray(t_s, dtype=float)
        env = taper_envelope(t, self.sweep_s, self.taper_in_s, self.taper_out_s)
        t_in = np.clip(t, 0, self.sweep_s)
        if self.start_hz == self.end_hz:  # chirp's logarithmic law needs two frequencies
            wave = np.sin(2 * np.pi * self.start_hz * t_in)
        else:
            method = "linear" if self.spacing == "linear" else "logarithmic"
            wave = signal.chirp(t_in, self.start_hz, self.sweep_s, self.end_hz, method=method, phi=-90)
        return self.amplitude * env * wave

    def frequency_hz(self, t_s: float) -> float:
        x = min(max(t_s / self.sweep_s, 0.0), 1.0)
        if self.spacing == "linear":
            return self.start_hz + (self.end_hz - self.start_hz) * x
        return self.start_hz * (self.end_hz / self.start_hz) ** x

    def time_at_s(self, freq_hz: float) -> float:
        """When (s from the start) the sweep passes ``freq_hz`` (clipped to the sweep)."""
        if self.start_hz == self.end_hz:
            return 0.0
        if self.spacing == "linear":
            x = (freq_hz - self.start_hz) / (self.end_hz - self.start_hz)
        else:
            x = math.log(freq_hz / self.start_hz) / math.log(self.end_hz / self.start_hz)
        return min(max(x, 0.0), 1.0) * self.sweep_s


@dataclass(frozen=True)
class RetunedDwell:
    """A sine dwell whose frequency was changed during its hold, phase-continuously: each change
    ``(t_s, to_hz, glide_s)`` glides linearly from the frequency before it to ``to_hz`` over
    ``glide_s`` from ``t_s`` (s from the dwell's start), in order."""

    dwell: SineDwell
    changes: tuple[tuple[float, float, float], ...] = ()

    @property
    def duration_s(self) -> float:
        return self.dwell.duration_s

    @property
    def amplitude(self) -> float:
        return self.dwell.amplitude

    def frequency_hz(self, t_s: float) -> float:
        freq = self.dwell.freq_hz
        for start_s, to_hz, glide_s in self.changes:
            if t_s <= start_s:
                break
            if t_s < start_s + glide_s:
                return freq + (to_hz - freq) * (t_s - start_s) / glide_s
            freq = to_hz
        return freq

    def phase_rad(self, t_s: np.ndarray) -> np.ndarray:
        """The sine's phase: the integral of the frequency from the start."""
        t = np.asarray(t_s, dtype=float)
        phase = 2 * np.pi * self.dwell.freq_hz * t
        freq = self.dwell.freq_hz
        for start_s, to_hz, glide_s in self.changes:
            tau = np.clip(t - start_s, 0.0, None)
            gliding = np.minimum(tau, glide_s)
            phase = phase + 2 * np.pi * (to_hz - freq) * (gliding**2 / (2 * glide_s) + (tau - gliding))
            freq = to_hz
        return phase

    def value(self, t_s: np.ndarray) -> np.ndarray:
        t = np.asarray(t_s, dtype=float)
        d = self.dwell
        env = taper_envelope(t, d.duration_s, d.taper_in_s, d.taper_out_s)
        return d.amplitude * env * np.sin(self.phase_rad(t))


@dataclass(frozen=True)
class NotchedSweep:
    """A sweep whose amplitude is lowered to ``notch_amplitude`` from ``notch_start_hz`` to
    ``notch_end_hz`` (a response limit's notch): it ramps down along a raised cosine over ``ramp_s``
    before the notch's first frequency and back up over ``ramp_s`` after its last."""

    sweep: Sweep
    notch_start_hz: float
    notch_end_hz: float
    notch_amplitude: float
    ramp_s: float

    def __post_init__(self) -> None:
        lo, hi = sorted((self.sweep.start_hz, self.sweep.end_hz))
        if not lo <= self.notch_start_hz < self.notch_end_hz <= hi or not self.ramp_s > 0:
            raise ValueError(f"notch {self.notch_start_hz}-{self.notch_end_hz} Hz not within {lo}-{hi} Hz")
        if not 0 <= self.notch_amplitude <= self.sweep.amplitude:
            raise ValueError(f"notch amplitude {self.notch_amplitude} above the sweep's")

    @property
    def duration_s(self) -> float:
        return self.sweep.duration_s

    @property
    def amplitude(self) -> float:
        return self.sweep.amplitude

    def frequency_hz(self, t_s: float) -> float:
        return self.sweep.frequency_hz(t_s)

    def notch_window_s(self) -> tuple[float, float]:
        """When (s from the start) the sweep passes the notch's first and last frequency."""
        t = sorted(self.sweep.time_at_s(f) for f in (self.notch_start_hz, self.notch_end_hz))
        return t[0], t[1]

    def value(self, t_s: np.ndarray) -> np.ndarray:
        t = np.asarray(t_s, dtype=float)
        t1, t2 = self.notch_window_s()
        dip = taper_envelope(t - (t1 - self.ramp_s), t2 - t1 + 2 * self.ramp_s, self.ramp_s, self.ramp_s)
        scale = 1 - (1 - self.notch_amplitude / self.sweep.amplitude) * dip if self.sweep.amplitude else 1.0
        return self.sweep.value(t) * scale


@dataclass(frozen=True)
class HalfSinePulse:
    """A hammer blow: a half-sine force pulse of ``amplitude`` newtons lasting ``width_s``."""

    amplitude: float
    width_s: float = 2e-4
    delay_s: float = 0.01
    record_s: float = 0.5

    def __post_init__(self) -> None:
        if self.width_s <= 0 or self.delay_s < 0 or self.record_s < self.delay_s + self.width_s:
            raise ValueError(f"invalid pulse {self}")

    @property
    def duration_s(self) -> float:
        return self.record_s

    def value(self, t_s: np.ndarray) -> np.ndarray:
        tau = np.asarray(t_s, dtype=float) - self.delay_s
        inside = (tau >= 0) & (tau <= self.width_s)
        return np.where(inside, self.amplitude * np.sin(np.pi * np.clip(tau, 0, None) / self.width_s), 0.0)

    def frequency_hz(self, t_s: float) -> float:
        """A pulse has no single frequency; its spectrum is flat to about 1 / width."""
        return 1.0 / self.width_s


@dataclass(frozen=True, eq=False)
class SampledDrive:
    """A displacement drive given as samples (a road under the wheel, a post's drive file):
    ``displacement_m`` at ``sample_rate_hz`` from t = 0, linear between samples (as the plant's
    first-order hold takes its input), tapered in and out by raised cosines inside its duration, so
    that a drive that does not start and end at rest still starts and stops smoothly.

    A non-linear tyre is linearised at one operating point for the whole drive (a broadband drive
    has no single frequency): the equivalent sine of the drive, the frequency ``sigma_v / (2 pi
    sigma_z)`` and amplitude ``sqrt(2) sigma_z`` of the sine with the drive's rms displacement and
    rms velocity (:func:`drivers.setpoints.equivalent_sine`), is what :meth:`frequency_hz` and
    :attr:`amplitude` report. A non-linear damper is linearised statistically for the drive's
    :attr:`density` (:func:`bench.models.setup.drive_density`).
    """

    displacement_m: np.ndarray
    sample_rate_hz: float
    taper_in_s: float = 1.0
    taper_out_s: float = 1.0
    amplitude: float = field(init=False)
    equivalent_frequency_hz: float = field(init=False)
    density: DriveDensity = field(init=False)

    def __post_init__(self) -> None:
        z = np.asarray(self.displacement_m, dtype=float)
        if z.ndim != 1 or z.size < 2 or not np.all(np.isfinite(z)) or not self.sample_rate_hz > 0:
            raise ValueError("a sampled drive needs at least two finite samples and a positive rate")
        _check_taper(self.duration_s, self.taper_in_s, self.taper_out_s)
        object.__setattr__(self, "displacement_m", z)
        amplitude, frequency_hz = equivalent_sine(z, self.sample_rate_hz)
        object.__setattr__(self, "amplitude", amplitude)
        object.__setattr__(self, "equivalent_frequency_hz", frequency_hz)
        object.__setattr__(self, "density", drive_density(z, self.sample_rate_hz))

    @property
    def duration_s(self) -> float:
        return (np.size(self.displacement_m) - 1) / self.sample_rate_hz

    def value(self, t_s: np.ndarray) -> np.ndarray:
        t = np.asarray(t_s, dtype=float)
        env = taper_envelope(t, self.duration_s, self.taper_in_s, self.taper_out_s)
        position = np.clip(t * self.sample_rate_hz, 0, self.displacement_m.size - 1)
        below = np.minimum(position.astype(int), self.displacement_m.size - 2)
        z = self.displacement_m
        return env * (z[below] + (position - below) * (z[below + 1] - z[below]))

    def frequency_hz(self, t_s: float) -> float:
        """The equivalent sine's frequency (see the class docstring), whatever ``t_s``."""
        return self.equivalent_frequency_hz
