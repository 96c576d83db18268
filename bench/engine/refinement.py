"""Grid refinement of an adaptive stepped sine: where to add the next dwell, and why.

Between measured points the FRF is read by linear interpolation of its magnitude in dB and its
(unwrapped) phase in degrees over frequency. The error of that reading in an interval is estimated
at its middle as the largest difference between the straight line and the parabolas through the
interval's ends and either neighbour (the curvature the measured points show). The next point is:

1. **model peak**: a single-mode resonance ``1 / |H|^2 = a f^4 + b f^2 + c`` through the largest
   measured magnitude and its two neighbours predicts the peak at ``f^2 = -b / 2a``; when that lies
   between the neighbours and farther than ``min_spacing_hz`` from every measured point, a point
   goes there (the peak is what a fixed grid misses);
2. else **steep**: the middle of the interval with the largest estimated error beyond the targets
   (``interpolation_db``, ``interpolation_deg``), if the interval is wider than twice
   ``min_spacing_hz``;
3. else none: the grid is fine enough (or the caller's budget is spent).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from sequences import AdaptiveDwell


@dataclass(frozen=True)
class AddedPoint:
    """A frequency to measure next and why (``reason`` for people and the points table)."""

    freq_hz: float
    reason: str


def _parabola_at(x: np.ndarray, y: np.ndarray, at: float) -> float:
    return float(np.polyval(np.polyfit(x, y, 2), at))


def interpolation_errors(freqs_hz: np.ndarray, frf: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Estimated errors (dB, degrees) of linear interpolation at the middle of each interval of the
    sorted ``freqs_hz``; zero where no neighbour gives a parabola (fewer than three points)."""
    f = np.asarray(freqs_hz, float)
    db = 20 * np.log10(np.abs(frf))
    deg = np.degrees(np.unwrap(np.angle(frf)))
    n = f.size
    err_db, err_deg = np.zeros(max(n - 1, 0)), np.zeros(max(n - 1, 0))
    for j in range(n - 1):
        mid = 0.5 * (f[j] + f[j + 1])
        for lo in (j - 1, j):
            if lo < 0 or lo + 3 > n:
                continue
            sl = slice(lo, lo + 3)
            err_db[j] = max(err_db[j], abs(_parabola_at(f[sl], db[sl], mid) - 0.5 * (db[j] + db[j + 1])))
            err_deg[j] = max(err_deg[j], abs(_parabola_at(f[sl], deg[sl], mid) - 0.5 * (deg[j] + deg[j + 1])))
    return err_db, err_deg


def predicted_peak_hz(freqs_hz: np.ndarray, frf: np.ndarray) -> float | None:
    """The single-mode resonance's peak through the largest |H| and its neighbours (None: the
    largest is at an end of the grid, or the three points show no peak)."""
    mag = np.abs(frf)
    i = int(np.argmax(mag))
    if i == 0 or i == len(mag) - 1:
        return None
    x = np.asarray(freqs_hz[i - 1 : i + 2], float) ** 2
    a, b, _ = np.polyfit(x, 1.0 / mag[i - 1 : i + 2] ** 2, 2)
    if a <= 0:
        return None
    x_peak = -b / (2 * a)
    if not x[0] < x_peak < x[2]:
        return None
    return float(np.sqrt(x_peak))


def next_point(freqs_hz: Sequence[float], frf: Sequence[complex], plan: AdaptiveDwell) -> AddedPoint | None:
    """The next point to measure given the FRF points so far (any order), or None."""
    order = np.argsort(freqs_hz)
    f = np.asarray(freqs_hz, float)[order]
    h = np.asarray(frf, complex)[order]
    keep = np.isfinite(h) & (h != 0)
    f, h = f[keep], h[keep]
    if f.size < 3:
        return None
    peak = predicted_peak_hz(f, h)
    if peak is not None and np.min(np.abs(f - peak)) > plan.min_spacing_hz:
        return AddedPoint(round(peak, 3), f"model peak: a single-mode fit puts the peak at {peak:.2f} Hz")
    err_db, err_deg = interpolation_errors(f, h)
    score = np.maximum(err_db / plan.interpolation_db, err_deg / plan.interpolation_deg)
    score[np.diff(f) <= 2 * plan.min_spacing_hz] = 0.0
    j = int(np.argmax(score))
    if score[j] <= 1.0:
        return None
    mid = round(float(0.5 * (f[j] + f[j + 1])), 3)
    return AddedPoint(
        mid,
        f"steep: interpolating {f[j]:g}-{f[j + 1]:g} Hz errs about {err_db[j]:.2f} dB / {err_deg[j]:.1f} deg",
    )
