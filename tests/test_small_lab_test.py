"""A lab's own small test gives what its data supports: without a free run the configured plate
mass is used, flagged nominal, with its effect on the contact force stated; with fewer than four
dwells per amplitude there is no tyre fit, and the measured ratios come with their 95 % intervals
and why there is no fit. Before, three dwells at 2 mm without a free run gave no analysis at all
(``m_comp unknown``), and the docs' import example (2 points) gave an empty report.

Physics: the simulated shaker's plate weighs 12 kg, the configured plate mass by default, so the
nominal m_comp is right and the measured F_wfs/F_contact must match the plant's closed-form ratio
(Model 2, paper tyre at 2.5 bar, linear) within its 95 % interval at each dwell (3 dwells, fixed
seed: all three inside with probability 0.86 for a correct interval; asserted with 1.5x its
width). Each kilogram of m_comp moves the contact force by (2 pi f)^2 |Z|: 126 N at 40 Hz, 2 mm.
With the nominal mass 1 kg off, the tread mass moves by 1 kg the other way, as the finding says."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from bench.analysis.shaker_models import shaker_response
from bench.app.analyze import analyze_campaign
from bench.app.run_analysis import RunAnalyser, RunInputs, initial_knowledge
from bench.cli.exit_codes import ExitCode
from bench.config import parse_bench_config
from bench.models.setup import BenchSetup
from bench.simulated_campaign import SHAKER_GRID_HZ, simulate_dwells
from tests.campaign_files import StoredRun, write_campaign
from tests.commands import wfsbench
from tests.documented import assert_documented

SETUP = BenchSetup.paper_shaker(2.5, nonlinear=False)
FREQS_HZ = np.array([10.0, 25.0, 40.0])


@pytest.fixture(scope="module")
def small_test(tmp_path_factory) -> Path:
    """Three dwells at 2 mm and 2.5 bar, no free run."""
    grid = simulate_dwells(SETUP, FREQS_HZ, 2e-3, seed=41)
    runs = [StoredRun("small", "dwell_grid", tuple(grid), {"tyre_pressure_bar": 2.5})]
    return write_campaign(tmp_path_factory.mktemp("small") / "small.h5", runs)


def test_three_dwells_without_a_free_run_give_the_measured_ratios_and_say_why_no_fit(small_test):
    run = wfsbench("analyze", str(small_test))
    assert run.returncode == ExitCode.INCOMPLETE, run.stderr
    text = run.stdout
    assert (
        "FLAG m_comp 12 kg nominal (the bench configuration's masses.plate_kg): not measured, no free run"
        in text
    )
    assert (
        "2 mm: 3 dwells 10-40 Hz; no tyre fit: 3 reliable dwells, a tyre fit needs at least 4 (Model 2 has"
        " three parameters and the fit a residual to be judged by); the measured F_wfs/F_contact (95 %):"
    ) in text
    assert text.splitlines()[-1] == (
        "== analysis partial: 1 of 1 run not complete (small partial: 2 mm: no tyre fit: 3 reliable"
        " dwells, a tyre fit needs at least 4 (Model 2 has three parameters and the fit a residual to be"
        " judged by))"
    )
    doc = json.loads(wfsbench("analyze", str(small_test), "--json").stdout)
    assert doc["status"] == "partial" and doc["runs"][0]["status"] == "partial"
    (shaker,) = doc["shaker"]
    assert shaker["free_run"]["nominal"] is True and shaker["free_run"]["m_comp_kg"] == 12.0
    assert shaker["amplitudes"] == []
    (ratios,) = shaker["ratios_only"]
    wfs, contact = shaker_response(SETUP.model, SETUP.tyre, SETUP.sensor, FREQS_HZ)
    truth = wfs / contact
    measured = np.array([p["ratio"] for p in ratios["ratios"]])
    half = np.array([p["ratio_ci95"] for p in ratios["ratios"]])
    assert [p["freq_hz"] for p in ratios["ratios"]] == list(FREQS_HZ)
    assert np.all(np.abs(measured - np.abs(truth)) <= 1.5 * half), (measured, np.abs(truth), half)
    phase = np.array([p["phase_deg"] for p in ratios["ratios"]])
    phase_half = np.array([p["phase_ci95_deg"] for p in ratios["ratios"]])
    assert np.all(np.abs(phase - np.degrees(np.angle(truth))) <= 1.5 * phase_half)
    # each printed ratio line carries its interval
    assert len(re.findall(r"^2 mm \d+ Hz: \|F_wfs/F_contact\| \S+ \+/- \S+, phase", text, re.M)) == 3


def test_the_report_of_a_small_test_is_not_empty(small_test, tmp_path):
    run = wfsbench("report", str(small_test), "--out", str(tmp_path / "report"))
    assert run.returncode == 0, run.stderr
    html = (tmp_path / "report" / "report.html").read_text(encoding="utf-8")
    assert "|F_wfs/F_contact|" in html and "no tyre fit" in html and "nominal" in html


def test_a_nominal_plate_mass_one_kilogram_off_moves_the_tread_mass_by_one_kilogram():
    grid = simulate_dwells(SETUP, SHAKER_GRID_HZ, 2e-3, seed=42)
    tread = {}
    for plate_kg in (12.0, 13.0):
        k = initial_knowledge(parse_bench_config(f"[masses]\nplate_kg = {plate_kg}\n", "lab.toml"))
        outcome = RunAnalyser(k).analyse(
            RunInputs("grid", "dwell_grid", {"tyre_pressure_bar": 2.5}, dwells=tuple(grid))
        )
        assert outcome.status == "complete", outcome
        fit = k.shaker[2.5].nearest(2e-3).identification
        tread[plate_kg] = fit.best_fit.values["tread_mass_kg"]
        (finding,) = [f for f in fit.findings if "nominal" in f]
        # (2 pi 70 Hz)^2 x 2 mm = 387 N per kg at the grid's top
        assert finding.startswith(
            f"m_comp {plate_kg:g} kg is nominal, not measured (no free run): each kg it is off moves"
            " the contact force by 387 N at 70 Hz"
        )
    assert tread[12.0] == pytest.approx(SETUP.tyre.tread_mass_kg, abs=0.01)
    assert tread[13.0] - tread[12.0] == pytest.approx(-1.0, abs=0.01)
    # what docs/analysis.md quotes (printed with -s)
    text = f"analysed as 13 kg gives a tread mass of {tread[13.0]:.4f} kg for {SETUP.tyre.tread_mass_kg:g}"
    print(f"\n  {text}")
    assert_documented("docs/analysis.md", text)


def test_the_docs_import_example_two_points_gives_ratios_not_an_empty_report(tmp_path):
    """As docs/import.md's example: a free run at 10 and 30 Hz, a grid at 10 and 40 Hz."""
    free = simulate_dwells(BenchSetup.paper_free_run(), np.array([10.0, 30.0]), 2e-3, seed=43)
    grid = simulate_dwells(SETUP, np.array([10.0, 40.0]), 2e-3, seed=44)
    runs = [
        StoredRun(
            "free", "free_run", tuple(free), {"wheel_fitted": False}, channels=("z_base_m", "f_plate_n")
        ),
        StoredRun("grid", "dwell_grid", tuple(grid), {"tyre_pressure_bar": 2.5}),
    ]
    analysis = analyze_campaign(write_campaign(tmp_path / "example.h5", runs))
    grid_run = analysis.runs[-1]
    assert grid_run.status == "partial" and grid_run.omitted == (
        "2 mm: no tyre fit: 2 reliable dwells, a tyre fit needs at least 4 (Model 2 has three parameters"
        " and the fit a residual to be judged by)",
    )
    assert sum("|F_wfs/F_contact|" in line for line in grid_run.lines) == 2
