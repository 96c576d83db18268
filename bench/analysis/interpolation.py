"""Reading an FRF between its measured points, and how far that reading is from a known truth.

A stepped-sine FRF is known at its dwells only; in between it is read by linear interpolation of
the magnitude in dB and of the unwrapped phase in degrees over frequency (the refinement of an
adaptive grid estimates the error of exactly this reading). With a closed-form truth, e.g. the
plant's exact response, the largest errors of that reading over a band and the error of the peak
(the largest measured point against the true maximum) tell how well a grid covered the response.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.analysis.validation import AnalysisInputError


def interpolate_frf(freq_hz: np.ndarray, value: np.ndarray, at_hz: np.ndarray) -> np.ndarray:
    """The FRF at ``at_hz`` (within the measured range) interpolated linearly in dB and phase."""
    order = np.argsort(freq_hz)
    f = np.asarray(freq_hz, float)[order]
    h = np.asarray(value, complex)[order]
    if f.size < 2 or np.any(np.diff(f) <= 0) or np.any(h == 0) or not np.all(np.isfinite(h)):
        raise AnalysisInputError(
            "interpolation needs two or more distinct frequencies with finite, non-zero values"
        )
    at = np.asarray(at_hz, float)
    if at.min() < f[0] or at.max() > f[-1]:
        raise AnalysisInputError(
            f"{at.min():g}-{at.max():g} Hz is outside the measured {f[0]:g}-{f[-1]:g} Hz"
        )
    db = np.interp(at, f, 20 * np.log10(np.abs(h)))
    phase = np.interp(at, f, np.unwrap(np.angle(h)))
    return 10 ** (db / 20) * np.exp(1j * phase)


@dataclass(frozen=True)
class GridError:
    """Errors of a measured grid against the truth: the largest magnitude (dB) and phase (degrees)
    error of the interpolated FRF over the band, and of the peak: the largest measured magnitude
    against the true maximum, relative (``peak_height``) and in frequency (``peak_hz``, Hz)."""

    max_db: float
    max_deg: float
    peak_height: float
    peak_hz: float
    true_peak_hz: float
    measured_peak_hz: float


def grid_error(freq_hz: np.ndarray, value: np.ndarray, truth_hz: np.ndarray, truth: np.ndarray) -> GridError:
    """Compare measured points with the truth sampled densely at ``truth_hz`` (the band)."""
    at = np.asarray(truth_hz, float)
    true = np.asarray(truth, complex)
    read = interpolate_frf(freq_hz, value, at)
    err_db = np.abs(20 * np.log10(np.abs(read) / np.abs(true)))
    err_deg = np.abs(np.degrees(np.angle(read / true)))
    mag = np.abs(np.asarray(value, complex))
    i, k = int(np.argmax(mag)), int(np.argmax(np.abs(true)))
    measured_hz = float(np.asarray(freq_hz, float)[i])
    return GridError(
        float(err_db.max()),
        float(err_deg.max()),
        float(mag[i] / np.abs(true[k]) - 1),
        measured_hz - float(at[k]),
        float(at[k]),
        measured_hz,
    )
