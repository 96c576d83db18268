"""FRFs from a sine sweep: H1 or H2 (chosen per FRF from the data), and coherence, by Welch.

``H1 = S_xy / S_xx`` is unbiased by noise on the response ``y`` and biased low by noise on the
reference ``x`` (``H1 = H / (1 + N_x / S_xx,true)``); ``H2 = S_yy / S_yx`` is the opposite
(``H2 = H (1 + N_y / S_yy,true)``). Their ratio is the coherence ``H1 / H2 = gamma^2``, which is
symmetric and so cannot tell which channel is noisy. Segments are Hann-windowed with 50 % overlap;
by default the segment length is the longest power of two that still gives at least
``MIN_AVERAGES`` averages (overridable). The standard uncertainty of a point is
``|H| sqrt((1 - gamma^2) / (gamma^2 n_avg))``.

**Choice of estimator** (``estimator="auto"``, the default; ``"h1"``/``"h2"`` override it): per
FRF, the relative bias each estimator would have is judged from the channels' noise densities
``N`` against their in-band spectra: ``e_x = N_x / (S_xx - N_x)`` (H1's bias) and
``e_y = N_y / (S_yy - N_y)`` (H2's), medians over the excited in-band bins. H2 is chosen when
``e_x > e_y`` (the reference is the noisier channel), H1 otherwise. The noise densities are the
known sensor floors when given (``noise_psd``, one-sided, units^2/Hz: white noise of rms ``s`` at
sample rate ``fs`` is ``2 s^2 / fs``), otherwise the median of each channel's own spectrum in
``noise_band_hz`` (default ``(2 f_max, 0.4 fs)``: above the sweep and its second harmonic, below the
anti-alias roll-off), where a band-limited sweep leaves only noise. Without either, ``"auto"``
raises rather than guess.

A bin is *reliable* when it lies in the requested band, the reference carries at least
``energy_floor`` of the band's median power there, the coherence reaches ``min_coherence``, and the
excitation of that bin arrived at least half a segment after the record's start and before its
end. The last condition is specific to swept excitation: a bin swept in the first (last) half
segment is seen by one segment only, on its window's flank, where windowing the response and
windowing the excitation are not interchangeable; H1 is then biased by tens of percent while the
coherence, from a single effective average, stays near one. The excitation time of each bin is the
energy centroid of the reference's short-window spectrogram (segment / 8), so broadband excitation
(centroid mid-record) is unaffected. A band without any reliable bin raises an error: no number is
made up where the sweep put no energy.

**Ratio of two responses** (:func:`sweep_ratio`, ``N / D`` of two channels recorded over the same
sweep, e.g. F_WFS / F_contact): not the ratio of two Welch FRFs. Each Welch segment's Hann window
weighs a bin by where the sweep crossed it: a bin swept 1 s into the first 8 s segment gets a
window of 0.14, so the excitation of the sweep's first and last bins is largely thrown away, and
the window's spectral spread makes each segment see neighbouring frequencies (the coherence drops
below one without noise, and a ratio that changes with frequency is biased: up to 12 % at the top
of the paper's sweep). The ratio is instead an instrumental-variable estimate on the whole record's
DFT (rectangular window, the record's ends ramped over ``END_RAMP_S`` so that its periodic extension
has no step): ``H = sum Z* N / sum Z* D`` over the fine bins of each Welch bin, the reference ``Z``
as the instrument (its own noise then enters neither ``N`` nor ``D``). Its standard uncertainty is
``sigma^2 = s^2 sum |Z|^2 / |sum Z* D|^2`` with ``s^2`` the residual power of ``N - H D``
(``N``'s noise plus ``|H|^2`` times ``D``'s), estimated per bin from a ratio linear in frequency over
the three Welch bins around it. Checked over seeds on the four-post plant (tests): coverage of the
exact ratio and sigma over the actual scatter near 1 from the flank to the middle of the band.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from bench.analysis.frf import Frf
from bench.analysis.validation import AnalysisInputError, as_sample_rate, as_signals

MIN_AVERAGES = 7
ESTIMATORS = ("auto", "h1", "h2")
#: Fewest noise-band bins from which a channel's noise floor is estimated.
MIN_NOISE_BINS = 8
#: Short spectrogram segments for the excitation time of each bin: a fraction of the Welch segment.
TIME_RESOLUTION_DIVISOR = 8
#: Cosine ramp at each end of a record for :func:`sweep_ratio`: long enough that a record cut
#: mid-signal (the compensator's latency) has no step in its periodic extension, short enough not to
#: window the sweep's last bins (on the four-post plant, 0.02 s: bias at most 0.6 % at 0.5-0.7 Hz,
#: coverage 86-90 % above 27.5 Hz; no ramp: 2.4 % and 88-90 %; 0.1 s: 0.5 % and 53-79 %).
END_RAMP_S = 0.02
#: Welch bins on each side whose fine bins estimate a bin's residual noise in :func:`sweep_ratio`.
NOISE_NEIGHBOUR_BINS = 1


@dataclass(frozen=True)
class SweepFrf:
    """``frf`` (the chosen estimator, with sigma and the reliable mask) plus both estimators and the
    ``coherence`` per bin; ``n_averages`` Welch segments of ``resolution_hz``. ``estimator`` is the
    one used (``"h1"`` or ``"h2"``); ``reference_noise_ratio`` and ``response_noise_ratio`` are the
    median ``N/(S - N)`` of reference and response over the excited band (what ``"auto"`` compares;
    NaN when the choice was given). ``flank``: coherent in-band bins swept within half a segment of
    the record's ends (left out of ``frf.reliable``: over ``Z`` they are biased, and their Welch
    power is low, the last segment's window falling over them; a ratio of two responses estimated
    by :func:`sweep_ratio` has no such bias, see :attr:`ratio_usable`)."""

    frf: Frf
    h1: np.ndarray
    h2: np.ndarray
    coherence: np.ndarray
    n_averages: int
    resolution_hz: float
    estimator: str
    reference_noise_ratio: float
    response_noise_ratio: float
    flank: np.ndarray

    @property
    def ratio_usable(self) -> np.ndarray:
        """Bins usable in a ratio with another response of the same sweep estimated by
        :func:`sweep_ratio` (whole record, no segment windows): reliable, or reliable but for the
        sweep's flank, whose bias is the Welch segments'. Measured on the four-post plant,
        F_WFS/F_contact by :func:`sweep_ratio` from 0.49 Hz is within 0.6 % with noise averaged
        out, where each Welch FRF over Z is off by up to 240 % (and their ratio by up to 12 % at
        the sweep's top, where F_WFS/F_contact changes with frequency)."""
        return self.frf.reliable | self.flank


def default_segment(n_samples: int) -> int:
    """Longest power-of-two segment with at least ``MIN_AVERAGES`` half-overlapping averages."""
    nperseg = 2 ** int(np.floor(np.log2(max(2 * n_samples / (MIN_AVERAGES + 1), 2))))
    return max(nperseg, 16)


def _noise_floor(
    name: str, psd: np.ndarray, f: np.ndarray, noise_psd: Mapping[str, float] | None, noise_band: tuple
) -> float:
    """The channel's noise density: given, or the median of its spectrum in the noise band."""
    if noise_psd is not None and name in noise_psd:
        return float(noise_psd[name])
    quiet = (f >= noise_band[0]) & (f <= noise_band[1])
    if quiet.sum() < MIN_NOISE_BINS:
        raise AnalysisInputError(
            f"{name}: no noise floor given and only {int(quiet.sum())} bins in the noise band"
            f" {noise_band} Hz; give noise_psd or choose the estimator ('h1' or 'h2')"
        )
    return float(np.median(psd[quiet]))


def _noise_ratio(psd: np.ndarray, floor: float, excited: np.ndarray) -> float:
    """Median of ``N / (S - N)`` over the excited bins (infinite where the signal is below the noise)."""
    signal = psd[excited] - floor
    with np.errstate(divide="ignore"):
        ratio = np.where(signal > 0, floor / np.where(signal > 0, signal, 1.0), np.inf)
    return float(np.median(ratio))


def _excitation_time_s(
    x: np.ndarray, fs: float, seg: int, f: np.ndarray, gaps_s: Sequence[tuple[float, float]] = ()
) -> np.ndarray:
    """Energy centroid in time of the reference at each frequency ``f`` (short-window spectrogram),
    from the windows that hold no bridged stretch (``gaps_s``: what fills one is no excitation)."""
    from scipy.signal import spectrogram
    short = max(seg // TIME_RESOLUTION_DIVISOR, 16)
    fc, tc, sxx = spectrogram(
        x, fs=fs, window="hann", nperseg=short, noverlap=short - max(short // 4, 1), detrend="constant"
    )
    half_s = 0.5 * short / fs
    for start_s, end_s in gaps_s:
        sxx[:, (tc + half_s > start_s) & (tc - half_s < end_s)] = 0.0
    total = np.sum(sxx, axis=1)
    centroid = np.divide(sxx @ tc, total, out=np.full(fc.size, x.size / (2 * fs)), where=total > 0)
    return np.interp(f, fc, centroid)


def _bridged_bins(
    f: np.ndarray, t_exc: np.ndarray, gaps_s: Sequence[tuple[float, float]], *, fs: float, seg: int
) -> np.ndarray:
    """The bins a bridged stretch of the record spoils: those excited within it (their excitation
    time known to the short spectrogram's window), widened by half the main lobe of a gate of its
    length, ``1 / 2L`` either side, over which the gate spreads what was swept there (the shorter
    the stretch, the wider). Bins the gate's sidelobes spoil further out lose their coherence and
    are left out by the coherence test (``tests/analysis/test_analysis_sweep_lost_frames.py``)."""
    bridged = np.zeros(f.size, bool)
    resolution_s = max(seg // TIME_RESOLUTION_DIVISOR, 16) / fs
    for start_s, end_s in gaps_s:
        near = (t_exc >= start_s - resolution_s) & (t_exc <= end_s + resolution_s)
        if not near.any():  # a stretch shorter than the bins' spacing in time: the nearest bin
            near[np.argmin(np.abs(t_exc - 0.5 * (start_s + end_s)))] = True
        lobe_hz = 0.5 / max(end_s - start_s, 1.0 / fs)
        bridged |= (f >= f[near].min() - lobe_hz) & (f <= f[near].max() + lobe_hz)
    return bridged


def sweep_frfs(
    reference: np.ndarray,
    responses: Mapping[str, np.ndarray],
    fs_hz: float,
    *,
    band_hz: tuple[float, float],
    reference_name: str = "reference",
    nperseg: int | None = None,
    estimator: str = "auto",
    noise_psd: Mapping[str, float] | None = None,
    noise_band_hz: tuple[float, float] | None = None,
    min_coherence: float = 0.9,
    energy_floor: float = 1e-3,
    gaps_s: Sequence[tuple[float, float]] = (),
) -> dict[str, SweepFrf]:
    """FRFs of every response channel over ``reference`` (see the module docstring).

    ``noise_psd`` maps channel names (``reference_name`` and response names) to known one-sided
    noise densities; channels not in it have their floor estimated in ``noise_band_hz``.
    ``gaps_s``: stretches of the record (s) where frames were lost and the record only bridges them
    (:func:`bench.analysis.records.on_true_times`): a bin excited within one (its excitation time
    known to an eighth of a segment, the short spectrogram's window) is neither reliable nor a
    flank bin. Elsewhere a segment over a stretch sees all its channels bridged alike: the
    response's transient at the stretch's edges is what the coherence test judges.
    """
    from scipy.signal import csd, welch
    fs = as_sample_rate(fs_hz)
    if estimator not in ESTIMATORS:
        raise AnalysisInputError(f"estimator must be one of {ESTIMATORS}, got {estimator!r}")
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
    excited = in_band & (sxx >= energy_floor * np.median(sxx[in_band]))
    t_exc = _excitation_time_s(x, fs, seg, f, gaps_s)
    half_seg_s = 0.5 * seg / fs
    covered = (t_exc >= half_seg_s) & (t_exc <= n / fs - half_seg_s)
    bridged = _bridged_bins(f, t_exc, gaps_s, fs=fs, seg=seg)
    noise_band = noise_band_hz or (2.0 * hi, 0.4 * fs)
    out = {}
    for name, y in sig.items():
        _, sxy = csd(x, y, **kw)
        _, syy = welch(y, **kw)
        with np.errstate(divide="ignore", invalid="ignore"):
            h1 = sxy / sxx
            h2 = syy / np.conj(sxy)
            coh = np.abs(sxy) ** 2 / (sxx * syy)
        coh = np.nan_to_num(coh, nan=0.0)
        usable = excited & (coh >= min_coherence) & ~bridged
        reliable = usable & covered
        if not reliable.any():
            raise AnalysisInputError(
                f"{name}: no bin in {band_hz} Hz with excitation energy, coherence and full window coverage"
            )
        chosen, ref_ratio, resp_ratio = estimator, np.nan, np.nan
        if estimator == "auto":
            ref_floor = _noise_floor(reference_name, sxx, f, noise_psd, noise_band)
            ref_ratio = _noise_ratio(sxx, ref_floor, excited)
            resp_ratio = _noise_ratio(syy, _noise_floor(name, syy, f, noise_psd, noise_band), excited)
            chosen = "h2" if ref_ratio > resp_ratio else "h1"
        value = np.where(in_band, h1 if chosen == "h1" else h2, np.nan)
        with np.errstate(divide="ignore", invalid="ignore"):
            sigma = np.abs(value) * np.sqrt((1 - coh) / (coh * n_avg))
        keep = in_band
        frf = Frf(f[keep], value[keep], sigma[keep], reliable[keep], name, reference_name)
        out[name] = SweepFrf(
            frf,
            h1[keep],
            h2[keep],
            coh[keep],
            n_avg,
            fs / seg,
            chosen,
            float(ref_ratio),
            float(resp_ratio),
            (in_band & (coh >= min_coherence) & ~covered & ~bridged)[keep],
        )
    return out


def _bands(f: np.ndarray, centres: np.ndarray, half_width: float) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the ascending fine bins ``f`` in ``[centre - half_width, centre + half_width)``
    for each centre, one row each padded to the longest, and the mask of those inside."""
    lo, hi = np.searchsorted(f, centres - half_width), np.searchsorted(f, centres + half_width)
    index = lo[:, None] + np.arange(max(int(np.max(hi - lo, initial=0)), 1))
    return np.minimum(index, f.size - 1), index < hi[:, None]


def sweep_ratio(
    reference: np.ndarray,
    numerator: np.ndarray,
    denominator: np.ndarray,
    fs_hz: float,
    *,
    freq_hz: np.ndarray,
    resolution_hz: float,
    denominator_per_reference: Callable[[np.ndarray], np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``numerator / denominator`` at the bins ``freq_hz`` (width ``resolution_hz``, e.g. a
    :class:`SweepFrf`'s) and its standard uncertainty, by the reference as instrument on the whole
    record (see the module docstring). ``denominator_per_reference(freq_hz)``: a known FRF whose
    product with the reference is added to the denominator (the plate-mass term of a contact force,
    ``m_comp w^2``). Returns ``(value, sigma)``."""
    fs = as_sample_rate(fs_hz)
    channels = {"reference": reference, "numerator": numerator, "denominator": denominator}
    sig = as_signals(channels, min_samples=64)
    n = sig["reference"].size
    ramp = min(round(END_RAMP_S * fs), n // 4)
    window = np.ones(n)
    if ramp > 0:
        rise = 0.5 - 0.5 * np.cos(np.pi * (np.arange(ramp) + 0.5) / ramp)
        window[:ramp], window[n - ramp :] = rise, rise[::-1]
    f = np.fft.rfftfreq(n, 1.0 / fs)
    z, num, den = (np.fft.rfft((x - np.mean(x)) * window) for x in sig.values())
    if denominator_per_reference is not None:
        den = den + np.asarray(denominator_per_reference(f)) * z
    centres = np.asarray(freq_hz, dtype=float)
    half = 0.5 * resolution_hz
    wide_half = (1 + 2 * NOISE_NEIGHBOUR_BINS) * half
    # the fine bins ascend: each bin's band [lo, hi) of them, padded to the longest (mask: inside)
    group, in_group = _bands(f, centres, half)
    cross = np.sum(np.conj(z[group]) * den[group] * in_group, axis=1)
    found = in_group.any(axis=1) & (cross != 0)
    value = np.full(centres.size, np.nan, complex)
    value[found] = np.sum(np.conj(z[group]) * num[group] * in_group, axis=1)[found] / cross[found]
    # noise: the residual of num = (a + b x) den over the bin and its neighbours, x = (f - centre)
    # over the half-width (least squares by its 2x2 normal equations, well conditioned: x is
    # nearly symmetric about 0)
    wide, in_wide = _bands(f, centres, wide_half)
    n_wide = in_wide.sum(axis=1)
    short = found & (n_wide <= 2)
    if short.any():
        raise AnalysisInputError(
            f"{int(n_wide[short][0])} fine bins around {centres[short][0]:g} Hz cannot estimate the noise:"
            " the record is too short for the resolution"
        )
    d, y = den[wide] * in_wide, num[wide] * in_wide
    x = (f[wide] - centres[:, None]) / wide_half
    d2 = np.abs(d) ** 2
    g00, g01, g11 = np.sum(d2, axis=1), np.sum(x * d2, axis=1), np.sum(x**2 * d2, axis=1)
    r0, r1 = np.sum(np.conj(d) * y, axis=1), np.sum(x * np.conj(d) * y, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        det = g00 * g11 - g01**2
        a, b = (g11 * r0 - g01 * r1) / det, (g00 * r1 - g01 * r0) / det
        residual_power = np.sum(np.abs(y - (a[:, None] + b[:, None] * x) * d) ** 2, axis=1) / (n_wide - 2)
        noise = np.sqrt(residual_power * np.sum(np.abs(z[group] * in_group) ** 2, axis=1)) / np.abs(cross)
    sigma = np.where(found, noise, np.nan)
    return value, sigma
