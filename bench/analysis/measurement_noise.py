"""A sensor's white noise as the measurement itself shows it: the level of its spectrum above the
band the compensation takes from it (docs/analysis.md, *The band's noise*).

The compensation's filters roll off to zero at ``STOP_BAND_FACTOR`` times their design band
(:mod:`bench.analysis.fir`): what the measurement holds above that is not in the compensated force,
and on a wheel it is the sensors' noise (the tyre and the wheel pass next to no contact force there).
Its density, taken as white, is the noise the band must carry through the filters. A contact force
that does reach up there counts as noise: the band only widens. The band of the estimate ends below
where a logger's anti-alias filter rolls off (:data:`NOISE_BAND_END_FRACTION` of the rate, or the
logger's stated bandwidth), where the noise is no longer what passes the filters.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import welch

from bench.analysis.blockwise import Record
from bench.analysis.fir import STOP_BAND_FACTOR
from bench.analysis.validation import AnalysisInputError

#: The band of the estimate ends at this fraction of the sample rate: an acquisition's anti-alias
#: filter is flat below it and rolls off above it toward half the rate.
NOISE_BAND_END_FRACTION = 0.3
#: Welch segments of the estimate (s): 4 Hz bins.
NOISE_SEGMENT_S = 0.25
#: The narrowest band an estimate is made over (Hz): ten bins of :data:`NOISE_SEGMENT_S` segments.
MIN_NOISE_BAND_HZ = 10 / NOISE_SEGMENT_S
#: Samples per block of the estimate: its memory stays a few blocks whatever the record's length.
NOISE_BLOCK = 1 << 16
#: The most blocks an estimate reads, evenly spread over a long record: 16 blocks of 0.25 s segments
#: average about 8000 segments, which leave a white density's mean over ten bins within 0.4 % (one
#: standard deviation), so more only costs time (an hour at 1 kHz holds 55 blocks).
NOISE_MAX_BLOCKS = 16


def noise_band_hz(
    design_band_hz: float, fs_hz: float, bandwidth_hz: float | None = None
) -> tuple[float, float]:
    """Where a measurement at ``fs_hz`` shows its sensors' noise for filters designed to
    ``design_band_hz``: from their stop band to :data:`NOISE_BAND_END_FRACTION` of the rate, or to
    the logger's ``bandwidth_hz`` below that (a low rate or a narrow logger leaves less than
    :data:`MIN_NOISE_BAND_HZ`, or nothing: :func:`estimable`)."""
    hi = NOISE_BAND_END_FRACTION * fs_hz
    if bandwidth_hz is not None:
        hi = min(hi, bandwidth_hz)
    return STOP_BAND_FACTOR * design_band_hz, hi


def estimable(band_hz: tuple[float, float]) -> bool:
    """Whether ``band_hz`` is wide enough for an estimate (:data:`MIN_NOISE_BAND_HZ`)."""
    return band_hz[1] - band_hz[0] >= MIN_NOISE_BAND_HZ


def white_noise_rms(x: Record, fs_hz: float, band_hz: tuple[float, float]) -> float:
    """The rms per sample of the white noise whose density ``x`` shows in ``band_hz``: its Welch
    density averaged over the band's bins, ``S``, as ``sqrt(S fs / 2)`` (a white noise of rms
    ``sigma`` has the one-sided density ``2 sigma^2 / fs``). The mean, not the median, of the bins:
    unbiased for noise, and a spectral line only widens the band. The density is averaged over
    blocks of :data:`NOISE_BLOCK` samples, at most :data:`NOISE_MAX_BLOCKS` spread evenly over the
    record (a last block shorter than a segment is left out), weighted by their length; only
    those blocks are read (``x``: an array, or a record on disk read by slice)."""
    lo, hi = band_hz
    if not 0 <= lo < hi <= fs_hz / 2:
        raise AnalysisInputError(f"noise band {lo:g}-{hi:g} Hz does not lie within 0-{fs_hz / 2:g} Hz")
    n_segment = min(round(NOISE_SEGMENT_S * fs_hz), x.size)
    means, sizes = [], []
    starts = range(0, x.size, NOISE_BLOCK)
    chosen = np.unique(
        np.linspace(0, len(starts) - 1, min(len(starts), NOISE_MAX_BLOCKS)).round().astype(int)
    )
    for start in (starts[i] for i in chosen):
        block = np.asarray(x[start : start + NOISE_BLOCK], dtype=float)
        if block.size < n_segment:
            continue
        f, density = welch(block, fs=fs_hz, nperseg=n_segment)
        inside = (f >= lo) & (f <= hi)
        if not inside.any():
            raise AnalysisInputError(f"noise band {lo:g}-{hi:g} Hz holds no bin of a {x.size}-sample record")
        means.append(np.mean(density[inside]))
        sizes.append(block.size)
    return float(np.sqrt(np.average(means, weights=sizes) * fs_hz / 2))
