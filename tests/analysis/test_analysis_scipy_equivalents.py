"""Where scipy does the job, the analysis uses it; each replacement is checked numerically equal to
the definition it replaced, and the exact first-order-hold discretisation against scipy's."""

import numpy as np
from scipy.signal import cont2discrete, welch

from bench.analysis.compensation import _coloured_noise_covariance
from bench.analysis.dwell import _fit_window
from bench.analysis.fir import double_differentiator, fir_response
from bench.analysis.hammer import _half_power
from bench.models.linear_system import LinearSystem


def test_fir_response_equals_its_definition():
    taps, _ = double_differentiator(1000.0, band_hz=120.0)
    f = np.linspace(0.0, 500.0, 777)
    direct = np.exp(-2j * np.pi * np.outer(f / 1000.0, np.arange(taps.size))) @ taps
    np.testing.assert_allclose(
        fir_response(taps, f, 1000.0), direct, rtol=1e-12, atol=1e-9 * np.abs(direct).max()
    )


def test_half_power_width_equals_interpolated_crossings():
    """A decaying 2 kHz oscillation, zeta 2 %: the half-power points by peak_widths equal the linear
    interpolation between the bins around each crossing, and give zeta within 2 %."""
    fs, zeta, f_n = 10_000.0, 0.02, 2000.0
    t = np.arange(3000) / fs
    w_d = 2 * np.pi * f_n * np.sqrt(1 - zeta**2)
    x = np.exp(-zeta * 2 * np.pi * f_n * t) * np.sin(w_d * t)
    f_peak, zeta_hp = _half_power(x, fs)
    n_fft = 1 << int(np.ceil(np.log2(max(64 * x.size, 1 << 16))))
    p = np.abs(np.fft.rfft(x, n_fft)) ** 2
    f = np.fft.rfftfreq(n_fft, 1 / fs)
    k = int(np.argmax(p[1:])) + 1
    a, b, c = np.log(p[k - 1 : k + 2])
    half = 0.5 * np.exp(b - 0.25 * (a - c) * 0.5 * (a - c) / (a - 2 * b + c))
    lo = k - np.argmax(p[k::-1] <= half)  # first bin at or below half power, walking down
    hi = k + np.argmax(p[k:] <= half)
    f1 = np.interp(half, [p[lo], p[lo + 1]], [f[lo], f[lo + 1]])
    f2 = np.interp(half, [p[hi], p[hi - 1]], [f[hi], f[hi - 1]])
    assert abs(zeta_hp / ((f2 - f1) / (2 * f_peak)) - 1) < 1e-12
    assert abs(zeta_hp / zeta - 1) < 0.02


def test_dwell_fit_by_qr_equals_the_normal_equations():
    """One cycle of 50 Hz at 1 kHz (too short for the local noise density: the white estimate is
    used): coefficients and fundamental sigma as with lstsq and inv(X'X)."""
    rng = np.random.default_rng(3)
    fs, freq = 1000.0, 50.0
    t = np.arange(20) / fs
    y = np.stack([np.sin(2 * np.pi * freq * t + 0.3) + 0.01 * rng.standard_normal(t.size)] * 2, axis=1)
    y[:, 1] *= 3.0
    cols = [np.ones_like(t)]
    for k in range(1, 4):
        cols += [np.cos(k * 2 * np.pi * freq * t), np.sin(k * 2 * np.pi * freq * t)]
    X = np.stack(cols, axis=1)
    fit = _fit_window(t, y, 2 * np.pi * freq, 3, X)
    coef = np.linalg.lstsq(X, y, rcond=None)[0]
    res = y - X @ coef
    cov = np.linalg.inv(X.T @ X)
    sigma = np.sqrt(np.sum(res**2, axis=0) / (t.size - X.shape[1]) * (cov[1, 1] + cov[2, 2]))
    np.testing.assert_allclose(fit.coef, coef, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(fit.fundamental_sigma, sigma, rtol=1e-10)


def test_coloured_noise_covariance_by_qr_equals_the_normal_equations():
    rng = np.random.default_rng(4)
    fs, n = 1000.0, 5000
    X = rng.standard_normal((n, 3)) @ np.array([[1.0, 0.9, 0.0], [0.0, 0.1, 0.0], [0.0, 0.0, 2.0]])
    res = np.convolve(rng.standard_normal(n), np.ones(5) / 5, mode="same")
    f_psd, psd = welch(res, fs=fs, nperseg=min(n, 4096))
    spec = np.fft.rfft(X, axis=0)
    density = np.interp(np.fft.rfftfreq(n, 1 / fs), f_psd, psd) * fs / 2
    density[1 : (n + 1) // 2] *= 2
    meat = ((spec.conj().T * density) @ spec).real / n
    bread = np.linalg.inv(X.T @ X)
    np.testing.assert_allclose(_coloured_noise_covariance(X, res, fs), bread @ meat @ bread, rtol=1e-9)


def test_first_order_hold_equals_scipy():
    """``discretize_foh`` steps ``x[k+1] = Phi x + G0 u[k] + G1 u[k+1]``; scipy's 'foh' uses the state
    ``x - G1 u``: the same system when ``Ad = Phi``, ``Bd = G0 + Phi G1``, ``Dd = D + C G1``."""
    m, k, d = 3.8, 3.8 * (2 * np.pi * 2200.0) ** 2, 2 * 0.02 * np.sqrt(3.8**2 * (2 * np.pi * 2200.0) ** 2)
    a = np.array([[0.0, 1.0], [-k / m, -d / m]])
    b = np.array([[0.0], [1.0 / m]])
    c = np.array([[1.0, 0.0], [-k / m, -d / m]])
    dd = np.array([[0.0], [1.0 / m]])
    system = LinearSystem(a, b, c, dd, ("force",), ("x", "acceleration"), ("x", "v"))
    dt = 1e-4
    disc = system.discretize_foh(dt)
    ad, bd, cd, ddd, _ = cont2discrete((a, b, c, dd), dt, method="foh")
    np.testing.assert_allclose(disc.phi, ad, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(disc.g0 + disc.phi @ disc.g1, bd, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(disc.D + disc.C @ disc.g1, ddd, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(disc.C, cd)
