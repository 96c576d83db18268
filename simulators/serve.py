"""Run the simulated bench as a standalone process: the controller on Modbus TCP and on Modbus RTU
over a pseudo-terminal, the WFS on another pseudo-terminal."""

from __future__ import annotations

import asyncio
import contextlib
import signal
from collections.abc import Callable

from simulators.bench_sim import BenchRunner, SimulatedBench
from simulators.controller_server import ControllerServer
from simulators.faults import ByteFaults
from simulators.ports import TTY_RX_BUFFER_BYTES, PtyBridge, PtyLink
from simulators.wfs_device import WfsDevice


async def serve(
    host: str = "127.0.0.1",
    port: int = 0,
    *,
    paced: bool = True,
    seed: int = 1,
    bit_error_rate: float = 0.0,
    ready: Callable[[str], None] = print,
) -> None:
    """Serve until SIGINT/SIGTERM; ``ready`` receives the lines announcing the addresses."""
    bench = SimulatedBench.paper_shaker(seed=seed)
    link = PtyLink(rx_buffer_bytes=TTY_RX_BUFFER_BYTES if paced else None)  # paced: overruns as a UART
    rtu_line = PtyBridge("actuator")
    device = WfsDevice(link, bench, seed=seed, faults=ByteFaults(seed=seed, bit_error_rate=bit_error_rate))
    runner = BenchRunner(bench, paced=paced)
    runner.sinks.append(device)
    tcp, rtu = ControllerServer(bench), ControllerServer(bench)
    device.start()
    runner.start()
    try:
        bound_host, bound_port = await tcp.serve_tcp(host, port)
        await rtu.serve_rtu(rtu_line.device_path)
        ready(f"actuator controller: modbus tcp {bound_host}:{bound_port}")
        ready(f"actuator controller: modbus rtu {rtu_line.host_path} (8N1)")
        ready(f"wfs acquisition: serial {link.path}")
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            with contextlib.suppress(NotImplementedError):
                loop.add_signal_handler(sig, stop.set)
        await stop.wait()
    finally:
        await tcp.close()
        await rtu.close()
        runner.stop()
        device.stop()
        link.close()
        rtu_line.close()
