"""Excitation setpoints, checked against the bench's limit envelope before any write.

The envelope (:class:`~sequences.limits.BenchLimits`, the same one the sequences were validated
against) is the software's own, tighter than the controller's hardware limits: a setpoint outside it
raises :class:`LimitError` and nothing reaches the controller.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from drivers.errors import LimitError
from drivers.register_map import WaveformCode
from sequences.limits import DRIVE_MAX_SAMPLES, DRIVE_RATE_RANGE_HZ, BenchLimits


def check_amplitude(limits: BenchLimits, amplitude_mm: float, mean_mm: float) -> None:
    """Amplitude and mean within the stroke: ``|mean_mm| + amplitude_mm <= stroke_mm``."""
    _finite(amplitude_mm=amplitude_mm, mean_mm=mean_mm)
    if not 0.0 <= amplitude_mm <= limits.stroke_mm:
        raise LimitError(f"amplitude_mm={amplitude_mm} outside 0..{limits.stroke_mm} mm (limits.stroke_mm)")
    if abs(mean_mm) + amplitude_mm > limits.stroke_mm:
        raise LimitError(
            f"mean_mm={mean_mm} with amplitude_mm={amplitude_mm} outside the ±{limits.stroke_mm} mm stroke"
            " (limits.stroke_mm)"
        )


def check_frequency(limits: BenchLimits, name: str, freq_hz: float) -> None:
    _finite(**{name: freq_hz})
    if not limits.min_freq_hz <= freq_hz <= limits.max_freq_hz:
        raise LimitError(
            f"{name}={freq_hz} outside {limits.min_freq_hz}..{limits.max_freq_hz} Hz"
            " (limits.min_freq_hz, max_freq_hz)"
        )


def check_timing(limits: BenchLimits, taper_in_s: float, taper_out_s: float, duration_s: float) -> None:
    """``duration_s`` is the whole excitation (0 means until stopped); the tapers must fit in it."""
    _finite(taper_in_s=taper_in_s, taper_out_s=taper_out_s, duration_s=duration_s)
    for name, value in (("taper_in_s", taper_in_s), ("taper_out_s", taper_out_s)):
        if value < limits.min_taper_s:
            raise LimitError(
                f"{name}={value} below the minimum taper {limits.min_taper_s} s (limits.min_taper_s)"
            )
    if not 0 <= duration_s <= limits.max_step_s:
        raise LimitError(f"duration {duration_s} s outside 0..{limits.max_step_s} s (limits.max_step_s)")
    if duration_s and taper_in_s + taper_out_s > duration_s:
        raise LimitError(f"tapers {taper_in_s} + {taper_out_s} s do not fit in {duration_s} s")


def _finite(**values: float) -> None:
    for name, value in values.items():
        if not isinstance(value, int | float) or not math.isfinite(value):
            raise LimitError(f"{name}={value!r} is not a finite number")


@dataclass(frozen=True)
class DwellSetpoint:
    """A sine dwell: taper in, hold ``dwell_s`` (0: until stopped), taper out."""

    freq_hz: float
    amplitude_mm: float
    dwell_s: float = 0.0
    taper_in_s: float = 1.0
    taper_out_s: float = 1.0
    mean_mm: float = 0.0

    def registers(self, limits: BenchLimits) -> dict[str, float]:
        """The holding-register values of this dwell, after checking it against ``limits``."""
        check_amplitude(limits, self.amplitude_mm, self.mean_mm)
        check_frequency(limits, "freq_hz", self.freq_hz)
        total = self.taper_in_s + self.dwell_s + self.taper_out_s if self.dwell_s else 0.0
        check_timing(limits, self.taper_in_s, self.taper_out_s, total)
        return {
            "waveform": WaveformCode.SINE_DWELL,
            "amplitude_mm": self.amplitude_mm,
            "frequency_hz": self.freq_hz,
            "dwell_s": self.dwell_s,
            "taper_in_s": self.taper_in_s,
            "taper_out_s": self.taper_out_s,
            "mean_mm": self.mean_mm,
        }


@dataclass(frozen=True)
class SweepNotch:
    """A sweep's amplitude lowered to ``amplitude_mm`` from ``start_hz`` to ``end_hz`` (a response
    limit's notch), ramped down before and up after over ``ramp_s``."""

    start_hz: float
    end_hz: float
    amplitude_mm: float
    ramp_s: float = 0.1


#: The registers that clear a notch (a sweep without one after a sweep with one).
NO_NOTCH = {"notch_start_hz": 0.0, "notch_end_hz": 0.0, "notch_amplitude_mm": 0.0}


