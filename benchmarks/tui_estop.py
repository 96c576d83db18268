"""The terminal UI on the paced simulated bench (1 kHz WFS stream): e-stop latency and redraw rate.

E-stop: a 60 s dwell runs; F12 is posted to the app as a key event and the time until the simulated
controller's state reads e-stop is taken by a watcher thread polling the controller model every
0.2 ms. Baseline in the same run: ``engine.request_estop()`` called directly on the UI's thread
(what the key handler calls), without the key's dispatch through the app. After each stop the bench is reset
and the dwell started again. Redraw rate: the live view's redraws per second and the time each
takes, with the 1 kHz stream running (the run screen's plots full) and, as baseline, with the
same plots and no stream (after an e-stop).

Run: PYTHONPATH=. .venv/bin/python benchmarks/tui_estop.py [--presses 20] [--seconds 5]
"""

from __future__ import annotations

import argparse
import asyncio
import statistics
import tempfile
import threading
import time
from pathlib import Path
from typing import ClassVar

from bench.app.plan import plan_campaign
from bench.engine import events as ev
from bench.engine.states import RunState
from bench.tui import panes
from bench.tui.app import WfsBenchApp
from bench.tui.plot import BraillePlot
from drivers.register_map import ControllerState

FILES = Path(__file__).resolve().parents[1] / "tests" / "tui" / "files"
WATCH_PERIOD_S = 0.0002


class TimedApp(WfsBenchApp):
    """The app, timing each redraw of its live view."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.redraws: list[tuple[float, float]] = []  # (when, seconds taken)

    def refresh_live(self) -> None:
        start = time.perf_counter()
        super().refresh_live()
        self.redraws.append((start, time.perf_counter() - start))


class TimedPlot(BraillePlot):
    """Times each drawing of a plot (done when the screen is painted, after a redraw asked for it)."""

    draws: ClassVar[list[tuple[float, float]]] = []

    def _draw(self) -> None:
        start = time.perf_counter()
        super()._draw()
        TimedPlot.draws.append((start, time.perf_counter() - start))


def watch_estop(controller, started: threading.Event, seen: list[float]) -> None:
    """Poll the simulated controller until it is in e-stop; note when."""
    started.set()
    deadline = time.perf_counter() + 5.0
    while controller.state != ControllerState.ESTOP and time.perf_counter() < deadline:
        time.sleep(WATCH_PERIOD_S)
    seen.append(time.perf_counter())


async def until(pilot, condition, what: str, timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            raise TimeoutError(f"timed out waiting for {what}")
        await pilot.pause(0.01)


def rate_and_cost(times: list[tuple[float, float]], since: float, until_s: float, what: str) -> str:
    window = [d * 1e3 for t, d in times if since <= t < until_s]
    costs = sorted(window)
    return (
        f"{len(window) / (until_s - since):.1f} {what}/s, {statistics.median(costs):.2f} ms median,"
        f" {costs[-1]:.2f} ms worst each"
    )


def redraw_figures(app: TimedApp, since: float, until_s: float) -> str:
    return (
        f"{rate_and_cost(app.redraws, since, until_s, 'redraws')};"
        f" {rate_and_cost(TimedPlot.draws, since, until_s, 'plot drawings')}"
    )


async def run(presses: int, seconds: float, work: Path) -> None:  # noqa: PLR0915 - one measurement
    app = TimedApp(FILES / "paced.toml", work / "run-0.h5")
    plan = plan_campaign(FILES / "long_dwell.toml", FILES / "paced.toml")
    points: list[ev.PointStarted | ev.SequenceFinished] = []
    async with app.run_test(size=(120, 40)) as pilot:
        await until(pilot, app.session.opened.is_set, "the bench")
        app.session.engine.bus.subscribe(
            lambda e: points.append(e) if isinstance(e, ev.PointStarted | ev.SequenceFinished) else None
        )
        controller = app.session.devices.lab.bench.controller
        trace = app.session.trace

        async def start_dwell(index: int) -> None:
            if app.session.engine.state is RunState.ESTOPPED:
                app.session.reset()
                await until(pilot, lambda: app.session.engine.state is RunState.HYDRAULICS_LOW, "the reset")
                await until(pilot, lambda: not app.session.running.is_set(), "the sequence's end")
                # the controller tapers out of its e-stop before it takes commands again
                await until(pilot, lambda: controller.state == ControllerState.HYDRAULICS_LOW, "the taper")
            app.session.out_path = work / f"run-{index}.h5"
            app.plan = plan
            before = len(points)
            app.action_start()
            await until(pilot, lambda: len(points) > before, "the dwell")
            if isinstance(points[before], ev.SequenceFinished):
                raise RuntimeError(f"the dwell did not start: {points[before]}")

        async def estop(by_key: bool) -> float:
            started, seen = threading.Event(), []
            watcher = threading.Thread(target=watch_estop, args=(controller, started, seen))
            watcher.start()
            started.wait()
            t0 = time.perf_counter()
            if by_key:
                app.simulate_key("f12")
            else:
                app.session.engine.request_estop()
            await asyncio.to_thread(watcher.join)
            if controller.state != ControllerState.ESTOP:
                raise RuntimeError("the controller did not reach e-stop within 5 s")
            await until(pilot, lambda: not app.session.running.is_set(), "the sequence's end")
            return (seen[0] - t0) * 1e3

        await start_dwell(0)
        first = trace.samples_seen
        await until(pilot, lambda: trace.samples_seen - first >= 5000, "5 s of samples", 30)
        t_stream, first = time.perf_counter(), trace.samples_seen
        await pilot.pause(seconds)
        t_stream_end = time.perf_counter()
        samples_rate = (trace.samples_seen - first) / (t_stream_end - t_stream)
        key_ms, direct_ms = [], []
        key_ms.append(await estop(by_key=True))
        t_idle = time.perf_counter()
        await pilot.pause(seconds)
        t_idle_end = time.perf_counter()
        for i in range(1, 2 * presses):
            await start_dwell(i)
            by_key = i % 2 == 0
            (key_ms if by_key else direct_ms).append(await estop(by_key))
    print(f"stream while the dwell ran: about {samples_rate:.0f} samples/s into the live view")
    print(f"redraws, streaming at 1 kHz: {redraw_figures(app, t_stream, t_stream_end)}")
    print(f"redraws, same plots, no stream (baseline): {redraw_figures(app, t_idle, t_idle_end)}")
    for name, values in (("F12 key", key_ms), ("request_estop() on the UI thread (baseline)", direct_ms)):
        print(
            f"e-stop by {name}, {len(values)} presses: median {statistics.median(values):.1f} ms,"
            f" worst {max(values):.1f} ms"
        )
    print(f"ratio key / baseline (medians): {statistics.median(key_ms) / statistics.median(direct_ms):.2f}")


def main() -> None:
    panes.BraillePlot = TimedPlot  # the run screen's plots, timed
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--presses", type=int, default=20, help="e-stops by key (and as many baseline)")
    parser.add_argument("--seconds", type=float, default=5.0, help="length of each redraw measurement")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as work:
        asyncio.run(run(args.presses, args.seconds, Path(work)))


if __name__ == "__main__":
    main()
