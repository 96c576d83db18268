"""Shared fixtures: a simulated bench with its runner, the controller served on 127.0.0.1."""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable

import pytest

from drivers.actuator import ActuatorClient
from drivers.setpoints import SoftLimits
from simulators.bench_sim import BenchRunner, SimulatedBench
from simulators.controller_server import ControllerServer


def wait_until(predicate: Callable[[], bool], timeout_s: float, what: str) -> None:
    """Poll ``predicate`` until true; fail the test with ``what`` after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s} s waiting for {what}")
        time.sleep(0.005)


async def async_wait_until(predicate, timeout_s: float, what: str):
    """Async variant: ``predicate`` is an async callable returning a truthy value, which is returned."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = await predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s} s waiting for {what}")
        await asyncio.sleep(0.01)


@pytest.fixture
def bench():
    """A paper shaker bench advanced in real time (the controller's tapers run at wall-clock pace)."""
    bench = SimulatedBench.paper_shaker(seed=1)
    runner = BenchRunner(bench, paced=True)
    runner.start()
    yield bench
    runner.stop()
    assert runner.error is None


@pytest.fixture
async def controller(bench):
    server = ControllerServer(bench)
    host, port = await server.serve_tcp("127.0.0.1", 0)
    server.address = (host, port)
    yield server
    await server.close()


@pytest.fixture
async def client(controller):
    host, port = controller.address
    client = ActuatorClient.tcp(host, port, limits=SoftLimits(), timeout_s=0.3)
    await client.connect()
    yield client
    await client.close()
