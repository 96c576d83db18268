"""Every interlock the engine can trip lights a lamp on the Bench screen: its checks', its own (a
host stall that lost frames, the excitation's watchdog) and any other name an interlock trips under.
A run that ends interlocked never leaves every lamp green: the host stall that did is made here, on
the paced simulated bench, by holding the engine's thread while the WFS goes on sending."""

from __future__ import annotations

import threading
from pathlib import Path

from textual.widgets import Static

from bench.engine import events as ev
from bench.engine.interlocks import ENGINE_INTERLOCKS, HOST_STALLED
from bench.engine.states import RunState
from bench.tui.app import WfsBenchApp
from tests.tui.keys import press
from tests.tui.test_tui import finished, open_app, start_long_dwell, text_of, until
from tests.waiting import wait_until

#: The paced bench of the UI's tests (tests/tui/files/paced.toml), with the engine's backlog short:
#: held, the engine's subscription fills in 0.2 s, the reader waits, the device holds its frames
#: for 1 s (flow control) and then drops them: the host stall loses frames.
STALLING = """\
[simulation]
paced = true
own_process = false
flow_control = true

[actuator]
watchdog_ms = 10000

[timing]
wfs_silence_s = 2.0
backlog_s = 0.2
"""
#: The longest the engine's thread is held waiting for the device to drop frames (about 1.2 s on an
#: idle machine; the simulated lab shares the test's process, which a busy machine slows).
HOLD_LIMIT_S = 60.0


def lamps(app: WfsBenchApp) -> dict[str, str]:
    """The Bench screen's interlock lamps as drawn: each lamp's text and its colour."""
    content = app.query_one("#bench-lamps", Static).visual
    plain = content.plain
    return {
        plain[span.end + 1 :].split("   ")[0]: str(span.style)
        for span in content.spans
        if plain[span.start : span.end] == "●"
    }


async def test_every_interlock_the_engine_can_trip_lights_a_lamp(app: WfsBenchApp) -> None:
    """A lamp each for the engine's checks and its own interlocks, green until one trips; a name
    without a lamp of its own (a check a bench adds) lights one under its name."""
    async with app.run_test(size=(120, 40)) as pilot:
        await open_app(pilot, app)
        await press(pilot, "f2")
        names = app.interlock_names
        assert set(ENGINE_INTERLOCKS) <= set(names)
        assert {"WFS link lost", "actuator link lost", "controller interlock"} <= set(names)
        await until(pilot, lambda: all(lamps(app).get(n) == "green" for n in names), "every lamp green")
        tripped = (*names, "amplitude excursion")
        for name in tripped:  # as the engine publishes them, on its bus
            app.session.engine.bus.publish(ev.InterlockTripped(name, "a test's trip", "test-s000-dwell_grid"))
        await until(pilot, lambda: all(lamps(app).get(n) == "red" for n in tripped), "every lamp red")


async def test_a_host_stall_that_lost_frames_lights_its_lamp(tmp_path: Path) -> None:
    """The engine's thread held mid-dwell, as a busy machine holds it, until the device dropped
    frames: the run ends interlocked on the host stall, and its lamp is the red one."""
    config = tmp_path / "stalling.toml"
    config.write_text(STALLING)
    app = WfsBenchApp(config, tmp_path / "campaign.h5")
    async with app.run_test(size=(120, 40)) as pilot:
        held = threading.Event()

        def hold_once(event: ev.Event) -> None:  # on the engine's thread
            if isinstance(event, ev.PointStarted) and not held.is_set():
                held.set()
                device = app.session.devices.lab.device
                wait_until(lambda: device.frames_dropped > 0, HOLD_LIMIT_S, "the device dropping frames")

        await open_app(pilot, app)
        app.session.engine.bus.subscribe(hold_once)
        recorded = await start_long_dwell(pilot, app)
        await until(pilot, lambda: finished(recorded) is not None, "the end of the sequence")
        assert held.is_set() and app.session.devices.lab.device.frames_dropped > 0
        outcome = finished(recorded)
        assert outcome.status == "interlocked" and outcome.reason.startswith("host stalled: "), outcome
        assert app.session.engine.state is RunState.INTERLOCKED
        await press(pilot, "f2")
        await until(pilot, lambda: lamps(app).get(HOST_STALLED) == "red", "the host stall's lamp red")
        assert [name for name, colour in lamps(app).items() if colour != "green"] == [HOST_STALLED]
        assert "INTERLOCK host stalled" in text_of(app, "#banner")
