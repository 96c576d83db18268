"""Actuator client against the simulated controller over Modbus TCP on 127.0.0.1."""

from __future__ import annotations

import asyncio
import contextlib
import re
import shutil
import subprocess
import time

import pytest
from pymodbus.client import AsyncModbusTcpClient
from pymodbus.constants import ExcCodes

from bench.models.setup import BenchSetup
from drivers.actuator import ActuatorClient
from drivers.errors import (
    CommandOutcomeUnknownError,
    CommandRejectedError,
    ConnectionLostError,
    DeviceExceptionError,
    LimitError,
    LinkTimeoutError,
    NotConfiguredError,
    ProtocolMismatchError,
)
from drivers.register_map import (
    ControllerState,
    ErrorCode,
    InterlockFlag,
    default_map_path,
    load_register_map,
)
from drivers.setpoints import DwellSetpoint, SweepSetpoint
from sequences.limits import BenchLimits
from simulators.bench_sim import SimulatedBench
from simulators.controller_server import ControllerServer
from simulators.plant import PlantSimulator, SensorRealism
from tests.waiting import async_wait_until

#: The bound of a wait for the controller (wall clock): generous for a loaded machine, never a
#: measured time (the tapers and ramps are timed on the bench's own clock where they are tested).
DEADLINE_S = 30.0
DWELL = DwellSetpoint(freq_hz=10.0, amplitude_mm=2.0, taper_in_s=0.2, taper_out_s=0.2)


async def _arm(client: ActuatorClient) -> None:
    await client.hydraulics_low()
    await client.hydraulics_high()


async def _state_is(client: ActuatorClient, *states: ControllerState):
    status = await client.read_status()
    return status if status.state in states else None


async def test_connect_reads_protocol_version_and_state(client):
    status = await client.read_status()
    assert status.protocol_version == 1
    assert status.state == ControllerState.OFF


async def test_dwell_runs_reaches_amplitude_and_stop_tapers(client, bench):
    await _arm(client)
    await client.configure(DWELL)
    await client.start()
    status = await async_wait_until(
        lambda: _running_at_amplitude(client), DEADLINE_S, "the dwell to reach its amplitude"
    )
    assert status.frequency_hz == 10.0
    assert status.achieved_amplitude_mm == pytest.approx(2.0, rel=0.05)
    await client.stop()
    assert (await client.read_status()).state in (ControllerState.TAPERING, ControllerState.HYDRAULICS_HIGH)
    status = await async_wait_until(
        lambda: _state_is(client, ControllerState.HYDRAULICS_HIGH), DEADLINE_S, "stop"
    )
    assert abs(status.displacement_mm) < 0.05
    assert status.cycle_count >= 3


async def _running_at_amplitude(client):
    status = await client.read_status()
    ok = status.state == ControllerState.RUNNING and status.achieved_amplitude_mm > 1.9
    return status if ok else None


async def test_sweep_is_configured_and_finishes_by_itself(client):
    await _arm(client)
    await client.configure(SweepSetpoint(2.0, 8.0, 0.8, 1.0, spacing="log", taper_in_s=0.2, taper_out_s=0.2))
    await client.start()
    done = await async_wait_until(
        lambda: _state_is(client, ControllerState.HYDRAULICS_HIGH), DEADLINE_S, "end"
    )
    assert done.interlock == InterlockFlag(0)


@pytest.mark.parametrize(
    "setpoint",
    [
        DwellSetpoint(freq_hz=10.0, amplitude_mm=50.0),
        DwellSetpoint(freq_hz=500.0, amplitude_mm=1.0),
        SweepSetpoint(0.01, 30.0, 20.0, 1.0),
        DwellSetpoint(freq_hz=10.0, amplitude_mm=1.0, taper_in_s=0.0),
    ],
)
async def test_out_of_limit_setpoints_refused_before_anything_is_written(client, controller, setpoint):
    before = controller.writes_received
    with pytest.raises(LimitError):
        await client.configure(setpoint)
    assert controller.writes_received == before


