"""One simulated bench shared by the simulated controller and the simulated WFS.

The bench is advanced by the samples it produces: :class:`BenchRunner` advances it block by block,
either paced to real time or as fast as the streaming WFS device's port drains (backpressure from a
blocking write, never slower than real time; a host that stops draining makes the device drop frames
and the bench runs on in real time, so the controller's clock, watchdog and tapers keep running:
the device waits for its host on a thread of its own, never holding the bench up). Each block goes from the
controller's function generator (the displacement command) through the plant (servo actuator,
specimen, sensors) to the controller's readbacks and to every sink (the WFS device). A lock keeps
the controller consistent between the runner thread and the Modbus server's event loop.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from bench.models.setup import BenchKind, BenchSetup
from drivers.register_map import MOVING_STATES
from simulators.controller_model import CONTROLLER_CLOCK_HZ, ControllerModel
from simulators.plant import HalfSinePulse, PlantSimulator, SensorRealism
from simulators.worker import Worker

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class BenchBlock:
    """One block of the bench's output: ``channels`` sampled at ``rate_hz`` from ``start_s`` on.

    ``fast`` holds what the acquisition converts at ``fast_rate_hz`` (its 10 kHz converter) over
    the same time span, before the anti-alias filter: ``fz_wfs_n``, for a triggered capture.
    The analog channels lag the bench by ``latency_samples`` output samples (the acquisition's
    anti-alias filter). ``sync_flags`` are the controller's digital sync outputs (uint8 bits of
    :mod:`simulators.function_generator`) at every internal sample of the block, undelayed: a whole
    number of them per output sample (none: no sync outputs).
    """

    start_s: float
    rate_hz: float
    channels: dict[str, np.ndarray]
    fast: dict[str, np.ndarray] = field(default_factory=dict)
    fast_rate_hz: float = 0.0
    sync_flags: np.ndarray = field(default_factory=lambda: np.zeros(0, np.uint8))
    latency_samples: int = 0

    def __len__(self) -> int:
        return len(next(iter(self.channels.values())))


class BenchSink(Protocol):
    """A device fed by the bench (the WFS device).

    A sink whose ``deliver`` may wait for a host (backpressure) says so with a true attribute
    ``waits_for_host``: the runner then feeds it from a thread of its own (see :class:`BenchRunner`).
    """

    @property
    def paces_bench(self) -> bool:
        """True while the sink streams and its host drains: the unpaced runner then runs at its pace."""
        ...

    def deliver(self, block: BenchBlock) -> None: ...


class ControllerTransducer:
    """The controller's own displacement transducer on post 1, sampled on the controller's clock.

    It reads the actuator's true displacement at every ``internal_rate_hz / CONTROLLER_CLOCK_HZ``-th
    internal sample of the plant, before and apart from the WFS acquisition (its anti-alias filter and
    output rate play no part).
    """

    def __init__(self, internal_rate_hz: float) -> None:
        step = internal_rate_hz / CONTROLLER_CLOCK_HZ
        if abs(step - round(step)) > 1e-9 * step or round(step) < 1:
            raise ValueError(f"internal rate {internal_rate_hz:g} Hz is no multiple of the controller clock")
        self._step = round(step)
        self._phase = 0  # internal samples since the last controller sample, modulo the step

    def read(self, displacement_m: np.ndarray) -> np.ndarray:
        """The displacement (m) at the controller's sample instants within the internal-rate block."""
        first = (self._step - 1 - self._phase) % self._step
        self._phase = (self._phase + len(displacement_m)) % self._step
        return displacement_m[first :: self._step]


