"""Runs on a busy lab PC: false interlocks and lost frames beside busy processes.

The paced smoke sequence (real time, the simulated devices standing in for hardware: the WFS link
overruns a real tty's buffer when the host stops reading) and the first ``--grid-s`` seconds of the
paper's shaker campaign (then Ctrl-C's signal, SIGINT: aborted), each ``--runs`` times as a user
runs them (``wfsbench run ... --realtime``, a fresh interpreter each), with ``--busy`` processes
spinning on the cores meanwhile (``yes > /dev/null``). Nothing is injected: every interlock is a
false one. Per run: its runs' statuses and reasons, the frames lost within its recordings (the
``gap`` events) and the host stalls that lost frames. The baseline, measured in the same run, is
the same smoke run with no busy process.

    PYTHONPATH=. .venv/bin/python benchmarks/busy_host.py [--runs 10] [--busy 4] [--grid-s 120]
"""

from __future__ import annotations

import argparse
import contextlib
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from bench.store import open_campaign

ROOT = Path(__file__).resolve().parents[1]
SEQUENCES = ROOT / "sequences" / "files"


@dataclass
class RunResult:
    """One command's campaign file, read back: statuses, interlocks, frames lost, host stalls."""

    what: str
    wall_s: float
    statuses: list[str]
    interlocks: list[str]
    frames_lost: int
    host_stalls: list[str]


@contextlib.contextmanager
def busy(processes: int) -> Iterator[None]:
    """``processes`` busy loops (``yes > /dev/null``) for as long as the block runs."""
    spinning = [subprocess.Popen(["yes"], stdout=subprocess.DEVNULL) for _ in range(processes)]
    try:
        yield
    finally:
        for process in spinning:
            process.terminate()
            process.wait()


def run_sequence(sequence: str, out: Path, stop_after_s: float | None) -> RunResult:
    """``wfsbench run SEQUENCE --out OUT --realtime``, sent SIGINT after ``stop_after_s``."""
    command = [
        sys.executable,
        "-m",
        "bench.cli",
        "run",
        str(SEQUENCES / sequence),
        "--out",
        str(out),
        "--realtime",
    ]
    start = time.perf_counter()
    process = subprocess.Popen(command, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        process.wait(timeout=stop_after_s)
    except subprocess.TimeoutExpired:
        process.send_signal(signal.SIGINT)
        process.wait(timeout=60)
    wall_s = time.perf_counter() - start
    with open_campaign(out) as campaign:
        runs = campaign.runs
        interlocks = [f"{r.run_id}: {r.reason}" for r in runs if r.status == "interlocked"]
        lost = sum(int(e.fields["missing"]) for r in runs for e in r.events if e.kind == "gap")
        stalls = [
            e.text for r in runs for e in r.events if e.kind == "host stall" and e.fields["frames_lost"]
        ]
        return RunResult(sequence, wall_s, [r.status for r in runs], interlocks, lost, stalls)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--busy", type=int, default=4)
    parser.add_argument("--grid-s", type=float, default=120.0)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        base = run_sequence("smoke.toml", Path(folder) / "baseline.h5", None)
        print(
            f"baseline, no busy process: smoke {base.wall_s:.1f} s, statuses {base.statuses}, "
            f"frames lost {base.frames_lost}"
        )
        results: list[RunResult] = []
        with busy(args.busy):
            for i in range(args.runs):
                for sequence, stop in (("smoke.toml", None), ("paper_shaker.toml", args.grid_s)):
                    result = run_sequence(sequence, Path(folder) / f"{i}-{sequence}.h5", stop)
                    results.append(result)
                    print(
                        f"{i + 1}/{args.runs} {sequence}: {result.wall_s:.1f} s"
                        f" ({result.wall_s / base.wall_s:.2f}x the baseline's smoke),"
                        f" statuses {result.statuses},"
                        f" interlocks {result.interlocks or 'none'}, frames lost {result.frames_lost},"
                        f" host stalls {len(result.host_stalls)}",
                        flush=True,
                    )
    false_trips = sum(len(r.interlocks) for r in results)
    lost = sum(r.frames_lost for r in results)
    stalls = sum(len(r.host_stalls) for r in results)
    print(
        f"{len(results)} runs beside {args.busy} busy processes: {false_trips} false interlocks,"
        f" {lost} frames lost, {stalls} host stalls recorded"
    )


if __name__ == "__main__":
    main()
