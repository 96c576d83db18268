"""One fit of a sine at a known frequency on true sample times, against its closed form.

Frames lost on a link leave gaps that the frame counter shows. The fit places each sample at the
time its counter gives, so a window with gaps of any size at any place gives the same phasor as the
whole window, within the noise (the noise's standard error grows as sqrt(n / n_present)). The
tolerance below is 6 standard errors of the least-squares phasor, sigma * sqrt(2 / n_present):
a seeded test that a 6-sigma miss would fail about once in 10^8.
"""

from __future__ import annotations

import numpy as np
import pytest

from bench.numerics.sine_fit import SEQ_MODULUS, fit_latest_cycles, fit_sine, frame_offsets

RATE_HZ = 1000.0


def _record(freq_hz: float, n: int, noise: float, seed: int) -> tuple[np.ndarray, complex]:
    rng = np.random.default_rng(seed)
    phasor = 1.3 * np.exp(1j * rng.uniform(-np.pi, np.pi))
    t = np.arange(n) / RATE_HZ
    y = 0.2 + np.real(phasor * np.exp(2j * np.pi * freq_hz * t)) + 0.05 * np.cos(6 * np.pi * freq_hz * t)
    return y + noise * rng.standard_normal(n), phasor


def _with_gaps(n: int, rng: np.random.Generator) -> np.ndarray:
    """Sample indices of ``n`` with 1-4 gaps of random places and sizes (1 to 5,000 frames)."""
    keep = np.ones(n, bool)
    for _ in range(rng.integers(1, 5)):
        size = int(min(rng.choice([1, 10, 100, 350, 1000, 3000, 5000]), n // 3))
        start = int(rng.integers(1, n - size - 1))
        keep[start : start + size] = False
    return np.flatnonzero(keep)


@pytest.mark.parametrize("seed", range(20))
def test_the_fit_with_gaps_equals_the_closed_form(seed):
    rng = np.random.default_rng(100 + seed)
    freq_hz = float(rng.choice([0.5, 3.7, 16.0, 36.0, 70.0]))
    n, noise = 16_000, 0.01
    y, phasor = _record(freq_hz, n, noise, seed)
    kept = _with_gaps(n, rng)
    seq = (kept + 4_294_960_000) % SEQ_MODULUS  # the counter wraps inside the window
    offsets = frame_offsets(seq)
    assert np.array_equal(offsets, kept - kept[0])
    fit = fit_sine(y[kept], offsets, RATE_HZ, freq_hz, n_harmonics=3)
    # the fit's phasor refers to its window's first sample: back to the record's first
    at_zero = fit.phasors[0] * np.exp(2j * np.pi * freq_hz * kept[0] / RATE_HZ)
    standard_error = noise * np.sqrt(2.0 / len(kept))
    assert abs(at_zero - phasor) < 6 * standard_error
    assert fit.frames_missing == kept[-1] - kept[0] + 1 - len(kept)


def test_a_gap_fitted_as_contiguous_would_have_read_a_third_of_the_amplitude():
    """The defect the true times remove: 1 mm at 16 Hz with 453 frames lost mid-window read as if
    contiguous is far off; on true times it is 1 mm."""
    y, _ = _record(16.0, 2000, 0.0, 1)
    kept = np.r_[np.arange(800), np.arange(1253, 2000)]
    contiguous = fit_sine(y[kept], np.arange(kept.size), RATE_HZ, 16.0)
    true = fit_sine(y[kept], kept, RATE_HZ, 16.0, n_harmonics=3)
    assert abs(contiguous.amplitude - 1.3) > 0.2
    assert true.amplitude == pytest.approx(1.3, abs=1e-9)
    assert true.frames_missing == 453 and true.span_samples == 2000


def test_the_latest_whole_cycles_count_their_missing_ends():
    """A window of 4 cycles at 10 Hz whose last 50 frames were lost: its span is the 400 sample
    times, 50 of them missing, not the 350 present."""
    y, _ = _record(10.0, 400, 0.0, 2)
    fit = fit_latest_cycles(y[:350], np.arange(350), RATE_HZ, 10.0, start=0, end=400)
    assert fit.span_samples == 400 and fit.frames_missing == 50
    assert fit_latest_cycles(y[:50], np.arange(50), RATE_HZ, 10.0) is None  # no whole cycle


def test_a_counter_that_goes_back_counts_one_sample():
    assert frame_offsets(np.array([10, 11, 15, 0, 1])).tolist() == [0, 1, 5, 6, 7]
    assert frame_offsets(np.array([5, 6]), reference=3).tolist() == [2, 3]
    assert frame_offsets(np.zeros(0)).size == 0


def test_a_fit_with_fewer_samples_than_unknowns_is_refused():
    with pytest.raises(ValueError, match="needs more than 3 samples"):
        fit_sine(np.ones(3), np.arange(3), RATE_HZ, 10.0)
    with pytest.raises(ValueError, match="3 samples but 2 offsets"):
        fit_sine(np.ones(3), np.arange(2), RATE_HZ, 10.0)
