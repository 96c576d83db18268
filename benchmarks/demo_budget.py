"""What `wfsbench demo` must do, each part timed alone on the demo's own amount of data, against
the wall time that 100x real time allows.

The demo is run once as a user runs it (a fresh interpreter); then each part of its work is timed
by itself, in this process, with nothing else running in it: no threads, no links, no engine:

- imports: a fresh interpreter importing what the demo's command imports, less an empty one;
- plant: the simulated plant alone streaming the recorded sample time in the unpaced simulated
  bench's blocks, one operating point (no re-linearisation: its cheapest case);
- WFS line, both ends: the recorded frames encoded (sync, CRC) in those blocks as the simulated WFS
  sends them, then parsed (sync search, CRC check, sequence accounting) in 4 KiB reads as the
  reader receives them;
- recording: every channel of every run of the demo's file written again through the store's
  writer in those blocks (shuffle, deflate, HDF5, fsync once a second);
- analysis: the whole file analysed afresh (what the campaign's post-run analyses do in all);
- figures: the report's figures drawn from that analysis.

Their sum is a floor for one process: the engine, the Modbus exchanges, the threads and their
hand-overs come on top. Baseline: the budget, the recorded sample time / 100.

    PYTHONPATH=. .venv/bin/python benchmarks/demo_budget.py
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import h5py
import numpy as np

from bench.app.analyze import analyze_campaign
from bench.models.setup import BenchSetup
from bench.report.figure_files import write_figures
from bench.report.figure_list import campaign_figure_specs
from bench.store import CampaignWriter
from benchmarks.demo_speed import command_time_s, excitation_s
from benchmarks.timing import best_time_s
from drivers.wfs_frame import encode, new_frames
from drivers.wfs_stream import StreamParser
from sequences.channels import Channel
from simulators.bench_sim import UNPACED_BLOCK_S
from simulators.plant import PlantSimulator, SensorRealism

TARGET_SPEEDUP = 100.0
READ_SIZE_BYTES = 4096
RATE_HZ = 1000.0


def import_time_s() -> float:
    """A fresh interpreter importing the demo's command and its report, less an empty interpreter."""

    def interpreter(code: str) -> float:
        return best_time_s(lambda: subprocess.run([sys.executable, "-c", code], check=True), repeats=3)

    return interpreter("import bench.cli.main, bench.demo, bench.app.report") - interpreter("pass")


def plant_time_s(sample_time_s: float) -> float:
    """The plant streaming ``sample_time_s`` of a 40 Hz, 2 mm dwell in unpaced blocks."""
    plant = PlantSimulator(BenchSetup.paper_shaker(2.5), SensorRealism(seed=1))
    plant.set_operating_point(40.0, 2e-3)
    n_block = round(UNPACED_BLOCK_S * plant.internal_rate_hz)
    t_s = np.arange(n_block) / plant.internal_rate_hz
    n_blocks = round(sample_time_s / UNPACED_BLOCK_S)

    def stream() -> None:
        for k in range(n_blocks):
            plant.advance(2e-3 * np.sin(2 * np.pi * 40.0 * (t_s + k * UNPACED_BLOCK_S)))

    return best_time_s(stream, repeats=1)


def line_time_s(n_frames: int) -> tuple[float, float]:
    """(encode, parse) wall times of ``n_frames`` WFS frames: encoded in unpaced blocks, parsed
    in 4 KiB reads."""
    per_block = round(UNPACED_BLOCK_S * RATE_HZ)
    frames = new_frames(per_block)
    frames["fz"] = np.random.default_rng(0).normal(0.0, 100.0, per_block)
    n_blocks = n_frames // per_block

    def encoded() -> list[bytes]:
        out = []
        for k in range(n_blocks):
            frames["seq"] = np.arange(k * per_block, (k + 1) * per_block)
            out.append(encode(frames))
        return out

    start = time.perf_counter()
    data = b"".join(encoded())
    encode_s = time.perf_counter() - start

    def parse() -> None:
        parser = StreamParser()
        for i in range(0, len(data), READ_SIZE_BYTES):
            parser.feed(data[i : i + READ_SIZE_BYTES])

    return encode_s, best_time_s(parse, repeats=1)


def _runs(path: Path) -> Iterator[tuple[list[Channel], dict[str, np.ndarray]]]:
    """Each run's channel specifications and samples, read with h5py."""
    with h5py.File(path, "r") as f:
        for run in f["runs"].values():
            datasets = run["channels"]
            specs = [
                Channel(name, str(d.attrs.get("unit", "")), d.dtype.str.lstrip("<>|="))
                for name, d in datasets.items()
            ]
            yield specs, {name: d[()] for name, d in datasets.items()}


def recording_time_s(path: Path, out: Path) -> float:
    """Every channel of every run of ``path`` written again through the store, in unpaced blocks."""
    runs = list(_runs(path))
    per_block = round(UNPACED_BLOCK_S * RATE_HZ)

    def write() -> None:
        out.unlink(missing_ok=True)
        writer = CampaignWriter.create(
            out, software_version="bench", config_toml="", sequence_toml="", sequence_name=""
        )
        for number, (specs, samples) in enumerate(runs):
            run = writer.begin_run(
                f"{number:03d}",
                kind="dwell_grid",
                step={},
                conditions={},
                channels=specs,
                sample_rate_hz=RATE_HZ,
            )
            n = next(iter(samples.values())).size
            for start in range(0, n, per_block):
                run.append({name: values[start : start + per_block] for name, values in samples.items()})
            run.finish("complete")
        writer.close()

    return best_time_s(write, repeats=1)


def main() -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        whole_s, campaign_s = command_time_s(work / "demo")
        campaign = work / "demo" / "campaign.h5"
        recorded_s, within_s = excitation_s(campaign)
        n_frames = round(recorded_s * RATE_HZ)
        encode_s, parse_s = line_time_s(n_frames)
        analysis_s = best_time_s(lambda: analyze_campaign(campaign), repeats=1)
        analysis = analyze_campaign(campaign)
        specs = campaign_figure_specs(analysis)
        parts = {
            "imports": import_time_s(),
            "plant (unpaced blocks, one operating point)": plant_time_s(recorded_s),
            "WFS frames encoded (simulated device)": encode_s,
            "WFS frames parsed (reader, 4 KiB reads)": parse_s,
            "recording (every channel through the store)": recording_time_s(campaign, work / "again.h5"),
            "analysis of the whole file": analysis_s,
            "report figures": best_time_s(lambda: write_figures(specs, work / "figures"), repeats=1),
        }
    budget_s = recorded_s / TARGET_SPEEDUP
    total_s = sum(parts.values())
    print(
        f"wfsbench demo: {recorded_s:.0f} s of samples ({within_s:.0f} s within the excitations, "
        f"{n_frames:,} frames) in {whole_s:.1f} s ({recorded_s / whole_s:.0f}x; campaign alone "
        f"{campaign_s:.1f} s, {recorded_s / campaign_s:.0f}x)"
    )
    print(f"baseline, the budget at {TARGET_SPEEDUP:.0f}x real time: {budget_s:.2f} s")
    for name, seconds in parts.items():
        print(f"  {name:46} {seconds:6.2f} s  {seconds / budget_s:5.2f} of the budget")
    print(
        f"  {'sum: the parts alone, one after another':46} {total_s:6.2f} s  {total_s / budget_s:5.2f} of the"
        f" budget ({recorded_s / total_s:.0f}x real time at best in one process); the command takes"
        f" {whole_s / total_s:.1f}x the sum"
    )


if __name__ == "__main__":
    main()
