"""Hammer test of the bare sensor (paper, section 2.2 and Figure 3): eigenfrequency, damping ratio
by two independent methods, and the stiffness from the known sensor mass.

The free decay starts when the hammer has let go (the hammer force back below 1 % of its peak, or
the response's largest peak without a hammer channel) and ends where its envelope sinks to five
times the noise measured before the blow.

- Half-power: the decay's spectrum (zero-padded FFT) peaks at the damped frequency; the bandwidth
  between the points at half the peak power gives ``zeta = (f2 - f1) / (2 f_peak)``.
- Logarithmic decrement: the decay, band-limited-interpolated eightfold so that the peaks of a
  2 kHz vibration sampled at 10 kHz are found, has peaks ``x_i``; a straight line through
  ``ln x_i`` over time gives the decay rate ``sigma``, ``delta = sigma T_d`` and
  ``zeta = delta / sqrt(4 pi^2 + delta^2)``.

Undamped eigenfrequency ``f_n = f_d / sqrt(1 - zeta^2)`` (zeta from the decrement), stiffness
``k = m (2 pi f_n)^2`` and damping ``d = 2 zeta sqrt(k m)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.analysis.validation import AnalysisInputError, as_sample_rate, as_signal

#: Band-limited interpolation factor: a 2 kHz ring sampled at 10 kHz has 5 samples per period, so a
#: sampled peak can miss the true one by up to cos(36 deg) = 19 %; eightfold leaves 0.3 %.
UPSAMPLING = 8
#: The decay ends where its envelope sinks to this many times the pre-blow noise rms (Gaussian noise
#: exceeds 5 sigma once in 1.7 million samples: what lies above is the decay).
NOISE_MULTIPLE = 5.0
#: The hammer has let go when its force is back below this fraction of its peak (the pulse's tail:
#: the structure then rings freely, while a larger residual contact would still drive it).
RELEASE_FRACTION = 0.01
#: Without a hammer channel, the decay starts at the response's largest peak; the pre-blow noise is
#: taken from the record up to this long before it (the blow's rise, a fraction of a millisecond,
#: stays out).
PRE_BLOW_GAP_S = 0.002
#: Fewest pre-blow samples for a noise rms known to about 20 % (1 / sqrt(2 n)).
MIN_NOISE_SAMPLES = 16
#: A decay must start at least this many noise rms above the noise to carry a few decades of decay
#: between its start and the end at ``NOISE_MULTIPLE``.
MIN_SIGNAL_TO_NOISE = 20.0
#: Peaks used by the decrement lie above this multiple of NOISE_MULTIPLE times the noise (near the
#: noise floor the largest of signal plus noise is biased upwards, flattening the decay) and above
#: this fraction of the largest peak (a fiftieth: the well-resolved part of the decay).
PEAK_NOISE_FACTOR = 4.0
PEAK_FRACTION = 0.02
#: Successive decay peaks are one damped period apart; 0.7 of it keeps noise wiggles from counting
#: as peaks while tolerating the interpolation's jitter.
PEAK_SPACING_PERIODS = 0.7
#: Largest relative difference of the two damping estimates before the result is flagged: each is
#: required within 10 % of the truth, so two sound estimates differ by at most about 20 %.
DAMPING_AGREEMENT = 0.2


@dataclass(frozen=True)
class HammerResult:
    """``eigenfrequency_hz`` (undamped) and ``damped_frequency_hz``; damping ratios by half-power
    and by logarithmic decrement; ``stiffness_n_per_m`` and ``damping_ns_per_m`` from the sensor
    mass; ``n_peaks`` used by the decrement; ``decay_start_s``/``decay_stop_s`` of the analysed free decay."""

    eigenfrequency_hz: float
    damped_frequency_hz: float
    damping_ratio_half_power: float
    damping_ratio_log_decrement: float
    stiffness_n_per_m: float
    damping_ns_per_m: float
    n_peaks: int
    decay_start_s: float
    decay_stop_s: float

    @property
    def damping_ratio_disagreement(self) -> float:
        """Relative difference of the two damping ratios, ``|zeta_hp / zeta_ld - 1|``."""
        return abs(self.damping_ratio_half_power / self.damping_ratio_log_decrement - 1)


def _half_power(x: np.ndarray, fs: float) -> tuple[float, float]:
    from scipy.signal import peak_widths
    n_fft = 1 << int(np.ceil(np.log2(max(64 * x.size, 1 << 16))))
    p = np.abs(np.fft.rfft(x, n_fft)) ** 2
    f = np.fft.rfftfreq(n_fft, 1 / fs)
    k = int(np.argmax(p[1:])) + 1
    if k >= p.size - 1:
        raise AnalysisInputError("the spectrum peaks at the Nyquist frequency: sample faster")
    # parabolic refinement of the peak on the log power
    a, b, c = np.log(p[k - 1 : k + 2])
    shift = 0.5 * (a - c) / (a - 2 * b + c)
    f_peak = f[k] + shift * (f[1] - f[0])
    half = 0.5 * np.exp(b - 0.25 * (a - c) * shift)
    # the half-power crossings, linearly interpolated between bins: peak_widths measured at
    # p[k] - (p[k] - half), the whole spectrum as the peak's base
    base = (np.array([p[k] - half]), np.array([0]), np.array([p.size - 1]))
    _, _, left, right = peak_widths(p, [k], rel_height=1.0, prominence_data=base)
    if left[0] <= 0 or right[0] >= p.size - 1:
        raise AnalysisInputError("half-power points not found: the resonance is not resolved")
    df = f[1] - f[0]
    f1, f2 = left[0] * df, right[0] * df
    return float(f_peak), float((f2 - f1) / (2 * f_peak))


def analyse_hammer_decay(
    response_n: np.ndarray, fs_hz: float, sensor_mass_kg: float, *, hammer_n: np.ndarray | None = None
) -> HammerResult:
    """Analyse a hammer test record (see the module docstring)."""
    from scipy.signal import find_peaks, resample
    fs = as_sample_rate(fs_hz)
    x = as_signal("response", response_n, min_samples=64)
    if sensor_mass_kg <= 0:
        raise AnalysisInputError("sensor mass must be positive")
    if hammer_n is not None:
        h = as_signal("hammer", hammer_n, min_samples=x.size)
        if h.size != x.size:
            raise AnalysisInputError("hammer and response channels have different lengths")
        hit = int(np.argmax(np.abs(h)))
        after = np.flatnonzero(np.abs(h[hit:]) < RELEASE_FRACTION * np.abs(h[hit]))
        if after.size == 0:
            raise AnalysisInputError("the hammer force never returns to zero: no free decay")
        start = hit + int(after[0])
        pre = x[: max(hit - 2, 0)]
    else:
        start = int(np.argmax(np.abs(x)))
        pre = x[: max(start - int(PRE_BLOW_GAP_S * fs), 0)]
    if pre.size < MIN_NOISE_SAMPLES:
        raise AnalysisInputError(
            f"at least {MIN_NOISE_SAMPLES} samples before the blow are needed for the noise level"
        )
    noise = float(np.std(pre))
    peak = float(np.max(np.abs(x[start:])))
    if peak <= MIN_SIGNAL_TO_NOISE * noise:
        raise AnalysisInputError(f"the response ({peak:.3g}) barely rises above the noise ({noise:.3g})")
    above = np.flatnonzero(np.abs(x[start:]) > NOISE_MULTIPLE * noise)
    stop = start + int(above[-1]) + 1
    decay = x[start:stop] - np.mean(pre)
    if decay.size < 16:
        raise AnalysisInputError("the free decay is too short to analyse")
    f_d, zeta_hp = _half_power(decay, fs)

    # Interpolate from quiet to quiet (before the blow to past the decay): an FFT interpolation of a
    # segment that starts mid-vibration would ring from the wrap-around jump.
    first = max(start - 4 * int(np.ceil(fs / f_d)), 0)
    last = min(stop + 4 * int(np.ceil(fs / f_d)), x.size)
    fine = resample(x[first:last] - np.mean(pre), (last - first) * UPSAMPLING)
    t = np.arange(fine.size) / (fs * UPSAMPLING)
    # peaks well above the noise only: near the noise floor the largest of signal-plus-noise is biased
    # upwards, which would flatten the decay
    floor = max(PEAK_NOISE_FACTOR * NOISE_MULTIPLE * noise, PEAK_FRACTION * float(np.max(fine)))
    idx, _ = find_peaks(fine, height=floor, distance=int(PEAK_SPACING_PERIODS * fs * UPSAMPLING / f_d))
    idx = idx[t[idx] >= (start - first) / fs]
    if idx.size < 3:
        raise AnalysisInputError(f"only {idx.size} decay peaks above the noise: no logarithmic decrement")
    slope = np.polyfit(t[idx], np.log(fine[idx]), 1)[0]
    delta = -slope / f_d
    zeta_ld = float(delta / np.sqrt(4 * np.pi**2 + delta**2))
    f_n = f_d / np.sqrt(1 - zeta_ld**2)
    k = sensor_mass_kg * (2 * np.pi * f_n) ** 2
    return HammerResult(
        eigenfrequency_hz=float(f_n),
        damped_frequency_hz=f_d,
        damping_ratio_half_power=zeta_hp,
        damping_ratio_log_decrement=zeta_ld,
        stiffness_n_per_m=float(k),
        damping_ns_per_m=float(2 * zeta_ld * np.sqrt(k * sensor_mass_kg)),
        n_peaks=int(idx.size),
        decay_start_s=start / fs,
        decay_stop_s=stop / fs,
    )
