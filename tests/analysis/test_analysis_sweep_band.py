"""Sweep FRFs on synthetic data, the valid band, and garbage in."""

import numpy as np
import pytest
from scipy.signal import lfilter

from bench.analysis.frf import valid_band
from bench.analysis.sweep import sweep_frfs
from bench.analysis.validation import AnalysisInputError

FS = 1000.0


def _sweep(seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(int(40 * FS)) / FS
    x = np.sin(2 * np.pi * (0.5 * t + (20 - 0.5) * t**2 / (2 * 40)))
    y = lfilter([0.5, 0.5], [1.0], x) + 1e-3 * rng.standard_normal(t.size)  # two-tap average
    return x, y


def test_h1_matches_known_filter_in_band():
    """H(f) = 0.5 (1 + e^{-jwT}): the reliable bins must agree to 1 %."""
    x, y = _sweep()
    res = sweep_frfs(x, {"y": y}, FS, band_hz=(1.0, 19.0))["y"]
    frf = res.frf
    truth = 0.5 * (1 + np.exp(-2j * np.pi * frf.freq_hz / FS))
    ok = frf.reliable
    assert ok.mean() > 0.9
    np.testing.assert_allclose(frf.value[ok], truth[ok], rtol=0.01)
    assert res.n_averages >= 7 and np.all(res.coherence[ok] > 0.9)


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
    band = valid_band(f, h, reliable)
    assert band.lowest_hz == 3.0 and band.upper_hz == 3.0 and band.limited_by == "unreliable point"
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
