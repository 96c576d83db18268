"""A campaign on the simulated lab for integration tests: the engine the application builds, over
the real transports (the controller on Modbus TCP on 127.0.0.1, the WFS on a pty), run on a thread.

Faults and requests are placed by sample counts, not by the wall clock: :class:`AtHold` acts from
the engine's own thread once a chosen point has held its amplitude for a given number of WFS
samples. :class:`ControllerTimeline` is a bench sink that notes, block by block on the bench's own
clock, what the controller model does, so that a test can tell when the actuator came to rest.
"""

from __future__ import annotations

import contextlib
import os
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench.app.devices import BenchDevices, open_bench
from bench.app.engine_build import build_engine
from bench.app.recorder import Recorder
from bench.config import BenchConfig, load_bench_config
from bench.engine import events as ev
from bench.engine.engine import Engine
from bench.engine.stops import RunOutcome
from bench.store import CampaignWriter
from drivers.register_map import MOVING_STATES, ControllerState
from drivers.wfs_frame import Status
from sequences import DwellGrid, Hydraulics, Sequence, dump_sequence
from simulators.bench_sim import BenchBlock, SimulatedBench

#: Generous bound (s, wall clock) for a whole short campaign on a loaded machine: a timeout only.
RUN_TIMEOUT_S = 60.0
#: The niceness a paced lab's threads are given where the test may raise it (root).
REAL_TIME_NICE = -10


#: A paced simulated bench with its devices in the test's process (where faults are injected) and
#: the WFS link flow-controlled, holding frames up to 5 s for a reader the test machine holds up: the
#: devices starve with the test on a loaded machine (for over 1 s beside four busy processes), and a
#: host stall that lost frames would end the run before what the test is about.
PACED_IN_PROCESS = "[simulation]\npaced = true\nown_process = false\nflow_control = true\nwfs_hold_s = 5.0\n"


def bench_config(tmp_path: Path, text: str = "", name: str = "bench.toml") -> BenchConfig:
    """The simulated shaker bench configured by TOML ``text`` (every key left out takes its default)."""
    path = tmp_path / name
    path.write_text(f'kind = "shaker"\n{text}')
    return load_bench_config(path)


def grid_sequence(
    freqs_hz: tuple[float, ...],
    amplitude_mm: float = 1.0,
    *,
    measure_min_s: float = 0.5,
    taper_s: float = 0.2,
) -> Sequence:
    """Hydraulics low then high, then one dwell grid at ``amplitude_mm`` (the smoke sequence's
    short timing, measuring at least ``measure_min_s``)."""
    grid = DwellGrid(
        freqs_hz=freqs_hz,
        amplitudes_mm=(amplitude_mm,),
        settle_cycles=2,
        settle_min_s=0.1,
        measure_cycles=2,
        measure_min_s=measure_min_s,
        taper_in_s=taper_s,
        taper_out_s=taper_s,
    )
    steps = (Hydraulics("low"), Hydraulics("high"), grid)
    return Sequence(name="itest", description="", steps=steps, source="<test>")


def sim_time_s(bench: SimulatedBench) -> float:
    """The bench's own clock (s): the controller's internal samples generated so far."""
    with bench.lock:
        generator = bench.controller.generator
        return generator.n / generator.rate_hz


@dataclass(frozen=True)
class ControllerSnapshot:
    """The controller model at the end of one bench block."""

    end_s: float  # bench clock
    wall_s: float  # time.monotonic() when the block was delivered
    state: ControllerState
    at_rest: bool  # generator at rest: no excitation, not frozen, mean settled at zero
    frozen: bool  # e-stop: the generator holds its last command
    command_m: float  # the last displacement command


class ControllerTimeline:
    """A bench sink (it never paces the bench) keeping a :class:`ControllerSnapshot` per block."""

    paces_bench = False

    def __init__(self, bench: SimulatedBench) -> None:
        self.bench = bench
        self.snapshots: list[ControllerSnapshot] = []
        self.block_s = 0.0  # longest block seen (s): the timeline's resolution

    def deliver(self, block: BenchBlock) -> None:
        with self.bench.lock:
            ctrl = self.bench.controller
            generator = ctrl.generator
            snapshot = ControllerSnapshot(
                block.start_s + len(block) / block.rate_hz,
                time.monotonic(),
                ctrl.state,
                generator.at_rest,
                generator.waveform is None and ctrl.state == ControllerState.ESTOP,
                generator.last_m,
            )
        self.block_s = max(self.block_s, len(block) / block.rate_hz)
        self.snapshots.append(snapshot)

    def after(self, end_s: float) -> list[ControllerSnapshot]:
        return [s for s in self.snapshots if s.end_s > end_s]

    def stop_before(self, end_s: float) -> ControllerSnapshot:
        """The first block of the stop that ended the excitation running at ``end_s``: the first
        block, after the last running one up to ``end_s``, where the controller no longer runs."""
        running = [s for s in self.snapshots if s.end_s <= end_s and s.state == ControllerState.RUNNING]
        assert running, f"the controller did not run before {end_s:.3f} s"
        return self.first(stopped, running[-1].end_s)

    def first(self, predicate: Callable[[ControllerSnapshot], bool], after_s: float) -> ControllerSnapshot:
        found = next((s for s in self.after(after_s) if predicate(s)), None)
        assert found is not None, f"no block after {after_s:.3f} s where the controller is as awaited"
        return found


