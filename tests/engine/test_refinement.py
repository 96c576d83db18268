"""Grid refinement against closed-form FRFs: a narrow resonance missed by a coarse grid is found,
and refinement stops once reading the FRF between measured points is accurate to the targets."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.analysis.interpolation import grid_error
from bench.engine.refinement import next_point, predicted_peak_hz
from sequences import AdaptiveDwell

PLAN = AdaptiveDwell(max_added_points=40)


def resonance(freq_hz: np.ndarray | float, f_n_hz: float = 41.3, zeta: float = 0.026) -> np.ndarray:
    """Transmissibility of a single mode: (1 + 2 j zeta r) / (1 - r^2 + 2 j zeta r)."""
    r = np.asarray(freq_hz, float) / f_n_hz
    return (1 + 2j * zeta * r) / (1 - r**2 + 2j * zeta * r)


def refine(freqs_hz: list[float], plan: AdaptiveDwell) -> tuple[list[float], list[str]]:
    reasons = []
    for _ in range(plan.max_added_points):
        added = next_point(freqs_hz, list(resonance(np.array(freqs_hz))), plan)
        if added is None:
            break
        assert min(abs(f - added.freq_hz) for f in freqs_hz) > plan.min_spacing_hz
        freqs_hz.append(added.freq_hz)
        reasons.append(added.reason)
    return sorted(freqs_hz), reasons


def test_the_single_mode_fit_predicts_the_peak_of_a_single_mode() -> None:
    f = np.array([38.0, 42.0, 46.0])
    peak = predicted_peak_hz(f, 1 / (1 - (f / 41.3) ** 2 + 0.05j * f / 41.3))  # a constant numerator
    assert peak == pytest.approx(41.3 * math.sqrt(1 - 2 * 0.025**2), abs=1e-9)


def test_refinement_finds_a_narrow_peak_between_coarse_points_and_stops_when_fine_enough() -> None:
    coarse = [5.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0]
    band = np.linspace(5.0, 70.0, 13001)
    before = grid_error(np.array(coarse), resonance(np.array(coarse)), band, resonance(band))
    assert before.max_db > 5.0  # the coarse grid misses the peak badly
    freqs, reasons = refine(list(coarse), PLAN)
    assert len(reasons) < PLAN.max_added_points  # it stopped by its targets, not by the budget
    assert reasons[0].startswith("model peak")
    after = grid_error(np.array(freqs), resonance(np.array(freqs)), band, resonance(band))
    assert abs(after.peak_height) <= 0.005 and abs(after.peak_hz) <= 0.05
    # the estimate reads the curvature at the middle of each interval: the true error stays within
    # twice the targets
    assert after.max_db <= 2 * PLAN.interpolation_db
    assert after.max_deg <= 2 * PLAN.interpolation_deg


def test_the_budget_bounds_the_added_points() -> None:
    plan = AdaptiveDwell(max_added_points=3)
    freqs, reasons = refine([5.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0], plan)
    assert len(reasons) == 3 and len(freqs) == 11


def test_a_flat_response_adds_nothing() -> None:
    f = [1.0, 2.0, 5.0, 10.0]
    assert next_point(f, [2.0 + 0j] * 4, PLAN) is None
