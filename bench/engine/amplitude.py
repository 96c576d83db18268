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
