"""The WFS reader's worst stall while a whole grid is analysed and while a report renders.

The reader (``drivers.wfs_reader.WfsReader``) streams 1 kHz frames at 921600 baud from the paced
simulated WFS, which runs in a process of its own as hardware would (``bench.app.lab_process``);
a thread of this process drains the frames as the engine does. Per phase, the longest time the
port went unread between two reads (``WfsReader.longest_unread_s``) and the frames lost, for:

- idle: nothing else runs (the baseline, measured in the same run);
- the analysis of a whole campaign (the paper's shaker grids at three pressures, the free run, the
  hammer test) in this process, on a thread, as the bench did it before;
- the same analysis in a process of its own (``bench.app.analysis_process``), each run's records
  read here (``run_inputs``);
- the same again with the objects alive at its start frozen out of the garbage collector's passes,
  as a sequence runs on the bench now (``bench.app.collector``);
- the report (figures and page) rendered in this process, on a thread;
- the report rendered by ``wfsbench report`` in another process, as a user would beside a run.

The figures that matter: the stall against the time the port's receive buffer lasts at the line
rate (4095 bytes at 921600 baud, 10 bits a byte: 44.4 ms; 64 ms of 1 kHz frames of 64 bytes), and
the largest backlog one read took against the buffer's 4095 bytes. The backlog is the surer of the
two: a reader held by the interpreter's lock inside the port's read, after its system call, is not
seen by the clock, but the bytes that piled up meanwhile are.

    PYTHONPATH=. .venv/bin/python benchmarks/reader_stall.py [--campaign FILE] [--repeats 3]

Without ``--campaign`` the paper's shaker campaign (hammer.toml, paper_shaker.toml) is first run
on the unpaced simulated bench into a temporary file.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from bench.app.analysis_process import AnalysisProcess
from bench.app.collector import collector_frozen
from bench.app.lab_process import LabProcess
from bench.app.plan import plan_campaign
from bench.app.report import write_report
from bench.app.run import run_campaign
from bench.app.run_analysis import RunAnalyser, initial_knowledge, run_inputs, runs_to_analyse
from bench.app.simulated import SimulatedLabSettings
from bench.config import default_bench_config
from bench.store import open_campaign
from benchmarks.timing import run_benchmark
from drivers.wfs_reader import WfsReader
from simulators.ports import TTY_RX_BUFFER_BYTES

ROOT = Path(__file__).resolve().parents[1]
BAUDRATE = 921600
BUFFER_LASTS_S = TTY_RX_BUFFER_BYTES * 10 / BAUDRATE
IDLE_S = 3.0


def make_campaign(folder: Path) -> Path:
    out = folder / "campaign.h5"
    for name in ("hammer.toml", "paper_shaker.toml"):
        outcome = run_campaign(plan_campaign(ROOT / "sequences" / "files" / name), out)
        assert outcome.status == "complete", outcome.reason
    return out


def analyse_here(campaign_path: Path) -> None:
    analyser = RunAnalyser(initial_knowledge(default_bench_config()))
    with open_campaign(campaign_path) as campaign:
        for run in runs_to_analyse(campaign):
            analyser.analyse(run_inputs(run, campaign))


def analyse_in_process(campaign_path: Path) -> None:
    with AnalysisProcess(initial_knowledge(default_bench_config())) as process:
        with open_campaign(campaign_path) as campaign:
            for run in runs_to_analyse(campaign):
                process.submit(run_inputs(run, campaign))
        while process.outstanding:
            process.next_result(None)


def report_here(campaign_path: Path, out_dir: Path) -> None:
    write_report(campaign_path, out_dir)


def report_in_process(campaign_path: Path, out_dir: Path) -> None:
    subprocess.run(
        [sys.executable, "-m", "bench.cli", "report", str(campaign_path), "--out", str(out_dir)],
        cwd=ROOT,
        check=True,
        capture_output=True,
    )


class Drain:
    """Takes the reader's frames as the engine does, on a thread of its own."""

    def __init__(self, reader: WfsReader) -> None:
        self.subscription = reader.subscribe(lossless=True)
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while not self.stop.is_set():
            self.subscription.get_all(0.05)

    def close(self) -> None:
        self.stop.set()
        self.thread.join()
        self.subscription.close()


@dataclass
class Phase:
    """One phase's figures: wall time (s), the reader's longest stall (s), the most bytes one read
    took (how full the port's buffer got), frames lost (by the frames' counter) and bytes the
    simulated link dropped because the port's buffer was full."""

    wall_s: float
    stall_s: float
    backlog_bytes: int
    frames_lost: int
    bytes_overrun: int


