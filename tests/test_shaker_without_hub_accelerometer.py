"""A shaker campaign recorded without a hub accelerometer (a clamped hub needs none, and many labs'
exports have no such column) is analysed in full: the tyre fit, the compensator, both valid bands;
only the hub-acceleration term of the model compensation is left out (the hub taken as not moving),
and the report says so. Before, the file's grid failed its analysis (``FLAG analysis failed``).

Physics: on the shaker the hub is clamped, so ``a_hub`` is noise and its term ``G_A a_hub`` of the
compensated force is noise too: the compensated ratio without it equals the one with it within the
points' own uncertainty, and the identified tyre is the same (the fit does not use ``a_hub``)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from bench.analysis.records import HUB_ACCELERATION, SHAKER_CHANNELS
from bench.app.analyze import analyze_campaign
from bench.cli.exit_codes import ExitCode
from bench.models.setup import BenchSetup
from bench.simulated_campaign import FREE_RUN_GRID_HZ, SHAKER_GRID_HZ, simulate_dwells
from tests.campaign_files import StoredRun, write_campaign
from tests.commands import wfsbench

SETUP = BenchSetup.paper_shaker(2.5, nonlinear=False)


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> tuple[Path, Path]:
    """The same campaign written with and without the hub-acceleration channel."""
    free = simulate_dwells(BenchSetup.paper_free_run(), FREE_RUN_GRID_HZ[::3], 2e-3, seed=31)
    grid = simulate_dwells(SETUP, SHAKER_GRID_HZ, 2e-3, seed=32)
    folder = tmp_path_factory.mktemp("no_hub")
    written = []
    for name, grid_channels in (("with_hub", None), ("without_hub", SHAKER_CHANNELS)):
        runs = [
            StoredRun("free", "free_run", tuple(free), {"wheel_fitted": False}, channels=SHAKER_CHANNELS[:2]),
            StoredRun("grid", "dwell_grid", tuple(grid), {"tyre_pressure_bar": 2.5}, channels=grid_channels),
        ]
        written.append(write_campaign(folder / f"{name}.h5", runs))
    return written[0], written[1]


def test_the_grid_without_hub_acceleration_is_analysed_in_full_and_says_what_it_left_out(files):
    _, without_hub = files
    run = wfsbench("analyze", str(without_hub), "--json")
    assert run.returncode == ExitCode.OK, run.stdout[-2000:] + run.stderr
    doc = json.loads(run.stdout)
    assert doc["status"] == "complete"
    (amp,) = doc["shaker"][0]["amplitudes"]
    assert amp["hub_acceleration_recorded"] is False and amp["selected_model"] == 2
    grid = next(r for r in doc["runs"] if r["run_id"] == "grid")
    assert (
        "2 mm no hub-acceleration channel: the clamped hub is taken as not moving (the model-compensated"
        " ratio without its hub-acceleration term); whether it moved is not checked"
    ) in grid["summary"]


def test_without_hub_acceleration_the_tyre_and_the_compensated_ratio_are_those_with_it(files):
    with_hub, without_hub = files
    a = analyze_campaign(with_hub).knowledge.shaker[2.5].nearest(2e-3)
    b = analyze_campaign(without_hub).knowledge.shaker[2.5].nearest(2e-3)
    assert a.hub_acceleration_recorded and not b.hub_acceleration_recorded
    # the fit does not use a_hub: the same tyre to the last digit
    assert b.identification.best_fit.values == a.identification.best_fit.values
    tyre = b.identification.best_fit.values
    assert tyre["stiffness_n_per_m"] == pytest.approx(SETUP.tyre.stiffness_n_per_m, rel=0.02)
    assert tyre["tread_mass_kg"] == pytest.approx(SETUP.tyre.tread_mass_kg, rel=0.03)
    # G_A a_hub of a clamped hub is noise: within 3 sigma of the point at every dwell
    with_a, without_a = a.compensated_per_contact, b.compensated_per_contact
    assert np.all(np.abs(without_a.value - with_a.value) <= 3 * with_a.sigma)
    assert b.valid_band_compensated.upper_hz == a.valid_band_compensated.upper_hz
    assert HUB_ACCELERATION not in b.fits[0].channels
