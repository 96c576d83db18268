"""Wall time to analyse the data volume of the paper's whole campaign, end to end.

Campaign: 9 shaker dwell grids (1 / 2 / 5 mm x 1.5 / 2.5 / 3.5 bar, 22 frequencies 0.5-70 Hz), the
free run (13 frequencies 1-100 Hz), a four-post sweep (0.1-30 Hz over 60 s) with the post's own
free run, and a hammer test (10 kHz). The records are simulated first (not timed); the analysis
then runs the top-level API: one shaker campaign per pressure (dwell fits, m_comp, contact-force
correction, Models 1-3 per amplitude, amplitude dependence, compensator design, valid bands), the
four-post run with the 2.5 bar campaign as its tyre (m_comp of the post, m_wheel, compensation,
sweep FRFs, valid bands, quarter car with its body and wheel modes), and the hammer blow. The
baseline, timed in the same run, is a plain numpy FFT of every recorded channel (the same data
volume).

Run: ``OMP_NUM_THREADS=1 python benchmarks/analysis_speed.py`` (one core, as the target states).
"""

from __future__ import annotations

import time

import numpy as np

from bench.analysis.records import WHEEL_CHANNELS, DwellRecord, HammerRecord, SweepRecord
from bench.analysis.runs import analyse_four_post, analyse_hammer, analyse_shaker_campaign
from bench.models.benches import TyreModel
from bench.models.setup import BenchKind, BenchSetup
from simulators.plant import HalfSinePulse, PlantSimulator, SensorRealism, SineDwell, Sweep

FS = 1000.0
SHAKER_HZ = np.r_[0.5, 1, 2, 4, 7, 10, 14, 18, 22, 25, 28, 31, 34, 37, 40, 43, 46, 50, 55, 60, 65, 70]
FREE_HZ = np.r_[1, 2, 5, 10, 20, 30, 40, 50, 60, 70, 80, 90, 100]
PRESSURES_BAR = (1.5, 2.5, 3.5)
AMPLITUDES_M = (1e-3, 2e-3, 5e-3)
TAPER_S = 0.3


def _dwells(setup, freqs, amplitude, seed) -> list[DwellRecord]:
    plant = PlantSimulator(setup, realism=SensorRealism(seed=seed))
    records = []
    for f in freqs:
        hold = max(1.0, 2.2 / f + 0.2)
        rec = plant.simulate(SineDwell(float(f), amplitude, hold, taper_in_s=TAPER_S, taper_out_s=TAPER_S))
        channels = {c: rec[c] for c in WHEEL_CHANNELS}
        records.append(DwellRecord(float(f), amplitude, FS, channels, hold_s=(TAPER_S, TAPER_S + hold)))
    return records


def simulate_campaign():
    grids = {
        p: [
            r
            for i, a in enumerate(AMPLITUDES_M)
            for r in _dwells(BenchSetup.paper_shaker(p), SHAKER_HZ, a, seed=3 * j + i)
        ]
        for j, p in enumerate(PRESSURES_BAR)
    }
    free = _dwells(BenchSetup.paper_free_run(), FREE_HZ, 2e-3, seed=99)
    qc = BenchSetup.paper_quarter_car(2.5, model=TyreModel.WHEEL_TREAD)  # the shaker campaign's tyre
    post_free = _dwells(BenchSetup(BenchKind.FREE_RUN, rig=qc.rig), FREE_HZ, 2e-3, seed=98)
    sweep = Sweep(0.1, 30.0, 60.0, 2e-3)
    rec = PlantSimulator(qc, realism=SensorRealism(seed=7)).simulate(sweep)
    sweep_record = SweepRecord(
        sweep.start_hz, sweep.end_hz, sweep.amplitude, FS, {c: rec[c] for c in WHEEL_CHANNELS}
    )
    hammer_setup = BenchSetup.paper_hammer()
    hammer = PlantSimulator(hammer_setup, output_rate_hz=10 * FS).simulate(
        HalfSinePulse(amplitude=3000.0, width_s=1.5e-4, delay_s=0.02, record_s=0.3)
    )
    hammer_record = HammerRecord(10 * FS, {c: hammer[c] for c in ("fz_wfs_n", "f_hammer_n")})
    return grids, free, (post_free, sweep_record), hammer_record


def analyse_campaign(grids, free, four_post, hammer):
    sensor = BenchSetup.paper_hammer().sensor
    campaigns = {
        p: analyse_shaker_campaign(records, free, wheel_mass_kg=29.0, sensor=sensor)
        for p, records in grids.items()
    }
    post_free, sweep = four_post
    car = analyse_four_post(sweep, post_free, tyre=campaigns[2.5], wheel_mass_kg=29.0, sensor=sensor)
    return campaigns, car, analyse_hammer(hammer, sensor_mass_kg=sensor.mass_kg)


def baseline(grids, free, four_post, hammer):
    """A plain FFT of every recorded channel: the cheapest look at the same data."""
    records = [r for g in grids.values() for r in g] + free + four_post[0] + [four_post[1], hammer]
    arrays = [x for r in records for x in r.channels.values()]
    for a in arrays:
        np.fft.rfft(a)
    return sum(a.size for a in arrays)


def main() -> None:
    data = simulate_campaign()
    t0 = time.perf_counter()
    n_samples = baseline(*data)
    t_base = time.perf_counter() - t0
    t0 = time.perf_counter()
    campaigns, car, hammer = analyse_campaign(*data)
    t_analysis = time.perf_counter() - t0
    print(f"data volume: {n_samples} samples ({n_samples * 8 / 1e6:.1f} MB as float64)")
    print(f"baseline numpy FFT of every channel: {1e3 * t_base:.1f} ms")
    print(
        f"analysis end to end: {t_analysis:.3f} s ({t_analysis / t_base:.0f}x the FFT baseline; target < 2 s)"
    )
    k = {
        p: c.nearest(2e-3).identification.best_fit.tyre.stiffness_n_per_m / 1e3 for p, c in campaigns.items()
    }
    print("k at 10 Hz, 2 mm [kN/m]: " + ", ".join(f"{p} bar {v:.1f}" for p, v in k.items()))
    print("\n".join(["", "2.5 bar shaker campaign:", *campaigns[2.5].summary_lines()]))
    print("\n".join(["", *car.summary_lines(), "", *hammer.summary_lines()]))


if __name__ == "__main__":
    main()