@dataclass(frozen=True)
class SweepSetpoint:
    """A sine sweep from ``start_hz`` to ``end_hz`` in ``duration_s`` (tapers inside), linear or log,
    with a ``notch`` if given."""

    start_hz: float
    end_hz: float
    duration_s: float
    amplitude_mm: float
    spacing: str = "linear"
    taper_in_s: float = 1.0
    taper_out_s: float = 1.0
    mean_mm: float = 0.0
    notch: SweepNotch | None = None

    def registers(self, limits: BenchLimits) -> dict[str, float]:
        """The holding-register values of this sweep, after checking it against ``limits`` (a notch
        within the sweep's band, no deeper than nothing and no higher than the sweep)."""
        if self.spacing not in ("linear", "log"):
            raise LimitError(f"spacing={self.spacing!r} must be 'linear' or 'log'")
        check_amplitude(limits, self.amplitude_mm, self.mean_mm)
        check_frequency(limits, "start_hz", self.start_hz)
        check_frequency(limits, "end_hz", self.end_hz)
        if self.duration_s <= 0:
            raise LimitError(f"duration_s={self.duration_s} must be > 0")
        check_timing(limits, self.taper_in_s, self.taper_out_s, self.duration_s)
        code = WaveformCode.LINEAR_SWEEP if self.spacing == "linear" else WaveformCode.LOG_SWEEP
        notch = {}
        if self.notch is not None:
            n = self.notch
            _finite(notch_start_hz=n.start_hz, notch_end_hz=n.end_hz, notch_amplitude_mm=n.amplitude_mm)
            lo, hi = sorted((self.start_hz, self.end_hz))
            if not lo <= n.start_hz < n.end_hz <= hi:
                raise LimitError(f"notch {n.start_hz:g}-{n.end_hz:g} Hz not within the sweep's {lo:g}-{hi:g}")
            if not 0 <= n.amplitude_mm <= self.amplitude_mm:
                raise LimitError(f"notch amplitude {n.amplitude_mm} mm outside 0..{self.amplitude_mm} mm")
            if n.ramp_s < limits.min_taper_s:
                raise LimitError(f"notch ramp_s={n.ramp_s} below the minimum taper {limits.min_taper_s} s")
            notch = {
                "notch_start_hz": n.start_hz,
                "notch_end_hz": n.end_hz,
                "notch_amplitude_mm": n.amplitude_mm,
                "amplitude_ramp_s": n.ramp_s,
            }
        return {
            **notch,
            "waveform": code,
            "amplitude_mm": self.amplitude_mm,
            "sweep_start_hz": self.start_hz,
            "sweep_end_hz": self.end_hz,
            "sweep_duration_s": self.duration_s,
            "taper_in_s": self.taper_in_s,
            "taper_out_s": self.taper_out_s,
            "mean_mm": self.mean_mm,
        }


@dataclass(frozen=True)
class AmplitudeUpdate:
    """A new amplitude for the sine dwell holding now, reached along a raised cosine of ``ramp_s``;
    ``mean_mm`` is the running dwell's mean (the stroke holds both)."""

    amplitude_mm: float
    ramp_s: float
    mean_mm: float = 0.0

    def registers(self, limits: BenchLimits) -> dict[str, float]:
        """The holding-register values of this update, after checking it against ``limits`` (the
        ramp is a change of amplitude: no shorter than the shortest taper)."""
        check_amplitude(limits, self.amplitude_mm, self.mean_mm)
        _finite(ramp_s=self.ramp_s)
        if self.ramp_s < limits.min_taper_s:
            raise LimitError(
                f"ramp_s={self.ramp_s} below the minimum taper {limits.min_taper_s} s (limits.min_taper_s)"
            )
        return {"amplitude_update_mm": self.amplitude_mm, "amplitude_ramp_s": self.ramp_s}


@dataclass(frozen=True)
class FrequencyUpdate:
    """A new frequency for the sine dwell holding now, reached by a linear glide of ``glide_s``."""

    freq_hz: float
    glide_s: float

    def registers(self, limits: BenchLimits) -> dict[str, float]:
        """The holding-register values of this update, after checking it against ``limits``."""
        check_frequency(limits, "freq_hz", self.freq_hz)
        _finite(glide_s=self.glide_s)
        if self.glide_s < limits.min_taper_s:
            raise LimitError(f"glide_s={self.glide_s} below the minimum taper {limits.min_taper_s} s")
        return {"frequency_update_hz": self.freq_hz, "amplitude_ramp_s": self.glide_s}


#: Samples of a drive per upload request (the ``drive_block`` register's count).
DRIVE_BLOCK_SAMPLES = 60


