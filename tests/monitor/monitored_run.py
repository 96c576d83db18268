"""``wfsbench run --realtime --monitor`` of the smoke sequence in a process of its own (the monitor
is served by the run's process: it is under test), and what its campaign file says of the run.

The run keeps real time above the machine's other work where the test may raise it (niceness
:data:`~tests.campaign_lab.REAL_TIME_NICE` as root, its threads and children inheriting it), as a
lab runs a real-time bench on a PC it cannot keep idle (``tests/campaign_lab.py``); the monitor's
server lowers itself below the bench from there (``bench/monitor/server_process.py``)."""

from __future__ import annotations

import contextlib
import os
import socket
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from bench.store import open_campaign
from tests.campaign_lab import REAL_TIME_NICE
from tests.waiting import LineReader

ROOT = Path(__file__).resolve().parents[2]
SMOKE = ROOT / "sequences" / "files" / "smoke.toml"
#: The smoke sequence's points (``wfsbench check``).
SMOKE_POINTS = 8


@dataclass
class MonitoredRun:
    process: subprocess.Popen
    url: str
    lines: LineReader
    out: Path


@contextlib.contextmanager
def monitored_run(out: Path, *options: str, port: int = 0) -> Iterator[MonitoredRun]:
    """The paced smoke run into ``out`` with ``--monitor 127.0.0.1:PORT`` (0: a free port), once its
    monitor listens; ended (SIGTERM, then kill) if still running when the block ends."""
    command = [sys.executable, "-m", "bench.cli", "run", str(SMOKE), "--realtime", "--out", str(out)]
    raised = ["nice", "-n", str(REAL_TIME_NICE)] if os.geteuid() == 0 else []
    process = subprocess.Popen(
        [*raised, *command, "--monitor", f"127.0.0.1:{port}", *options],
        cwd=ROOT,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        lines = LineReader(process.stdout)
        said = "the monitor's address"
        first = lines.until(lambda line: line.startswith("monitor: ") or line == "", 60, said)
        assert first[-1].startswith("monitor: http://127.0.0.1:"), first
        yield MonitoredRun(process, first[-1].split()[1], lines, out)
    finally:
        ended(process)


def ended(process: subprocess.Popen) -> None:
    """``process`` ended: asked to (SIGTERM) if still running, killed if it does not within 30 s."""
    if process.poll() is None:
        process.terminate()
        try:
            process.wait(30)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


def free_port() -> int:
    """A port of 127.0.0.1 free at this moment: for a monitor whose viewers wait for it to listen."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@dataclass(frozen=True)
class Recorded:
    """What the campaign file holds of the run: per run its status, point statuses and samples,
    the link's counters at the end, and the host stalls recorded."""

    statuses: tuple[str, ...]
    points: tuple[tuple[str, ...], ...]
    samples: int
    frames_ok: int
    frames_missing: int
    gaps: int
    host_stalls: int


def recorded(path: Path) -> Recorded:
    with open_campaign(path) as campaign:
        runs = campaign.runs
        last = runs[-1].link_counters
        return Recorded(
            tuple(r.status for r in runs),
            tuple(tuple(str(p.status) for p in r.points) for r in runs),
            sum(r.n_samples for r in runs),
            int(last["frames_ok"]),
            sum(int(r.link_counters["frames_missing"]) for r in runs),
            sum(int(r.link_counters["gaps"]) for r in runs),
            sum(1 for r in runs for e in r.events if e.kind == "host stall"),
        )


def assert_untouched(result: Recorded) -> None:
    """The run as the bench records it alone: complete, every point done at its first attempt, every
    frame the link delivered recorded (the link's count equals the samples), none missing, no gap,
    no host stall."""
    assert result.statuses == ("complete", "complete", "complete"), result
    assert sum(len(p) for p in result.points) == SMOKE_POINTS, result
    assert all(status == "done" for p in result.points for status in p), result
    assert result.frames_ok == result.samples, result
    assert (result.frames_missing, result.gaps, result.host_stalls) == (0, 0, 0), result