@pytest.mark.parametrize(
    ("changes", "words"),
    [
        ({"force_interlock_n": -100.0}, "force_interlock_n must be > 0"),
        ({"displacement_interlock_mm": -1.0}, "displacement_interlock_mm must be > 0"),
        ({"force_interlock_n": 0.0}, "force_interlock_n must be > 0"),
        ({"force_interlock_n": 10_000.0}, "force_interlock_n 10000.0 must be above force_n"),
    ],
)
def test_negative_zero_or_low_interlock_thresholds_cannot_reach_a_client(changes, words):
    """The thresholds the client writes with every setpoint come from the bench's limits, which
    refuse a negative or zero one (the controller would refuse it, and 0 means its hardware limit)
    and one below the host's own limit."""
    with pytest.raises(ValueError, match=words):
        BenchLimits(**changes)


async def test_a_mask_with_no_existing_post_is_refused_by_the_controller(client):
    for mask in (0, 0xFFF0, 0x0002):  # the simulated shaker has post 1 only
        with pytest.raises(CommandRejectedError, match="INVALID_SETPOINT"):
            await client.configure(DWELL, channel_mask=mask)
    await client.configure(DWELL, channel_mask=0x0001)


async def test_command_not_allowed_in_state_is_a_typed_refusal(client):
    await client.configure(DWELL)
    with pytest.raises(CommandRejectedError, match="NOT_ALLOWED_IN_STATE"):
        await client.start()  # hydraulics are off
    assert (await client.read_status()).error == ErrorCode.NOT_ALLOWED_IN_STATE


async def _raw_write(controller, address: int, words: list[int]):
    """One write request from an independent raw Modbus client (no soft limits, no client logic)."""
    host, port = controller.address
    raw = AsyncModbusTcpClient(host, port=port, timeout=1, retries=0)
    assert await raw.connect()
    try:
        return await raw.write_registers(address, words, device_id=1)
    finally:
        raw.close()


async def _raw_write_named(controller, values: dict[str, float]) -> None:
    """Write named holding registers raw; fail the test on a refusal."""
    for address, words in controller.map.encode_many("holding", values):
        response = await _raw_write(controller, address, words)
        assert not response.isError(), response


async def test_start_is_refused_unless_the_last_configure_completed(client, controller):
    await _arm(client)
    before = controller.writes_received
    with pytest.raises(NotConfiguredError):
        await client.start()  # nothing configured yet
    await client.configure(DWELL)
    # a second configure fails on the controller's side: it may hold a half-written setpoint
    controller.faults.exception_next = 1  # DEVICE_FAILURE
    with pytest.raises(DeviceExceptionError):
        await client.configure(DwellSetpoint(freq_hz=5.0, amplitude_mm=1.0))
    sent = controller.writes_received
    with pytest.raises(NotConfiguredError):
        await client.start()
    assert controller.writes_received == sent > before  # START never went out
    assert (await client.read_status()).state == ControllerState.HYDRAULICS_HIGH
    await client.configure(DWELL)
    await client.start()
    assert (await client.read_status()).state == ControllerState.RUNNING
    await client.stop()


async def test_garbage_writes_are_refused_by_the_controller(client, controller):
    [(address, words)] = controller.map.encode_many("holding", {"command": 999})
    assert (await _raw_write(controller, address, words)).exception_code == ExcCodes.ILLEGAL_VALUE
    [(address, words)] = controller.map.encode_many("holding", {"taper_out_s": float("nan")})
    assert (await _raw_write(controller, address, words)).exception_code == ExcCodes.ILLEGAL_VALUE
    before = await client.read_table("holding")
    # half of a float32: refused, nothing applied
    response = await _raw_write(controller, 11, [0x4000])
    assert response.isError()
    assert response.exception_code == ExcCodes.ILLEGAL_ADDRESS
    after = await client.read_table("holding")
    assert after == before
    assert (await client.read_status()).state == ControllerState.OFF


