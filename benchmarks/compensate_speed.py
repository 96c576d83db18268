"""``wfsbench compensate`` throughput and memory on an hour of 1 kHz road data.

An hour of ISO 8608 class C road at 60 km/h on the simulated quarter car (3.6 million samples of
Fz and hub acceleration), compensated with the demo campaign's identification as the command does:
the filters designed at the measurement's rate, then the compensated force and its 95 % band
computed block by block (:class:`bench.analysis.measurement_compensation.CompensationStream`), once
consumed in memory and once written to the HDF5 output. Against, in the same run:

- the baseline: one FIR of the compensator's length over the same hour by ``scipy.signal.lfilter``
  (what filtering the force alone, with no band, costs);
- the memory of the whole-record way: every filter of the compensation (the compensator's two,
  one per parameter, one per other amplitude) applied by ``lfilter`` to the whole record at once,
  each result kept, as an implementation without blocks would.

Throughput is samples per second over the rate (x real time); peak memory is the largest traced
allocation (``tracemalloc``; numpy reports its arrays to it) beyond the inputs.

    PYTHONPATH=. .venv/bin/python benchmarks/compensate_speed.py [--campaign FILE] [--hours H]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path

from scipy.signal import lfilter

from bench.analysis.measurement_noise import noise_band_hz, white_noise_rms
from bench.analysis.records import HUB_ACCELERATION, WFS_FORCE
from bench.app.analyze import analyze_campaign
from bench.app.compensate import prepare_compensation, write_output
from bench.models.benches import TyreModel
from bench.models.road import road_drive
from bench.models.setup import BenchSetup
from bench.simulated_road import simulate_road
from bench.store.measurement import Measurement

RATE_HZ = 1000.0
CAR = BenchSetup.paper_quarter_car(2.5, model=TyreModel.WHEEL_TREAD)


def _measured(run: Callable[[], object]) -> tuple[float, float]:
    """Processor seconds and traced peak (MB) of ``run``."""
    tracemalloc.start()
    start = time.process_time()
    run()
    seconds = time.process_time() - start
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return seconds, peak / 1e6


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--campaign", help="a campaign file with the 2.5 bar tyre (default: run the demo)")
    parser.add_argument("--hours", type=float, default=1.0, help="hours of road (default 1)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        if args.campaign is None:
            from bench.demo import run_demo

            run_demo(folder, seed=1)
        analysis = analyze_campaign(Path(args.campaign) if args.campaign else folder / "campaign.h5")
        start = time.perf_counter()
        drive = road_drive("C", speed_km_h=60, duration_s=3600 * args.hours, sample_rate_hz=RATE_HZ, seed=11)
        record = simulate_road(CAR, drive, seed=12)
        channels = {name: record.channels[name] for name in (WFS_FORCE, HUB_ACCELERATION)}
        measurement = Measurement("road C 60 km/h", RATE_HZ, channels)
        n = measurement.n_samples
        print(f"{n} samples ({n / RATE_HZ / 3600:g} h) simulated in {time.perf_counter() - start:.0f} s")
        del record, drive

        compensation = prepare_compensation(analysis, measurement, 2.5)
        start = time.process_time()  # a second time: the first pays for the freed simulation's memory
        compensation = prepare_compensation(analysis, measurement, 2.5)
        design_s = time.process_time() - start
        filters = compensation.filters
        start = time.process_time()
        band = noise_band_hz(filters.basis.band_hz, RATE_HZ)
        for x in channels.values():
            white_noise_rms(x, RATE_HZ, band)
        noise_s = time.process_time() - start
        n_parameters, n_others = filters.sensitivity_wfs.shape[1], filters.deviation_wfs.shape[1]
        print(
            f"filters: {filters.n_taps} taps, {2 * (1 + n_parameters + n_others)} FIRs (compensator,"
            f" {n_parameters} parameters, {n_others} other amplitudes, each on Fz and a_hub);"
            f" designed in {design_s:.2f} s, of which the two channels' noise estimate {noise_s:.2f} s"
        )

        def consume() -> None:
            for block in compensation.blocks():
                block.force_n.sum()

        blocks_s, blocks_mb = _measured(consume)
        out = folder / "out.h5"
        write_s, write_mb = _measured(lambda: write_output(compensation, out, campaign=Path("campaign.h5")))
        size_mb = out.stat().st_size / 1e6
        x = channels[WFS_FORCE]
        baseline_s, baseline_mb = _measured(lambda: lfilter(filters.compensator.taps_wfs, [1.0], x))
        a = channels[HUB_ACCELERATION] - compensation.accelerometer_offset_m_s2
        columns_f = [filters.compensator.taps_wfs, *filters.sensitivity_wfs.T, *filters.deviation_wfs.T]
        columns_a = [filters.compensator.taps_accel, *filters.sensitivity_accel.T, *filters.deviation_accel.T]
        whole_s, whole_mb = _measured(
            lambda: [
                lfilter(h_f, [1.0], x) + lfilter(h_a, [1.0], a)
                for h_f, h_a in zip(columns_f, columns_a, strict=True)
            ]
        )
    realtime = n / RATE_HZ
    print(f"\ninputs: {2 * n * 8 / 1e6:.0f} MB (two float64 channels), held by the caller in every case\n")
    print("| what | processor time | x real time | against the baseline | traced peak beyond the inputs |")
    print("|---|---|---|---|---|")
    rows = (
        ("baseline: one FIR of the same length (lfilter), Fz only", baseline_s, baseline_mb),
        ("compensate: force and 95 % band, block by block, in memory", blocks_s, blocks_mb),
        (f"compensate: the same written to the HDF5 output ({size_mb:.0f} MB)", write_s, write_mb),
        ("every filter by lfilter over the whole record, kept (no blocks)", whole_s, whole_mb),
    )
    for name, seconds, mb in rows:
        print(
            f"| {name} | {seconds:.2f} s | {realtime / seconds:,.0f}x | {seconds / baseline_s:.2f}x the time"
            f" | {mb:.0f} MB |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
