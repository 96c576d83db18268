"""Actuator client against the simulated controller over Modbus RTU on a real pseudo-terminal pair.

socat (Debian) joins two ptys back to back, as a null-modem cable: the controller opens one end,
the client the other, 8N1 (ptys refuse parity).
"""

from __future__ import annotations

import asyncio
import os
import shutil
import subprocess

import pytest

from drivers.actuator import ActuatorClient
from drivers.register_map import ControllerState
from drivers.setpoints import DwellSetpoint
from sequences.limits import BenchLimits
from simulators.controller_server import ControllerServer
from tests.waiting import async_wait_until, wait_until

pytestmark = pytest.mark.skipif(shutil.which("socat") is None, reason="socat (Debian) not installed")


@pytest.fixture
def pty_pair(tmp_path):
    """Two pty paths joined by socat: (controller side, host side)."""
    device, host = str(tmp_path / "controller"), str(tmp_path / "host")
    proc = subprocess.Popen(
        ["socat", f"pty,raw,echo=0,link={device}", f"pty,raw,echo=0,link={host}"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    try:
        wait_until(lambda: os.path.exists(device) and os.path.exists(host), 5, "socat's ptys")
        yield device, host
    finally:
        proc.terminate()
        proc.wait(timeout=5)


@pytest.fixture
async def rtu_client(bench, pty_pair):
    device, host = pty_pair
    server = ControllerServer(bench)
    await server.serve_rtu(device, baudrate=115200)
    client = ActuatorClient.rtu(host, baudrate=115200, limits=BenchLimits(), timeout_s=0.5)
    yield client
    await client.close()
    await server.close()


async def _status_when(client: ActuatorClient, predicate):
    status = await client.read_status()
    return status if predicate(status) else None


async def test_dwell_over_rtu_on_a_pty_pair(rtu_client):
    client = rtu_client
    status = await client.connect()  # checks the protocol version
    assert status.protocol_version == 1
    assert status.state == ControllerState.OFF
    await client.hydraulics_low()
    await client.hydraulics_high()
    await client.configure(DwellSetpoint(freq_hz=8.0, amplitude_mm=1.5, taper_in_s=0.2, taper_out_s=0.3))
    await client.start()
    running = await async_wait_until(
        lambda: _status_when(
            client, lambda s: s.state == ControllerState.RUNNING and s.achieved_amplitude_mm > 1.47
        ),
        3.0,
        "the dwell to reach its amplitude over RTU",
    )
    assert running.frequency_hz == pytest.approx(8.0)
    assert running.achieved_amplitude_mm == pytest.approx(1.5, rel=0.02)
    before_stop = await client.read_status()
    await client.stop()
    assert (await client.read_status()).state == ControllerState.TAPERING
    rest = await async_wait_until(
        lambda: _status_when(client, lambda s: s.state == ControllerState.HYDRAULICS_HIGH),
        2.0,
        "the tapered stop",
    )
    # the 0.3 s taper, counted on the controller's clock (1 kHz ticks, updated every 10 ms block)
    assert rest.sample_count - before_stop.sample_count >= 300 - 10
    assert abs(rest.displacement_mm) < 0.05
    assert rest.cycle_count >= 4


async def test_the_rtu_line_is_paced_at_its_baud_rate(rtu_client):
    """A status read is two requests (input registers 0-6 and 10-19): 8 + 19 and 8 + 25 bytes on
    the wire, 600 bits, 5.2 ms at 115200 baud; a pty alone would answer far sooner."""
    client = rtu_client
    await client.connect()
    wire_s = (8 + 5 + 2 * 7 + 8 + 5 + 2 * 10) * 10 / 115200
    loop = asyncio.get_running_loop()
    durations = []
    for _ in range(5):
        started = loop.time()
        await client.read_status()
        durations.append(loop.time() - started)
    assert min(durations) >= wire_s
