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
from scipy.signal import find_peaks, resample

from bench.analysis.validation import AnalysisInputError, as_sample_rate, as_signal

UPSAMPLING = 8
NOISE_MULTIPLE = 5.0
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

    def summary_lines(self) -> list[str]:
        """A short report with units; the two damping estimates are flagged when they disagree by
        more than ``DAMPING_AGREEMENT`` (they are independent: one of them is then not to be trusted)."""
        lines = [
            f"hammer: eigenfrequency {self.eigenfrequency_hz:.1f} Hz"
            f" (damped {self.damped_frequency_hz:.1f} Hz), free decay"
            f" {1e3 * self.decay_start_s:.1f}-{1e3 * self.decay_stop_s:.1f} ms, {self.n_peaks} peaks",
            f"damping ratio: half-power {self.damping_ratio_half_power:.4f},"
            f" logarithmic decrement {self.damping_ratio_log_decrement:.4f}",
            f"from the sensor mass: stiffness {self.stiffness_n_per_m:.4g} N/m,"
            f" damping {self.damping_ns_per_m:.4g} Ns/m",
        ]
        if self.damping_ratio_disagreement > DAMPING_AGREEMENT:
            lines.append(
                f"FLAG: the damping ratios disagree by {100 * self.damping_ratio_disagreement:.0f} %"
                f" (more than {100 * DAMPING_AGREEMENT:.0f} %): check the decay (noise, a second mode)"
            )
        return lines


def _half_power(x: np.ndarray, fs: float) -> tuple[float, float]:
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
    lo = k
    while lo > 0 and p[lo] > half:
        lo -= 1
    hi = k
    while hi < p.size - 1 and p[hi] > half:
        hi += 1
    if lo == 0 or hi == p.size - 1:
        raise AnalysisInputError("half-power points not found: the resonance is not resolved")
    f1 = np.interp(half, [p[lo], p[lo + 1]], [f[lo], f[lo + 1]])
    f2 = np.interp(half, [p[hi], p[hi - 1]], [f[hi], f[hi - 1]])
    return float(f_peak), float((f2 - f1) / (2 * f_peak))


def analyse_hammer_decay(
    response_n: np.ndarray, fs_hz: float, sensor_mass_kg: float, *, hammer_n: np.ndarray | None = None
) -> HammerResult:
    """Analyse a hammer test record (see the module docstring)."""
    fs = as_sample_rate(fs_hz)
    x = as_signal("response", response_n, min_samples=64)
    if sensor_mass_kg <= 0:
        raise AnalysisInputError("sensor mass must be positive")
    if hammer_n is not None:
        h = as_signal("hammer", hammer_n, min_samples=x.size)
        if h.size != x.size:
            raise AnalysisInputError("hammer and response channels have different lengths")
        hit = int(np.argmax(np.abs(h)))
        after = np.flatnonzero(np.abs(h[hit:]) < 0.01 * np.abs(h[hit]))
        if after.size == 0:
            raise AnalysisInputError("the hammer force never returns to zero: no free decay")
        start = hit + int(after[0])
        pre = x[: max(hit - 2, 0)]
    else:
        start = int(np.argmax(np.abs(x)))
        pre = x[: max(start - int(0.002 * fs), 0)]
    if pre.size < 16:
        raise AnalysisInputError("at least 16 samples before the blow are needed for the noise level")
    noise = float(np.std(pre))
    peak = float(np.max(np.abs(x[start:])))
    if peak <= 20 * noise:
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
    floor = max(4 * NOISE_MULTIPLE * noise, 0.02 * float(np.max(fine)))
    idx, _ = find_peaks(fine, height=floor, distance=int(0.7 * fs * UPSAMPLING / f_d))
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
