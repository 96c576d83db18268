"""Run the simulated bench as a standalone process: the controller on TCP, the WFS on a pty."""

from __future__ import annotations

import asyncio
import contextlib
import signal

from simulators.bench_sim import BenchRunner, SimulatedBench
from simulators.controller_server import ControllerServer
from simulators.faults import ByteFaults
from simulators.ports import PtyLink
from simulators.wfs_device import WfsDevice


async def serve(
    host: str = "127.0.0.1",
    port: int = 0,
    *,
    paced: bool = True,
    seed: int = 1,
    bit_error_rate: float = 0.0,
    ready=print,
) -> None:
    """Serve until SIGINT/SIGTERM; ``ready`` receives the lines announcing the addresses."""
    bench = SimulatedBench.paper_shaker(seed=seed)
    link = PtyLink()
    device = WfsDevice(link, seed=seed, faults=ByteFaults(seed=seed, bit_error_rate=bit_error_rate))
    runner = BenchRunner(bench, paced=paced)
    runner.sinks.append(device)
    controller = ControllerServer(bench)
    device.start()
    runner.start()
    try:
        bound_host, bound_port = await controller.serve_tcp(host, port)
        ready(f"actuator controller: modbus tcp {bound_host}:{bound_port}")
        ready(f"wfs acquisition: serial {link.path}")
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            with contextlib.suppress(NotImplementedError):
                loop.add_signal_handler(sig, stop.set)
        await stop.wait()
    finally:
        await controller.close()
        runner.stop()
        device.stop()
        link.close()
