"""Sine-dwell analysis: the phasor of every channel at the excitation frequency.

The analysed window is the latest whole number of excitation cycles inside ``[start_s, stop_s]``
(the caller passes the hold phase; settling time goes at its start). Each channel is fitted by
linear least squares with an offset, the fundamental and harmonics 2..n below the Nyquist frequency,
all channels sharing one design matrix. The residual gives the noise level and, through the
covariance of the least-squares coefficients, the standard uncertainty of the fundamental phasor.

Settling is checked by fitting the first and the last half of the window separately: a channel has
settled when its fundamental changed by no more than ``5 sigma`` of the difference plus
``settle_tolerance`` of its amplitude, and the residual of the first half is not larger than that
of the second beyond what noise explains (a decaying free vibration). The residual test is an F
test of the two halves' residual variances at a stated false-alarm rate, ``SETTLING_FALSE_ALARM``
per dwell (shared among its channels), with degrees of freedom reduced for noise correlated from
sample to sample (the acquisition's anti-alias filter): ``n (1 - rho^2) / (1 + rho^2)`` for a
lag-1 correlation ``rho``, the variance estimate's effective sample size. A fixed ratio (1.5x)
flagged about 3 good two-cycle dwells per grid of 22, whose halves have a handful of degrees of
freedom.

**True sample times.** A record whose frames were lost on the link is not a contiguous run of time:
``sample_offsets`` (each sample's offset in sample times from the record's first, from the frame
counter: :func:`bench.numerics.sine_fit.frame_offsets`) place every sample at its true time, the
window is chosen in time (its whole cycles counted in sample times, the lost ones included), and the
design is built on those times (:func:`bench.numerics.sine_fit.sine_design`), so a gap costs samples,
never a shift of phase. The noise near the fundamental is then estimated from the residual as white
(a periodogram needs evenly spaced samples), and the fit notes how many frames its window missed.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from bench.analysis.frf import Frf, phasor_ratio
from bench.analysis.validation import AnalysisInputError, as_sample_rate, as_signals
from bench.numerics.sine_fit import harmonic_phasors, sine_design

#: Fewest periodogram bins the noise density at a dwell's frequency is averaged over (the nearest
#: ones when fewer lie within 25 % of it): 8 complex bins, 16 degrees of freedom, so the density is
#: known to about 25 % (one sigma) even for a window of two cycles.
MIN_NOISE_BINS = 8
#: The fewest degrees of freedom a phasor's noise estimate has (:data:`MIN_NOISE_BINS` complex bins;
#: a window too short for them is taken as white, over more samples than that): what a test of a
#: fit's chi^2 against these uncertainties assumes of them (:func:`bench.analysis.lsq.chi2_exceedance`).
NOISE_ESTIMATE_DOF = 2 * MIN_NOISE_BINS
#: Probability that a settled dwell (stationary noise) is flagged by the residual test, all its
#: channels together.
SETTLING_FALSE_ALARM = 0.01
#: ... and it must have grown by at least this much: in long windows the F test alone flagged a growth
#: of a few ten percent from the non-linear tyre's slow settling, harmless to the fundamental.
MIN_RESIDUAL_GROWTH = 1.5
DRIFT_SIGMAS = 5.0


@dataclass(frozen=True)
class ChannelFit:
    """Least-squares sine fit of one channel over the analysed window (channel units).

    ``amplitude``: complex phasor of the fundamental, ``x = Re(A exp(j w t))`` with ``t`` from the
    record's first sample; ``amplitude_sigma``: its standard uncertainty; ``harmonics``: phasors of
    harmonics 2, 3, ... (those below Nyquist); ``offset``: mean value; ``residual_rms``: rms of what
    the fit leaves; ``thd``: total harmonic distortion, ``sqrt(sum |harmonics|^2) / |amplitude|``;
    ``drift``: change of the fundamental between the window's halves over its amplitude;
    ``settled``: the verdict of the module's settling test.
    """

    amplitude: complex
    amplitude_sigma: float
    harmonics: np.ndarray
    offset: float
    residual_rms: float
    thd: float
    drift: float
    settled: bool


@dataclass(frozen=True)
class DwellFit:
    """All channels of one dwell at ``freq_hz`` over ``n_cycles`` whole cycles from ``start_s`` to
    ``stop_s``. ``settled`` is true when every channel settled; ``notes`` explain any doubt;
    ``frames_missing`` of the window's sample times had no frame (lost on the link)."""

    freq_hz: float
    n_cycles: int
    start_s: float
    stop_s: float
    channels: dict[str, ChannelFit]
    settled: bool
    notes: tuple[str, ...]
    frames_missing: int = 0

    def ratio(self, output: str, input: str) -> tuple[complex, float]:
        """FRF point ``output / input`` and its standard uncertainty."""
        a, b = self.channels[output], self.channels[input]
        h, s = phasor_ratio(a.amplitude, a.amplitude_sigma, b.amplitude, b.amplitude_sigma)
        return complex(h), float(s)


