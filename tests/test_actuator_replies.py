"""Every reply is checked against its request. An RTU line has no transaction ids, so a late reply
lands on the next request: served here as RTU frames over TCP on 127.0.0.1 (a serial-to-Ethernet
converter), the real pymodbus server answering strictly in order."""

from __future__ import annotations

import pytest
from pymodbus import FramerType

from drivers.actuator import ActuatorClient
from drivers.errors import CommandOutcomeUnknownError, LinkError, LinkTimeoutError, MalformedReplyError
from drivers.register_map import ControllerState
from simulators.controller_server import ControllerServer

TIMEOUT_S = 0.3


@pytest.fixture
async def rtu_over_tcp(bench):
    server = ControllerServer(bench)
    host, port = await server.serve_tcp("127.0.0.1", 0, framer=FramerType.RTU)
    client = ActuatorClient.rtu(f"socket://{host}:{port}", timeout_s=TIMEOUT_S)
    await client.connect()
    yield server, client
    await client.close()
    await server.close()


async def test_a_read_that_gets_a_late_write_reply_drains_and_retries(rtu_over_tcp):
    server, client = rtu_over_tcp
    server.faults.delay_next, server.faults.delay_s = 1, TIMEOUT_S + 0.15
    with pytest.raises(CommandOutcomeUnknownError):
        await client.hydraulics_low()  # its reply comes late, while the read below waits
    status = await client.read_status()  # the first attempt gets the write's reply
    assert status.state == ControllerState.HYDRAULICS_LOW  # the write was applied, once
    assert status.protocol_version == 1


async def test_a_write_that_gets_a_late_read_reply_is_an_unknown_outcome(rtu_over_tcp):
    server, client = rtu_over_tcp
    client.read_attempts = 1
    server.faults.delay_next, server.faults.delay_s = 1, TIMEOUT_S + 0.15
    with pytest.raises(LinkTimeoutError):
        await client.read_status()
    before = server.writes_received
    with pytest.raises(CommandOutcomeUnknownError, match="function code 4"):
        await client.hydraulics_low()  # answered first by the late read reply
    client.read_attempts = 3
    assert (await client.read_status()).state == ControllerState.HYDRAULICS_LOW
    assert server.writes_received == before + 1  # not re-sent


async def test_a_state_code_the_protocol_does_not_define_is_a_link_error(rtu_over_tcp, bench):
    _server, client = rtu_over_tcp
    with bench.lock:
        bench.controller.state = 42  # a controller with a newer firmware
    with pytest.raises(MalformedReplyError, match="state") as err:
        await client.read_status()
    assert isinstance(err.value, LinkError)
    assert not isinstance(err.value, ValueError)


async def test_arming_the_watchdog_is_sent_again_when_its_reply_comes_too_late(bench):
    """A busy host's late reply to the watchdog's arming left the bench unopened ("no reply ... not
    re-sent"). Arming lands the same twice, so it is the one write sent again: over Modbus TCP (the
    late reply is told apart by its transaction id) the bench arms, and the controller holds the
    watchdog asked for."""
    server = ControllerServer(bench)
    host, port = await server.serve_tcp("127.0.0.1", 0)
    client = ActuatorClient.tcp(host, port, timeout_s=TIMEOUT_S)
    await client.connect()
    try:
        before = server.writes_received
        server.faults.delay_next, server.faults.delay_s = 1, TIMEOUT_S + 0.15
        await client.start_heartbeat(period_s=0.1, watchdog_ms=2000)
        assert server.writes_received == before + 2
        with bench.lock:
            assert bench.controller.setpoints["watchdog_ms"] == 2000
        await client.stop_heartbeat()
    finally:
        await client.close()
        await server.close()
