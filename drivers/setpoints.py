"""Excitation setpoints and the bench's soft limits they are checked against before any write.

Soft limits are the software's own envelope, tighter than the controller's hardware limits: a
setpoint outside them raises :class:`LimitError` and nothing reaches the controller.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from drivers.errors import LimitError
from drivers.register_map import WaveformCode


@dataclass(frozen=True)
class SoftLimits:
    """The envelope every setpoint must fit in.

    ``displacement_limit_mm`` and ``force_limit_n`` are also written to the controller as its
    interlock thresholds.
    """

    max_amplitude_mm: float = 10.0
    min_frequency_hz: float = 0.1
    max_frequency_hz: float = 100.0
    max_mean_mm: float = 20.0
    displacement_limit_mm: float = 15.0
    force_limit_n: float = 20_000.0
    min_taper_s: float = 0.1
    max_duration_s: float = 3600.0

    def check_interlock(self) -> None:
        """The interlock thresholds written with every setpoint: finite and not negative (the
        controller refuses a negative one, and 0 would mean its hardware limit, not "none")."""
        _finite(displacement_limit_mm=self.displacement_limit_mm, force_limit_n=self.force_limit_n)
        for name in ("displacement_limit_mm", "force_limit_n"):
            if getattr(self, name) <= 0:
                raise LimitError(f"{name}={getattr(self, name)} must be > 0")

    def check_amplitude(self, amplitude_mm: float, mean_mm: float) -> None:
        _finite(amplitude_mm=amplitude_mm, mean_mm=mean_mm)
        if not 0.0 <= amplitude_mm <= self.max_amplitude_mm:
            raise LimitError(f"amplitude_mm={amplitude_mm} outside 0..{self.max_amplitude_mm} mm")
        if abs(mean_mm) > self.max_mean_mm:
            raise LimitError(f"mean_mm={mean_mm} outside ±{self.max_mean_mm} mm")
        if amplitude_mm > self.displacement_limit_mm:
            raise LimitError(
                f"amplitude_mm={amplitude_mm} exceeds the displacement limit {self.displacement_limit_mm} mm"
            )

    def check_frequency(self, name: str, freq_hz: float) -> None:
        _finite(**{name: freq_hz})
        if not self.min_frequency_hz <= freq_hz <= self.max_frequency_hz:
            raise LimitError(f"{name}={freq_hz} outside {self.min_frequency_hz}..{self.max_frequency_hz} Hz")

    def check_timing(self, taper_in_s: float, taper_out_s: float, duration_s: float) -> None:
        """``duration_s`` is the whole excitation (0 means until stopped); the tapers must fit in it."""
        _finite(taper_in_s=taper_in_s, taper_out_s=taper_out_s, duration_s=duration_s)
        for name, value in (("taper_in_s", taper_in_s), ("taper_out_s", taper_out_s)):
            if value < self.min_taper_s:
                raise LimitError(f"{name}={value} below the minimum taper {self.min_taper_s} s")
        if not 0 <= duration_s <= self.max_duration_s:
            raise LimitError(f"duration {duration_s} s outside 0..{self.max_duration_s} s")
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

    def registers(self, limits: SoftLimits) -> dict[str, float]:
        """The holding-register values of this dwell, after checking it against ``limits``."""
        limits.check_amplitude(self.amplitude_mm, self.mean_mm)
        limits.check_frequency("freq_hz", self.freq_hz)
        total = self.taper_in_s + self.dwell_s + self.taper_out_s if self.dwell_s else 0.0
        limits.check_timing(self.taper_in_s, self.taper_out_s, total)
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
class SweepSetpoint:
    """A sine sweep from ``start_hz`` to ``end_hz`` in ``duration_s`` (tapers inside), linear or log."""

    start_hz: float
    end_hz: float
    duration_s: float
    amplitude_mm: float
    spacing: str = "linear"
    taper_in_s: float = 1.0
    taper_out_s: float = 1.0
    mean_mm: float = 0.0

    def registers(self, limits: SoftLimits) -> dict[str, float]:
        """The holding-register values of this sweep, after checking it against ``limits``."""
        if self.spacing not in ("linear", "log"):
            raise LimitError(f"spacing={self.spacing!r} must be 'linear' or 'log'")
        limits.check_amplitude(self.amplitude_mm, self.mean_mm)
        limits.check_frequency("start_hz", self.start_hz)
        limits.check_frequency("end_hz", self.end_hz)
        if self.duration_s <= 0:
            raise LimitError(f"duration_s={self.duration_s} must be > 0")
        limits.check_timing(self.taper_in_s, self.taper_out_s, self.duration_s)
        code = WaveformCode.LINEAR_SWEEP if self.spacing == "linear" else WaveformCode.LOG_SWEEP
        return {
            "waveform": code,
            "amplitude_mm": self.amplitude_mm,
            "sweep_start_hz": self.start_hz,
            "sweep_end_hz": self.end_hz,
            "sweep_duration_s": self.duration_s,
            "taper_in_s": self.taper_in_s,
            "taper_out_s": self.taper_out_s,
            "mean_mm": self.mean_mm,
        }
