"""A host stall on the paced simulated bench, over the real transports (Modbus TCP, the WFS pty):
the engine's thread is held mid-point (the machine busy with other work), the reader then waits on
its full subscription, the port goes unread and the device, held back by the link's flow control,
drops what it cannot keep after 1 s; the engine is held until it has. The run ends as a host stall
with the frames lost counted, recorded in the campaign file, never as a lost link. And a port
holding unread bytes is not a silent link.

With flow control the machine's own stalls (tenths of a second, on a loaded test machine) lose
nothing, so the held engine is the one stall that ends the run; the port's 4095-byte overrun
without it is tested on the reader (tests/test_wfs_host_stall.py)."""

from __future__ import annotations

import threading
import time

from bench.engine import events as ev
from bench.store import open_campaign
from tests.campaign_lab import bench_config, grid_sequence, lab_campaign
from tests.waiting import wait_until

#: The shortest stall that loses frames here: the backlog's 0.2 s and the device's 1 s hold.
STALL_S = 1.2
#: The longest the engine is held waiting for the device to drop frames (the simulated lab shares
#: the test's process, so that its counter can be read, and a busy machine slows it).
HOLD_LIMIT_S = 60.0
#: Paced with flow control, and a short backlog: the engine's subscription fills in 0.2 s of a
#: stall, the reader then waits, and the device drops frames after 1 s of holding them.
CONFIG = (
    "[simulation]\npaced = true\nflow_control = true\nown_process = false\n"
    "[actuator]\nwatchdog_ms = 10000\n[timing]\nbacklog_s = 0.2\nwfs_silence_s = 2.0\n"
)


def test_a_held_engine_overruns_the_port_and_the_run_ends_as_a_host_stall(tmp_path):
    config = bench_config(tmp_path, CONFIG)
    path = tmp_path / "campaign.h5"
    with lab_campaign(config, grid_sequence((10.0, 12.0), measure_min_s=1.0), path) as campaign:
        held = threading.Event()

        def hold_once(event: ev.Event) -> None:  # on the engine's thread, as a busy machine would
            if isinstance(event, ev.PointStarted) and event.index == 1 and not held.is_set():
                held.set()
                device = campaign.lab.device
                wait_until(lambda: device.frames_dropped > 0, HOLD_LIMIT_S, "the device dropping frames")

        campaign.engine.bus.subscribe(hold_once)
        campaign.start()
        outcome = campaign.wait()
    assert held.is_set()
    assert outcome.status == "interlocked", outcome
    assert outcome.reason.startswith("host stalled: "), outcome.reason
    assert "link lost" not in outcome.reason
    # the held engine's stall, the one that lost frames (the machine's own stalls lose none here)
    (stall,) = [s for s in campaign.of(ev.HostStalled) if s.frames_lost]
    assert stall.stalled_s >= STALL_S - 0.2
    assert not [t for t in campaign.of(ev.InterlockTripped) if t.name == "WFS link lost"]
    with open_campaign(path) as f:
        (run,) = f.runs
        recorded = [e.fields["frames_lost"] for e in run.events if e.kind == "host stall"]
        assert run.status == "interlocked" and run.reason == outcome.reason
        assert [lost for lost in recorded if lost] == [stall.frames_lost]
        gaps = sum(e.fields["missing"] for e in run.events if e.kind == "gap")
        assert gaps >= stall.frames_lost  # the lost frames are the file's gaps


def test_bytes_waiting_unread_at_the_port_are_no_silence(tmp_path):
    """The reader held (its lossless subscription full) while the paced device goes on sending: the
    port holds bytes, so the link is not silent however long ago the reader last read."""
    config = bench_config(tmp_path, CONFIG)
    with lab_campaign(config, grid_sequence((10.0,)), tmp_path / "c.h5") as campaign:
        reader = campaign.devices.acquisition
        subscription = reader.subscribe(lossless=True, max_frames=10)
        reader.start_stream()
        try:
            first = subscription.get(5)
            assert first is not None
            threading.Event().wait(0.6)  # the reader waits on the full subscription meanwhile
            assert time.monotonic() - reader.last_arrival_s > 0.5  # the reader has not read since
            assert reader.link_silence_s() == 0.0
        finally:
            subscription.close()
            reader.stop_stream()


def test_a_stall_whose_losses_were_not_read_says_so():
    """A run that ended before the frames after its stall were read does not claim it lost none."""
    seen = ev.HostStalled("r", 2.0, 17)
    unknown = ev.HostStalled("r", 2.0, 0, counted=False)
    assert seen.text == "host stall: the WFS port went unread for 2.00 s, 17 frames lost (r)"
    assert unknown.text == (
        "host stall: the WFS port went unread for 2.00 s; the frames it lost are not known: the run"
        " ended before the stream after it was read (r)"
    )
