"""A sequence run through the engine on the simulated bench, unpaced: how much faster than real time,
and what the engine costs per point.

The whole chain runs: the controller over Modbus TCP on 127.0.0.1, the WFS over a pty, the engine,
the HDF5 recorder and the post-run analysis. Figures:

- recorded sample time over wall time (how much faster than the bench's real time);
- the engine's overhead per point: the wall time of its actuator calls (configure, start, status
  readbacks, stops) per point, against the point's own duration (sample time from its first to
  its last active sample);
- baseline, measured in the same run: the plant alone simulating the same sample time as one dwell
  at 1 kHz output (no links, no recording), as the ratio of its speed to the chain's.

    PYTHONPATH=. .venv/bin/python benchmarks/campaign_speed.py [--sequence paper_shaker.toml]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from bench.app import run as app_run
from bench.app.plan import plan_sequence
from bench.config import default_bench_config
from bench.engine import events as ev
from bench.models.setup import BenchSetup
from bench.store import open_campaign
from benchmarks.timing import best_time_s, run_benchmark
from sequences import load_sequence, shipped_file
from simulators.plant import PlantSimulator, SensorRealism, SineDwell


class TimedActuator:
    """The actuator contract with the wall time of every call added up."""

    def __init__(self, actuator) -> None:
        self._actuator = actuator
        self.seconds = 0.0
        self.calls = 0

    def __getattr__(self, name: str):
        method = getattr(self._actuator, name)

        def timed(*args, **kwargs):
            start = time.perf_counter()
            try:
                return method(*args, **kwargs)
            finally:
                self.seconds += time.perf_counter() - start
                self.calls += 1

        return timed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--sequence", default="smoke.toml", help="a shipped sequence file")
    parser.add_argument("--kind", default="shaker", choices=("shaker", "four_post"))
    args = parser.parse_args()

    config = default_bench_config(args.kind)
    path = shipped_file(args.sequence)
    plan = plan_sequence(load_sequence(path, config.limits), config, path.read_text())
    timed: list[TimedActuator] = []
    build = app_run.build_engine

    def build_timed(config, devices):
        devices.actuator = TimedActuator(devices.actuator)
        timed.append(devices.actuator)
        return build(config, devices)

    app_run.build_engine = build_timed
    points: list[ev.PointDone] = []
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "campaign.h5"
        start = time.perf_counter()
        outcome = app_run.run_campaign(
            plan, out, subscribers=(lambda e: points.append(e) if isinstance(e, ev.PointDone) else None,)
        )
        wall_s = time.perf_counter() - start
        with open_campaign(out) as campaign:
            recorded_s = sum(run.n_samples / run.sample_rate_hz for run in campaign.runs)
    rate_hz = config.wfs.rate_hz
    point_s = sum(p.end_sample - p.start_sample for p in points) / rate_hz

    plant = PlantSimulator(BenchSetup.paper_shaker(2.5), SensorRealism(seed=1))
    dwell = SineDwell(40.0, 2e-3, recorded_s, taper_in_s=0.3, taper_out_s=0.3)
    plant_s = best_time_s(lambda: plant.simulate(dwell), repeats=1)

    actuator = timed[0]
    print(f"sequence {plan.sequence.name}: {outcome.status}, {len(points)} point attempts")
    print(
        f"recorded {recorded_s:.1f} s of samples in {wall_s:.2f} s wall: {recorded_s / wall_s:.1f}x real time"
    )
    print(
        f"baseline: the plant alone simulates {recorded_s:.1f} s in {plant_s:.2f} s"
        f" ({recorded_s / plant_s:.0f}x real time); the whole chain takes {wall_s / plant_s:.1f}x"
        " the plant's time"
    )
    per_point_ms = 1e3 * actuator.seconds / len(points)
    print(
        f"engine's actuator calls: {actuator.calls} in {actuator.seconds:.2f} s,"
        f" {per_point_ms:.1f} ms per point attempt against {1e3 * point_s / len(points):.0f} ms of excitation"
        f" ({100 * actuator.seconds / point_s:.2f} % of the points' own duration)"
    )


if __name__ == "__main__":
    run_benchmark(main)
