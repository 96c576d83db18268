"""The settling verdict's false-alarm rate on good short dwells of the simulated plant, and that it
still catches a dwell analysed before its free vibration died out."""

import numpy as np
import pytest

from bench.analysis.records import WHEEL_CHANNELS, DwellRecord, fit_dwell_record
from bench.models.setup import BenchSetup
from bench.simulated_campaign import SHAKER_GRID_HZ, TAPER_S
from simulators.plant import PlantSimulator, SensorRealism, SineDwell
from tests.documented import assert_documented

N_SEEDS = 20


def _two_cycle_grid(seed: int) -> list[DwellRecord]:
    """The shaker grid with holds of two cycles after the analysis's 0.2 s settling allowance."""
    plant = PlantSimulator(BenchSetup.paper_shaker(2.5, nonlinear=False), realism=SensorRealism(seed=seed))
    records = []
    for f in SHAKER_GRID_HZ:
        hold_s = 2.05 / f + 0.2 + 0.35  # the settling allowance and 0.35 s of taper-in ringing
        rec = plant.simulate(SineDwell(f, 2e-3, hold_s, taper_in_s=TAPER_S, taper_out_s=TAPER_S))
        channels = {c: rec[c] for c in WHEEL_CHANNELS}
        hold = (TAPER_S + 0.35, TAPER_S + hold_s)
        records.append(DwellRecord(f, 2e-3, plant.output_rate_hz, channels, hold_s=hold))
    return records


@pytest.mark.validation
@pytest.mark.slow
def test_false_alarm_rate_of_good_two_cycle_dwells():
    """440 good dwells of two cycles each (20 seeds x 22 frequencies): at most 1 % flagged (the
    fixed seeds' figure is the one docs/analysis.md quotes). The fixed 1.5x residual limit flagged
    about 3 per grid (about 60 here); a settling test told the white-noise level of the whole
    residual instead of the density at the dwell's frequency, and dwells that shared one seed's
    noise, flagged 8."""
    flagged = []
    for seed in range(N_SEEDS):
        for record in _two_cycle_grid(seed):
            fit = fit_dwell_record(record, WHEEL_CHANNELS, settle_s=0.2)
            assert fit.n_cycles == 2
            if not fit.settled:
                flagged.append((seed, record.label, fit.notes))
    print(f"\n  {len(flagged)} of {N_SEEDS * len(SHAKER_GRID_HZ)} good two-cycle dwells flagged")
    assert len(flagged) <= 0.01 * N_SEEDS * len(SHAKER_GRID_HZ), flagged
    total = N_SEEDS * len(SHAKER_GRID_HZ)
    said = f"Of {total} good two-cycle dwells of the simulated plant {len(flagged)} are flagged"
    assert_documented("docs/analysis.md", said)


def test_unsettled_short_dwell_still_caught():
    """The same two-cycle dwells analysed from the start of the taper-in (settle 0, hold from 0):
    the amplitude still rises and the free vibration decays; every such dwell above 2 Hz is flagged."""
    records = _two_cycle_grid(0)
    caught = []
    for record in records:
        early = DwellRecord(
            record.freq_hz, 2e-3, record.sample_rate_hz, record.channels, hold_s=(0.0, 2.05 / record.freq_hz)
        )
        caught.append(not fit_dwell_record(early, WHEEL_CHANNELS, settle_s=0.0).settled)
    assert np.all(np.array(caught)[SHAKER_GRID_HZ > 2])
