"""FRFs from a sine sweep: H1, H2 and coherence from Welch cross-spectra.

``H1 = S_xy / S_xx`` is unbiased by noise on the response, ``H2 = S_yy / S_yx`` by noise on the
reference; their ratio is the coherence ``H1 / H2 = gamma^2``. Segments are Hann-windowed with 50 %
overlap; by default the segment length is the longest power of two that still gives at least
``MIN_AVERAGES`` averages (overridable). The standard uncertainty of a point is
``|H| sqrt((1 - gamma^2) / (gamma^2 n_avg))``.

A bin is *reliable* when it lies in the requested band, the reference carries at least
``energy_floor`` of the band's median power there, and the coherence reaches ``min_coherence``.
A band without any reliable bin raises an error: no number is made up where the sweep put no energy.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy.signal import csd, welch

from bench.analysis.frf import Frf
from bench.analysis.validation import AnalysisInputError, as_sample_rate, as_signals

MIN_AVERAGES = 7


@dataclass(frozen=True)
class SweepFrf:
    """``frf`` (H1 or H2 as chosen, with sigma and the reliable mask) plus both estimators and the
    ``coherence`` per bin; ``n_averages`` Welch segments of ``resolution_hz``."""

    frf: Frf
    h1: np.ndarray
    h2: np.ndarray
    coherence: np.ndarray
    n_averages: int
    resolution_hz: float


def default_segment(n_samples: int) -> int:
    """Longest power-of-two segment with at least ``MIN_AVERAGES`` half-overlapping averages."""
    nperseg = 2 ** int(np.floor(np.log2(max(2 * n_samples / (MIN_AVERAGES + 1), 2))))
    return max(nperseg, 16)


def sweep_frfs(
    reference: np.ndarray,
    responses: Mapping[str, np.ndarray],
    fs_hz: float,
    *,
    band_hz: tuple[float, float],
    reference_name: str = "reference",
    nperseg: int | None = None,
    estimator: str = "h1",
    min_coherence: float = 0.9,
    energy_floor: float = 1e-3,
) -> dict[str, SweepFrf]:
    """FRFs of every response channel over ``reference`` (see the module docstring)."""
    fs = as_sample_rate(fs_hz)
    if estimator not in ("h1", "h2"):
        raise AnalysisInputError(f"estimator must be 'h1' or 'h2', got {estimator!r}")
    sig = as_signals({reference_name: reference, **responses}, min_samples=64)
    x = sig.pop(reference_name)
    n = x.size
    seg = default_segment(n) if nperseg is None else int(nperseg)
    if not 16 <= seg <= n:
        raise AnalysisInputError(f"segment of {seg} samples does not fit a record of {n}")
    n_avg = (n - seg) // (seg // 2) + 1
    kw = {"fs": fs, "window": "hann", "nperseg": seg, "noverlap": seg // 2, "detrend": "constant"}
    f, sxx = welch(x, **kw)
    lo, hi = band_hz
    in_band = (f >= lo) & (f <= hi)
    if not in_band.any():
        raise AnalysisInputError(f"band {band_hz} Hz holds no frequency bin (resolution {fs / seg:.3g} Hz)")
    floor = energy_floor * np.median(sxx[in_band])
    out = {}
    for name, y in sig.items():
        _, sxy = csd(x, y, **kw)
        _, syy = welch(y, **kw)
        with np.errstate(divide="ignore", invalid="ignore"):
            h1 = sxy / sxx
            h2 = syy / np.conj(sxy)
            coh = np.abs(sxy) ** 2 / (sxx * syy)
        coh = np.nan_to_num(coh, nan=0.0)
        reliable = in_band & (sxx >= floor) & (coh >= min_coherence)
        if not reliable.any():
            raise AnalysisInputError(f"{name}: no bin in {band_hz} Hz with excitation energy and coherence")
        value = np.where(in_band, h1 if estimator == "h1" else h2, np.nan)
        with np.errstate(divide="ignore", invalid="ignore"):
            sigma = np.abs(value) * np.sqrt((1 - coh) / (coh * n_avg))
        keep = in_band
        frf = Frf(f[keep], value[keep], sigma[keep], reliable[keep], name, reference_name)
        out[name] = SweepFrf(frf, h1[keep], h2[keep], coh[keep], n_avg, fs / seg)
    return out
