"""`wfsbench demo` as a user runs it, against the sample time it records: how much faster than
real time, with and without the fixed costs around the campaign.

The command runs in a subprocess of its own (a fresh interpreter: imports included), once per
``--repeats``. Figures per run:

- the whole command's wall time (imports, the three sequences, the report) against the sample
  time recorded in its campaign file;
- the campaign alone (the three sequences through the engine, as the demo's own line reports it);
- how much of the recorded sample time lies within the points' excitations (the rest is rest
  recorded between points while the engine configures and starts the next one);
- baseline, measured in the same run: the plant alone simulating the recorded sample time as one
  dwell (no links, no recording, no analysis), as a ratio to the whole command's time.

    PYTHONPATH=. .venv/bin/python benchmarks/demo_speed.py [--repeats 3]
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py

from bench.models.setup import BenchSetup
from benchmarks.timing import best_time_s
from simulators.plant import PlantSimulator, SensorRealism, SineDwell

CAMPAIGN_LINE = re.compile(r"recorded (?P<recorded>[\d.]+) s of samples in (?P<wall>[\d.]+) s")


def excitation_s(path: Path) -> tuple[float, float]:
    """(recorded sample time, sample time within the points' excitations) of a campaign file (s),
    read with h5py directly: every run's channel length and its points table."""
    recorded = within = 0.0
    with h5py.File(path, "r") as f:
        for run in f["runs"].values():
            rate_hz = float(run.attrs["sample_rate_hz"])
            recorded += next(iter(run["channels"].values())).shape[0] / rate_hz
            points = run["points"][()]
            within += float((points["end_sample"] - points["start_sample"]).sum()) / rate_hz
    return recorded, within


def command_time_s(out_dir: Path) -> tuple[float, float]:
    """Wall time of the whole demo command (a fresh interpreter) and of its campaign (the demo's
    own line), in seconds."""
    start = time.perf_counter()
    run = subprocess.run(
        [sys.executable, "-m", "bench.cli", "demo", "--out", str(out_dir)],
        capture_output=True,
        text=True,
        check=True,
    )
    whole_s = time.perf_counter() - start
    campaign = CAMPAIGN_LINE.search(run.stdout)
    if campaign is None:
        raise SystemExit(f"the demo printed no campaign line:\n{run.stdout[-2000:]}")
    return whole_s, float(campaign["wall"])


def plant_time_s(sample_time_s: float) -> float:
    """Wall time of the plant alone simulating ``sample_time_s`` of one dwell at 1 kHz output (s)."""
    plant = PlantSimulator(BenchSetup.paper_shaker(2.5), SensorRealism(seed=1))
    return best_time_s(lambda: plant.simulate(SineDwell(40.0, 2e-3, sample_time_s)), repeats=1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    for _ in range(args.repeats):
        with tempfile.TemporaryDirectory() as tmp:
            command_s, campaign_s = command_time_s(Path(tmp))
            recorded_s, within_s = excitation_s(Path(tmp) / "campaign.h5")
        plant_s = plant_time_s(recorded_s)
        print(
            f"wfsbench demo: {recorded_s:.0f} s of samples ({within_s:.0f} s within the points' excitations)"
            f" in {command_s:.1f} s: {recorded_s / command_s:.1f}x real time;"
            f" the campaign alone {campaign_s:.1f} s: {recorded_s / campaign_s:.1f}x;"
            f" baseline, the plant alone: {plant_s:.2f} s ({recorded_s / plant_s:.0f}x),"
            f" the command takes {command_s / plant_s:.1f}x the plant's time"
        )


if __name__ == "__main__":
    main()
