"""The paper's campaign recorded on the simulated plant, as the analysis's records.

A composition root like the CLI: it joins the simulators to the analysis records, so the demo, the
analysis benchmark and the tests make their simulated runs one way. Records carry the measured
channels only, as a real bench records them; ``include_truth`` adds the plant's true contact force
(``f_contact_n``) for tests that compare against it.

The plant is driven by the ideal servo (:class:`simulators.plant.IdealServo`): these records stand
for a campaign whose every dwell reached its commanded amplitude, as the run engine's amplitude
control achieves on the servo-hydraulic actuator (and beyond its flow limit, which a campaign's
grid respects). Runs through the engine use the servo-hydraulic actuator.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.analysis.records import WHEEL_CHANNELS, DwellRecord, HammerRecord, SweepRecord
from bench.models.benches import TyreModel
from bench.models.parameters import PAPER_TYRE_STIFFNESS_N_PER_M
from bench.models.setup import BenchKind, BenchSetup
from simulators.plant import HalfSinePulse, IdealServo, PlantSimulator, SensorRealism, SineDwell, Sweep

#: The shaker dwell grid, 0.5-70 Hz, denser around the tread resonance of any plausible tyre.
SHAKER_GRID_HZ = np.r_[0.5, 1, 2, 4, 7, 10, 14, 18, 22, 25, 28, 31, 34, 37, 40, 43, 46, 50, 55, 60, 65, 70]
#: The free run without a wheel, 1-100 Hz (paper, 2.3).
FREE_RUN_GRID_HZ = np.r_[1, 2, 5, 10, 20, 30, 40, 50, 60, 70, 80, 90, 100]
PAPER_AMPLITUDES_M = (1e-3, 2e-3, 5e-3)
#: The four-post linear sine sweep 0.1-30 Hz (paper, 2.4) over 60 s at 2 mm.
PAPER_SWEEP = Sweep(0.1, 30.0, 60.0, 2e-3)
TAPER_S = 0.3
TRUTH_CHANNEL = "f_contact_n"


def simulate_dwells(
    setup: BenchSetup,
    freqs_hz: np.ndarray,
    amplitude_m: float,
    *,
    seed: int,
    include_truth: bool = False,
) -> list[DwellRecord]:
    """One sine dwell per frequency: 0.3 s tapers and a hold of at least 1 s and 2.2 cycles plus
    the analysis's 0.2 s settling allowance."""
    plant = PlantSimulator(setup, realism=SensorRealism(seed=seed), actuator=IdealServo())
    keep = (*WHEEL_CHANNELS, TRUTH_CHANNEL) if include_truth else WHEEL_CHANNELS
    records = []
    for f in np.asarray(freqs_hz, dtype=float):
        hold_s = max(1.0, 2.2 / f + 0.2)
        rec = plant.simulate(SineDwell(f, amplitude_m, hold_s, taper_in_s=TAPER_S, taper_out_s=TAPER_S))
        channels = {c: rec[c] for c in keep}
        records.append(
            DwellRecord(f, amplitude_m, plant.output_rate_hz, channels, hold_s=(TAPER_S, TAPER_S + hold_s))
        )
    return records


def simulate_sweep(setup: BenchSetup, sweep: Sweep, *, seed: int, include_truth: bool = False) -> SweepRecord:
    plant = PlantSimulator(setup, realism=SensorRealism(seed=seed), actuator=IdealServo())
    rec = plant.simulate(sweep)
    keep = (*WHEEL_CHANNELS, TRUTH_CHANNEL) if include_truth else WHEEL_CHANNELS
    return SweepRecord(
        sweep.start_hz,
        sweep.end_hz,
        sweep.sweep_s,
        sweep.amplitude,
        plant.output_rate_hz,
        {c: rec[c] for c in keep},
    )


def simulate_hammer(setup: BenchSetup | None = None, *, seed: int = 0) -> HammerRecord:
    """A hammer blow on the bare sensor, recorded at 10 kHz as in the paper's Figure 3."""
    plant = PlantSimulator(
        setup or BenchSetup.paper_hammer(), realism=SensorRealism(seed=seed), output_rate_hz=10_000.0
    )
    rec = plant.simulate(HalfSinePulse(amplitude=3000.0, width_s=1.5e-4, delay_s=0.02, record_s=0.3))
    return HammerRecord(plant.output_rate_hz, {c: rec[c] for c in plant.channels})


@dataclass(frozen=True)
class PaperCampaign:
    """Every record of the paper's campaign on the simulated bench."""

    shaker: dict[float, list[DwellRecord]]  # per tyre pressure (bar): 1 / 2 / 5 mm dwell grids
    shaker_free_run: list[DwellRecord]
    post_free_run: list[DwellRecord]
    four_post: SweepRecord
    hammer: HammerRecord
    quarter_car: BenchSetup


def simulate_paper_campaign(
    seed: int = 1, four_post_model: TyreModel = TyreModel.WHEEL_TREAD
) -> PaperCampaign:
    """Shaker dwells at 1.5 / 2.5 / 3.5 bar and 1 / 2 / 5 mm, the free run, the four-post sweep of
    one corner at 2.5 bar with the post's own free run, and a hammer blow; non-linear tyre."""
    shaker = {
        pressure: [
            record
            for i, amplitude in enumerate(PAPER_AMPLITUDES_M)
            for record in simulate_dwells(
                BenchSetup.paper_shaker(pressure), SHAKER_GRID_HZ, amplitude, seed=seed + 10 * j + i
            )
        ]
        for j, pressure in enumerate(sorted(PAPER_TYRE_STIFFNESS_N_PER_M))
    }
    car = BenchSetup.paper_quarter_car(2.5, model=four_post_model)
    return PaperCampaign(
        shaker=shaker,
        shaker_free_run=simulate_dwells(BenchSetup.paper_free_run(), FREE_RUN_GRID_HZ, 2e-3, seed=seed + 100),
        post_free_run=simulate_dwells(
            BenchSetup(BenchKind.FREE_RUN, rig=car.rig), FREE_RUN_GRID_HZ, 2e-3, seed=seed + 101
        ),
        four_post=simulate_sweep(car, PAPER_SWEEP, seed=seed + 102),
        hammer=simulate_hammer(seed=seed + 103),
        quarter_car=car,
    )
