"""How well a compensated force follows the true contact force on a road: rms errors per band, the
share of samples inside the 95 % band, and the measured-over-true ratio over frequency.

Band-limited quantities are taken from the record's DFT (a brick-wall mask: no filter transient, and
Parseval makes the rms of a band exact): ``band_rms(x, lo, hi)`` is the rms of the part of ``x``
between ``lo`` (inclusive) and ``hi`` (exclusive). Octaves are the ISO 266 ones, ``f_c / sqrt 2`` to
``f_c sqrt 2``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.analysis.validation import AnalysisInputError

#: The band of the rms error the paper's four-post results are judged in (Hz).
ERROR_BAND_HZ = (0.0, 30.0)
#: ISO 266 octave centres (Hz) covering the band up to 30 Hz.
OCTAVE_CENTRES_HZ = (1.0, 2.0, 4.0, 8.0, 16.0, 31.5)
#: Segment of the Welch estimates of the ratios (s): 0.25 Hz bins.
RATIO_SEGMENT_S = 4.0


def band_limited(x: np.ndarray, fs_hz: float, band_hz: tuple[float, float]) -> np.ndarray:
    """``x`` with every DFT bin outside ``[lo, hi)`` removed (``lo = 0`` keeps the mean)."""
    lo, hi = band_hz
    spectrum = np.fft.rfft(x)
    f = np.fft.rfftfreq(x.size, 1 / fs_hz)
    spectrum[(f < lo) | (f >= hi)] = 0
    return np.fft.irfft(spectrum, x.size)


def band_rms(x: np.ndarray, fs_hz: float, band_hz: tuple[float, float]) -> float:
    """The rms of ``x``'s part in ``[lo, hi)`` (Parseval over the DFT bins)."""
    lo, hi = band_hz
    spectrum = np.fft.rfft(x)
    f = np.fft.rfftfreq(x.size, 1 / fs_hz)
    inside = (f >= lo) & (f < hi)
    weight = np.where((f == 0) | ((x.size % 2 == 0) & (f == fs_hz / 2)), 1.0, 2.0)  # bins without a twin
    return float(np.sqrt(np.sum(weight[inside] * np.abs(spectrum[inside]) ** 2)) / x.size)


def octave_band(centre_hz: float) -> tuple[float, float]:
    return centre_hz / np.sqrt(2), centre_hz * np.sqrt(2)


@dataclass(frozen=True)
class ForceErrors:
    """One force's error against the true contact force: ``rms_n`` in :data:`ERROR_BAND_HZ` and
    ``octave_rms_n`` per octave of :data:`OCTAVE_CENTRES_HZ` (N)."""

    rms_n: float
    octave_rms_n: tuple[float, ...]


def force_errors(force_n: np.ndarray, truth_n: np.ndarray, fs_hz: float) -> ForceErrors:
    """:class:`ForceErrors` of ``force_n`` against ``truth_n`` (finite, one length)."""
    error = np.asarray(force_n, dtype=float) - np.asarray(truth_n, dtype=float)
    if not np.all(np.isfinite(error)):
        raise AnalysisInputError(
            "force errors need finite samples: cut the record where the filters are defined"
        )
    return ForceErrors(
        band_rms(error, fs_hz, ERROR_BAND_HZ),
        tuple(band_rms(error, fs_hz, octave_band(c)) for c in OCTAVE_CENTRES_HZ),
    )


def coverage(
    force_n: np.ndarray,
    u95_n: np.ndarray,
    truth_n: np.ndarray,
    fs_hz: float,
    band_hz: tuple[float, float] | None,
) -> float:
    """The share of samples whose true force lies within ``force +/- u95``; with ``band_hz`` both
    forces limited to that band first (the compensation's claim within its valid band), else as
    they are."""
    force, truth = np.asarray(force_n, dtype=float), np.asarray(truth_n, dtype=float)
    if band_hz is not None:
        force, truth = band_limited(force, fs_hz, band_hz), band_limited(truth, fs_hz, band_hz)
    return float(np.mean(np.abs(force - truth) <= u95_n))


def ratio_over_truth(force_n: np.ndarray, truth_n: np.ndarray, fs_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """``F / F_contact`` over frequency (H1 with the true force as the reference: its own noise-free
    signal), Welch segments of :data:`RATIO_SEGMENT_S`; frequencies (Hz) and complex ratios."""
    from scipy.signal import csd, welch

    n = min(round(RATIO_SEGMENT_S * fs_hz), force_n.size)
    f, s_tt = welch(truth_n, fs=fs_hz, nperseg=n)
    _, s_tf = csd(truth_n, force_n, fs=fs_hz, nperseg=n)
    return f[1:], s_tf[1:] / s_tt[1:]


@dataclass(frozen=True)
class RoadValidation:
    """The compensation of one simulated road drive against its true contact force.

    ``identification``: what the compensation rested on; ``valid_band_hz`` its valid band; ``raw``,
    ``hub_compensated`` (``F_wfs + m_wheel a_hub``, the lag undone) and ``model_compensated``: their
    :class:`~bench.analysis.road_validation.ForceErrors`; ``truth_rms_n``: the true force's rms in the
    same band; ``coverage_valid_band``: the share of samples whose true force lies in the 95 % band,
    both limited to the valid band; ``coverage_whole``: the same unfiltered; ``median_u95_n``: the
    band's median half-width; ``noise_wfs_n``: the Fz noise the band carries; ``hub_lag_ms``: the
    accelerometer's lag undone; ``assumptions``: what the compensation assumed, as it says it;
    ``traces``: the signals over the span where the filters are defined
    (``t_s``, ``truth``, ``raw``, ``hub_compensated``, ``model_compensated``, ``u95``, and
    ``error_in_band``: the model-compensated force's error limited to the valid band), for figures."""

    road_class: str
    speed_km_h: float
    identification: str
    valid_band_hz: tuple[float, float]
    raw: ForceErrors
    hub_compensated: ForceErrors
    model_compensated: ForceErrors
    truth_rms_n: float
    coverage_valid_band: float
    coverage_whole: float
    median_u95_n: float
    noise_wfs_n: float
    hub_lag_ms: float
    assumptions: tuple[str, ...]
    traces: dict[str, np.ndarray]