class SimulatedBench:
    """Plant plus controller model, advanced in whole output samples.

    On the hammer setup (the bare sensor on its foundation) the plant's input is the hammer's force
    (:meth:`strike`), not the actuator; the bench's displacement, plate-force and hub-acceleration
    transducers then read zero, and the controller's generator runs on unused.
    """

    #: channels the bench's transducers always deliver (the WFS device wires them to aux inputs)
    BENCH_CHANNELS = ("z_base_m", "f_plate_n", "a_hub_m_s2")

    def __init__(self, plant: PlantSimulator, clock: Callable[[], float] | None = time.monotonic) -> None:
        """``clock``: seconds for the controller's watchdog (None: the controller's sample clock)."""
        self.plant = plant
        self.lock = threading.RLock()
        self.controller = ControllerModel(plant.internal_rate_hz, clock)
        self.transducer = ControllerTransducer(plant.internal_rate_hz)
        self._internal_samples = 0
        self._blows: list[tuple[int, HalfSinePulse]] = []  # (first internal sample, pulse)
        self._drift: tuple[Callable[[float], BenchSetup], int] | None = None  # setup at t, from sample

    @classmethod
    def paper_shaker(cls, pressure_bar: float = 2.5, seed: int = 1) -> SimulatedBench:
        setup = BenchSetup.paper_shaker(pressure_bar=pressure_bar)
        return cls(PlantSimulator(setup, SensorRealism(seed=seed)))

    @property
    def output_rate_hz(self) -> float:
        return self.plant.output_rate_hz

    def set_output_rate(self, rate_hz: float) -> None:
        """Change the acquisition's output rate (the plant's decimation); ValueError if not possible."""
        with self.lock:
            self.plant.set_output_rate(rate_hz)

    @property
    def moving(self) -> bool:
        """The actuator runs, tapers, or its command is not yet back at rest (mean position zero)."""
        with self.lock:
            ctrl = self.controller
            return ctrl.state in MOVING_STATES or not ctrl.generator.at_rest

    def mount(self, setup: BenchSetup) -> None:
        """Put another specimen on the bench (see :meth:`PlantSimulator.mount`); only at rest.

        Raises RuntimeError while the actuator moves: nobody changes a wheel on a running shaker.
        """
        with self.lock:
            if self.moving:
                raise RuntimeError(
                    f"cannot change the bench to {setup.kind.value} while the actuator is moving "
                    f"(controller {self.controller.state.name}): stop it first"
                )
            self._blows.clear()
            self.plant.mount(setup)
            self._drift = None  # a new specimen: what drifted was the old one

    def drift(self, setup_at: Callable[[float], BenchSetup] | None) -> None:
        """Let the values of what is mounted change as the bench runs (a tyre warming up):
        ``setup_at(t_s)`` is the setup ``t_s`` seconds of bench time from now, applied before each
        block (:meth:`PlantSimulator.retune`; it returns the same object while nothing changed);
        None: no more change. Deterministic in bench time, whatever the blocks."""
        with self.lock:
            self._drift = None if setup_at is None else (setup_at, self._internal_samples)

    def strike(self, pulse: HalfSinePulse) -> None:
        """A hammer blow on the bare sensor, ``pulse.delay_s`` after the next sample.

        Raises RuntimeError unless the hammer setup is mounted.
        """
        with self.lock:
            if self.plant.setup.kind is not BenchKind.HAMMER:
                mounted = self.plant.setup.kind.value
                raise RuntimeError(f"a hammer blow needs the bare sensor on the bench; mounted: {mounted}")
            self._blows.append((self._internal_samples, pulse))

    def _hammer_force_n(self, n_internal: int) -> np.ndarray:
        """The hammer's force over the next ``n_internal`` samples (finished blows are forgotten)."""
        rate_hz = self.plant.internal_rate_hz
        n = self._internal_samples + np.arange(n_internal)
        force = np.zeros(n_internal)
        for first, pulse in self._blows:
            force += pulse.value((n - first) / rate_hz)
        end = self._internal_samples + n_internal
        self._blows = [(f, p) for f, p in self._blows if (end - f) / rate_hz <= p.duration_s]
        return force

    def advance(self, n_samples: int) -> BenchBlock:
        """Advance ``n_samples`` output samples: command -> plant -> controller readbacks."""
        with self.lock:
            ctrl, plant = self.controller, self.plant
            start_s = self._internal_samples / plant.internal_rate_hz
            n_internal = n_samples * plant.oversampling
            command = ctrl.command_block(n_internal)
            sync = ctrl.generator.take_sync_flags()
            if plant.setup.kind is BenchKind.HAMMER:
                channels = plant.advance(self._hammer_force_n(n_internal))
                for name in self.BENCH_CHANNELS:
                    channels[name] = np.zeros(n_samples)
            else:
                if self._drift is not None:
                    setup_at, since = self._drift
                    setup = setup_at((self._internal_samples - since) / plant.internal_rate_hz)
                    if setup is not plant.setup:
                        plant.retune(setup)
                plant.set_operating_point(ctrl.current_frequency_hz(), ctrl.amplitude_m, ctrl.drive_density())
                channels = plant.advance(command)
            ctrl.observe(channels["z_base_m"], channels["f_plate_n"], plant.output_rate_hz)
            ctrl.measure_amplitude(self.transducer.read(plant.converter_z_base_m))
            self._internal_samples += n_internal
            fast = {"fz_wfs_n": plant.converter_fz_n}
            return BenchBlock(
                start_s,
                plant.output_rate_hz,
                channels,
                fast,
                plant.internal_rate_hz,
                sync,
                plant.latency_samples,
            )