@dataclass(frozen=True)
class _Fit:
    coef: np.ndarray  # (p, channels)
    residual_rms: np.ndarray
    fundamental_sigma: np.ndarray
    residual_lag1: np.ndarray  # lag-1 correlation of the residual, per channel
    dof: int


def _fit_window(
    t: np.ndarray, y: np.ndarray, w: float, n_harm: int, X: np.ndarray, *, contiguous: bool = True
) -> _Fit:
    """Least-squares fit of ``y`` (samples x channels) at times ``t`` with ``X`` the design of ``t``
    (the rows of a longer window's design are the same numbers); ``contiguous``: ``t`` is evenly
    spaced (no frame lost), so the noise near the fundamental can be taken from a periodogram."""
    from scipy.linalg import solve_triangular  # loaded where the analysis first fits

    w_dt = w * (t[1] - t[0]) if t.size > 1 else 0.0
    # QR instead of the normal equations: (X'X)^-1 = R^-1 R^-T without squaring X's condition
    q, r = np.linalg.qr(X)
    coef = solve_triangular(r, q.T @ y)
    res = y - X @ coef
    dof = max(t.size - X.shape[1], 1)
    square_sum = np.sum(res**2, axis=0)
    variance = _local_noise_variance(res, w_dt, n_harm, t.size / dof) if contiguous else None
    if variance is None:  # white noise: the diagonal of (X'X)^-1 times the residual variance
        r_inv = solve_triangular(r, np.eye(r.shape[0]))
        variance = square_sum / dof * (np.sum(r_inv[1] ** 2) + np.sum(r_inv[2] ** 2))
    lag1 = np.sum(res[1:] * res[:-1], axis=0) / np.maximum(square_sum, 1e-300)
    return _Fit(coef, np.sqrt(square_sum / t.size), np.sqrt(variance), lag1, dof)


def _residual_growth_limit(fit: _Fit, half: _Fit, n_channels: int) -> np.ndarray:
    """Largest ratio of the first half's residual rms to the last half's that stationary noise
    exceeds with probability ``SETTLING_FALSE_ALARM / n_channels`` (F test, effective dof), and
    at least ``MIN_RESIDUAL_GROWTH``."""
    from scipy.special import fdtri  # loaded where the analysis first fits

    rho = np.clip(fit.residual_lag1, 0.0, 0.95)
    dof = np.maximum(half.dof * (1 - rho**2) / (1 + rho**2), 1.0)
    quantile = np.sqrt(fdtri(dof, dof, 1 - SETTLING_FALSE_ALARM / n_channels))
    return np.maximum(quantile, MIN_RESIDUAL_GROWTH)