class SteppedClock:
    """The controller's watchdog clock, advanced by the test with the bench it steps."""

    def __init__(self) -> None:
        self.now_s = 0.0

    def __call__(self) -> float:
        return self.now_s


async def test_heartbeat_loss_tapers_to_a_stop_within_watchdog_plus_taper():
    """On a stepped clock: the bench advances only when the test says, so the watchdog's bound is
    checked in controller time, whatever the load of the machine."""
    period_s, watchdog_s, taper_s, block_s = 0.05, 1.0, 0.2, 0.01
    clock = SteppedClock()
    bench = SimulatedBench(PlantSimulator(BenchSetup.paper_shaker(), SensorRealism(seed=1)), clock)
    server = ControllerServer(bench)
    host, port = await server.serve_tcp("127.0.0.1", 0)
    client = ActuatorClient.tcp(host, port, timeout_s=0.3)

    def step(seconds: float) -> None:
        for _ in range(round(seconds / block_s)):
            clock.now_s += block_s
            bench.advance(round(block_s * bench.output_rate_hz))

    try:
        await client.connect()
        await _arm(client)
        await client.configure(DWELL)
        await client.start_heartbeat(period_s=period_s, watchdog_ms=int(watchdog_s * 1000))
        await client.start()
        # two watchdog periods of controller time, a heartbeat period after each heartbeat received
        echo = (await client.read_status()).heartbeat_echo
        for _ in range(round(2 * watchdog_s / period_s)):
            status = await async_wait_until(
                lambda echo=echo: _heartbeat_changed(client, echo), DEADLINE_S, "the next heartbeat"
            )
            echo, last_beat_s = status.heartbeat_echo, clock.now_s
            step(period_s)
        assert (await client.read_status()).state == ControllerState.RUNNING
        await client.stop_heartbeat()
        if (await client.read_status()).heartbeat_echo != echo:
            last_beat_s = clock.now_s  # one more heartbeat landed before the task stopped
        while bench.controller.state == ControllerState.RUNNING:
            step(block_s)
        tripped = await client.read_status()
        # the watchdog is checked once per block of the bench: the trip comes within one block
        assert watchdog_s <= clock.now_s - last_beat_s <= watchdog_s + block_s + 1e-9
        assert InterlockFlag.WATCHDOG in tripped.interlock
        step(taper_s + block_s)
        rest = await client.read_status()
        assert rest.state == ControllerState.INTERLOCK
        assert rest.sample_count - tripped.sample_count <= (taper_s + block_s) * 1000
        assert abs(rest.displacement_mm) < 0.05
        await client.reset_interlock()
        assert (await client.read_status()).state == ControllerState.HYDRAULICS_LOW
    finally:
        await client.close()
        await server.close()


async def _heartbeat_changed(client: ActuatorClient, echo: int):
    status = await client.read_status()
    return status if status.heartbeat_echo != echo else None


async def test_heartbeat_refuses_a_watchdog_one_slow_reply_would_trip(client, controller):
    before = controller.writes_received
    # 0.3 s timeout x 3 attempts + 0.1 s period = 1.0 s: a 900 ms watchdog could trip on one slow reply
    with pytest.raises(ValueError, match="900 ms watchdog would trip on one slow reply"):
        await client.start_heartbeat(period_s=0.1, watchdog_ms=900)
    assert controller.writes_received == before


async def test_slow_replies_do_not_starve_the_heartbeat_with_the_defaults(controller):
    host, port = controller.address
    client = ActuatorClient.tcp(host, port)  # every default: timeout, attempts, heartbeat, watchdog
    await client.connect()
    try:
        await _arm(client)
        await client.configure(DWELL)
        await client.start_heartbeat()
        await client.start()
        await async_wait_until(lambda: _state_is(client, ControllerState.RUNNING), DEADLINE_S, "running")
        # the next requests (the read's attempts, or heartbeats in between) answer too late: the
        # link is held for up to timeout x attempts, the heartbeat waits behind it
        controller.faults.delay_s = client.timeout_s + 0.05
        controller.faults.delay_next = client.read_attempts
        with contextlib.suppress(LinkTimeoutError):
            await client.read_status()
        await async_wait_until(
            _true_when(lambda: controller.faults.delay_next == 0), DEADLINE_S, "the slow replies"
        )
        status = await client.read_status()
        assert status.state == ControllerState.RUNNING, status
        assert status.interlock == InterlockFlag(0)
        await client.stop()
    finally:
        await client.close()