def stopped(s: ControllerSnapshot) -> bool:
    """The controller no longer runs the excitation: tapering, at rest, tripped or e-stopped."""
    return s.state != ControllerState.RUNNING


def at_rest(s: ControllerSnapshot) -> bool:
    """Not moving, the generator at rest (the taper and the mean's ramp finished)."""
    return s.state not in MOVING_STATES and s.at_rest


@dataclass
class Injection:
    """Where an action was taken: the run's samples, the bench clock, the wall clock."""

    run_sample: int
    sim_s: float
    wall_s: float


class AtHold:
    """Engine subscriber: calls ``action()`` once, on the engine's thread, when point ``index``
    (its first attempt) has held its amplitude for ``hold_samples`` WFS samples (the hold sync bit
    counted in the recorded frames), so the action lands mid-point whatever the machine's speed."""

    def __init__(
        self, bench: SimulatedBench, index: int, hold_samples: int, action: Callable[[], None]
    ) -> None:
        self.bench = bench
        self.index = index
        self.hold_samples = hold_samples
        self.action = action
        self.injection: Injection | None = None
        self._in_point = False
        self._held = 0

    def __call__(self, event: ev.Event) -> None:
        if isinstance(event, ev.PointStarted):
            self._in_point = event.index == self.index and event.attempt == 1
        elif isinstance(event, ev.SamplesRecorded) and self._in_point and self.injection is None:
            status = np.asarray(event.columns["status"])
            self._held += int(np.count_nonzero(status & int(Status.AMPLITUDE_HOLD)))
            if self._held >= self.hold_samples:
                self.injection = Injection(
                    event.first_sample + len(status), sim_time_s(self.bench), time.monotonic()
                )
                self.action()


@dataclass
class LabCampaign:
    """An engine on the simulated lab, recording into a campaign file, run on a thread."""

    engine: Engine
    devices: BenchDevices
    sequence: Sequence
    events: list[ev.Event] = field(default_factory=list)
    outcome: RunOutcome | None = None
    error: BaseException | None = None
    _thread: threading.Thread | None = None

    @property
    def lab(self):
        return self.devices.lab

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="itest-engine", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            self.outcome = self.engine.run(self.sequence)
        except BaseException as exc:  # reported by wait()
            self.error = exc

    def wait(self, timeout_s: float = RUN_TIMEOUT_S) -> RunOutcome:
        assert self._thread is not None
        self._thread.join(timeout_s)
        assert not self._thread.is_alive(), f"the campaign did not end within {timeout_s} s"
        if self.error is not None:
            raise self.error
        assert self.outcome is not None
        return self.outcome

    def of(self, kind: type) -> list:
        return [e for e in self.events if isinstance(e, kind)]


@contextlib.contextmanager
def real_time_priority(raise_it: bool = True) -> Iterator[None]:
    """The calling thread, and every thread and process it starts meanwhile (the simulated lab's,
    the engine's), above the machine's other work: niceness :data:`REAL_TIME_NICE` where the test
    may raise it (as root), put back after. As a lab runs a bench that keeps real time on a PC it
    cannot keep idle: a paced lab in the test's process otherwise starves beside the suite's own
    load, and the stall rightly ends the run before what the test is about."""
    before = os.getpriority(os.PRIO_PROCESS, 0)  # Linux: the calling thread's
    if raise_it:
        with contextlib.suppress(PermissionError):
            os.setpriority(os.PRIO_PROCESS, 0, REAL_TIME_NICE)
    try:
        yield
    finally:
        os.setpriority(os.PRIO_PROCESS, 0, before)


@contextlib.contextmanager
def lab_campaign(config: BenchConfig, sequence: Sequence, path: Path) -> Iterator[LabCampaign]:
    """Open the simulated lab of ``config``, build its engine as the application does
    (:func:`bench.app.engine_build.build_engine`) with the recorder writing ``path``; the caller adds
    its hooks and starts the run. The engine's thread is joined before the lab closes. A paced lab
    runs above the machine's other work where the test may raise it (:func:`real_time_priority`)."""
    with (
        real_time_priority(config.simulation.paced),
        open_bench(config) as devices,
        CampaignWriter.create(
            path,
            software_version="test",
            config_toml=config.to_toml(),
            sequence_toml=dump_sequence(sequence),
            sequence_name=sequence.name,
            config_name=config.source,
        ) as writer,
    ):
        assert devices.lab is not None, "the configuration must name the simulated devices"
        engine = build_engine(config, devices)
        engine.bus.subscribe(Recorder(writer), critical=True)
        campaign = LabCampaign(engine, devices, sequence)
        engine.bus.subscribe(campaign.events.append)
        try:
            yield campaign
        finally:
            if campaign._thread is not None:
                if campaign._thread.is_alive():
                    engine.request_abort()
                campaign._thread.join(RUN_TIMEOUT_S)
