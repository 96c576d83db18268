"""Amplitude held within the dwell against amplitude corrected by repeats, on the paper's shaker campaign.

The shipped ``paper_shaker.toml`` (the free run and 9 dwell grids, 211 points) runs twice in the
same process through the whole chain on the simulated bench (noise, the non-linear tyre, the
servo-hydraulic actuator; the controller over Modbus TCP, the WFS over a pty), unpaced: once with
the amplitude held within the dwell (``[amplitude] hold_within_dwell = true``, the default) and once
corrected by repeats only (``false``, the baseline). From each campaign file, read back as any file:

- bench time: the samples recorded in all the campaign's runs (what the bench spends on them, rest
  between points included) and the excitation time (every attempt from its first to its last
  active sample);
- point attempts, points and the share of points repeated;
- the amplitude error of every done point, ``achieved / target - 1``, at 40-70 Hz and overall;
- the amplitude updates made within the dwells.

Unpaced, the simulated bench runs ahead of the engine by the frames buffered between them (a few
tenths of a second of samples): an update lands that much later in the hold than on a bench that
runs in real time, which makes the held dwells' figure here the pessimistic one.

    PYTHONPATH=. .venv/bin/python benchmarks/amplitude_hold.py
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from bench.app import run as app_run
from bench.app.plan import plan_sequence
from bench.config import AmplitudeConfig, default_bench_config
from bench.store import open_campaign
from benchmarks.timing import run_benchmark
from sequences import load_sequence, shipped_file

BAND_HZ = (40.0, 70.0)


@dataclass(frozen=True)
class Campaign:
    name: str
    wall_s: float
    recorded_s: float
    excitation_s: float
    attempts: int
    points: int
    repeated: int  # points with more than one attempt
    updates: int
    band_errors: np.ndarray  # relative amplitude errors of the done points in BAND_HZ
    errors: np.ndarray  # of every done point


def run_campaign(name: str, *, hold: bool) -> Campaign:
    base = default_bench_config("shaker")
    config = replace(base, amplitude=AmplitudeConfig(hold_within_dwell=hold))
    path = shipped_file("paper_shaker.toml")
    plan = plan_sequence(load_sequence(path, config.limits), config)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "campaign.h5"
        start = time.perf_counter()
        outcome = app_run.run_campaign(plan, out)
        wall_s = time.perf_counter() - start
        assert outcome.status == "complete", outcome
        recorded = excitation = 0.0
        attempts = points = repeated = updates = 0
        band, every = [], []
        with open_campaign(out) as campaign:
            for run in campaign.runs:
                recorded += run.n_samples / run.sample_rate_hz
                excitation += sum(p.end_sample - p.start_sample for p in run.points) / run.sample_rate_hz
                attempts += len(run.points)
                updates += sum(p.amplitude_updates for p in run.points)
                for p in run.points:
                    if p.status != "done":
                        continue
                    points += 1
                    repeated += p.attempt > 1
                    error = p.achieved_amplitude_mm / p.amplitude_mm - 1
                    every.append(error)
                    if BAND_HZ[0] <= p.freq_hz <= BAND_HZ[1]:
                        band.append(error)
    return Campaign(
        name,
        wall_s,
        recorded,
        excitation,
        attempts,
        points,
        repeated,
        updates,
        np.array(band),
        np.array(every),
    )


def report(c: Campaign) -> None:
    print(
        f"  {c.name}: {c.recorded_s:.1f} s recorded, {c.excitation_s:.1f} s of excitation;"
        f" {c.points} points in {c.attempts} attempts, {c.repeated} repeated"
        f" ({100 * c.repeated / c.points:.1f} %); {c.updates} amplitude updates; run in {c.wall_s:.1f} s wall"
    )
    for what, errors in ((f"{BAND_HZ[0]:g}-{BAND_HZ[1]:g} Hz", c.band_errors), ("all", c.errors)):
        largest, rms = np.max(np.abs(errors)), np.sqrt(np.mean(errors**2))
        print(
            f"    amplitude error, {what} ({errors.size} points): largest {100 * largest:.2f} %,"
            f" rms {100 * rms:.2f} %, beyond 2 %: {int(np.sum(np.abs(errors) > 0.02))}"
        )


def main() -> None:
    held = run_campaign("held within the dwell", hold=True)
    repeats = run_campaign("corrected by repeats (baseline)", hold=False)
    print("paper_shaker.toml, unpaced, on the simulated servo-hydraulic actuator:")
    report(held)
    report(repeats)
    print(
        f"  held / repeats: bench time {held.recorded_s / repeats.recorded_s:.3f},"
        f" excitation {held.excitation_s / repeats.excitation_s:.3f},"
        f" attempts {held.attempts / repeats.attempts:.3f}"
    )


if __name__ == "__main__":
    run_benchmark(main)