#: Seconds of output per block: paced, short blocks (a bench one watches in real time); unpaced,
#: large blocks keep the simulation's overhead per block small when it runs far faster than real time.
PACED_BLOCK_S = 0.01
UNPACED_BLOCK_S = 0.2
#: The most output (s) a sink that waits for its host may hold queued behind the bench: beyond it
#: the bench waits for that sink. A host that stops draining never gets there (the WFS device drops
#: what it cannot send within its own 1 s wait); only one draining slower than real time for long does.
MAX_FEED_BACKLOG_S = 2.0
#: The most wall-clock time (s) a runner that fell behind its schedule (a stalled host process)
#: catches up, block after block without waiting.
MAX_CATCH_UP_S = 0.5


class _SinkFeed:
    """Feeds one sink that waits for its host (``sink.waits_for_host``) from a thread of its own, so
    that the bench, and the controller's clock with it, never waits for that host. Blocks are
    delivered in order; ``backlog_s`` is the output queued or being delivered."""

    def __init__(
        self, sink: BenchSink, changed: threading.Condition, on_error: Callable[[BaseException], None]
    ) -> None:
        self.sink = sink
        self._changed = changed  # the runner's: notified whenever a block has been delivered
        self._on_error = on_error
        self._blocks: deque[BenchBlock] = deque()
        self._busy = False
        self.backlog_s = 0.0
        self._stopping = False
        self._thread = threading.Thread(target=self._run, name="bench-feed", daemon=True)
        self._thread.start()

    @property
    def idle(self) -> bool:
        """Every block given has been delivered (call with the runner's condition held)."""
        return not self._blocks and not self._busy

    def put(self, block: BenchBlock) -> None:
        with self._changed:
            self._blocks.append(block)
            self.backlog_s += len(block) / block.rate_hz
            self._changed.notify_all()

    def stop(self, timeout_s: float) -> None:
        with self._changed:
            self._stopping = True
            self._changed.notify_all()
        self._thread.join(timeout_s)

    def _run(self) -> None:
        while True:
            with self._changed:
                while not self._blocks and not self._stopping:
                    self._changed.wait()
                if self._stopping:
                    return
                block = self._blocks.popleft()
                self._busy = True
            try:
                self.sink.deliver(block)
            except Exception as exc:  # a broken sink must be visible, not a silent dead thread
                self._on_error(exc)
                return
            finally:
                with self._changed:
                    self._busy = False
                    self.backlog_s -= len(block) / block.rate_hz
                    self._changed.notify_all()


