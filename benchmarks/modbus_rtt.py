"""Modbus TCP round trip on loopback: the client's status read against the simulated controller.

Baseline (same run): an asyncio TCP echo of a 12-byte message on the same loopback.
Run: python benchmarks/modbus_rtt.py [--requests N]
"""

from __future__ import annotations

import argparse
import asyncio
import time

import numpy as np

from drivers.actuator import ActuatorClient
from simulators.bench_sim import BenchRunner, SimulatedBench
from simulators.controller_server import ControllerServer


async def echo_baseline(n: int) -> np.ndarray:
    async def echo(reader, writer):
        while data := await reader.read(64):
            writer.write(data)
            await writer.drain()

    server = await asyncio.start_server(echo, "127.0.0.1", 0)
    port = server.sockets[0].getsockname()[1]
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    times = []
    for _ in range(n):
        t = time.perf_counter()
        writer.write(b"x" * 12)
        await reader.readexactly(12)
        times.append(time.perf_counter() - t)
    writer.close()
    await writer.wait_closed()
    server.close()
    await server.wait_closed()
    return np.array(times)


async def modbus(n: int) -> tuple[np.ndarray, np.ndarray]:
    bench = SimulatedBench.paper_shaker(seed=1)
    runner = BenchRunner(bench, paced=True)
    runner.start()
    server = ControllerServer(bench)
    host, port = await server.serve_tcp()
    client = ActuatorClient.tcp(host, port)
    await client.connect()
    reads, writes = [], []
    try:
        for _ in range(n):
            t = time.perf_counter()
            await client.read_status()
            reads.append(time.perf_counter() - t)
            t = time.perf_counter()
            await client.hydraulics_low()  # a one-register command write, idempotent at rest
            writes.append(time.perf_counter() - t)
    finally:
        await client.close()
        await server.close()
        runner.stop()
    return np.array(reads), np.array(writes)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--requests", type=int, default=2000)
    n = parser.parse_args().requests
    base = asyncio.run(echo_baseline(n))
    reads, writes = asyncio.run(modbus(n))
    b50 = np.percentile(base, 50)
    print(f"baseline TCP echo      : p50 {b50 * 1e3:.3f} ms  p99 {np.percentile(base, 99) * 1e3:.3f} ms")
    for name, t in (("read status (17 regs, 2 requests)", reads), ("write command (1 reg)", writes)):
        p50, p99 = np.percentile(t, 50), np.percentile(t, 99)
        print(f"{name:23}: p50 {p50 * 1e3:.3f} ms  p99 {p99 * 1e3:.3f} ms  ({p50 / b50:.1f}x the echo p50)")


if __name__ == "__main__":
    main()
