"""Excitation setpoints, checked against the bench's limit envelope before any write.

The envelope (:class:`~sequences.limits.BenchLimits`, the same one the sequences were validated
against) is the software's own, tighter than the controller's hardware limits: a setpoint outside it
raises :class:`LimitError` and nothing reaches the controller.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from drivers.errors import LimitError
from drivers.register_map import WaveformCode
from sequences.limits import BenchLimits


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
