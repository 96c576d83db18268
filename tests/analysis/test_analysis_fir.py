"""Offline FIR application: an output is finite only where the filter's whole input window lies
inside the record."""

import numpy as np
import pytest

from bench.analysis.fir import apply_aligned, design_fir, half_cosine_rolloff


@pytest.mark.parametrize(("n_taps", "latency"), [(9, 4), (9, 0), (9, 8), (160, 40)])
def test_apply_aligned_marks_edges_without_full_window(n_taps, latency):
    """A moving average of a constant is that constant wherever its window is complete; outputs
    started from zero history (the first n_taps - 1 - latency) or needing future input (the last
    latency) must be NaN, not a finite wrong value."""
    taps = np.full(n_taps, 1.0 / n_taps)
    out = apply_aligned(taps, np.full(500, 3.0), latency)
    head = n_taps - 1 - latency
    assert np.all(np.isnan(out[:head]))
    assert np.all(np.isnan(out[out.size - latency :]))
    np.testing.assert_allclose(out[head : out.size - latency], 3.0, rtol=1e-12)


def test_apply_aligned_record_shorter_than_filter_is_all_nan():
    assert np.all(np.isnan(apply_aligned(np.ones(50), np.ones(20), 10)))


def test_half_cosine_rolloff():
    f = np.array([0.0, 10.0, 12.5, 15.0, 20.0])
    np.testing.assert_allclose(half_cosine_rolloff(f, 10.0, 15.0), [1.0, 1.0, 0.5, 0.0, 0.0], atol=1e-15)


@pytest.mark.parametrize("seed", range(3))
def test_ridge_design_equals_the_stacked_least_squares_solution(seed):
    """With a ridge, design_fir solves the normal equations; their condition number is at most
    1 + n_taps / ridge, so the taps equal the SVD solution of the stacked real problem (the
    module's definition) to that times the machine precision. Weights as a compensator's: heavy in
    its band, light above it (there only the ridge keeps the problem well-posed)."""
    rng = np.random.default_rng(seed)
    fs, n_taps, latency, ridge = 1000.0, 160, 40, 1e-6
    f = np.linspace(0.01, fs / 2, 6 * n_taps + 1)
    target = (1 + 0.3 * rng.standard_normal(f.size)) * np.exp(1j * rng.uniform(-1, 1, f.size))
    weight = np.where(f <= 100.0, 10 ** rng.uniform(0, 2, f.size), 10 ** rng.uniform(-6, -3, f.size))
    taps = design_fir(f, target, weight, n_taps=n_taps, latency_samples=latency, fs_hz=fs, ridge=ridge)
    sw = np.sqrt(weight)
    d = target * np.exp(-2j * np.pi * f * latency / fs) * sw
    basis = np.exp(-2j * np.pi * np.outer(f / fs, np.arange(n_taps))) * sw[:, None]
    rows = np.vstack([basis.real, basis.imag, np.sqrt(ridge * np.mean(weight) * f.size) * np.eye(n_taps)])
    rhs = np.concatenate([d.real, d.imag, np.zeros(n_taps)])
    reference = np.linalg.lstsq(rows, rhs, rcond=None)[0]
    condition = np.linalg.cond(rows.T @ rows)
    assert 1e6 < condition <= 1 + n_taps / ridge
    error = np.max(np.abs(taps - reference)) / np.max(np.abs(reference))
    assert error < 4 * condition * np.finfo(float).eps
