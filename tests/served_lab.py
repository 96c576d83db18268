"""The simulated devices served outside the command under test, as a lab's real ones would be:
the controller on Modbus TCP at 127.0.0.1, the WFS on a pty, the bench paced in real time."""

from __future__ import annotations

import asyncio
import contextlib
import threading
from collections.abc import Iterator

from simulators.bench_sim import BenchRunner, SimulatedBench
from simulators.controller_server import ControllerServer
from simulators.ports import PtyLink
from simulators.wfs_device import WfsDevice


@contextlib.contextmanager
def served_lab() -> Iterator[tuple[ControllerServer, PtyLink, WfsDevice]]:
    """``(server, link, device)``: ``server.address`` is the controller's, ``link.path`` the WFS's
    pty. Everything is stopped on exit, and the bench runner must not have failed."""
    bench = SimulatedBench.paper_shaker(seed=1)
    runner = BenchRunner(bench, paced=True)
    link = PtyLink()
    device = WfsDevice(link, bench, seed=1)
    runner.sinks.append(device)
    server = ControllerServer(bench)
    loop = asyncio.new_event_loop()
    thread = threading.Thread(target=loop.run_forever, name="served-controller", daemon=True)
    thread.start()
    device.start()
    runner.start()
    try:
        server.address = asyncio.run_coroutine_threadsafe(server.serve_tcp("127.0.0.1", 0), loop).result(10)
        yield server, link, device
    finally:
        asyncio.run_coroutine_threadsafe(server.close(), loop).result(10)
        loop.call_soon_threadsafe(loop.stop)
        thread.join(timeout=5)
        runner.stop()
        device.stop()
        link.close()
        loop.close()
    assert runner.error is None
