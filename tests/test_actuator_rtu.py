"""Actuator client against the simulated controller over Modbus RTU on a real pseudo-terminal pair.

socat (Debian) joins two ptys back to back, as a null-modem cable: the controller opens one end,
the client the other, 8N1 (ptys refuse parity).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import time

import pytest

from drivers.actuator import ActuatorClient
from drivers.register_map import ControllerState
from drivers.setpoints import DwellSetpoint, SoftLimits
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
    client = ActuatorClient.rtu(host, baudrate=115200, limits=SoftLimits(), timeout_s=0.5)
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
    await client.stop()
    stopped_at = time.monotonic()
    assert (await client.read_status()).state == ControllerState.TAPERING
    rest = await async_wait_until(
        lambda: _status_when(client, lambda s: s.state == ControllerState.HYDRAULICS_HIGH),
        2.0,
        "the tapered stop",
    )
    assert time.monotonic() - stopped_at >= 0.25  # the 0.3 s taper, paced in real time
    assert abs(rest.displacement_mm) < 0.05
    assert rest.cycle_count >= 4
