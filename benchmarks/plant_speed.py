"""Simulated seconds per wall second of the plant, all sensor models on, at 1 kHz output.

    .venv/bin/python benchmarks/plant_speed.py [--seconds 60] [--repeats 5]

Each bench streams in 1-second blocks, as the simulated WFS device asks for them, two ways:
a dwell grid as in the paper's campaigns (10 s dwells, the non-linear tyre linearised once per
dwell) and a sweep rescheduled every second. The figure is the best of several repeats; the
baseline, measured in the same run, is one vectorised ``numpy.sin`` over the same number of
internal samples, so the ratio tells how many such passes the plant costs, whatever the
machine's load. Target: >= 500x real time.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # one core, as the target states

import argparse

import numpy as np

from bench.models.setup import BenchSetup
from benchmarks.timing import best_time_s
from simulators.plant import PlantSimulator, SensorRealism, Sweep

DWELL_S = 10


def stream(setup: BenchSetup, seconds: float, reschedule_every_s: int) -> None:
    plant = PlantSimulator(setup, realism=SensorRealism(seed=1))
    sweep = Sweep(0.5, 70.0, seconds, 0.002)
    t = np.arange(round(plant.internal_rate_hz)) / plant.internal_rate_hz
    for second in range(int(seconds)):
        if second % reschedule_every_s == 0:
            plant.set_operating_point(sweep.frequency_hz(second), sweep.amplitude)
        plant.advance(sweep.value(second + t))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="simulated seconds per repeat")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()

    samples = np.arange(round(args.seconds * 10_000)) * 1e-4
    baseline_s = best_time_s(lambda: np.sin(samples), args.repeats)
    print(f"baseline: numpy.sin over {samples.size} samples: {baseline_s * 1e3:.2f} ms")
    for name, setup in [
        ("shaker, Model 2, non-linear tyre", BenchSetup.paper_shaker(2.5)),
        ("quarter car, Model 3, non-linear tyre", BenchSetup.paper_quarter_car(2.5)),
    ]:
        for mode, every_s in [(f"{DWELL_S} s dwells", DWELL_S), ("sweep, rescheduled every 1 s", 1)]:
            wall_s = best_time_s(lambda s=setup, e=every_s: stream(s, args.seconds, e), args.repeats)
            print(
                f"{name}, {mode}: {args.seconds / wall_s:5.0f}x real time "
                f"({wall_s / baseline_s:5.1f} baseline passes; {args.seconds:.0f} s in {wall_s:.3f} s)"
            )


if __name__ == "__main__":
    main()
