"""Stopping the heartbeat ends it even when the stop meets a heartbeat write's reply.

pymodbus awaits each reply with ``asyncio.wait_for``; on Python 3.11 a cancellation that arrives in
the same loop iteration as the reply is lost (the write returns normally), so a heartbeat loop that
relied on the cancellation alone went on beating and ``close()`` waited for it forever (seen as an
``actuator call took longer than 5.0 s`` when a campaign closed the bench, about one close in
twenty). The interleaving is reproduced here exactly: the reply is set, then the stop is asked for,
before the heartbeat task runs again.
"""

from __future__ import annotations

import asyncio


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
