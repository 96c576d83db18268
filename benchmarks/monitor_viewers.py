"""The WFS reader during a paced run watched through the web monitor by 0, 1 and 20 viewers.

The paced smoke sequence (real time; the simulated lab in a process of its own, as hardware) run in
this process as ``wfsbench run --realtime`` runs it, per case:

- baseline: no monitor (measured in the same run);
- the monitor (``--monitor``: its feed on a thread of the bench, its server in a process of its own)
  with 0 viewers;
- 1 viewer reading the stream;
- 20 viewers, 19 reading the stream and 1 that never reads a byte.

The bench runs above the machine's other work where the benchmark may raise it (niceness -10 as
root, as the tests' paced labs do and as a lab runs a real-time bench); the monitor's server 19
steps below the bench (at most 19); the viewers are a process of their own (``tests/monitor/viewers.py``) at
niceness 10 (in a lab they sit at other computers). Per case: the largest backlog one read of the
port took (how full its 4095-byte receive buffer got: ``WfsReader.largest_backlog_bytes``), the
longest the port went unread, the frames lost (the runs' ``frames_missing``), the host stalls
recorded, the updates the reading viewers received, and the processor time of the bench's process
(its threads: engine, reader, recorder, the monitor's feed; not its children) per second of the run,
with the feed thread's own share: that figure the machine's load leaves as it is.

    PYTHONPATH=. .venv/bin/python benchmarks/monitor_viewers.py [--repeats 1]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from bench.app.plan import plan_campaign
from bench.app.run import run_campaign
from bench.cli.monitor import start_bench_monitor
from bench.monitor.listen import Listen
from bench.store import open_campaign
from benchmarks.timing import run_benchmark
from simulators.ports import TTY_RX_BUFFER_BYTES

ROOT = Path(__file__).resolve().parents[1]
SMOKE = ROOT / "sequences" / "files" / "smoke.toml"
VIEWERS_NICENESS = 10
#: The bench's niceness where it may be raised (root): as tests/campaign_lab.py runs a paced lab.
BENCH_NICENESS = -10
#: (name, viewers reading, viewers never reading); None: no monitor.
CASES: tuple[tuple[str, tuple[int, int] | None], ...] = (
    ("no monitor (baseline)", None),
    ("monitor, 0 viewers", (0, 0)),
    ("monitor, 1 viewer", (1, 0)),
    ("monitor, 20 viewers (1 never reading)", (19, 1)),
)


@dataclass
class Case:
    """One paced run's figures."""

    status: str
    reason: str
    backlog_bytes: int
    unread_s: float
    frames_lost: int
    host_stalls: int
    updates: list[int]
    wall_s: float
    bench_cpu_s: float  # this process's processor time in the run (its children's not counted)
    feed_cpu_s: float  # the monitor's feed thread's


def viewers(port: int, reading: int, silent: int) -> subprocess.Popen:
    command = [sys.executable, "-m", "tests.monitor.viewers", str(port), f"--readers={reading}"]
    lower = VIEWERS_NICENESS - os.getpriority(os.PRIO_PROCESS, 0)  # nice adds to the bench's own
    return subprocess.Popen(
        ["nice", "-n", str(lower), *command, f"--silent={silent}"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        text=True,
    )


def one_run(out: Path, watched: tuple[int, int] | None) -> Case:
    plan = plan_campaign(SMOKE, realtime=True)
    engines = []
    monitor = start_bench_monitor(Listen("127.0.0.1", 0)) if watched is not None else None
    crowd = viewers(monitor.server.port, *watched) if monitor is not None and sum(watched) else None
    if crowd is not None:  # every viewer connected before the run starts
        assert [crowd.stdout.readline(), crowd.stdout.readline()] == ["ready\n", "watching\n"]

    def on_engine(engine) -> None:
        engines.append(engine)
        if monitor is not None:
            monitor.feed.attach(engine, plan.config)

    start_wall_s, start_cpu_s = time.perf_counter(), time.process_time()
    try:
        outcome = run_campaign(plan, out, on_engine=on_engine)
    finally:
        wall_s, cpu_s = time.perf_counter() - start_wall_s, time.process_time() - start_cpu_s
        if monitor is not None:
            monitor.close()
    feed_cpu_s = monitor.feed.cpu_s if monitor is not None else 0.0
    seen = json.loads(crowd.communicate(timeout=120)[0]) if crowd is not None else {"readers": []}
    reader = engines[0].acquisition
    with open_campaign(out) as campaign:
        lost = sum(int(r.link_counters["frames_missing"]) for r in campaign.runs)
        stalls = sum(1 for r in campaign.runs for e in r.events if e.kind == "host stall")
    updates = [r.get("updates", 0) for r in seen["readers"]]
    backlog, unread_s = reader.largest_backlog_bytes, reader.longest_unread_s
    return Case(
        outcome.status, outcome.reason, backlog, unread_s, lost, stalls, updates, wall_s, cpu_s, feed_cpu_s
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=1)
    args = parser.parse_args()
    with contextlib.suppress(PermissionError):
        os.setpriority(os.PRIO_PROCESS, 0, BENCH_NICENESS)
    print(f"the bench at niceness {os.getpriority(os.PRIO_PROCESS, 0)}, the viewers at {VIEWERS_NICENESS}")
    print(f"load average before: {os.getloadavg()[0]:.1f}")
    results: dict[str, list[Case]] = {name: [] for name, _ in CASES}
    with tempfile.TemporaryDirectory() as folder:
        for repeat in range(args.repeats):
            for i, (name, watched) in enumerate(CASES):
                results[name].append(one_run(Path(folder) / f"run-{repeat}-{i}.h5", watched))
    baseline = results[CASES[0][0]]
    base = max(c.backlog_bytes for c in baseline)
    base_cpu = sum(c.bench_cpu_s for c in baseline) / sum(c.wall_s for c in baseline)
    for name, cases in results.items():
        backlog = max(c.backlog_bytes for c in cases)
        unread_ms = max(c.unread_s for c in cases) * 1e3
        updates = [u for c in cases for u in c.updates]
        seen = f", updates per reading viewer {min(updates)}-{max(updates)}" if updates else ""
        print(
            f"{name}: {', '.join(sorted({c.status for c in cases}))}; largest backlog {backlog} bytes ="
            f" {backlog / TTY_RX_BUFFER_BYTES:.2f} of the buffer ({backlog / base:.2f}x the baseline's),"
            f" longest unread {unread_ms:.1f} ms, frames lost {sum(c.frames_lost for c in cases)},"
            f" host stalls {sum(c.host_stalls for c in cases)}{seen}",
            flush=True,
        )
        wall_s, cpu_s = sum(c.wall_s for c in cases), sum(c.bench_cpu_s for c in cases)
        feed_s = sum(c.feed_cpu_s for c in cases)
        print(
            f"  the bench process's processor time {cpu_s / wall_s * 100:.1f} % of a core"
            f" ({cpu_s / wall_s / base_cpu:.2f}x the baseline's), of which the monitor's feed"
            f" {feed_s / wall_s * 100:.2f} %"
        )
        for case in cases:
            if case.reason:
                print(f"  {case.status}: {case.reason}")
    print(f"load average after: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    run_benchmark(main)