async def test_estop_freezes_and_needs_a_reset(client):
    await _arm(client)
    await client.configure(DWELL)
    await client.start()
    await client.estop()
    status = await client.read_status()
    assert status.state == ControllerState.ESTOP
    assert InterlockFlag.ESTOP in status.interlock
    with pytest.raises(CommandRejectedError):
        await client.start()
    await client.reset_interlock()
    # the release ramps from the frozen position back to rest, then hydraulics are low
    status = await async_wait_until(
        lambda: _state_is(client, ControllerState.HYDRAULICS_LOW), DEADLINE_S, "rest"
    )
    assert status.interlock == InterlockFlag(0)
    assert abs(status.displacement_mm) < 0.05


async def test_displacement_limit_trips_the_interlock(client, controller):
    await _arm(client)
    await client.configure(DWELL)
    # a lab limit set directly on the controller, below the running amplitude
    await _raw_write_named(controller, {"displacement_limit_mm": 1.0})
    await client.start()
    status = await async_wait_until(
        lambda: _state_is(client, ControllerState.INTERLOCK), DEADLINE_S, "interlock"
    )
    assert InterlockFlag.DISPLACEMENT in status.interlock


async def test_read_timeout_is_retried(client, controller):
    controller.faults.delay_next, controller.faults.delay_s = 1, 0.5
    status = await client.read_status()  # first attempt times out (0.3 s), the retry answers
    assert status.protocol_version == 1


async def test_write_timeout_is_not_resent(client, controller):
    controller.faults.delay_next, controller.faults.delay_s = 1, 0.5
    before = controller.writes_received
    with pytest.raises(CommandOutcomeUnknownError):
        await client.hydraulics_low()
    # The delayed write lands once; a re-sent copy would queue behind it on the same connection, so
    # after the write has landed, one more round trip proves nothing else was sent.
    await async_wait_until(
        lambda: _true_after(controller.writes_received >= before + 1), DEADLINE_S, "the delayed write to land"
    )
    await client.read_status()
    assert controller.writes_received == before + 1


async def test_exception_reply_is_typed(client, controller):
    controller.faults.exception_next = 3  # as many as the read attempts
    with pytest.raises(DeviceExceptionError) as err:
        await client.read_status()
    assert err.value.exception_code == 4


async def test_only_illegal_value_and_device_busy_are_refusals(client, controller):
    controller.faults.exception_next = 1  # DEVICE_FAILURE: the controller failed, it did not refuse
    with pytest.raises(DeviceExceptionError) as err:
        await client.hydraulics_low()
    assert not isinstance(err.value, CommandRejectedError)
    assert err.value.exception_code == ExcCodes.DEVICE_FAILURE
    with pytest.raises(CommandRejectedError, match="NOT_ALLOWED_IN_STATE"):  # DEVICE_BUSY
        await client.hydraulics_high()
    # an accepted write clears the reason of the last refusal
    await client.configure(DWELL)
    assert (await client.read_status()).error == ErrorCode.NONE


async def test_dropped_connection_is_typed(client, controller):
    controller.faults.delay_next, controller.faults.delay_s = 1, 0.25
    pending = asyncio.create_task(client.hydraulics_low())
    await async_wait_until(_true_when(lambda: controller.faults.delay_next == 0), DEADLINE_S, "the request")
    controller.drop_connections()
    with pytest.raises((ConnectionLostError, CommandOutcomeUnknownError)):
        await pending


def _true_when(predicate):
    async def check():
        return predicate()

    return check


