"""A road replay's drive uploaded to the simulated controller (docs/protocols.md, *Drive files*):
over Modbus TCP on loopback and over Modbus RTU at 115200 baud on a pty pair (socat), the upload's
time against the drive's own length (how much faster than real time the drive reaches the
controller) and, on RTU, against the wire time its requests and replies take at 10 bits per byte
(the baseline: what the line allows at best), both measured in the same run.

Run: PYTHONPATH=. .venv/bin/python benchmarks/drive_upload.py [--tcp-s 60] [--rtu-s 6]
"""

from __future__ import annotations

import argparse
import asyncio
import math
import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from drivers.actuator import ActuatorClient
from drivers.setpoints import DRIVE_BLOCK_SAMPLES, DriveSetpoint
from sequences.limits import BenchLimits
from simulators.bench_sim import SimulatedBench
from simulators.controller_server import ControllerServer

RATE_HZ = 1000.0
BAUD = 115200
#: An upload request (FC 16 of drive_offset and drive_block: address, function, start, quantity,
#: byte count, 122 registers, CRC) and its reply (address, function, start, quantity, CRC), in bytes.
REQUEST_BYTES = 1 + 1 + 2 + 2 + 1 + 2 * 122 + 2
REPLY_BYTES = 1 + 1 + 2 + 2 + 2


def drive(seconds: float) -> DriveSetpoint:
    n = round(seconds * RATE_HZ)
    return DriveSetpoint(5.0 * np.sin(2 * np.pi * 2.0 * np.arange(n) / RATE_HZ), RATE_HZ, 0.5, 0.5)


async def upload(client: ActuatorClient, setpoint: DriveSetpoint) -> float:
    await client.connect()
    start = time.perf_counter()
    await client.load_drive(setpoint)
    elapsed = time.perf_counter() - start
    assert await client.holds_drive(setpoint)
    await client.close()
    return elapsed


async def over_tcp(seconds: float) -> None:
    server = ControllerServer(SimulatedBench.paper_shaker(seed=1))
    host, port = await server.serve_tcp("127.0.0.1", 0)
    setpoint = drive(seconds)
    elapsed = await upload(ActuatorClient.tcp(host, port, limits=BenchLimits()), setpoint)
    await server.close()
    print(
        f"TCP loopback: {setpoint.n_samples} samples ({seconds:g} s of drive) in {elapsed:.3f} s:"
        f" {setpoint.n_samples / elapsed:,.0f} samples/s, {seconds / elapsed:.0f}x the drive's real time"
    )


async def over_rtu(seconds: float) -> None:
    folder = Path(tempfile.mkdtemp())
    device, host = str(folder / "controller"), str(folder / "host")
    socat = subprocess.Popen(
        ["socat", f"pty,raw,echo=0,link={device}", f"pty,raw,echo=0,link={host}"], stderr=subprocess.DEVNULL
    )
    try:
        while not (os.path.exists(device) and os.path.exists(host)):
            await asyncio.sleep(0.05)
        server = ControllerServer(SimulatedBench.paper_shaker(seed=1))
        await server.serve_rtu(device, baudrate=BAUD)
        setpoint = drive(seconds)
        client = ActuatorClient.rtu(host, baudrate=BAUD, limits=BenchLimits(), timeout_s=0.5)
        elapsed = await upload(client, setpoint)
        await server.close()
    finally:
        socat.terminate()
        socat.wait(timeout=5)
        shutil.rmtree(folder, ignore_errors=True)
    wire_s = math.ceil(setpoint.n_samples / DRIVE_BLOCK_SAMPLES) * (REQUEST_BYTES + REPLY_BYTES) * 10 / BAUD
    print(
        f"RTU {BAUD} baud: {setpoint.n_samples} samples ({seconds:g} s of drive) in {elapsed:.2f} s:"
        f" {setpoint.n_samples / elapsed:,.0f} samples/s, {seconds / elapsed:.2f}x the drive's real time;"
        f" the blocks' wire time {wire_s:.2f} s: {elapsed / wire_s:.2f}x it"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tcp-s", type=float, default=60.0, help="drive length uploaded over TCP (s)")
    parser.add_argument("--rtu-s", type=float, default=6.0, help="drive length uploaded over RTU (s)")
    args = parser.parse_args()
    asyncio.run(over_tcp(args.tcp_s))
    if shutil.which("socat") is None:
        print("RTU: socat (Debian) not installed: not measured")
        return
    asyncio.run(over_rtu(args.rtu_s))


if __name__ == "__main__":
    main()