def equivalent_sine(displacement: np.ndarray, sample_rate_hz: float) -> tuple[float, float]:
    """The sine with a drive's rms displacement and rms velocity: its amplitude ``sqrt 2 sigma_z``
    (the displacement's unit) and frequency ``sigma_v / (2 pi sigma_z)`` (Hz; 0 for a drive at
    rest). A broadband drive has no single frequency; where one is needed (a non-linear tyre's
    operating point, a response limit's level over frequency) this one stands for it."""
    z = np.asarray(displacement, dtype=float)
    sigma_z = float(np.std(z))
    sigma_v = float(np.std(np.diff(z))) * sample_rate_hz
    return math.sqrt(2) * sigma_z, sigma_v / (2 * math.pi * sigma_z) if sigma_z else 0.0


def drive_crc32(samples_mm: np.ndarray) -> int:
    """The CRC-32 the controller reports of a drive: over its samples as little-endian float32."""
    return zlib.crc32(np.asarray(samples_mm, dtype="<f4").tobytes())


@dataclass(frozen=True, eq=False)
class DriveSetpoint:
    """A displacement drive the controller plays from a file it was given (docs/protocols.md,
    *Drive files*): ``samples_mm`` about ``mean_mm`` at ``sample_rate_hz`` from the start, linear
    between samples, tapered in and out by raised cosines inside its length. The samples are held as
    the float32 values the controller receives, so its checksum is :attr:`crc32`."""

    samples_mm: np.ndarray
    sample_rate_hz: float
    taper_in_s: float = 1.0
    taper_out_s: float = 1.0
    mean_mm: float = 0.0
    crc32: int = field(init=False)

    def __post_init__(self) -> None:
        samples = np.ascontiguousarray(self.samples_mm, dtype="<f4")
        samples.setflags(write=False)
        object.__setattr__(self, "samples_mm", samples)
        object.__setattr__(self, "crc32", drive_crc32(samples))

    @property
    def n_samples(self) -> int:
        return int(self.samples_mm.size)

    @property
    def duration_s(self) -> float:
        """From the first sample to the last (the drive's length as the controller plays it)."""
        return (self.n_samples - 1) / self.sample_rate_hz

    @property
    def equivalent_frequency_hz(self) -> float:
        """The frequency of the drive's equivalent sine (:func:`equivalent_sine`)."""
        return equivalent_sine(self.samples_mm, self.sample_rate_hz)[1]

    @property
    def peak_mm(self) -> float:
        """The largest magnitude of the drive about its mean (0 for an empty drive)."""
        return float(np.max(np.abs(self.samples_mm))) if self.n_samples else 0.0

    def check(self, limits: BenchLimits) -> None:
        """The drive against ``limits`` (LimitError, nothing written): finite samples, at least two
        and at most :data:`DRIVE_MAX_SAMPLES`, a rate the controller takes, ``|mean| + peak`` within
        the stroke, the tapers at least the shortest and fitting in its length."""
        lo, hi = DRIVE_RATE_RANGE_HZ
        _finite(sample_rate_hz=self.sample_rate_hz)
        if not lo <= self.sample_rate_hz <= hi:
            raise LimitError(f"drive sample rate {self.sample_rate_hz:g} Hz outside {lo:g}..{hi:g} Hz")
        if not 2 <= self.n_samples <= DRIVE_MAX_SAMPLES:
            raise LimitError(f"a drive of {self.n_samples} samples: allowed 2..{DRIVE_MAX_SAMPLES}")
        bad = np.flatnonzero(~np.isfinite(self.samples_mm))
        if bad.size:
            raise LimitError(f"drive sample {bad[0]} is {self.samples_mm[bad[0]]}: not a finite number")
        check_amplitude(limits, self.peak_mm, self.mean_mm)
        check_timing(limits, self.taper_in_s, self.taper_out_s, self.duration_s)

    def registers(self, limits: BenchLimits) -> dict[str, float]:
        """The holding-register values that play the uploaded drive, after :meth:`check`."""
        self.check(limits)
        return {
            "waveform": WaveformCode.DRIVE,
            "taper_in_s": self.taper_in_s,
            "taper_out_s": self.taper_out_s,
            "mean_mm": self.mean_mm,
        }

    def upload_header(self) -> dict[str, float]:
        """The registers that begin its upload."""
        return {"drive_rate_hz": self.sample_rate_hz, "drive_length": self.n_samples}

    def upload_blocks(self) -> Iterator[dict[str, object]]:
        """The upload's requests after its header, in order: each ``drive_offset`` with the
        ``drive_block`` from there (the last one filled up with zeros)."""
        for offset in range(0, self.n_samples, DRIVE_BLOCK_SAMPLES):
            block = np.zeros(DRIVE_BLOCK_SAMPLES, dtype="<f4")
            part = self.samples_mm[offset : offset + DRIVE_BLOCK_SAMPLES]
            block[: part.size] = part
            yield {"drive_offset": offset, "drive_block": block.tolist()}
