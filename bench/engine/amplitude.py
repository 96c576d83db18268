"""Amplitude control: the achieved displacement amplitude against the commanded one.

A servo-hydraulic actuator does not reach the commanded amplitude exactly: the oil column, the valve
and the specimen's load change its gain with frequency. After each dwell the engine measures the
achieved amplitude on the displacement channel; beyond the tolerance the command is scaled by the
ratio of target to achieved (the inverse of the gain just measured at this very point) and the point
is repeated, a bounded number of times. Commanded, corrected and achieved amplitudes are recorded.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: The command is never scaled by more than this factor in one correction (a broken displacement
#: channel must not drive the actuator to its limits).
MAX_CORRECTION_FACTOR = 1.5


@dataclass(frozen=True)
class AmplitudeDecision:
    """``keep``: the point stands; otherwise repeat it with ``corrected_mm``. ``note`` says why."""

    keep: bool
    corrected_mm: float | None
    error: float  # (achieved - target) / target
    note: str = ""


@dataclass(frozen=True)
class AmplitudeControl:
    """``tolerance``: relative amplitude error accepted; ``max_corrections``: repeats per point;
    ``max_command_mm``: the largest command the soft limits allow."""

    tolerance: float = 0.02
    max_corrections: int = 3
    max_command_mm: float = float("inf")

    def decide(
        self, target_mm: float, commanded_mm: float, achieved_mm: float, corrections: int
    ) -> AmplitudeDecision:
        error = (achieved_mm - target_mm) / target_mm
        if abs(error) <= self.tolerance:
            return AmplitudeDecision(True, None, error)
        if not np.isfinite(achieved_mm) or achieved_mm <= 0:
            return AmplitudeDecision(True, None, error, "no displacement measured: amplitude not corrected")
        if corrections >= self.max_corrections:
            return AmplitudeDecision(
                True, None, error, f"amplitude {100 * error:+.1f} % after {corrections} corrections"
            )
        factor = float(np.clip(target_mm / achieved_mm, 1 / MAX_CORRECTION_FACTOR, MAX_CORRECTION_FACTOR))
        corrected = commanded_mm * factor
        if corrected > self.max_command_mm:
            return AmplitudeDecision(
                True,
                None,
                error,
                f"amplitude {100 * error:+.1f} %: the correction to {corrected:.3f} mm exceeds the"
                f" {self.max_command_mm:g} mm limit",
            )
        return AmplitudeDecision(False, corrected, error)


def achieved_amplitude_mm(displacement_m: np.ndarray, sample_rate_hz: float, freq_hz: float) -> float:
    """The fundamental's amplitude (mm) at ``freq_hz`` over the latest whole cycles of
    ``displacement_m`` (least squares on sine, cosine and offset); NaN when it holds no whole cycle."""
    n_cycles = int(np.floor(len(displacement_m) * freq_hz / sample_rate_hz + 1e-9))
    if n_cycles < 1:
        return float("nan")
    n = round(n_cycles * sample_rate_hz / freq_hz)
    window = np.asarray(displacement_m[len(displacement_m) - n :], dtype=float)
    phase = 2 * np.pi * freq_hz * np.arange(n) / sample_rate_hz
    design = np.column_stack([np.sin(phase), np.cos(phase), np.ones(n)])
    (a, b, _), *_ = np.linalg.lstsq(design, window, rcond=None)
    return 1e3 * float(np.hypot(a, b))


class ServoGains:
    """The actuator's gain (achieved over commanded amplitude) measured last at each frequency, to
    start a new point with the command that reaches its target: the gain changes slowly with
    frequency (and amplitude), so the gain interpolated from the points already run (the nearest
    one's beyond them) saves most repeats when an adaptive grid adds points between its
    frequencies or runs its next amplitude."""

    def __init__(self) -> None:
        self._gain: dict[float, float] = {}

    def record(self, freq_hz: float, commanded_mm: float, achieved_mm: float) -> None:
        if np.isfinite(achieved_mm) and achieved_mm > 0 and commanded_mm > 0:
            self._gain[freq_hz] = achieved_mm / commanded_mm

    def command_mm(self, freq_hz: float, target_mm: float) -> float:
        """The command expected to achieve ``target_mm`` at ``freq_hz`` (the target when no gain is
        known yet), never scaled by more than :data:`MAX_CORRECTION_FACTOR`."""
        if not self._gain:
            return target_mm
        freqs = sorted(self._gain)
        gain = float(np.interp(freq_hz, freqs, [self._gain[f] for f in freqs]))
        factor = float(np.clip(1.0 / gain, 1 / MAX_CORRECTION_FACTOR, MAX_CORRECTION_FACTOR))
        return target_mm * factor
