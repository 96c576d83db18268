"""Sine-dwell fit on synthetic records with known phasors and seeded noise."""

import numpy as np
import pytest

from bench.analysis.dwell import dwell_frf, fit_dwell
from bench.analysis.validation import AnalysisInputError

FS = 1000.0


def _record(freq_hz, phasors, noise, seed, *, duration_s=3.0, harmonics=None):
    rng = np.random.default_rng(seed)
    t = np.arange(round(duration_s * FS)) / FS
    out = {}
    for name, a in phasors.items():
        x = np.real(a * np.exp(2j * np.pi * freq_hz * t)) + 0.3
        for k, ak in (harmonics or {}).get(name, {}).items():
            x = x + np.real(ak * np.exp(2j * np.pi * k * freq_hz * t))
        out[name] = x + noise[name] * rng.standard_normal(t.size)
    return out


@pytest.mark.parametrize("freq_hz", [0.5, 3.3, 17.0, 41.7, 99.0])
def test_phasors_harmonics_and_offset_recovered(freq_hz):
    """Noise-free: the fit is exact to rounding, whatever the frequency (0.5-100 Hz at 1 kHz)."""
    a, h2 = 2e-3 * np.exp(0.7j), 1e-4 * np.exp(-0.2j)
    duration = max(3.0, 4.2 / freq_hz)
    rec = _record(freq_hz, {"z": a}, {"z": 0.0}, 0, duration_s=duration, harmonics={"z": {2: h2}})
    fit = fit_dwell(rec, FS, freq_hz)
    ch = fit.channels["z"]
    assert abs(ch.amplitude - a) < 1e-12
    if 2 * freq_hz < FS / 2:
        assert abs(ch.harmonics[0] - h2) < 1e-12
        assert ch.thd == pytest.approx(abs(h2) / abs(a), rel=1e-9)
    assert ch.offset == pytest.approx(0.3, abs=1e-12)
    assert fit.settled
    assert fit.n_cycles >= 2


def test_uncertainty_covers_true_error():
    """With white noise, the complex error is circular Gaussian with E|e|^2 = sigma^2: it exceeds
    3 sigma with probability exp(-9); and sigma itself must not be inflated (median error ~ 0.83 sigma)."""
    h_true = 3.0 * np.exp(-1.2j)
    z = 1e-3 * np.exp(0.3j)
    errors = []
    for seed in range(60):
        rec = _record(23.0, {"z": z, "f": h_true * z}, {"z": 2e-5, "f": 1e-4}, seed)
        fit = fit_dwell(rec, FS, 23.0, start_s=0.5)
        h, s = fit.ratio("f", "z")
        errors.append(abs(h - h_true) / s)
    errors = np.array(errors)
    assert np.mean(errors <= 3) >= 0.95
    assert 0.6 < np.median(errors) < 1.1


def test_unsettled_dwell_is_flagged():
    """A free vibration decaying over the window (a dwell analysed too early) is not settled."""
    freq = 12.0
    t = np.arange(3000) / FS
    z = 1e-3 * np.sin(2 * np.pi * freq * t)
    f = 400 * z + 0.5 * np.exp(-t / 0.6) * np.sin(2 * np.pi * 31.0 * t)
    fit = fit_dwell({"z": z, "f": f}, FS, freq)
    assert not fit.settled
    assert not fit.channels["f"].settled and fit.channels["z"].settled
    assert any("f:" in n for n in fit.notes)


def test_amplitude_ramp_is_flagged():
    t = np.arange(4000) / FS
    z = 1e-3 * (1 + 0.2 * t) * np.sin(2 * np.pi * 8.0 * t)
    fit = fit_dwell({"z": z}, FS, 8.0)
    assert not fit.settled and fit.channels["z"].drift > 0.1


def test_dwell_frf_marks_unsettled_points_unreliable():
    t = np.arange(3000) / FS
    fits = []
    for freq, grow in ((5.0, 0.0), (2.0, 0.3)):
        z = 1e-3 * (1 + grow * t) * np.sin(2 * np.pi * freq * t)
        fits.append(fit_dwell({"z": z, "f": -2 * z}, FS, freq))
    frf = dwell_frf(fits, "f", "z")
    assert list(frf.freq_hz) == [2.0, 5.0]
    assert list(frf.reliable) == [False, True]
    np.testing.assert_allclose(frf.value, -2.0, rtol=1e-9)


def test_one_cycle_cannot_be_verified():
    t = np.arange(2500) / FS
    fit = fit_dwell({"z": np.sin(2 * np.pi * 0.5 * t)}, FS, 0.5)
    assert fit.n_cycles == 1 and not fit.settled
    assert "cannot be verified" in fit.notes[0]


@pytest.mark.parametrize(
    ("channels", "kwargs", "match"),
    [
        ({"z": np.r_[np.zeros(10), np.nan, np.zeros(989)]}, {}, "non-finite"),
        ({"z": np.zeros(1000), "f": np.zeros(999)}, {}, "different lengths"),
        ({"z": np.zeros(100)}, {"freq_hz": 2.0}, "less than one cycle"),
        ({"z": np.zeros(1000)}, {"freq_hz": 600.0}, "outside"),
        ({"z": np.zeros(1000)}, {"start_s": 0.9, "freq_hz": 2.0}, "less than one cycle"),
        ({}, {}, "no channels"),
    ],
)
def test_garbage_in_raises(channels, kwargs, match):
    kw = {"freq_hz": 10.0, **kwargs}
    with pytest.raises(AnalysisInputError, match=match):
        fit_dwell(channels, FS, **kw)
