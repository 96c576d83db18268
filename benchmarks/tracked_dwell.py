"""Tracked resonance dwell: its frequency error against the moving true resonance.

A ``tracked_dwell`` (search 34-48 Hz in 8 dwells, then 60 s of track at 1 mm) runs on the simulated
shaker at 2.5 bar (Modbus TCP, WFS on a pty, unpaced) while the world lowers the tyre's stiffness by
0.1 % per second of bench time with a seeded wander (a tyre warming up): the tread resonance falls by
about 0.05 % per second. Per look, the resonance the track estimated and the drive frequency against
the true resonance at that moment (the plant's own peak of F_WFS / F_contact, the tyre linearised
at 1 mm); the baseline, in the same run, is a dwell left at the frequency the search found.

    PYTHONPATH=. .venv/bin/python benchmarks/tracked_dwell.py
"""

from __future__ import annotations

import time

import numpy as np

from bench.app.devices import open_bench
from bench.app.engine_build import build_engine
from bench.config import default_bench_config
from bench.engine import events as ev
from bench.models.setup import BenchSetup
from sequences import Hydraulics, Sequence, TrackedDwell
from simulators.world import TyreDrift, drifted, wfs_contact_peak_hz

DRIFT = TyreDrift(-0.001, wander_per_sqrt_s=0.0005, seed=3)
STEP = TrackedDwell(34.0, 48.0, 1.0, search_points=8, plate_mass_kg=12.0, track_s=60.0, freq_band_pct=10.0)


def main() -> None:
    config = default_bench_config("shaker")
    sequence = Sequence("track", "", (Hydraulics("low"), Hydraulics("high"), STEP), "<benchmark>")
    looks: list[ev.ResonanceTracked] = []
    armed: dict[str, int] = {}
    samples = [0]
    with open_bench(config) as devices:
        engine = build_engine(config, devices)
        world = devices.lab.world

        def follow(event: ev.Event) -> None:
            if isinstance(event, ev.SamplesRecorded):
                samples[0] = event.first_sample + len(event)
            elif isinstance(event, ev.PointStarted) and event.index == len(STEP.search_freqs_hz()):
                world.drift_tyre(DRIFT)
                armed["sample"] = samples[0]
            elif isinstance(event, ev.ResonanceTracked):
                looks.append(event)

        engine.bus.subscribe(follow)
        start = time.perf_counter()
        outcome = engine.run(sequence)
        wall_s = time.perf_counter() - start
    assert outcome.status == "complete", outcome
    rate_hz = float(config.wfs.rate_hz)
    t_s = np.array([(look.sample - armed["sample"]) / rate_hz - STEP.update_s / 2 for look in looks])
    path: list[float] = []
    nominal = BenchSetup.paper_shaker(2.5)
    truth = np.array(
        [wfs_contact_peak_hz(drifted(nominal, DRIFT.factor(t, path)), 1e-3, (35.0, 45.0)) for t in t_s]
    )
    estimated = np.array([look.resonance_hz for look in looks])
    drive = np.array([look.drive_hz for look in looks])
    found = looks[0].drive_hz
    errors = {
        "tracked resonance": estimated / truth - 1,
        "tracked drive": drive / truth - 1,
        "left at the found frequency (baseline)": found / truth - 1,
    }
    print(
        f"tracked dwell, {len(looks)} looks over {t_s[-1]:.1f} s of track; the true resonance moved"
        f" {truth[0]:.3f} -> {truth[-1]:.3f} Hz; run in {wall_s:.1f} s wall"
    )
    baseline = np.max(np.abs(errors["left at the found frequency (baseline)"]))
    for name, e in errors.items():
        largest = np.max(np.abs(e))
        print(
            f"  {name}: largest {100 * largest:.3f} %, rms {100 * np.sqrt(np.mean(e**2)):.3f} %"
            f" ({largest / baseline:.3f} of the baseline's largest)"
        )


if __name__ == "__main__":
    main()
