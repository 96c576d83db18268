"""The engine's events into the monitor, off the real-time path.

:class:`MonitorFeed` is a subscriber of the engine's bus that only puts the event into a bounded
queue without waiting (the engine's thread spends a queue put on it); a thread of its own wakes every
:data:`PUBLISH_PERIOD_S`, takes what is queued into the :class:`~bench.monitor.view.BenchView` and
publishes the state if it changed. Should that thread fall behind, sample blocks are dropped first (the live
values skip a block) and any event once the queue is full; both are counted in the state
(``monitor.events_dropped``), and the bench never waits for the monitor.
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from bench.app.bench_status import bench_description
from bench.app.live_trace import LiveTrace
from bench.app.pace import DoneBefore
from bench.config import BenchConfig
from bench.engine import events as ev
from bench.engine.engine import Engine
from bench.engine.interlocks import interlock_names
from bench.engine.states import RunState
from bench.monitor.view import BenchView

#: Events the queue holds; sample blocks are dropped once it is half full.
QUEUE_EVENTS = 2048
#: Shortest interval between two published states (s): 5 updates a second at most.
PUBLISH_PERIOD_S = 0.2


@dataclass(frozen=True)
class _Do:
    """Something for the feed's thread to do in order with the events (attach, a launch, stop)."""

    action: Callable[[], None] | None  # None: stop


class MonitorFeed:
    """Subscriber of an engine's bus feeding a :class:`BenchView`; ``publish(state)`` is called on
    the feed's own thread with each new state (``/api/state``'s JSON less its number)."""

    def __init__(self, publish: Callable[[dict[str, Any]], object]) -> None:
        self._publish = publish
        self._queue: queue.Queue[ev.Event | _Do] = queue.Queue(QUEUE_EVENTS)
        self.dropped = 0
        self.cpu_s = 0.0  # the feed thread's processor time, once it has stopped
        self.view = BenchView("opening the bench", RunState.IDLE, (), None, dict)
        self.view.state = "opening"
        self._engine: Engine | None = None
        self._last: dict[str, Any] | None = None
        self._wake = threading.Event()  # set by close: take the queue now
        self._thread = threading.Thread(target=self._run, name="monitor-feed", daemon=True)
        self._thread.start()

    # -- the engine's thread (and any other) ------------------------------------------------------

    def __call__(self, event: ev.Event) -> None:
        """Take an event without waiting: a full queue drops it (counted)."""
        if isinstance(event, ev.SamplesRecorded) and self._queue.qsize() >= QUEUE_EVENTS // 2:
            self.dropped += 1  # the live values skip a block; the other events keep their room
            return
        try:
            self._queue.put_nowait(event)
        except queue.Full:
            self.dropped += 1

    def attach(self, engine: Engine, config: BenchConfig) -> None:
        """Watch ``engine`` (on the bench of ``config``) from now on, instead of any engine before."""
        if self._engine is not None:
            self._engine.bus.unsubscribe(self)
        self._engine = engine
        view = BenchView(
            bench_description(config),
            engine.state,
            interlock_names(engine.interlocks),
            LiveTrace(float(config.wfs.rate_hz), config.channels),
            engine.acquisition.link_counters,
        )
        self._queue.put(_Do(lambda: setattr(self, "view", view)))
        engine.bus.subscribe(self)

    def launched(self, done_before: DoneBefore) -> None:
        """The next sequence resumes a file holding ``done_before`` done already."""
        self._queue.put(_Do(lambda: self.view.launched(done_before)))

    def close(self) -> None:
        """Take what is queued, publish the last state, and stop."""
        if self._engine is not None:
            self._engine.bus.unsubscribe(self)
        self._queue.put(_Do(None))
        self._wake.set()
        self._thread.join()

    # -- the feed's thread ----------------------------------------------------------------------

    def _run(self) -> None:
        """Every :data:`PUBLISH_PERIOD_S`: take what is queued, then publish. The thread wakes five
        times a second whatever the bench's event rate, so the bench's threads are not kept switching
        to it (a close wakes it at once)."""
        while True:
            self._wake.wait(PUBLISH_PERIOD_S)
            self._wake.clear()
            while True:
                try:
                    item = self._queue.get_nowait()
                except queue.Empty:
                    break
                if isinstance(item, _Do):
                    if item.action is None:
                        self._send()
                        self.cpu_s = time.thread_time()
                        return
                    item.action()
                else:
                    self.view.apply(item)
            self._send()

    def _send(self) -> None:
        """Publish the state if it changed since the last one published."""
        state = self.view.snapshot()
        state["monitor"] = {"events_dropped": self.dropped}
        if state != self._last:
            self._last = state
            self._publish(state)


class StateServer(Protocol):
    """What serves the states (:class:`~bench.monitor.server_process.ServerProcess`)."""

    @property
    def url(self) -> str: ...

    def publish(self, state: dict[str, Any]) -> object: ...

    def close(self) -> None: ...


class BenchMonitor:
    """The web monitor of a bench: its server and its feed. ``with`` closes both."""

    def __init__(self, server: StateServer) -> None:
        """``server``: started, listening."""
        self.server = server
        self.feed = MonitorFeed(server.publish)

    def __enter__(self) -> BenchMonitor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self.feed.close()
        self.server.close()
