"""Offline FIR application: an output is finite only where the filter's whole input window lies
inside the record."""

import numpy as np
import pytest

from bench.analysis.fir import apply_aligned, half_cosine_rolloff


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
