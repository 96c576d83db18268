"""The bench's limit envelope, declared once: what a sequence is validated against before anything
moves, what the dry run checks the bench model's loads against, what the actuator client checks
every setpoint against before it writes one (and writes to the controller as its interlock
thresholds), and what the engine's interlocks trip on.

The bench configuration provides one :class:`BenchLimits`; the defaults are those of the simulated
shaker bench. Kinematic limits (stroke, velocity, acceleration, frequency range, timing) are checked
by the sequence validator from the steps alone; the force limits (actuator and WFS) need a model of
what stands on the bench and are checked by the dry run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: Gauge pressures (bar) a car tyre on the bench plausibly has: the range the shipped sequences'
#: pressure prompts accept, and what an imported campaign's stated pressure is checked against.
TYRE_PRESSURE_RANGE_BAR = (0.5, 4.5)
#: The sample rates (Hz) of a drive the actuator controller plays (a road replay's drive file): it
#: interpolates linearly between samples; below 100 Hz a road's band does not fit, 10 kHz is the
#: controller's own rate. And the most samples a drive may have (the controller's drive memory).
DRIVE_RATE_RANGE_HZ = (100.0, 10_000.0)
DRIVE_MAX_SAMPLES = 1 << 22


#: Each controller interlock threshold and the host limit it must lie above.
INTERLOCKS_ABOVE = (("displacement_interlock_mm", "stroke_mm"), ("force_interlock_n", "force_n"))


@dataclass(frozen=True, slots=True)
class BenchLimits:
    """Peak values a step may demand of the bench.

    - ``stroke_mm``: the largest peak displacement, ``|mean_mm| + amplitude_mm``.
    - ``velocity_mm_s``, ``acceleration_m_s2``: peak plate velocity and acceleration of a sine,
      ``2 pi f A`` and ``(2 pi f)^2 A``; a sweep is checked at its highest frequency.
    - ``force_n``: the actuator's peak dynamic force (plate force, plate mass included).
    - ``min_freq_hz``, ``max_freq_hz``: the excitation frequency range.
    - ``wfs_force_n``: the WFS's vertical load range (dynamic amplitude plus static load).
    - ``min_taper_s``: the shortest taper the controller accepts; ``max_step_s``: the longest
      excitation one setpoint may ask for (the controller's dwell/sweep duration registers).
    - ``max_capture_s``: the longest triggered capture the WFS acquisition can buffer (hammer test).
    - ``displacement_interlock_mm``, ``force_interlock_n``: the thresholds the controller trips its
      own interlock on (written with every setpoint), above ``stroke_mm`` and ``force_n``, which the
      engine's host-side interlocks trip on.
    """

    stroke_mm: float = 25.0
    velocity_mm_s: float = 1600.0
    acceleration_m_s2: float = 550.0
    force_n: float = 15_000.0
    min_freq_hz: float = 0.1
    max_freq_hz: float = 100.0
    wfs_force_n: float = 24_000.0
    min_taper_s: float = 0.1
    max_step_s: float = 3600.0
    max_capture_s: float = 2.0
    displacement_interlock_mm: float = 30.0
    force_interlock_n: float = 20_000.0

    def __post_init__(self) -> None:
        for name in self.__slots__:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                raise ValueError(f"BenchLimits.{name} must be a finite number, got {value!r}")
            if value <= 0:
                raise ValueError(f"BenchLimits.{name} must be > 0, got {value}")
        if self.min_freq_hz >= self.max_freq_hz:
            raise ValueError(f"BenchLimits: min_freq_hz {self.min_freq_hz} >= max_freq_hz {self.max_freq_hz}")
        for interlock, limit in INTERLOCKS_ABOVE:
            if getattr(self, interlock) <= getattr(self, limit):
                raise ValueError(
                    f"BenchLimits: {interlock} {getattr(self, interlock)} must be above {limit}"
                    f" {getattr(self, limit)} (the controller's trip lies beyond the host's)"
                )


def peak_velocity_mm_s(freq_hz: float, amplitude_mm: float) -> float:
    """Peak velocity of a sine of ``amplitude_mm`` at ``freq_hz``: 2 pi f A."""
    return 2 * math.pi * freq_hz * amplitude_mm


def peak_acceleration_m_s2(freq_hz: float, amplitude_mm: float) -> float:
    """Peak acceleration of a sine of ``amplitude_mm`` at ``freq_hz``: (2 pi f)^2 A."""
    return (2 * math.pi * freq_hz) ** 2 * amplitude_mm * 1e-3
