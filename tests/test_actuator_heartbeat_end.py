"""The heartbeat ends when it should: on its stop, even when the stop meets a heartbeat write's
reply, and when it is lost, even when the link comes back.

pymodbus awaits each reply with ``asyncio.wait_for``; on Python 3.11 a cancellation that arrives in
the same loop iteration as the reply is lost (the write returns normally), so a heartbeat loop that
relied on the cancellation alone went on beating and ``close()`` waited for it forever (seen as an
``actuator call took longer than 5.0 s`` when a campaign closed the bench, about one close in
twenty). The interleaving is reproduced here exactly: the reply is set, then the stop is asked for,
before the heartbeat task runs again.
"""

from __future__ import annotations

import asyncio

from drivers.register_map import ControllerState, InterlockFlag
from drivers.setpoints import DwellSetpoint
from tests.test_actuator_link import _true_after
from tests.waiting import async_wait_until


async def test_stop_heartbeat_ends_the_loop_when_the_reply_arrives_with_the_cancellation(client):
    await client.start_heartbeat(period_s=0.01)
    beat = client._heartbeat_task
    loop = asyncio.get_running_loop()
    in_flight = asyncio.Event()
    reply = loop.create_future()
    real_write = client._write

    async def write_awaiting_the_reply(values):
        if "heartbeat" in values and not reply.done():
            in_flight.set()
            await asyncio.wait_for(reply, timeout=5.0)  # as pymodbus awaits a reply
        else:
            await real_write(values)

    client._write = write_awaiting_the_reply
    await asyncio.wait_for(in_flight.wait(), timeout=5.0)
    reply.set_result(None)  # the reply lands ...
    stopping = asyncio.ensure_future(client.stop_heartbeat())  # ... as the stop cancels the beat
    await asyncio.wait({stopping}, timeout=5.0)  # a timeout only: it ends at once
    assert stopping.done() and beat.done(), "the heartbeat went on beating after its stop"


async def test_a_lost_heartbeat_stays_lost_when_the_link_comes_back(client, controller):
    """The controller drops the connection mid-dwell and pymodbus reconnects (within a fraction of
    a second, well inside the 3 s watchdog here); the heartbeat, once lost, must not resume, so the
    controller's watchdog stops the dwell (docs/protocols.md). A heartbeat revived by the
    reconnection kept a dwell running to its end while the engine had declared the run
    interlocked."""
    await client.hydraulics_low()
    await client.hydraulics_high()
    await client.configure(DwellSetpoint(freq_hz=10.0, amplitude_mm=2.0, taper_in_s=0.2, taper_out_s=0.2))
    await client.start_heartbeat(period_s=0.05, watchdog_ms=3000)
    await client.start()  # a dwell until stopped
    controller.drop_connections()
    await asyncio.wait_for(client.heartbeat_lost.wait(), 5.0)  # timeouts only, here and below
    await async_wait_until(lambda: _true_after(client.connected), 5.0, "pymodbus to reconnect")
    bench = controller.bench
    await async_wait_until(
        lambda: _true_after(_model_state(bench) == ControllerState.INTERLOCK), 10.0, "the watchdog's stop"
    )
    with bench.lock:
        assert bench.controller.flags == InterlockFlag.WATCHDOG
    assert client._heartbeat_task is not None and client._heartbeat_task.done()


def _model_state(bench) -> ControllerState:
    with bench.lock:
        return bench.controller.state


async def test_a_connection_dropped_between_two_beats_loses_the_heartbeat(client, controller):
    """The controller drops the connection while no heartbeat write is in flight (a 1 s period) and
    pymodbus reconnects before the next beat: the drop alone loses the heartbeat, with its reason,
    and no beat is written after it. Before, a drop between two beats went unnoticed: the next beat
    went out on the new connection and a run went on as if nothing had happened."""
    reasons: list[str] = []
    client.on_link_lost = reasons.append
    await client.start_heartbeat(period_s=1.0, watchdog_ms=5000)
    with controller.bench.lock:
        beats_before = controller.bench.controller.setpoints["heartbeat"]
    controller.drop_connections()
    await asyncio.wait_for(client.heartbeat_lost.wait(), 5.0)  # a timeout only: it is set at the drop
    assert reasons == ["link lost: the connection to the controller dropped"]
    assert client.heartbeat_failures == 0, "lost by the drop itself, not by a failed write"
    await asyncio.wait_for(client._heartbeat_task, 5.0)  # ends at its next beat, writing nothing
    with controller.bench.lock:
        assert controller.bench.controller.setpoints["heartbeat"] == beats_before