def phase(lab: LabProcess, reader: WfsReader, work: Callable[[], None], *, frozen: bool = False) -> Phase:
    """The figures of ``work``, run on a thread while the reader streams. ``frozen``: with the objects
    alive before it frozen out of the garbage collector's passes, as a sequence runs on the bench
    (whose one collection at a sequence's start comes before any stream; here it comes before the
    figures are taken)."""
    with collector_frozen() if frozen else contextlib.nullcontext():
        return _measured(lab, reader, work)


def _measured(lab: LabProcess, reader: WfsReader, work: Callable[[], None]) -> Phase:
    missing, overrun = reader.counters.frames_missing, lab.bytes_overrun()
    reader.longest_unread_s, reader.largest_backlog_bytes = 0.0, 0
    worker = threading.Thread(target=work)
    start = time.perf_counter()
    worker.start()
    worker.join()
    wall_s = time.perf_counter() - start
    lost, overrun = reader.counters.frames_missing - missing, lab.bytes_overrun() - overrun
    return Phase(wall_s, reader.longest_unread_s, reader.largest_backlog_bytes, lost, overrun)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--campaign", type=Path, help="a campaign file (default: run the paper's)")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        campaign = args.campaign or make_campaign(Path(folder))
        with open_campaign(campaign) as opened:
            print(f"campaign {campaign}: runs analysed {[r.run_id for r in runs_to_analyse(opened)]}")
        def in_process() -> None:
            analyse_in_process(campaign)

        phases: list[tuple[str, Callable[[], None]]] = [
            ("idle", lambda: time.sleep(IDLE_S)),
            ("analysis, this process (a thread)", lambda: analyse_here(campaign)),
            ("analysis, its own process (as the bench did)", in_process),
            ("analysis, its own process, collector frozen (as the bench does)", in_process),
            ("report, this process (a thread)", lambda: report_here(campaign, Path(folder) / "r1")),
            ("report, wfsbench report beside", lambda: report_in_process(campaign, Path(folder) / "r2")),
        ]
        with LabProcess(SimulatedLabSettings(paced=True)) as lab, WfsReader.serial(lab.wfs_port) as reader:
            assert reader.wait_connected(10)
            reader.stop_stream()
            reader.set_rate(1000)
            drain = Drain(reader)
            reader.start_stream()
            try:
                print(f"the port's receive buffer lasts {BUFFER_LASTS_S * 1e3:.1f} ms at {BAUDRATE} baud")
                measured: dict[str, list[Phase]] = {name: [] for name, _ in phases}
                for _ in range(args.repeats):
                    for name, work in phases:
                        measured[name].append(phase(lab, reader, work, frozen="frozen" in name))
                idle_stall = max(p.stall_s for p in measured["idle"])
                for name, results in measured.items():
                    walls = [p.wall_s for p in results]
                    stall = max(p.stall_s for p in results)
                    lost, overrun = sum(p.frames_lost for p in results), sum(p.bytes_overrun for p in results)
                    backlog = max(p.backlog_bytes for p in results)
                    print(
                        f"{name}: wall {min(walls):.2f}-{max(walls):.2f} s, worst reader stall"
                        f" {stall * 1e3:.1f} ms = {stall / BUFFER_LASTS_S:.2f} of the buffer's time"
                        f" ({stall / idle_stall:.1f}x idle), largest backlog {backlog} bytes ="
                        f" {backlog / TTY_RX_BUFFER_BYTES:.2f} of the buffer, frames lost {lost},"
                        f" bytes overrun at the port {overrun}",
                        flush=True,
                    )
            finally:
                reader.stop_stream()
                drain.close()
        print(full_collection_text())


def full_collection_text() -> str:
    """How long a full garbage collection holds this process's interpreter lock (best of 3), with
    every object alive now tracked and with them frozen out of it (``bench.app.collector``)."""

    def best_ms() -> float:
        times = []
        for _ in range(3):
            start = time.perf_counter()
            gc.collect()
            times.append(time.perf_counter() - start)
        return 1e3 * min(times)

    tracked, tracked_ms = len(gc.get_objects()), best_ms()
    with collector_frozen():
        frozen, frozen_ms = len(gc.get_objects()), best_ms()
    return (
        f"a full collection of this process: {tracked_ms:.1f} ms over {tracked} tracked objects;"
        f" with them frozen: {frozen_ms:.2f} ms over {frozen}"
    )


if __name__ == "__main__":
    run_benchmark(main)
