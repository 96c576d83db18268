"""Wheel mass from a run: its reported uncertainty against the scatter over noise realisations."""

import numpy as np
import pytest
from scipy.signal import butter, lfilter, sosfilt

from bench.analysis.compensation import estimate_wheel_mass

FS = 1000.0
SEEDS = 40


def _sweep_accelerations() -> tuple[np.ndarray, np.ndarray]:
    """Hub and contact accelerations of a 2 mm, 0.1-30 Hz linear sweep over 60 s; the contact side
    passes a 12 Hz resonance (damping ratio 0.2) so that the two regressors are not collinear."""
    t = np.arange(int(60 * FS)) / FS
    freq = 0.1 + 29.9 * t / 60
    phase = 2 * np.pi * (0.1 * t + 29.9 * t**2 / 120)
    a_hub = -2e-3 * (2 * np.pi * freq) ** 2 * np.sin(phase)
    w, zeta = 2 * np.pi * 12.0 / FS, 0.2
    a_contact = lfilter([w**2], [1 + 2 * zeta * w + w**2, -2 - 2 * zeta * w, 1], a_hub)
    return a_hub, a_contact


@pytest.mark.parametrize("colour", ["white", "low-frequency"])
def test_wheel_mass_sigma_matches_scatter(colour):
    """Over 40 noise realisations the reported sigma must match the empirical standard deviation of
    m_wheel within a factor 1.5 (the empirical std from 40 draws scatters by about 1/sqrt(80) = 11 %,
    so 1.5 is some 4 of its standard deviations; the double band-limit correction gave 5.9).
    Noise: white (a sensor floor) or concentrated below 3 Hz (a drifting load cell), where a flat
    in-band density would misjudge it."""
    a_hub, a_contact = _sweep_accelerations()
    n = a_hub.size
    low = butter(2, 3.0, fs=FS, output="sos")
    masses, sigmas = [], []
    for seed in range(SEEDS):
        rng = np.random.default_rng(seed)
        noise = 20.0 * rng.standard_normal(n)
        if colour == "low-frequency":
            noise = 200.0 * sosfilt(low, rng.standard_normal(n)) + 2.0 * rng.standard_normal(n)
        # F_contact - F_wfs = 25 kg rim side + 4 kg contact side, the accelerometer lagging 0.5 ms
        lagged = np.interp(np.arange(n) - 0.5e-3 * FS, np.arange(n), a_hub)
        diff = 25.0 * a_hub + 4.0 * a_contact + noise
        wm = estimate_wheel_mass(diff, np.zeros(n), lagged, FS, a_contact=a_contact, band_hz=(1.0, 25.0))
        masses.append(wm.mass_kg)
        sigmas.append(wm.sigma_kg)
    empirical = np.std(masses, ddof=1)
    reported = np.sqrt(np.mean(np.square(sigmas)))
    assert abs(np.mean(masses) - 29.0) < 3 * empirical
    assert 1 / 1.5 < reported / empirical < 1.5, (reported, empirical)
