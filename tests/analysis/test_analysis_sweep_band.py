"""Sweep FRFs on synthetic data, the valid band, and garbage in."""

import numpy as np
import pytest
from scipy.signal import butter, freqz, lfilter

from bench.analysis.frf import valid_band
from bench.analysis.sweep import sweep_frfs, sweep_ratio
from bench.analysis.validation import AnalysisInputError

FS = 1000.0


def _sweep(seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(int(40 * FS)) / FS
    x = np.sin(2 * np.pi * (0.5 * t + (20 - 0.5) * t**2 / (2 * 40)))
    y = lfilter([0.5, 0.5], [1.0], x) + 1e-3 * rng.standard_normal(t.size)  # two-tap average
    return x, y


def test_h1_matches_known_filter_in_band():
    """H(f) = 0.5 (1 + e^{-jwT}): the reliable bins must agree to 1 %. The sweep passes 0.5-20 Hz in
    40 s; bins swept within half a segment (4.1 s, 2 Hz of sweep) of either end are on a window
    flank and must be unreliable, every bin in between reliable."""
    x, y = _sweep()
    res = sweep_frfs(x, {"y": y}, FS, band_hz=(1.0, 19.0))["y"]
    frf = res.frf
    truth = 0.5 * (1 + np.exp(-2j * np.pi * frf.freq_hz / FS))
    ok = frf.reliable
    swept_at_s = (frf.freq_hz - 0.5) / (19.5 / 40)
    half_segment_s = 4096 / FS
    assert np.all(ok[(swept_at_s > half_segment_s + 0.5) & (swept_at_s < 40 - half_segment_s - 0.5)])
    assert not np.any(ok[(swept_at_s < half_segment_s - 0.5) | (swept_at_s > 40 - half_segment_s + 0.5)])
    assert res.estimator == "h1"  # the noise is on the response
    np.testing.assert_allclose(frf.value[ok], truth[ok], rtol=0.01)
    assert res.n_averages >= 7 and np.all(res.coherence[ok] > 0.9)


def test_ratio_of_two_responses_holds_to_the_sweeps_ends():
    """A low-pass (second-order Butterworth at 8 Hz) over the two-tap average, both driven by the
    0.5-20 Hz sweep: the exact ratio changes from 1 to 0.18 across the band. Noise-free, the ratio of
    the two Welch FRFs is off by 7.4 % at the sweep's top (the window's spread across a sweeping bin
    does not cancel where the ratio changes with frequency); ``sweep_ratio`` stays within 0.8 %."""
    x, _ = _sweep()
    b, a = butter(2, 8.0, fs=FS)
    num, den = lfilter(b, a, x), lfilter([0.5, 0.5], [1.0], x)
    frfs = sweep_frfs(x, {"num": num, "den": den}, FS, band_hz=(1.0, 19.0), estimator="h1")
    f = frfs["num"].frf.freq_hz
    value, sigma = sweep_ratio(x, num, den, FS, freq_hz=f, resolution_hz=frfs["num"].resolution_hz)
    truth = freqz(b, a, f, fs=FS)[1] / (0.5 * (1 + np.exp(-2j * np.pi * f / FS)))
    welch = frfs["num"].frf.value / frfs["den"].frf.value
    assert np.max(np.abs(welch / truth - 1)) > 0.05
    assert np.max(np.abs(value / truth - 1)) < 0.008
    assert np.all(np.isfinite(sigma)) and np.all(sigma > 0)
    with pytest.raises(AnalysisInputError, match="fine bins around"):
        sweep_ratio(x[:200], num[:200], den[:200], FS, freq_hz=np.array([10.0]), resolution_hz=FS / 400)


def test_band_without_energy_raises():
    x, y = _sweep()
    with pytest.raises(AnalysisInputError, match="no bin"):
        sweep_frfs(x, {"y": y}, FS, band_hz=(100.0, 200.0))


def test_sweep_mismatched_and_nan_raise():
    x, y = _sweep()
    with pytest.raises(AnalysisInputError, match="different lengths"):
        sweep_frfs(x, {"y": y[:-1]}, FS, band_hz=(1.0, 19.0))
    y[100] = np.nan
    with pytest.raises(AnalysisInputError, match="non-finite"):
        sweep_frfs(x, {"y": y}, FS, band_hz=(1.0, 19.0))


def test_valid_band_limits():
    f = np.arange(1.0, 11.0)
    h = np.ones(10, complex)
    assert valid_band(f, h).upper_hz == 10.0 and valid_band(f, h).limited_by == "end of data"
    h[6] = 1.11
    band = valid_band(f, h)
    assert band.upper_hz == 6.0 and band.limited_by == "amplitude"
    h[4] = np.exp(1j * np.radians(10.5))
    assert valid_band(f, h).limited_by == "phase" and valid_band(f, h).upper_hz == 4.0
    reliable = np.ones(10, bool)
    reliable[:2] = False
    reliable[3] = False
    band = valid_band(f, h, reliable)  # one point passes before the next unreliable one: no band
    assert band.lowest_hz == 3.0 and band.limited_by == "unreliable point"
    assert band.n_points == 1 and not band.determined and band.upper_hz == 0.0
    reliable[3] = True
    band = valid_band(f, h, reliable)
    assert band.upper_hz == 4.0 and band.n_points == 2 and band.determined
    assert valid_band(f, h, phase_tolerance_deg=11.0, amplitude_tolerance=0.2).upper_hz == 10.0


def test_valid_band_ignores_points_too_uncertain_to_judge():
    """A leading point whose uncertainty exceeds half the tolerance neither passes nor fails the
    band; a well-determined failing point still ends it."""
    f = np.array([0.5, 1.0, 2.0, 4.0, 8.0])
    h = np.array([1.15, 1.02, 0.99, 1.03, 1.3], dtype=complex)
    sigma = np.array([0.2, 0.01, 0.01, 0.01, 0.01])
    band = valid_band(f, h, sigma=sigma)
    assert (band.lowest_hz, band.upper_hz, band.limited_by) == (1.0, 4.0, "amplitude")
    assert valid_band(f, h).upper_hz == 0.0  # without uncertainty the noisy point decides
    noisy_middle = sigma.copy()
    noisy_middle[2] = 0.2
    assert valid_band(f, h, sigma=noisy_middle).limited_by == "unreliable point"


def _noisy_pair(noise_on: str, seed: int = 1):
    """A reference band-limited to 40 Hz through a known first-order low-pass; white noise (0-500 Hz)
    of the signal's rms on one channel, 1 % on the other."""
    rng = np.random.default_rng(seed)
    n = int(60 * FS)
    x = lfilter(*butter(4, 40.0, fs=FS), rng.standard_normal(n))
    b, a = [0.2], [1.0, -0.8]  # H = 0.2 / (1 - 0.8 e^{-jw/fs})
    y = lfilter(b, a, x)
    big, small = 1.0, 0.01
    xn = x + (big if noise_on == "reference" else small) * np.std(x) * rng.standard_normal(n)
    yn = y + (big if noise_on == "response" else small) * np.std(y) * rng.standard_normal(n)
    return xn, yn, lambda f: 0.2 / (1 - 0.8 * np.exp(-2j * np.pi * f / FS))


@pytest.mark.parametrize(("noise_on", "expected"), [("reference", "h2"), ("response", "h1")])
def test_auto_estimator_picks_the_one_unbiased_by_the_noisy_channel(noise_on, expected):
    """Noise on the reference biases H1 low by 1/(1 + N/S) and leaves H2 unbiased; noise on the
    response does the opposite. Equal rms spread over 500 Hz against a signal in 40 Hz gives
    N/S ~ 8 % in band, a bias of about 7 %. The rule, judging each channel's noise floor above the
    excited band (its noise band starts at 2 f_max = 60 Hz, above the 40 Hz low-pass), must pick the
    unbiased estimator: with 1 s segments (116 averages) its median error, random, stays below 3 %,
    the rejected one's exceeds 5 %."""
    x, y, truth = _noisy_pair(noise_on)
    res = sweep_frfs(x, {"y": y}, FS, band_hz=(2.0, 30.0), nperseg=1024)["y"]
    assert res.estimator == expected
    f, ok = res.frf.freq_hz, res.frf.reliable
    chosen = np.median(np.abs(res.frf.value[ok] / truth(f[ok]) - 1))
    other = res.h1 if expected == "h2" else res.h2
    rejected = np.median(np.abs(other[ok] / truth(f[ok]) - 1))
    assert chosen < 0.03 and rejected > 0.05, (chosen, rejected)
    forced = sweep_frfs(x, {"y": y}, FS, band_hz=(2.0, 30.0), nperseg=1024, estimator="h1")["y"]
    assert forced.estimator == "h1" and np.array_equal(forced.frf.value[ok], res.h1[ok])


def test_known_noise_floors_decide_and_missing_ones_raise():
    """Given sensor floors (white rms s at fs: 2 s^2 / fs) decide even without a quiet band; without
    them and without a quiet band the rule refuses to guess."""
    x, y, _ = _noisy_pair("reference")
    floors = {"reference": 2 * np.var(x) / FS, "y": 2 * (0.01 * np.std(y)) ** 2 / FS}
    res = sweep_frfs(x, {"y": y}, FS, band_hz=(2.0, 30.0), noise_psd=floors, noise_band_hz=(499.9, 500.0))
    assert res["y"].estimator == "h2"
    with pytest.raises(AnalysisInputError, match="noise floor"):
        sweep_frfs(x, {"y": y}, FS, band_hz=(2.0, 30.0), noise_band_hz=(499.9, 500.0))