class BenchRunner:
    """The thread that advances the bench and feeds its sinks.

    Blocks last about ``block_s`` (a whole number of output samples, at least one, at the output
    rate of the moment). Paced: one block per its duration of wall-clock time (deadline based, no
    drift). Unpaced: as fast as the streaming sinks accept the blocks; while no sink paces the bench
    (none streams, or their hosts stopped draining), the bench still runs in real time so that the
    controller's tapers and watchdog behave as on a real bench.

    The bench keeps its own time whatever a host does: a sink whose delivery waits for a host (the
    WFS device's, on a link its host drains: ``waits_for_host``) is fed from a thread of its own, and
    an unpaced bench waits for it no longer than real time allows, so when the host stops reading
    (or goes) the controller's clock, its tapers and its watchdog run on in real time. Other sinks
    are fed on the runner's thread right after each block, and see the controller as the block
    left it. A waiting sink may fall behind by at most :data:`MAX_FEED_BACKLOG_S`.
    """

    def __init__(self, bench: SimulatedBench, *, paced: bool = True, block_s: float | None = None) -> None:
        """``block_s``: seconds of output per block; by default :data:`PACED_BLOCK_S` or
        :data:`UNPACED_BLOCK_S`."""
        self.bench = bench
        self.paced = paced
        self.block_s = block_s if block_s is not None else PACED_BLOCK_S if paced else UNPACED_BLOCK_S
        self.sinks: list[BenchSink] = []
        self._worker = Worker(self._run, "bench-runner")
        self._stop = self._worker.stopping
        self.error: BaseException | None = None
        self.delivering = threading.Event()  # set once the first block reached the sinks (powered up)
        self._changed = threading.Condition()  # a feed delivered a block, or the runner is stopping
        self._feeds: dict[int, _SinkFeed] = {}  # id(sink) -> its feed

    def start(self) -> None:
        self._worker.start()

    def stop(self) -> None:
        with self._changed:
            self._stop.set()
            self._changed.notify_all()
        self._worker.stop()
        for feed in list(self._feeds.values()):
            feed.stop(5.0)

    def backlog_s(self, sink: BenchSink) -> float:
        """How far (s of output) ``sink`` lags behind the bench: queued or being delivered (0 for a
        sink fed on the runner's thread)."""
        with self._changed:
            feed = self._feeds.get(id(sink))
            return feed.backlog_s if feed is not None else 0.0

    def _failed(self, exc: BaseException) -> None:
        log.error("bench sink failed: %r", exc)
        with self._changed:
            if self.error is None:
                self.error = exc
            self._stop.set()
            self._changed.notify_all()

    def _feed_of(self, sink: BenchSink) -> _SinkFeed | None:
        if not getattr(sink, "waits_for_host", False):
            return None
        feed = self._feeds.get(id(sink))
        if feed is None:
            feed = self._feeds[id(sink)] = _SinkFeed(sink, self._changed, self._failed)
        return feed

    def _wait(
        self, feeds: list[_SinkFeed], ready: Callable[[_SinkFeed], bool] | None, deadline: float | None
    ) -> None:
        """Wait until every feed of ``feeds`` is ``ready`` (checked with their condition held; None:
        never), the stop, or ``deadline``."""
        with self._changed:
            while not self._stop.is_set() and not (ready is not None and all(map(ready, feeds))):
                left = None if deadline is None else deadline - time.monotonic()
                if left is not None and left <= 0:
                    return
                self._changed.wait(left)

    def _run(self) -> None:
        next_due = time.monotonic()  # the latest wall-clock time the next block may come
        try:
            while not self._stop.is_set():
                rate_hz = self.bench.output_rate_hz
                n_samples = max(1, round(self.block_s * rate_hz))
                period_s = n_samples / rate_hz
                sinks = list(self.sinks)
                feeds = [f for f in map(self._feed_of, sinks) if f is not None]
                pacing = [self._feeds[id(s)] for s in sinks if s.paces_bench and id(s) in self._feeds]
                hosted = not self.paced and any(s.paces_bench for s in sinks)
                # hosted: as fast as the hosts drain, but never slower than real time
                self._wait(pacing, _idle if hosted else None, next_due)
                self._wait(feeds, _within_backlog, None)
                if self._stop.is_set():
                    break
                now = time.monotonic()
                if hosted and now < next_due:
                    next_due = now + period_s  # ran ahead of real time: the next is due a block on
                else:
                    next_due = max(next_due, now - MAX_CATCH_UP_S) + period_s
                block = self.bench.advance(n_samples)
                for sink in sinks:
                    feed = self._feed_of(sink)
                    if feed is None:
                        sink.deliver(block)
                    else:
                        feed.put(block)
                if not self.delivering.is_set():  # powered up once every sink has had a block
                    self._wait(feeds, _idle, next_due)
                    with self._changed:
                        if all(f.idle for f in feeds):
                            self.delivering.set()
        except Exception as exc:  # a broken bench must be visible, not a silent dead thread
            self.error = exc
            log.exception("bench runner stopped")


def _idle(feed: _SinkFeed) -> bool:
    return feed.idle


def _within_backlog(feed: _SinkFeed) -> bool:
    return feed.backlog_s < MAX_FEED_BACKLOG_S
