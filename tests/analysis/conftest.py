"""Simulated runs shared by the analysis tests (session-scoped: each run is simulated once)."""

from dataclasses import dataclass, replace

import pytest

from bench.analysis.dwell import DwellFit
from bench.analysis.records import WHEEL_CHANNELS, DwellRecord, SweepRecord, fit_dwell_record
from bench.analysis.runs import (
    FourPostResult,
    ShakerCampaignResult,
    analyse_four_post,
    analyse_shaker_campaign,
)
from bench.models.benches import TyreModel
from bench.models.parameters import Suspension, Tyre
from bench.models.setup import BenchKind, BenchSetup
from bench.simulated_campaign import (
    FREE_RUN_GRID_HZ,
    PAPER_SWEEP,
    SHAKER_GRID_HZ,
    simulate_dwells,
    simulate_sweep,
)
from simulators.plant import IdealServo, PlantSimulator

#: A tyre that is not the paper's: softer, heavier tread, more damping, lighter wheel.
OTHER_TYRE = Tyre(stiffness_n_per_m=290e3, damping_ns_per_m=125.0, wheel_mass_kg=26.0, tread_mass_kg=4.6)


@dataclass
class DwellRun:
    """A simulated dwell grid: the ``records`` as the run engine stores them and their ``fits``."""

    plant: PlantSimulator
    amplitude_m: float
    records: list[DwellRecord]
    fits: list[DwellFit]


def run_dwells(setup, freqs, amplitude_m, seed) -> DwellRun:
    """A simulated dwell grid with the true contact force kept for comparison, and its fits."""
    records = simulate_dwells(setup, freqs, amplitude_m, seed=seed, include_truth=True)
    fits = [fit_dwell_record(r, WHEEL_CHANNELS) for r in records]
    return DwellRun(PlantSimulator(setup, actuator=IdealServo()), amplitude_m, records, fits)


@pytest.fixture(scope="session")
def free_run() -> DwellRun:
    return run_dwells(BenchSetup.paper_free_run(), FREE_RUN_GRID_HZ, 2e-3, seed=11)


@pytest.fixture(scope="session")
def shaker_linear() -> DwellRun:
    return run_dwells(BenchSetup.paper_shaker(2.5, nonlinear=False), SHAKER_GRID_HZ, 2e-3, seed=12)


@pytest.fixture(scope="session")
def shaker_other_tyre() -> DwellRun:
    setup = BenchSetup.paper_shaker(2.5, nonlinear=False).with_tyre(OTHER_TYRE)
    return run_dwells(setup, SHAKER_GRID_HZ, 2e-3, seed=13)


@pytest.fixture(scope="session")
def shaker_nonlinear() -> dict[float, DwellRun]:
    setup = BenchSetup.paper_shaker(2.5, nonlinear=True)
    return {a: run_dwells(setup, SHAKER_GRID_HZ, a, seed=20 + i) for i, a in enumerate((1e-3, 2e-3, 5e-3))}


@pytest.fixture(
    scope="session", params=[TyreModel.WHEEL_TREAD, TyreModel.WHEEL_TREAD_SIDEWALL], ids=["m2", "m3"]
)
def four_post(request) -> tuple[BenchSetup, SweepRecord]:
    """One corner of the paper's vehicle (non-linear tyre, Model 2 or 3 as the truth) on a linear
    sine sweep 0.1-30 Hz over 60 s at 2 mm."""
    setup = BenchSetup.paper_quarter_car(2.5, model=request.param)
    return setup, simulate_sweep(setup, PAPER_SWEEP, seed=30 + int(request.param), include_truth=True)


@pytest.fixture(scope="session")
def four_post_free_run() -> DwellRun:
    """The four-post rig's post without a vehicle: its own plate mass (m_comp) to identify."""
    rig = BenchSetup.paper_quarter_car().rig
    return run_dwells(BenchSetup(BenchKind.FREE_RUN, rig=rig), FREE_RUN_GRID_HZ, 2e-3, seed=14)


#: A quarter car that is not the paper's: heavier hub carrier, lighter and softer-sprung body, softer
#: damper (body mode 1.5 Hz, wheel mode 11.9 Hz with OTHER_TYRE).
OTHER_SUSPENSION = Suspension(
    unsprung_mass_above_kg=33.0, stiffness_n_per_m=26e3, damping_ns_per_m=2100.0, body_mass_kg=290.0
)


@pytest.fixture(scope="session")
def shaker_other_tyre_nonlinear() -> DwellRun:
    """OTHER_TYRE with the simulator's rubber non-linearity on the shaker, 2 mm."""
    setup = BenchSetup.paper_shaker(2.5, nonlinear=True).with_tyre(OTHER_TYRE)
    return run_dwells(setup, SHAKER_GRID_HZ, 2e-3, seed=15)


@pytest.fixture(scope="session")
def four_post_other_car() -> tuple[BenchSetup, SweepRecord]:
    """OTHER_TYRE (non-linear, Model 2) under OTHER_SUSPENSION on the same post as the paper's car."""
    paper = BenchSetup.paper_quarter_car(2.5, model=TyreModel.WHEEL_TREAD)
    setup = replace(paper, tyre=OTHER_TYRE, suspension=OTHER_SUSPENSION)
    return setup, simulate_sweep(setup, PAPER_SWEEP, seed=40, include_truth=True)


@pytest.fixture(scope="session")
def shaker_model3_nonlinear() -> DwellRun:
    """The paper's tyre at 2.5 bar with Model 3 (sidewall) as the truth on the shaker, 2 mm."""
    setup = BenchSetup.paper_shaker(2.5, model=TyreModel.WHEEL_TREAD_SIDEWALL, nonlinear=True)
    return run_dwells(setup, SHAKER_GRID_HZ, 2e-3, seed=16)


def analyse_runs(runs: list[DwellRun], free: DwellRun) -> ShakerCampaignResult:
    """The shaker campaign of the dwell grids ``runs`` (one tyre, one or more amplitudes)."""
    setup = runs[0].plant.setup
    return analyse_shaker_campaign(
        [r for run in runs for r in run.records],
        free.records,
        wheel_mass_kg=setup.tyre.wheel_mass_kg,
        sensor=setup.sensor,
    )


@pytest.fixture(scope="session")
def shaker_nonlinear_campaign(shaker_nonlinear, free_run) -> ShakerCampaignResult:
    return analyse_runs(list(shaker_nonlinear.values()), free_run)


@pytest.fixture(scope="session")
def shaker_model3_campaign(shaker_model3_nonlinear, free_run) -> ShakerCampaignResult:
    return analyse_runs([shaker_model3_nonlinear], free_run)


def same_tyre_campaign(setup: BenchSetup, request) -> ShakerCampaignResult:
    """The shaker campaign of the tyre a four-post car of the paper stands on (same model)."""
    if setup.model is TyreModel.WHEEL_TREAD_SIDEWALL:
        return request.getfixturevalue("shaker_model3_campaign")
    return request.getfixturevalue("shaker_nonlinear_campaign")


@pytest.fixture(scope="session")
def four_post_analysis(four_post, four_post_free_run, request) -> tuple[BenchSetup, FourPostResult]:
    """The paper's four-post run analysed with its post's free run and the same tyre's shaker campaign."""
    setup, sweep = four_post
    result = analyse_four_post(
        sweep,
        four_post_free_run.records,
        tyre=same_tyre_campaign(setup, request),
        wheel_mass_kg=setup.tyre.wheel_mass_kg,
        sensor=setup.sensor,
    )
    return setup, result
