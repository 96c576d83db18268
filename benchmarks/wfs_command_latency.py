"""Round-trip time of a WFS command (IDENT) through the reader over a real pseudo-terminal.

Baseline (same run, same device and pty): the command written and its reply read with pyserial
directly, without the reader thread, so the figure shows what the reader adds.
Run: python benchmarks/wfs_command_latency.py [--commands N] [--streaming]
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import serial

from drivers.wfs_commands import format_command, parse_reply
from drivers.wfs_reader import WfsReader
from simulators.bench_sim import BenchRunner, SimulatedBench
from simulators.ports import PtyLink
from simulators.wfs_device import WfsDevice


def round_trips_ms(command: Callable[[], object], n: int) -> list[float]:
    times = []
    for _ in range(n):
        t0 = time.perf_counter()
        command()
        times.append((time.perf_counter() - t0) * 1000)
    return sorted(times)


def describe(times_ms: list[float]) -> str:
    p99 = times_ms[min(len(times_ms) - 1, round(0.99 * len(times_ms)))]
    return f"p50 {statistics.median(times_ms):.2f} ms, p99 {p99:.2f} ms, max {times_ms[-1]:.2f} ms"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--commands", type=int, default=300)
    parser.add_argument("--streaming", action="store_true", help="frames stream at 1 kHz meanwhile")
    args = parser.parse_args()
    link = PtyLink()
    bench = SimulatedBench.paper_shaker(seed=1)
    device = WfsDevice(link, bench, seed=1)
    runner = BenchRunner(bench, paced=True)
    runner.sinks.append(device)
    device.start()
    runner.start()
    try:
        with serial.Serial(link.path, baudrate=921600, timeout=1) as raw:
            line = format_command("IDENT")

            def raw_ident() -> None:
                raw.write(line)
                parse_reply(raw.read_until(b"\r\n"))

            baseline = round_trips_ms(raw_ident, args.commands)
        with WfsReader.serial(link.path) as reader:
            reader.wait_connected(5)
            view = reader.subscribe(lossless=False, max_frames=256)
            if args.streaming:
                reader.start_stream()
            measured = round_trips_ms(reader.identify, args.commands)
            if args.streaming:
                reader.stop_stream()
            view.close()
    finally:
        runner.stop()
        device.stop()
        link.close()
    mode = "while streaming 1 kHz" if args.streaming else "stream stopped"
    print(f"IDENT round trip over a pty, {args.commands} commands, {mode}")
    print(f"baseline, pyserial without the reader: {describe(baseline)}")
    print(f"through WfsReader.command            : {describe(measured)}")


if __name__ == "__main__":
    main()
