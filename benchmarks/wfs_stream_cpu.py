"""CPU share of the WFS reader thread streaming 1 kHz in real time over a pty, and frames lost.

Baseline (same run): the CPU the idle reader thread uses over the same time with the stream stopped.
Run: python benchmarks/wfs_stream_cpu.py [--seconds 30]   (--seconds 600 for the 10-minute figure)
"""

from __future__ import annotations

import argparse
import os
import time

from drivers.wfs_reader import Subscription, WfsReader
from simulators.bench_sim import BenchRunner, SimulatedBench
from simulators.ports import PtyLink
from simulators.wfs_device import WfsDevice


def thread_cpu_s(native_id: int) -> float:
    """User plus system CPU time of one thread of this process, from /proc."""
    with open(f"/proc/self/task/{native_id}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def measure(reader: WfsReader, sub: Subscription, seconds: float) -> tuple[float, int]:
    tid = reader.thread_id
    if tid is None:
        raise RuntimeError("the reader thread is not running")
    cpu0, t0, frames = thread_cpu_s(tid), time.monotonic(), 0
    while time.monotonic() - t0 < seconds:
        block = sub.get(timeout_s=0.5)
        frames += len(block) if block else 0
    return (thread_cpu_s(tid) - cpu0) / (time.monotonic() - t0), frames


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seconds", type=float, default=30.0)
    seconds = parser.parse_args().seconds
    link = PtyLink()
    bench = SimulatedBench.paper_shaker(seed=1)
    device = WfsDevice(link, bench, seed=1)
    runner = BenchRunner(bench, paced=True)
    runner.sinks.append(device)
    device.start()
    runner.start()
    reader = WfsReader.serial(link.path)
    reader.start()
    try:
        reader.wait_connected(5)
        sub = reader.subscribe(lossless=True)
        idle_share, _ = measure(reader, sub, min(5.0, seconds))
        reader.start_stream()
        share, frames = measure(reader, sub, seconds)
        reader.stop_stream()
        c = reader.counters
    finally:
        reader.close()
        runner.stop()
        device.stop()
        link.close()
    print(f"streamed {seconds:.0f} s at 1 kHz over a pty: {frames} frames delivered")
    print(f"reader thread CPU: {100 * share:.2f} % of one core (idle baseline {100 * idle_share:.2f} %)")
    print(
        f"frames lost: {c.frames_missing}, CRC rejects: {c.crc_rejects}, bytes discarded: {c.bytes_discarded}"
    )


if __name__ == "__main__":
    main()
