"""The identified tyre's 95 % intervals cover the simulator's truth over seeds: at the default noise,
with a free run that lacks its 100 Hz dwell, and with ten times the displacement noise. The errors
the points share (the displacement's in F_wfs/Z and F_contact/Z, m_comp's in every F_contact/Z)
are propagated; treated as independent, m_T was covered in 65-80 % of the seeds and k in 65 %. Over
100 seeds at 2 mm: k 92, c 96, m_T 97 (before the dwells of a seed stopped sharing their noise and
the fit's relative floor came down from 1e-4 to 1e-5: m_T 92, and 77 at 5 mm with a stated sensor)."""

import pytest

from bench.analysis import DwellRecord, analyse_shaker_campaign
from bench.analysis.records import WHEEL_CHANNELS
from bench.models.setup import BenchSetup
from bench.simulated_campaign import FREE_RUN_GRID_HZ, SHAKER_GRID_HZ, TAPER_S
from simulators.plant import PlantSimulator, SensorRealism, SineDwell
from tests.documented import assert_documented

#: Seeds per case and the fewest of them whose interval must hold the truth: a correct 95 % interval
#: covers fewer than 90 of 100 seeds with probability 1.2 %, fewer than 17 of 20 with 1.6 % (the
#: seeds are fixed, so a pass is a pass). The default case takes 100 seeds, the others 20.
SEEDS_AND_MIN_COVERED = {100: 90, 20: 17}
#: ... and the most of them whose fit may be flagged as outside its noise (a fit that describes the
#: data is, once in a hundred): more than 4 of 100 with probability 0.34 %, more than 2 of 20 with 0.1 %.
SEEDS_AND_MOST_FLAGGED = {100: 4, 20: 2}
#: How docs/analysis.md names each case after its figures.
DOCUMENTED_CASES = {
    "default": "at the default noise",
    "free-run-without-100-hz": "without the 100 Hz free-run dwell",
    "displacement-noise-x10": "with ten times the displacement noise",
}


def _dwells(setup, freqs_hz, realism) -> list[DwellRecord]:
    plant = PlantSimulator(setup, realism=realism)
    records = []
    for f in freqs_hz:
        hold_s = max(1.0, 2.2 / f + 0.2)
        rec = plant.simulate(SineDwell(f, 2e-3, hold_s, taper_in_s=TAPER_S, taper_out_s=TAPER_S))
        channels = {c: rec[c] for c in WHEEL_CHANNELS if c in rec}
        hold = (TAPER_S, TAPER_S + hold_s)
        records.append(DwellRecord(f, 2e-3, plant.output_rate_hz, channels, hold_s=hold))
    return records


@pytest.mark.validation
@pytest.mark.parametrize(
    ("free_run_grid_hz", "displacement_noise_m", "n_seeds"),
    [(FREE_RUN_GRID_HZ, 2e-6, 100), (FREE_RUN_GRID_HZ[:-1], 2e-6, 20), (FREE_RUN_GRID_HZ, 2e-5, 20)],
    ids=["default", "free-run-without-100-hz", "displacement-noise-x10"],
)
def test_intervals_cover_the_truth(free_run_grid_hz, displacement_noise_m, n_seeds, request):
    setup = BenchSetup.paper_shaker(2.5, nonlinear=False)
    truth = setup.tyre
    names = ("stiffness_n_per_m", "damping_ns_per_m", "tread_mass_kg")
    covered = dict.fromkeys(names, 0)
    flagged = 0
    for seed in range(n_seeds):
        free = _dwells(
            BenchSetup.paper_free_run(),
            free_run_grid_hz,
            SensorRealism(seed=1000 + seed, displacement_noise_m=displacement_noise_m),
        )
        grid = _dwells(
            setup, SHAKER_GRID_HZ, SensorRealism(seed=2000 + seed, displacement_noise_m=displacement_noise_m)
        )
        identification = (
            analyse_shaker_campaign(grid, free, wheel_mass_kg=29.0, sensor=setup.sensor)
            .nearest(2e-3)
            .identification
        )
        fit = identification.best_fit
        flagged += any("outside its noise" in finding for finding in identification.findings)
        for name in names:
            covered[name] += abs(fit.values[name] - getattr(truth, name)) <= fit.ci95[name]
    print(f"\n  coverage over {n_seeds} seeds: {covered}, flagged outside the noise: {flagged}")
    assert all(c >= SEEDS_AND_MIN_COVERED[n_seeds] for c in covered.values()), covered
    assert flagged <= SEEDS_AND_MOST_FLAGGED[n_seeds]
    case = DOCUMENTED_CASES[request.node.callspec.id]
    figures = "/".join(str(c) for c in covered.values())
    assert_documented("docs/analysis.md", f"{figures} of {n_seeds} seeds {case} ({flagged} flagged")
    if n_seeds == 100:  # the README quotes the default case
        k, d, m = covered.values()
        assert_documented("README.md", f"cover the truth in {k}, {d} and {m} of 100 seeds")
