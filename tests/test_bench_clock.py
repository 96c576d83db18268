"""The simulated bench keeps its own time whatever the WFS host does: a device waiting for a host
that stopped reading (or went) never holds up the bench, so the controller's clock, its tapers and
its watchdog run on in real time (docs/protocols.md, *Flow control*)."""

from __future__ import annotations

import threading
import time

import pytest

from drivers.register_map import Command, ControllerState, WaveformCode
from drivers.wfs_reader import WfsReader
from simulators.bench_sim import BenchBlock, BenchRunner, SimulatedBench
from simulators.ports import PtyLink
from simulators.wfs_device import WfsDevice
from tests.waiting import wait_until

TAPER_S = 0.5


def _sim_time_s(bench: SimulatedBench) -> float:
    with bench.lock:
        generator = bench.controller.generator
        return generator.n / generator.rate_hz


class _StuckHost:
    """A sink that waits for its host (as the WFS device does) and whose host never drains."""

    waits_for_host = True

    def __init__(self, paces: bool) -> None:
        self.paces_bench = paces  # unpaced: it paced the bench until its host went
        self.stuck = threading.Event()
        self.release = threading.Event()

    def deliver(self, block: BenchBlock) -> None:
        self.stuck.set()
        self.release.wait(30)


@pytest.mark.parametrize("paced", [True, False], ids=["paced", "unpaced"])
def test_the_bench_advances_while_a_sink_waits_for_its_host(paced):
    bench = SimulatedBench.paper_shaker(seed=1)
    runner = BenchRunner(bench, paced=paced, block_s=0.01)
    sink = _StuckHost(paces=not paced)
    runner.sinks.append(sink)
    runner.start()
    try:
        assert sink.stuck.wait(10), "the sink got no block"
        stuck_at_s = _sim_time_s(bench)
        # a bench held up by its sink would never get there (before: not until the sink returned)
        wait_until(lambda: _sim_time_s(bench) > stuck_at_s + 0.5, 10.0, "the bench's clock to go on")
        assert runner.backlog_s(sink) > 0.4  # the sink is fed the blocks later, in order
    finally:
        sink.release.set()
        runner.stop()
    assert runner.error is None


class _RestTimeline:
    """A sink on the runner's thread: the wall-clock time the controller was first seen at rest after
    ``watch()``."""

    paces_bench = False

    def __init__(self, bench: SimulatedBench) -> None:
        self.bench = bench
        self.watching = False
        self.at_rest_wall_s: float | None = None

    def deliver(self, block: BenchBlock) -> None:
        with self.bench.lock:
            ctrl = self.bench.controller
            rest = ctrl.state == ControllerState.HYDRAULICS_HIGH and ctrl.generator.at_rest
        if self.watching and rest and self.at_rest_wall_s is None:
            self.at_rest_wall_s = time.monotonic()


@pytest.mark.parametrize("paced", [True, False], ids=["paced", "unpaced"])
def test_the_controller_stops_within_its_taper_after_the_wfs_reader_goes(paced):
    """The WFS host streams, then goes (its port closed, nothing drains the link); once the device
    has been waiting for it a while, the controller is told to stop: it comes to rest within its
    taper plus a block and scheduling, as with a host that reads (before: about 1 s later, its clock
    held up by the device's wait)."""
    bench = SimulatedBench.paper_shaker(seed=1)
    link = PtyLink()
    device = WfsDevice(link, bench, seed=1)
    runner = BenchRunner(bench, paced=paced)
    timeline = _RestTimeline(bench)
    runner.sinks += [device, timeline]
    device.start()
    runner.start()
    reader = WfsReader.serial(link.path)
    try:
        reader.start()
        assert reader.wait_connected(10)
        with bench.lock:
            ctrl = bench.controller
            setpoints = {
                "waveform": WaveformCode.SINE_DWELL, "amplitude_mm": 1.0, "frequency_hz": 10.0,
                "taper_in_s": 0.05, "taper_out_s": TAPER_S, "watchdog_ms": 0,
            }  # fmt: skip
            assert ctrl.write_setpoints(setpoints) is None
            for command in (Command.HYDRAULICS_LOW, Command.HYDRAULICS_HIGH, Command.START):
                assert ctrl.command(command) is None
        stream = reader.subscribe(lossless=True, max_frames=2000)
        reader.start_stream()
        stream.read_frames(500, timeout_s=20)  # the host reads: the stream runs
        reader.close()  # the host goes; the device's writes fill the link and wait
        wait_until(lambda: runner.backlog_s(device) > 0.3, 20.0, "the device waiting for its host")
        timeline.watching = True
        stop_wall_s = time.monotonic()
        with bench.lock:
            assert ctrl.state == ControllerState.RUNNING
            assert ctrl.command(Command.STOP) is None
        wait_until(lambda: timeline.at_rest_wall_s is not None, 10.0, "the controller at rest")
        took_s = timeline.at_rest_wall_s - stop_wall_s
        # within the taper, one block (the bench advances a block at a time) and scheduling
        assert took_s < TAPER_S + runner.block_s + 0.3, f"stop took {took_s:.3f} s, taper {TAPER_S} s"
    finally:
        reader.close()
        runner.stop()
        device.stop()
        link.close()
    assert runner.error is None
