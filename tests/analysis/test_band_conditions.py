"""A valid band says what it rests on: a shaker campaign without a free run takes m_comp as the
configured plate mass, and its model-compensated band holds only if that mass is right. The
tolerance the analysis states is checked against the true contact force of the simulated bench
(plate 12 kg): with the nominal mass off by less than the tolerance, the compensated force over the
TRUE contact force stays within the band's tolerances at every band point; well beyond it, it does
not, although the ratio measured on the bench (against the wrongly corrected contact) still does:
the tyre fit absorbs the error into the tread mass."""

from __future__ import annotations

import numpy as np
import pytest

from bench.analysis.dwell import dwell_phasors
from bench.analysis.runs import analyse_shaker_campaign, nominal_free_run
from bench.models.parameters import WfsSensor
from bench.models.setup import BenchSetup
from bench.report.analysis_document import AmplitudeDoc
from bench.report.text import summary_lines
from bench.simulated_campaign import FREE_RUN_GRID_HZ, SHAKER_GRID_HZ, simulate_dwells

TRUE_PLATE_KG = 12.0
AMPLITUDE_M = 2e-3


@pytest.fixture(scope="module")
def grid():
    setup = BenchSetup.paper_shaker(2.5, nonlinear=False)
    return simulate_dwells(setup, SHAKER_GRID_HZ, AMPLITUDE_M, seed=31)


def _analysed(grid, nominal_kg: float):
    result = analyse_shaker_campaign(
        grid,
        nominal_free_run(nominal_kg, "the test's plate mass"),
        wheel_mass_kg=29.0,
        sensor=WfsSensor(),
    )
    return result, result.amplitudes[AMPLITUDE_M]


def _true_deviation(amp) -> tuple[float, float]:
    """The largest ``| |H|-1 |`` and ``|phase H|`` (deg) over the compensated band of the
    compensated force against the true contact force ``F_plate + m_true w^2 Z``."""
    fits = amp.fits
    f = np.array([d.freq_hz for d in fits])
    g_f, g_a = amp.compensator.response(f)
    (wfs, _), (acc, _), (plate, _), (z, _) = (
        dwell_phasors(fits, c) for c in ("fz_wfs_n", "a_hub_m_s2", "f_plate_n", "z_base_m")
    )
    ratio = (g_f * wfs + g_a * acc) / (plate + TRUE_PLATE_KG * (2 * np.pi * f) ** 2 * z)
    band = amp.valid_band_compensated
    inside = (f >= band.lowest_hz) & (f <= band.upper_hz)
    amplitude = np.max(np.abs(np.abs(ratio[inside]) - 1))
    return float(amplitude), float(np.max(np.abs(np.angle(ratio[inside], deg=True))))


def test_a_measured_plate_mass_gives_no_condition(grid):
    free = simulate_dwells(BenchSetup.paper_free_run(), FREE_RUN_GRID_HZ, AMPLITUDE_M, seed=32)
    result = analyse_shaker_campaign(grid, free, wheel_mass_kg=29.0, sensor=WfsSensor())
    amp = result.amplitudes[AMPLITUDE_M]
    assert amp.band_conditions == () and amp.plate_mass_tolerance_kg is None
    assert AmplitudeDoc.of(amp).band_conditions == ()


def test_the_band_holds_within_the_stated_tolerance_and_fails_well_beyond_it(grid):
    result, amp = _analysed(grid, TRUE_PLATE_KG)
    tolerance_kg = amp.plate_mass_tolerance_kg
    band = amp.valid_band_compensated
    assert band.determined and 0.005 < tolerance_kg < 1.0, tolerance_kg
    (condition,) = amp.band_conditions
    assert condition.startswith(f"holds only if the nominal m_comp {TRUE_PLATE_KG:g} kg (no free run)")
    assert f"{1000 * tolerance_kg:.3g} g" in condition and "0.5 kg off:" in condition
    text = "\n".join(summary_lines(result))
    assert f"model-compensated band {condition}" in text
    doc = AmplitudeDoc.of(amp)
    assert doc.band_conditions == (condition,) and doc.plate_mass_tolerance_kg == tolerance_kg

    for nominal_kg in (TRUE_PLATE_KG + 0.8 * tolerance_kg, TRUE_PLATE_KG - 0.8 * tolerance_kg):
        _, off = _analysed(grid, nominal_kg)
        if not off.valid_band_compensated.determined:
            continue
        amplitude, phase_deg = _true_deviation(off)
        assert amplitude <= band.amplitude_tolerance and phase_deg <= band.phase_tolerance_deg, nominal_kg

    _, far = _analysed(grid, TRUE_PLATE_KG + 4 * tolerance_kg)
    assert far.valid_band_compensated == band  # the ratio the bench measures sees nothing
    amplitude, phase_deg = _true_deviation(far)
    assert amplitude > band.amplitude_tolerance or phase_deg > band.phase_tolerance_deg
