"""Repeated dwells are repeats: a check measurement at a point the campaign holds already (a grid at
the same pressure and amplitude, later in the campaign) is kept and combined with the original into
one point, and the spread of the repeats is reported as the bench's repeatability. The original
grid's analysis no longer fails (``two records of the same dwell``), nothing of it is lost.

Physics: two repeats of the same plant differ by their noise only, so their spread is of the order
of their stated noise (for two repeats the relative rms spread is |h1 - h2| / 2, whose expectation
is about 0.7 of the noise measure: asserted below 4x, which noise exceeds with negligible
probability) and the combined point is about 1/sqrt(2) as uncertain as either. A check measured on
a tyre whose pressure drifted (390 to 380 kN/m, about 0.1 bar) differs far outside the noise near
the tread resonance and is flagged."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from bench.app.analyze import analyze_campaign
from bench.cli.exit_codes import ExitCode
from bench.models.setup import BenchSetup
from bench.simulated_campaign import FREE_RUN_GRID_HZ, SHAKER_GRID_HZ, simulate_dwells
from tests.campaign_files import StoredRun, write_campaign
from tests.commands import wfsbench
from tests.documented import assert_documented

SETUP = BenchSetup.paper_shaker(2.5, nonlinear=False)
DOCUMENT = "docs/analysis.md"
CHECK_HZ = np.array([34.0, 40.0])


def _runs(check_setup: BenchSetup | None) -> list[StoredRun]:
    free = simulate_dwells(BenchSetup.paper_free_run(), FREE_RUN_GRID_HZ[::3], 2e-3, seed=51)
    original = simulate_dwells(SETUP, SHAKER_GRID_HZ, 2e-3, seed=52)
    other = simulate_dwells(BenchSetup.paper_shaker(1.5, nonlinear=False), SHAKER_GRID_HZ[::3], 2e-3, seed=53)
    runs = [
        StoredRun(
            "free", "free_run", tuple(free), {"wheel_fitted": False}, channels=("z_base_m", "f_plate_n")
        ),
        StoredRun("grid-2.5", "dwell_grid", tuple(original), {"tyre_pressure_bar": 2.5}),
        StoredRun("grid-1.5", "dwell_grid", tuple(other), {"tyre_pressure_bar": 1.5}),
    ]
    if check_setup is not None:
        check = simulate_dwells(check_setup, CHECK_HZ, 2e-3, seed=54)
        runs.append(StoredRun("check-2.5", "dwell_grid", tuple(check), {"tyre_pressure_bar": 2.5}))
    return runs


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("repeats")
    drifted = SETUP.with_tyre(replace(SETUP.tyre, stiffness_n_per_m=380e3))
    return {
        name: write_campaign(folder / f"{name}.h5", _runs(check))
        for name, check in (("without", None), ("check", SETUP), ("drifted", drifted))
    }


def test_a_check_measurement_is_combined_and_its_spread_reported(files):
    run = wfsbench("analyze", str(files["check"]), "--json")
    assert run.returncode == ExitCode.OK, run.stderr
    doc = json.loads(run.stdout)
    assert doc["status"] == "complete"
    assert [(r["run_id"], r["status"]) for r in doc["runs"]] == [
        ("free", "complete"),
        ("grid-2.5", "complete"),
        ("grid-1.5", "complete"),
        ("check-2.5", "complete"),
    ]
    at_25 = next(s for s in doc["shaker"] if s["tyre_pressure_bar"] == 2.5)
    (amp,) = at_25["amplitudes"]
    assert amp["n_dwells"] == len(SHAKER_GRID_HZ)  # one point per frequency
    assert [(r["freq_hz"], r["n"], r["outside_noise"]) for r in amp["repeats"]] == [
        (34.0, 2, False),
        (40.0, 2, False),
    ]
    for r in amp["repeats"]:
        for channel, spread in r["spread"].items():
            assert spread <= 4 * r["noise"][channel], (channel, spread, r["noise"][channel])
    spreads = [100 * v for r in amp["repeats"] for v in r["spread"].values()]
    noises = [100 * v for r in amp["repeats"] for v in r["noise"].values()]
    said = (
        f"spread {min(spreads):.2g}-{max(spreads):.2g} % against a noise of"
        f" {min(noises):.2g}-{max(noises):.2g} %"
    )
    print(f"\n  {said}")
    assert_documented(DOCUMENT, said)
    model2 = next(m for m in amp["models"] if m["model"] == 2)["values"]
    assert model2["stiffness_n_per_m"] == pytest.approx(SETUP.tyre.stiffness_n_per_m, rel=0.02)
    assert model2["tread_mass_kg"] == pytest.approx(SETUP.tyre.tread_mass_kg, rel=0.03)
    summary = next(r for r in doc["runs"] if r["run_id"] == "check-2.5")["summary"]
    assert any(line.startswith("2 mm repeatability: 2 dwell(s) measured more than once") for line in summary)
    assert not [line for line in summary if line.startswith("FLAG")]


def test_the_combined_point_is_sqrt2_less_uncertain_and_the_original_analysis_is_kept(files):
    alone = analyze_campaign(files["without"]).knowledge.shaker[2.5].nearest(2e-3)
    both = analyze_campaign(files["check"])
    combined = both.knowledge.shaker[2.5].nearest(2e-3)
    at = np.flatnonzero(np.isin(alone.frfs.wfs_per_z.freq_hz, CHECK_HZ))
    ratio = combined.frfs.wfs_per_z.sigma[at] / alone.frfs.wfs_per_z.sigma[at]
    assert np.all((ratio > 0.55) & (ratio < 0.85)), ratio  # 1/sqrt(2) = 0.71 for equal repeats
    said = f"the combined points {ratio[0]:.2f} and {ratio[1]:.2f}x as uncertain"
    print(f"\n  {said}")
    assert_documented(DOCUMENT, said)
    # the original grid's analysis is there, not failed, with its tyre
    original = next(r for r in both.runs if r.run_id == "grid-2.5")
    assert original.status == "complete" and original.name == "shaker"


def test_repeats_of_a_tyre_whose_pressure_drifted_are_flagged(files):
    analysis = analyze_campaign(files["drifted"])
    amplitude = analysis.knowledge.shaker[2.5].nearest(2e-3)
    assert [r.outside_noise for r in amplitude.repeats] == [True, True]
    spreads = [100 * v for r in amplitude.repeats for v in r.spread.values()]
    softer = 100 * (1 - 380e3 / SETUP.tyre.stiffness_n_per_m)
    said = (
        f"a check on a tyre {softer:.1f} % softer (its pressure drifted):"
        f" {min(spreads):.2g}-{max(spreads):.2g} %"
    )
    print(f"\n  {said}")
    assert_documented(DOCUMENT, said)
    check = next(r for r in analysis.runs if r.run_id == "check-2.5")
    assert "FLAG 2 mm repeats of dwell 2 mm at 34 Hz differ far outside their noise" in "\n".join(check.lines)