def _local_noise_variance(res: np.ndarray, w_dt: float, n_harm: int, dof_factor: float) -> np.ndarray | None:
    """``E|dA|^2 = 2 G(f) / T`` from the residual's one-sided PSD ``G`` near the fundamental.

    Sensor noise is not white after the acquisition's anti-alias filter (and rarely is in a lab):
    the fundamental's error depends on the noise density at the excitation frequency only. ``G`` is
    averaged over the periodogram bins within 25 % of the fundamental, except DC and the bins of the
    fitted components, and over at least the :data:`MIN_NOISE_BINS` such bins nearest to it: a
    window of few cycles (a low-frequency dwell, a settling test's half window) has few bins near
    its fundamental, and taking the whole residual as white would understate the noise there by
    the share of the band the anti-alias filter removes. ``None`` when the window has fewer than
    :data:`MIN_NOISE_BINS` bins besides the fitted components.
    """
    n = res.shape[0]
    spec = np.fft.rfft(res, axis=0)
    k = np.arange(spec.shape[0])
    cycles = w_dt * n / (2 * np.pi)  # the fundamental's bin (whole cycles in the window)
    eligible = (k > 0) & (k < n // 2)
    for h in range(1, n_harm + 1):
        eligible &= np.abs(k - h * cycles) > 1.5
    if eligible.sum() < MIN_NOISE_BINS:
        return None
    distance = np.where(eligible, np.abs(k - cycles), np.inf)
    nearest = np.argsort(distance, kind="stable")[:MIN_NOISE_BINS]
    near = eligible & (distance <= 0.25 * cycles)
    near[nearest] = True
    # |R_k|^2 / n estimates the two-sided density times fs; E|dA|^2 = 2 G / T = 4 S / n^2 * n.
    density = np.mean(np.abs(spec[near]) ** 2, axis=0) / n
    return 4.0 * density / n * dof_factor


def fit_dwell(
    channels: Mapping[str, np.ndarray],
    fs_hz: float,
    freq_hz: float,
    *,
    start_s: float = 0.0,
    stop_s: float | None = None,
    n_harmonics: int = 3,
    settle_tolerance: float = 0.005,
    sample_offsets: np.ndarray | None = None,
) -> DwellFit:
    """Fit every channel of a dwell record at ``freq_hz`` (see the module docstring);
    ``sample_offsets``: each sample's true offset in sample times from the first (None: the
    samples are contiguous).

    Raises :class:`AnalysisInputError` for NaNs, mismatched lengths, a frequency at or above
    Nyquist, or a window shorter than one cycle.
    """
    fs = as_sample_rate(fs_hz)
    data = as_signals(channels)
    if not 0 < freq_hz < fs / 2:
        raise AnalysisInputError(f"dwell frequency {freq_hz} Hz outside (0, {fs / 2}) Hz")
    if n_harmonics < 1:
        raise AnalysisInputError("n_harmonics must be at least 1")
    n_total = next(iter(data.values())).size
    at = _sample_offsets(sample_offsets, n_total)
    n_harm = max(1, min(n_harmonics, int(np.ceil(fs / 2 / freq_hz)) - 1))
    k0, k_end, n_cycles = _window(at, fs, freq_hz, start_s, stop_s)
    n_samples = k_end - k0
    inside = (at >= k0) & (at < k_end)
    present = int(np.count_nonzero(inside))
    if present < 2 * (2 * n_harm + 1):
        raise AnalysisInputError(f"dwell window of {present} samples is too short to fit")
    contiguous = present == n_samples
    names = list(data)
    y = np.stack([data[n][inside] for n in names], axis=1)
    t, w = at[inside] / fs, 2 * np.pi * freq_hz
    X = sine_design(t, freq_hz, n_harm)  # the halves' designs are its rows
    full = _fit_window(t, y, w, n_harm, X, contiguous=contiguous)
    a1 = harmonic_phasors(full.coef, 1)
    harm = np.array([harmonic_phasors(full.coef, k) for k in range(2, n_harm + 1)]).reshape(
        n_harm - 1, len(names)
    )

    notes: list[str] = []
    if not contiguous:
        notes.append(
            f"{n_samples - present} of the window's {n_samples} frames lost on the link"
            f" ({100 * (n_samples - present) / n_samples:.1f} %): fitted on the frames' true times"
        )
    halves = _halves(t, (k0 / fs, k_end / fs), n_cycles, freq_hz, fs=fs, min_samples=2 * (2 * n_harm + 1))
    settled, drift, settle_notes = _settling(
        full,
        (t, y, X),
        halves,
        freq_hz,
        names=names,
        settle_tolerance=settle_tolerance,
        contiguous=contiguous,
    )
    notes += settle_notes

    fits = {}
    for i, name in enumerate(names):
        amp = complex(a1[i])
        thd = float(np.sqrt(np.sum(np.abs(harm[:, i]) ** 2)) / abs(amp)) if amp != 0 else float("nan")
        fits[name] = ChannelFit(
            amplitude=amp,
            amplitude_sigma=float(full.fundamental_sigma[i]),
            harmonics=harm[:, i].copy(),
            offset=float(full.coef[0, i]),
            residual_rms=float(full.residual_rms[i]),
            thd=thd,
            drift=float(drift[i]),
            settled=bool(settled[i]),
        )
    return DwellFit(
        freq_hz=float(freq_hz),
        n_cycles=n_cycles,
        start_s=k0 / fs,
        stop_s=(k_end - 1) / fs,
        channels=fits,
        settled=bool(np.all(settled)),
        notes=tuple(notes),
        frames_missing=n_samples - present,
    )


def _halves(
    t: np.ndarray,
    window_s: tuple[float, float],
    n_cycles: int,
    freq_hz: float,
    *,
    fs: float,
    min_samples: int,
) -> tuple[np.ndarray, np.ndarray] | None:
    """The samples of the window's first and last ``n_cycles // 2`` whole cycles (in time), or None
    when it holds fewer than two cycles or a half fewer than ``min_samples`` frames."""
    if n_cycles < 2:
        return None
    half_s = (n_cycles // 2) / freq_hz
    early, late = t < window_s[0] + half_s - 0.5 / fs, t >= window_s[1] - half_s - 0.5 / fs
    return (early, late) if min(early.sum(), late.sum()) >= min_samples else None


def _settling(
    full: _Fit,
    window: tuple[np.ndarray, np.ndarray, np.ndarray],
    halves: tuple[np.ndarray, np.ndarray] | None,
    freq_hz: float,
    *,
    names: list[str],
    settle_tolerance: float,
    contiguous: bool,
) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """The settling test of the module docstring on the halves of ``window`` (times, samples x
    channels, design): per channel whether it settled and its drift, and notes that explain a doubt."""
    if halves is None:
        note = "fewer than 2 cycles of frames in the window: settling cannot be verified"
        return np.zeros(len(names), bool), np.full(len(names), np.nan), [note]
    t, y, X = window
    w, n_harm = 2 * np.pi * freq_hz, (X.shape[1] - 1) // 2
    first, last = (_fit_window(t[h], y[h], w, n_harm, X[h], contiguous=contiguous) for h in halves)
    a1 = harmonic_phasors(full.coef, 1)
    diff = np.abs(harmonic_phasors(last.coef, 1) - harmonic_phasors(first.coef, 1))
    sigma_diff = np.hypot(first.fundamental_sigma, last.fundamental_sigma)
    amp_ok = diff <= DRIFT_SIGMAS * sigma_diff + settle_tolerance * np.abs(a1)
    limit = _residual_growth_limit(full, first, len(names))
    res_ok = first.residual_rms <= limit * last.residual_rms + 1e-12 * np.max(np.abs(y), axis=0)
    drift = np.divide(diff, np.abs(a1), out=np.zeros_like(diff), where=np.abs(a1) > 0)
    notes = []
    for i, name in enumerate(names):
        if not amp_ok[i]:
            notes.append(f"{name}: fundamental drifted by {100 * drift[i]:.2f} % within the window")
        if not res_ok[i]:
            notes.append(f"{name}: residual decays within the window (free vibration not settled)")
    return amp_ok & res_ok, drift, notes


def _window(
    at: np.ndarray, fs: float, freq_hz: float, start_s: float, stop_s: float | None
) -> tuple[int, int, int]:
    """The analysed window in sample times, ``(first, end, cycles)``: the latest whole cycles from
    ``start_s`` (or the first sample) to ``stop_s`` (or the last), whatever is missing inside."""
    last = int(at[-1]) + 1 if at.size else 0
    first = max(int(np.ceil(start_s * fs - 1e-9)), int(at[0]) if at.size else 0)
    end = last if stop_s is None else min(int(np.floor(stop_s * fs + 1e-9)) + 1, last)
    span_s = (end - first) / fs
    n_cycles = int(np.floor(span_s * freq_hz + 1e-9))
    if n_cycles < 1:
        raise AnalysisInputError(
            f"dwell window {span_s:.3f} s holds less than one cycle at {freq_hz} Hz (record too short)"
        )
    return end - round(n_cycles * fs / freq_hz), end, n_cycles


def _sample_offsets(sample_offsets: np.ndarray | None, n: int) -> np.ndarray:
    """The samples' offsets in sample times (contiguous when None), checked to rise."""
    if sample_offsets is None:
        return np.arange(n, dtype=np.int64)
    k = np.asarray(sample_offsets, dtype=np.int64)
    if k.shape != (n,):
        raise AnalysisInputError(f"{k.size} sample offsets for {n} samples")
    if n > 1 and np.any(np.diff(k) <= 0):
        raise AnalysisInputError("sample offsets do not rise from sample to sample")
    return k


def dwell_phasors(fits: Sequence[DwellFit], channel: str) -> tuple[np.ndarray, np.ndarray]:
    """One channel's phasors over a grid of dwells (sorted by frequency) and their standard
    uncertainties."""
    if not fits:
        raise AnalysisInputError("no dwells given")
    ch = [d.channels[channel] for d in sorted(fits, key=lambda d: d.freq_hz)]
    return np.array([c.amplitude for c in ch]), np.array([c.amplitude_sigma for c in ch])


def dwell_frf(fits: Sequence[DwellFit], output: str, input: str) -> Frf:
    """The FRF ``output / input`` over a grid of dwells (sorted by frequency); a dwell that did not
    settle gives an unreliable point."""
    if not fits:
        raise AnalysisInputError("no dwells given")
    ordered = sorted(fits, key=lambda d: d.freq_hz)
    points = [d.ratio(output, input) for d in ordered]
    return Frf(
        freq_hz=np.array([d.freq_hz for d in ordered]),
        value=np.array([p[0] for p in points]),
        sigma=np.array([p[1] for p in points]),
        reliable=np.array([d.settled for d in ordered]),
        output=output,
        input=input,
    )
