"""One simulated bench shared by the simulated controller and the simulated WFS.

The bench is advanced by the samples it produces: :class:`BenchRunner` advances it block by block,
either paced to real time or as fast as the streaming WFS device's port drains (backpressure from a
blocking write; a host that stops draining makes the device drop frames and the bench falls back
to real time, so the controller's watchdog and tapers keep running). Each block goes from the
controller's function generator (the displacement command) through the plant (servo actuator,
specimen, sensors) to the controller's readbacks and to every sink (the WFS device). A lock keeps
the controller consistent between the runner thread and the Modbus server's event loop.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from bench.models.setup import BenchSetup
from simulators.controller_model import ControllerModel
from simulators.plant import PlantSimulator, SensorRealism
from simulators.worker import Worker

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class BenchBlock:
    """One block of the bench's output: ``channels`` sampled at ``rate_hz`` from ``start_s`` on.

    The analog channels lag the bench by ``latency_samples`` output samples (the acquisition's
    anti-alias filter). ``sync_flags`` are the controller's digital sync outputs (uint8 bits of
    :mod:`simulators.function_generator`) at every internal sample of the block, undelayed: a whole
    number of them per output sample (none: no sync outputs).
    """

    start_s: float
    rate_hz: float
    channels: dict[str, np.ndarray]
    sync_flags: np.ndarray = field(default_factory=lambda: np.zeros(0, np.uint8))
    latency_samples: int = 0

    def __len__(self) -> int:
        return len(next(iter(self.channels.values())))


class BenchSink(Protocol):
    """A device fed by the bench (the WFS device)."""

    @property
    def paces_bench(self) -> bool:
        """True while the sink streams and its host drains: the unpaced runner then runs at its pace."""
        ...

    def deliver(self, block: BenchBlock) -> None: ...


class SimulatedBench:
    """Plant plus controller model, advanced in whole output samples."""

    def __init__(self, plant: PlantSimulator, clock: Callable[[], float] = time.monotonic) -> None:
        self.plant = plant
        self.lock = threading.RLock()
        self.controller = ControllerModel(plant.internal_rate_hz, clock)
        self._internal_samples = 0

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

    def advance(self, n_samples: int) -> BenchBlock:
        """Advance ``n_samples`` output samples: command -> plant -> controller readbacks."""
        with self.lock:
            ctrl, plant = self.controller, self.plant
            start_s = self._internal_samples / plant.internal_rate_hz
            n_internal = n_samples * plant.oversampling
            command = ctrl.command_block(n_internal)
            plant.set_operating_point(ctrl.current_frequency_hz(), ctrl.amplitude_m)
            sync = ctrl.generator.take_sync_flags()
            channels = plant.advance(command)
            ctrl.observe(channels["z_base_m"], channels["f_plate_n"], plant.output_rate_hz)
            self._internal_samples += n_internal
            return BenchBlock(start_s, plant.output_rate_hz, channels, sync, plant.latency_samples)


class BenchRunner:
    """The thread that advances the bench and feeds its sinks.

    Blocks last about ``block_s`` (a whole number of output samples, at least one, at the output
    rate of the moment). Paced: one block per its duration of wall-clock time (deadline based, no
    drift). Unpaced: as fast as the streaming sinks accept the blocks; while no sink paces the bench
    (none streams, or their hosts stopped draining), the bench still runs in real time so that the
    controller's tapers and watchdog behave as on a real bench.
    """

    def __init__(self, bench: SimulatedBench, *, paced: bool = True, block_s: float = 0.01) -> None:
        self.bench = bench
        self.paced = paced
        self.block_s = block_s
        self.sinks: list[BenchSink] = []
        self._worker = Worker(self._run, "bench-runner")
        self._stop = self._worker.stopping
        self.error: BaseException | None = None

    def start(self) -> None:
        self._worker.start()

    def stop(self) -> None:
        self._worker.stop()

    def _run(self) -> None:
        next_due = time.monotonic()
        try:
            while not self._stop.is_set():
                rate_hz = self.bench.output_rate_hz
                n_samples = max(1, round(self.block_s * rate_hz))
                period_s = n_samples / rate_hz
                if self.paced or not any(s.paces_bench for s in self.sinks):
                    next_due = max(next_due + period_s, time.monotonic() - 0.5)
                    delay = next_due - time.monotonic()
                    if delay > 0 and self._stop.wait(delay):
                        break
                else:
                    next_due = time.monotonic()
                block = self.bench.advance(n_samples)
                for sink in self.sinks:
                    sink.deliver(block)
        except Exception as exc:  # a broken bench must be visible, not a silent dead thread
            self.error = exc
            log.exception("bench runner stopped")