async def test_refused_connection_and_wrong_protocol_are_typed(controller, tmp_path):
    closed = ActuatorClient.tcp("127.0.0.1", 1, timeout_s=0.2)
    with pytest.raises(ConnectionLostError):
        await closed.connect()
    lab = tmp_path / "lab.toml"
    lab.write_text(default_map_path().read_text().replace("protocol_version = 1", "protocol_version = 2"))
    host, port = controller.address
    other = ActuatorClient.tcp(host, port, register_map=load_register_map(lab), timeout_s=0.3)
    with pytest.raises(ProtocolMismatchError, match="version 1"):
        await other.connect()
    await other.close()


@pytest.mark.skipif(shutil.which("mbpoll") is None, reason="mbpoll (Debian) not installed")
async def test_mbpoll_reads_status_and_protocol_version_as_documented(controller, client):
    """An independent Modbus implementation reads the registers at the documented addresses."""
    await _arm(client)
    host, port = controller.address
    args = ["mbpoll", "-m", "tcp", "-a", "1", "-p", str(port), "-1"]
    # mbpoll references are 1-based: input registers 0 (protocol_version) and 1 (state) are 1 and 2
    values = _mbpoll_values(await _run(*args, "-t", "3", "-r", "1", "-c", "2", host))
    assert values == {1: "1", 2: str(int(ControllerState.HYDRAULICS_HIGH))}
    # holding float32 amplitude_mm at address 10..11 (reference 11), high word first
    await client.configure(DWELL)
    values = _mbpoll_values(await _run(*args, "-t", "4:float", "-B", "-r", "11", "-c", "1", host))
    assert float(values[11]) == pytest.approx(2.0)


def _mbpoll_values(out: str) -> dict[int, str]:
    return {int(ref): value for ref, value in re.findall(r"^\[(\d+)\]:\s*(\S+)", out, re.MULTILINE)}


async def _run(*cmd: str) -> str:
    proc = await asyncio.create_subprocess_exec(*cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    out, _ = await asyncio.wait_for(proc.communicate(), 10)
    assert proc.returncode == 0, out.decode()
    return out.decode()


async def _true_after(value: bool) -> bool:
    """An awaitable view of a plain condition, for ``async_wait_until``."""
    return value


async def test_heartbeat_loss_is_an_event_when_the_controller_goes_away(controller):
    host, port = controller.address
    reasons: list[str] = []
    client = ActuatorClient.tcp(host, port, timeout_s=0.3, on_link_lost=reasons.append)
    await client.connect()
    try:
        await _arm(client)
        await client.configure(DWELL)
        await client.start_heartbeat(period_s=0.05, watchdog_ms=1000)
        await client.start()
        assert not client.heartbeat_lost.is_set()
        await controller.close()  # the controller's end of the link goes away mid-run
        closed_at = time.monotonic()
        # documented: within one heartbeat period plus one reply timeout (0.35 s); the wait allows
        # a loaded machine a further second before calling the bound broken
        await asyncio.wait_for(client.heartbeat_lost.wait(), 0.05 + 0.3 + 1.0)
        assert time.monotonic() - closed_at <= 0.05 + 0.3 + 1.0
        assert len(reasons) == 1
        assert "link lost" in reasons[0]
    finally:
        await client.close()


async def test_heartbeat_loss_is_an_event_when_replies_stop(client, controller):
    await _arm(client)
    reasons: list[str] = []
    client.on_link_lost = reasons.append
    await client.start_heartbeat(period_s=0.05, watchdog_ms=1000)
    echo = (await client.read_status()).heartbeat_echo
    await async_wait_until(lambda: _heartbeat_changed(client, echo), DEADLINE_S, "a heartbeat to land")
    assert not client.heartbeat_lost.is_set()
    controller.faults.delay_next, controller.faults.delay_s = 1000, 5.0  # the controller hangs
    await asyncio.wait_for(client.heartbeat_lost.wait(), 1.0 + 0.3 + 1.0)
    assert len(reasons) == 1
    assert "no heartbeat acknowledged" in reasons[0]
    controller.faults.delay_next = 0
