"""The engine's loop on the in-memory fake bench: points, amplitude control, pause, abort, e-stop,
interlocks and resume, each checked on the events the engine publishes."""

from __future__ import annotations

import itertools
import threading

import numpy as np
import pytest

from bench.app.recorder import Recorder
from bench.engine import events as ev
from bench.engine.amplitude import AmplitudeControl
from bench.engine.channels import FrameChannels
from bench.engine.engine import GO_ON_DESPITE, Engine
from bench.engine.interlocks import standard_interlocks
from bench.engine.points import SyncBits
from bench.engine.run_ids import RUN_ID
from bench.engine.states import RunState, TransitionRefusedError
from bench.engine.timing import EngineTiming
from bench.store import CampaignWriter, open_campaign
from drivers.errors import CommandRejectedError, LinkTimeoutError
from drivers.wfs_stream import Gap
from sequences import AnswerError, DwellGrid, FreeRun, Hydraulics, Prompt, Sequence, Sweep
from sequences.limits import BenchLimits
from tests.engine.fake_bench import ACTIVE_BIT, HOLD_BIT, FakeBench, FakeBlock, FakeStatus

RATE_HZ = 1000.0


class Answers:
    """Answers every prompt with its target, and remembers what was asked."""

    def __init__(self) -> None:
        self.asked: list[str] = []

    def answer(self, prompt: Prompt) -> object:
        self.asked.append(prompt.id)
        return prompt.check_answer(prompt.target if prompt.target is not None else True)


def make_engine(bench: FakeBench, *, clock=None, force_limit_n: float = 20_000.0) -> tuple[Engine, list]:
    seen: list = []
    engine = Engine(
        bench,
        bench,
        Answers(),
        channels=FrameChannels(),
        interlocks=standard_interlocks(
            FrameChannels().recorded,
            BenchLimits(stroke_mm=15.0, force_n=force_limit_n, force_interlock_n=2 * force_limit_n),
        ),
        sync_bits=SyncBits(ACTIVE_BIT, HOLD_BIT),
        sample_rate_hz=RATE_HZ,
        amplitude_control=AmplitudeControl(tolerance=0.02, max_corrections=3),
        timing=EngineTiming(status_period_s=0.0),
        clock=clock or itertools.count(0.0, 0.001).__next__,
    )
    engine.bus.subscribe(seen.append)
    return engine, seen


def grid(freqs_hz=(5.0, 10.0), amplitude_mm=2.0) -> DwellGrid:
    return DwellGrid(
        freqs_hz=tuple(freqs_hz),
        amplitudes_mm=(amplitude_mm,),
        settle_cycles=2,
        settle_min_s=0.1,
        measure_cycles=4,
        measure_min_s=0.3,
        taper_in_s=0.1,
        taper_out_s=0.1,
    )


def sequence(*steps) -> Sequence:
    return Sequence(name="test", description="", steps=tuple(steps), source="<test>")


def of(seen: list, kind: type) -> list:
    return [e for e in seen if isinstance(e, kind)]


def test_a_grid_records_every_point_with_its_hold_located_to_the_sample():
    bench = FakeBench()
    engine, seen = make_engine(bench)
    step = grid()
    assert engine.run(sequence(Hydraulics("high"), step)).status == "complete"
    assert engine.state is RunState.FINISHED
    points = of(seen, ev.PointDone)
    assert [(p.index, p.status) for p in points] == [(0, "done"), (1, "done")]
    for point, dwell in zip(points, step.dwells(), strict=True):
        assert point.hold_end_sample - point.hold_start_sample == round(dwell.hold_s * RATE_HZ)
        assert point.hold_start_sample - point.start_sample == round(dwell.taper_in_s * RATE_HZ)
        assert point.achieved_amplitude_mm == pytest.approx(2.0, rel=1e-3)
    blocks = of(seen, ev.SamplesRecorded)
    assert [b.first_sample for b in blocks] == list(np.cumsum([0] + [len(b) for b in blocks[:-1]]))
    started, finished = of(seen, ev.RunStarted), of(seen, ev.RunFinished)
    assert [r.run_id for r in started] == [r.run_id for r in finished] == ["test-s001-dwell_grid"]
    assert finished[0].status == "complete"
    assert bench.log[0] == "hydraulics high"


def test_amplitude_control_corrects_a_servo_that_falls_short_and_records_every_attempt():
    bench = FakeBench(gain=lambda f: 0.9 if f > 8 else 1.0)  # 10 % short at 10 Hz
    engine, seen = make_engine(bench)
    engine.run(sequence(grid()))
    at_10 = [p for p in of(seen, ev.PointDone) if p.freq_hz == 10.0]
    assert [p.status for p in at_10] == ["repeated", "done"]
    assert at_10[0].achieved_amplitude_mm == pytest.approx(1.8, rel=1e-3)
    assert at_10[1].commanded_amplitude_mm == pytest.approx(2.0 / 0.9, rel=1e-3)
    assert at_10[1].achieved_amplitude_mm == pytest.approx(2.0, rel=0.02)
    assert all(p.amplitude_mm == 2.0 for p in at_10)


def test_a_pause_interrupts_the_point_which_is_repeated_on_resume():
    bench = FakeBench()
    engine, seen = make_engine(bench)

    paused = []

    def pause_mid_second_point(b: FakeBench) -> None:
        if len(of(seen, ev.PointStarted)) == 2 and len(b._wave) > 500 and not paused:
            paused.append(True)
            engine.request_pause()

    def resume_when_paused(event) -> None:
        if isinstance(event, ev.StateChanged) and event.new is RunState.PAUSED:
            engine.request_resume()

    bench.on_block = pause_mid_second_point
    engine.bus.subscribe(resume_when_paused)
    assert engine.run(sequence(grid(freqs_hz=(5.0, 10.0, 20.0)))).status == "complete"
    points = of(seen, ev.PointDone)
    assert [(p.index, p.status) for p in points] == [
        (0, "done"),
        (1, "interrupted"),
        (1, "done"),
        (2, "done"),
    ]
    states = [e.new for e in of(seen, ev.StateChanged)]
    assert states == [
        RunState.RUNNING,
        RunState.PAUSING,
        RunState.PAUSED,
        RunState.RUNNING,
        RunState.FINISHED,
    ]
    assert bench.log.count("stop") == 1


def test_abort_tapers_out_and_keeps_the_data():
    bench = FakeBench()
    engine, seen = make_engine(bench)
    bench.on_block = lambda b: engine.request_abort() if len(of(seen, ev.SamplesRecorded)) == 20 else None
    assert engine.run(sequence(grid(freqs_hz=(5.0, 10.0, 20.0)))).status == "aborted"
    assert engine.state is RunState.ABORTED
    assert "stop" in bench.log and "estop" not in bench.log
    finished = of(seen, ev.RunFinished)[0]
    assert (finished.status, finished.reason) == ("aborted", "aborted by the operator")
    assert of(seen, ev.SequenceFinished)[0].status == "aborted"


def test_estop_reaches_the_controller_at_once_and_ends_the_run():
    bench = FakeBench()
    engine, seen = make_engine(bench)
    bench.on_block = lambda b: engine.request_estop() if len(of(seen, ev.SamplesRecorded)) == 12 else None
    assert engine.run(sequence(grid())).status == "e-stopped"
    assert engine.state is RunState.ESTOPPED
    assert bench.log[-1] != "start" and "estop" in bench.log
    assert of(seen, ev.RunFinished)[0].status == "e-stopped"
    engine.reset()
    assert engine.state is RunState.HYDRAULICS_LOW


def test_an_estop_sent_between_the_loops_look_and_its_status_read_ends_the_run_as_estopped():
    """The operator's thread e-stops right after the engine's loop looked at the request and before
    it reads the status: the controller's e-stop state is the e-stop's doing, not an interlock."""
    bench = FakeBench()
    engine, seen = make_engine(bench)
    read = bench.read_status

    def estop_then_read() -> FakeStatus:
        if len(of(seen, ev.SamplesRecorded)) >= 12 and not bench.estopped:
            engine.request_estop()
        return read()

    bench.read_status = estop_then_read
    assert engine.run(sequence(grid())).status == "e-stopped"
    assert of(seen, ev.RunFinished)[0].status == "e-stopped"
    assert not of(seen, ev.InterlockTripped)


@pytest.mark.parametrize(
    ("setup", "name"),
    [
        (lambda b: setattr(b, "force_per_m", 2e7), "force limit"),  # 2 mm -> 40 kN > 20 kN
        (lambda b: setattr(b, "link_down", True), "actuator link lost"),
        (lambda b: setattr(b, "silent", True), "WFS link lost"),
        (lambda b: setattr(b, "estopped", True), "controller interlock"),
    ],
)
def test_an_interlock_mid_point_stops_the_actuator_and_marks_the_run(setup, name):
    bench = FakeBench()
    engine, seen = make_engine(bench)

    def trip(b: FakeBench) -> None:
        if len(of(seen, ev.SamplesRecorded)) == 10:
            setup(b)

    bench.on_block = trip
    assert engine.run(sequence(grid())).status == "interlocked"
    assert engine.state is RunState.INTERLOCKED
    trips = of(seen, ev.InterlockTripped)
    assert trips and trips[0].name == name
    finished = of(seen, ev.RunFinished)[0]
    assert finished.status == "interlocked" and name in finished.reason
    assert len(of(seen, ev.SamplesRecorded)) >= 10  # the data so far was handed to the recorder


class Done:
    """A resume plan: the runs ``complete`` are complete (by default the free run), the grid
    ``test-s003-dwell_grid`` has point 0 done."""

    def __init__(self, complete: frozenset[str] = frozenset({"test-s001-free_run"})) -> None:
        self.complete = complete

    def run_complete(self, run_id: str) -> bool:
        return run_id in self.complete

    def completed_points(self, run_id: str) -> set[int]:
        return {0} if run_id == "test-s003-dwell_grid" else set()

    def recorded_samples(self, run_id: str) -> int:
        return 4321 if run_id == "test-s003-dwell_grid" else 0


def test_resume_skips_complete_runs_their_prompts_and_done_points():
    bench = FakeBench()
    engine, seen = make_engine(bench)
    pressure = Prompt(
        "p25",
        "Set 2.5 bar",
        answer="number",
        unit="bar",
        minimum=1,
        maximum=4,
        target=2.5,
        action="set_tyre_pressure",
    )
    wheel = Prompt("wheel", "Remove the wheel", action="remove_wheel")
    steps = (wheel, FreeRun(grid()), pressure, grid(freqs_hz=(5.0, 10.0, 20.0)))
    assert engine.run(sequence(*steps), resume=Done()).status == "complete"
    assert engine.operator.asked == ["p25"]
    assert [(p.run_id, p.index) for p in of(seen, ev.PointDone)] == [
        ("test-s003-dwell_grid", 1),
        ("test-s003-dwell_grid", 2),
    ]
    assert of(seen, ev.RunStarted)[0].conditions["tyre_pressure_bar"] == 2.5
    assert of(seen, ev.SamplesRecorded)[0].first_sample == 4321  # the new samples follow the file's
    assert all(p.start_sample >= 4321 for p in of(seen, ev.PointDone))


def test_resume_asks_again_a_prompt_without_a_measurement_of_its_own_before_unfinished_runs():
    """"Fit the wheel" then "set the pressure" then the grid: with the free run complete and the
    grid not, both prompts are asked again (the wheel was off for the free run); with the grid
    complete too, neither is."""
    fit = Prompt("fit", "Fit the wheel", action="fit_wheel")
    pressure = Prompt("p25", "Set 2.5 bar", answer="number", unit="bar", minimum=1, maximum=4, target=2.5)
    remove = Prompt("wheel", "Remove the wheel", action="remove_wheel")
    steps = (remove, FreeRun(grid()), Hydraulics("low"), fit, pressure, Hydraulics("high"), grid())
    engine, seen = make_engine(FakeBench())
    assert engine.run(sequence(*steps), resume=Done()).status == "complete"
    assert engine.operator.asked == ["fit", "p25"]
    assert of(seen, ev.RunStarted)[0].conditions["wheel_fitted"] is True
    engine, seen = make_engine(FakeBench())
    done_both = Done(frozenset({"test-s001-free_run", "test-s006-dwell_grid"}))
    assert engine.run(sequence(*steps), resume=done_both).status == "complete"
    assert engine.operator.asked == [] and not of(seen, ev.RunStarted)


def test_a_sweep_is_one_point_spanning_its_tapers():
    bench = FakeBench()
    engine, seen = make_engine(bench)
    step = Sweep(start_hz=1.0, end_hz=10.0, duration_s=3.0, amplitude_mm=2.0, taper_in_s=0.5, taper_out_s=0.5)
    assert engine.run(sequence(step)).status == "complete"
    (point,) = of(seen, ev.PointDone)
    assert point.end_sample - point.start_sample == 3000
    assert point.hold_end_sample - point.hold_start_sample == 2000


class Declines:
    def answer(self, prompt: Prompt) -> object:
        return False


class Silent:
    def answer(self, prompt: Prompt) -> object:
        raise AnswerError(f"{prompt.id}: no answer, the input ended")


@pytest.mark.parametrize(("operator", "reason"), [(Declines(), "declined"), (Silent(), "no valid answer")])
def test_a_declined_or_unanswered_prompt_aborts_before_anything_moves(operator, reason):
    bench = FakeBench()
    engine, seen = make_engine(bench)
    engine.operator = operator
    wheel = Prompt("wheel", "Remove the wheel", action="remove_wheel")
    outcome = engine.run(sequence(wheel, FreeRun(grid())))
    assert outcome.status == "aborted" and reason in outcome.reason
    assert not any(line.startswith(("configure", "start")) for line in bench.log)
    assert of(seen, ev.RunStarted) == []


class EstopThenSilent:
    """The technician presses the e-stop while the prompt waits, then leaves it unanswered."""

    def __init__(self) -> None:
        self.engine: Engine | None = None

    def answer(self, prompt: Prompt) -> object:
        self.engine.request_estop()
        raise AnswerError(f"{prompt.id}: no answer")


def test_an_estop_while_a_prompt_waits_ends_the_sequence_e_stopped_even_unanswered():
    bench = FakeBench()
    engine, seen = make_engine(bench)
    engine.operator = operator = EstopThenSilent()
    operator.engine = engine
    wheel = Prompt("wheel", "Remove the wheel", action="remove_wheel")
    outcome = engine.run(sequence(wheel, FreeRun(grid())))
    assert (outcome.status, outcome.reason) == ("e-stopped", "e-stop")
    assert engine.state is RunState.ESTOPPED
    assert bench.estopped and of(seen, ev.RunStarted) == []


class ReplyBehindFrames(FakeBench):
    """A serial line on which the STOP's reply comes behind the frames already in flight: the reader
    hands those to the lossless subscription first, so the reply arrives only once they are taken
    (a full subscription left undrained holds the reader, and the reply with it)."""

    IN_FLIGHT_BLOCKS = 5

    def __init__(self) -> None:
        super().__init__()
        self.in_flight = 0
        self.turn = threading.Condition()

    def stop_stream(self) -> None:
        with self.turn:
            self.in_flight = self.IN_FLIGHT_BLOCKS
            if not self.turn.wait_for(lambda: self.in_flight == 0, timeout=5.0):
                raise LinkTimeoutError("no reply to 'STOP': the reader is held by a full subscription")
        super().stop_stream()

    def get_all(self, timeout_s: float) -> FakeBlock | None:
        block = super().get_all(timeout_s)
        with self.turn:
            if self.in_flight and block is not None:
                self.in_flight -= 1
                self.turn.notify_all()
        return block


def test_the_stream_stops_while_its_frames_in_flight_are_recorded():
    bench = ReplyBehindFrames()
    engine, seen = make_engine(bench)
    assert engine.run(sequence(Hydraulics("high"), grid(freqs_hz=(10.0,)))).status == "complete"
    assert "stream stop" in bench.log
    recorded = sum(len(b.columns["status"]) for b in of(seen, ev.SamplesRecorded))
    assert recorded == bench._seq  # every frame sent, those in flight at the STOP included


def test_run_ids_read_back_as_sequence_step_and_kind():
    seq = Sequence(name="paper shaker", description="", steps=(Hydraulics("high"), grid()), source="<test>")
    match = RUN_ID.match(Engine.run_id(seq, 1))
    assert (match["sequence"], match["step"], match["kind"]) == ("paper_shaker", "001", "dwell_grid")


class TapersOutOfEstop(FakeBench):
    """A controller that, reset out of an e-stop, tapers for ``taper_reads`` status reads (it
    refuses commands meanwhile) before it rests at hydraulics low; None: it never comes to rest."""

    def __init__(self, taper_reads: int | None) -> None:
        super().__init__()
        self.taper_reads = taper_reads
        self.reads_after_reset: int | None = None

    def reset_interlock(self) -> None:
        super().reset_interlock()
        self.reads_after_reset = 0

    def read_status(self) -> FakeStatus:
        status = super().read_status()
        if self.reads_after_reset is None:
            return status
        self.reads_after_reset += 1
        tapering = self.taper_reads is None or self.reads_after_reset <= self.taper_reads
        return FakeStatus(tapering, status.interlock_reason, status.sample_count)


def _estopped(bench: FakeBench) -> Engine:
    engine, _ = make_engine(bench)
    engine.request_estop()
    assert engine.state is RunState.ESTOPPED
    return engine


def test_a_reset_returns_once_the_controller_has_tapered_out_of_its_estop():
    bench = TapersOutOfEstop(taper_reads=3)
    engine = _estopped(bench)
    engine.reset()
    assert bench.reads_after_reset == 4  # three reads while it tapered, the fourth at rest
    assert engine.state is RunState.HYDRAULICS_LOW


def test_a_controller_that_does_not_come_to_rest_fails_the_reset_and_the_engine_stays_stopped():
    bench = TapersOutOfEstop(taper_reads=None)
    engine = _estopped(bench)
    with pytest.raises(TimeoutError, match="still moves 10 s after the reset"):
        engine.reset()
    assert engine.state is RunState.ESTOPPED


class DeafBench(FakeBench):
    """A controller that acknowledges START but never runs the excitation."""

    def start(self) -> None:
        self._check_link()
        self.log.append("start ignored")


class WallClock:
    """A test's wall clock: ``step_s`` per reading."""

    def __init__(self, step_s: float) -> None:
        self.step_s = step_s
        self.now_s = 0.0

    def __call__(self) -> float:
        self.now_s += self.step_s
        return self.now_s


@pytest.mark.parametrize(
    ("block", "clock_step_s", "gate"),
    [(10_000, 0.1, "wall"), (50, 1.0, "samples")],
    ids=["samples-ahead-of-wall-time", "wall-time-ahead-of-samples"],
)
def test_the_start_watchdog_waits_for_five_seconds_of_wall_time_and_of_samples(block, clock_step_s, gate):
    """An engine far behind the stream (big blocks, little wall time) and a slow stream (small
    blocks, much wall time) both trip only once 5 s have passed on both clocks."""
    bench = DeafBench(block=block)
    clock = WallClock(clock_step_s)
    engine, seen = make_engine(bench, clock=clock)
    outcome = engine.run(sequence(Hydraulics("high"), grid(freqs_hz=(5.0,))))
    assert outcome.status == "interlocked"
    assert outcome.reason == "excitation watchdog: the controller did not start the excitation"
    assert engine.state is RunState.INTERLOCKED
    recorded_s = sum(len(b) for b in of(seen, ev.SamplesRecorded)) / RATE_HZ
    assert recorded_s > 5.0 and clock.now_s > 5.0
    if gate == "wall":  # the samples had passed 5 s long before the wall clock did
        assert recorded_s > 50.0 and clock.now_s < 10.0
    else:  # the wall clock had passed 5 s long before the samples did
        assert clock.now_s > 50.0 and recorded_s < 5.0 + 2 * block / RATE_HZ


def test_a_whole_excitation_and_a_long_tail_in_one_block_is_a_point_not_an_overrun():
    """An engine that catches up takes the whole excitation and much of what followed in one
    block: the excitation ended inside it, so the end watchdog does not trip."""
    bench = FakeBench(block=20_000)  # 20 s of samples; the excitation lasts about 1 s
    engine, seen = make_engine(bench)
    assert engine.run(sequence(Hydraulics("high"), grid(freqs_hz=(5.0,)))).status == "complete"
    (point,) = of(seen, ev.PointDone)
    assert point.status == "done"
    assert point.end_sample - point.start_sample < 2 * RATE_HZ


class RunawayBench(FakeBench):
    """A controller whose active output never falls after the start."""

    def get_all(self, timeout_s: float) -> FakeBlock | None:
        block = super().get_all(timeout_s)
        if block is not None and self.log[-1] == "start":
            block.frames["status"] |= ACTIVE_BIT
        return block


def test_an_excitation_that_runs_past_its_planned_end_trips_the_end_watchdog():
    bench = RunawayBench()
    engine, _ = make_engine(bench)
    outcome = engine.run(sequence(Hydraulics("high"), grid(freqs_hz=(5.0,))))
    assert outcome.status == "interlocked"
    assert outcome.reason == "excitation watchdog: the excitation did not end when planned"
    assert "stop" in bench.log


class GappyBench(FakeBench):
    """A link that loses 5 frames before the 30th frame of the third block it delivers."""

    def __init__(self) -> None:
        super().__init__()
        self.blocks = 0

    def get_all(self, timeout_s: float) -> FakeBlock | None:
        block = super().get_all(timeout_s)
        if block is not None:
            self.blocks += 1
            if self.blocks == 3:
                return FakeBlock(block.frames, gaps=(Gap(index=30, first_seq=0, missing=5),))
        return block


def test_a_gap_is_recorded_as_an_event_at_the_sample_it_came_before(tmp_path):
    bench = GappyBench()
    engine, seen = make_engine(bench)
    path = tmp_path / "gap.h5"
    empty = {"config_toml": "", "sequence_toml": "", "sequence_name": ""}
    with CampaignWriter.create(path, software_version="t", **empty) as writer:
        engine.bus.subscribe(Recorder(writer), critical=True)
        assert engine.run(sequence(Hydraulics("high"), grid(freqs_hz=(5.0,)))).status == "complete"
    (third,) = [b for b in of(seen, ev.SamplesRecorded) if b.gaps]
    assert third.gaps == ((30, 5),)
    with open_campaign(path) as campaign:
        (run,) = campaign.runs
        gaps = [e for e in run.events if e.kind == "gap"]
        assert [(e.sample, e.fields["missing"]) for e in gaps] == [(third.first_sample + 30, 5)]
        assert run.n_samples == sum(len(b) for b in of(seen, ev.SamplesRecorded))


class TricklingDeafBench(DeafBench):
    """A controller that never starts, behind a link that lets 1 frame in 100 through and reports
    the others lost."""

    def get_all(self, timeout_s: float) -> FakeBlock | None:
        block = super().get_all(timeout_s)
        if block is None:
            return None
        lost = len(block.frames) - 1
        return FakeBlock(block.frames[-1:], gaps=(Gap(index=0, first_seq=0, missing=lost),))


def test_a_link_that_loses_most_frames_does_not_hold_the_start_watchdog_off():
    """The watchdog counts the samples the link reported lost with those received: 5 s of them."""
    bench = TricklingDeafBench()
    engine, seen = make_engine(bench, clock=WallClock(0.1))
    outcome = engine.run(sequence(Hydraulics("high"), grid(freqs_hz=(5.0,))))
    assert outcome.reason == "excitation watchdog: the controller did not start the excitation"
    received = sum(len(b) for b in of(seen, ev.SamplesRecorded))
    assert received < 0.02 * 5 * RATE_HZ  # tripped after about 5 s of samples, 1 in 100 received


def sweep_step() -> Sweep:
    return Sweep(start_hz=1.0, end_hz=10.0, duration_s=3.0, amplitude_mm=2.0, taper_in_s=0.5, taper_out_s=0.5)


def pause_once_mid_excitation(engine: Engine, seen: list, after_blocks: int):
    """A bench hook that requests a pause once, ``after_blocks`` blocks into the first excitation,
    and a subscriber that resumes once paused."""
    paused: list[bool] = []

    def pause(b: FakeBench) -> None:
        if not paused and len(of(seen, ev.SamplesRecorded)) >= after_blocks and len(b._wave):
            paused.append(True)
            engine.request_pause()

    def resume(event) -> None:
        if isinstance(event, ev.StateChanged) and event.new is RunState.PAUSED:
            engine.request_resume()

    engine.bus.subscribe(resume)
    return pause


def test_a_pause_interrupts_a_sweep_which_is_repeated_from_its_start_on_resume(tmp_path):
    """The sweep under way is tapered out, recorded as interrupted, and run again whole: the file
    holds it once interrupted and once done, and its sweep record is the repeated one."""
    bench = FakeBench()
    engine, seen = make_engine(bench)
    bench.on_block = pause_once_mid_excitation(engine, seen, after_blocks=15)
    path = tmp_path / "sweep.h5"
    empty = {"config_toml": "", "sequence_toml": "", "sequence_name": ""}
    with CampaignWriter.create(path, software_version="t", **empty) as writer:
        engine.bus.subscribe(Recorder(writer), critical=True)
        outcome = engine.run(sequence(Hydraulics("high"), sweep_step()))
    assert (outcome.status, outcome.reason) == ("complete", "")
    states = [e.new for e in of(seen, ev.StateChanged)]
    assert states == [
        RunState.RUNNING,
        RunState.PAUSING,
        RunState.PAUSED,
        RunState.RUNNING,
        RunState.FINISHED,
    ]
    interrupted, done = of(seen, ev.PointDone)
    assert (interrupted.status, interrupted.attempt) == ("interrupted", 1)
    assert (done.status, done.attempt) == ("done", 2)
    assert interrupted.end_sample - interrupted.start_sample < 3000  # tapered out early
    assert done.end_sample - done.start_sample == 3000  # the whole sweep, from its start
    assert done.start_sample >= interrupted.end_sample
    assert bench.log.count("start") == 2 and bench.log.count("stop") == 1
    with open_campaign(path) as campaign:
        (run,) = campaign.runs
        assert run.status == "complete"
        assert [(p.index, p.status) for p in run.points] == [(0, "interrupted"), (0, "done")]
        record = run.sweep_record()
        assert len(record.channels["z_base_m"]) == 3000


def test_a_pause_in_a_free_run_repeats_the_dwell_under_way():
    bench = FakeBench()
    engine, seen = make_engine(bench)
    bench.on_block = pause_once_mid_excitation(engine, seen, after_blocks=5)
    assert engine.run(sequence(Hydraulics("high"), FreeRun(grid()))).status == "complete"
    assert [(p.index, p.status) for p in of(seen, ev.PointDone)] == [
        (0, "interrupted"),
        (0, "done"),
        (1, "done"),
    ]


def test_abort_during_a_sweep_tapers_out_and_ends_the_sequence_aborted():
    bench = FakeBench()
    engine, seen = make_engine(bench)
    bench.on_block = lambda b: engine.request_abort() if len(of(seen, ev.SamplesRecorded)) == 15 else None
    outcome = engine.run(sequence(Hydraulics("high"), sweep_step()))
    assert (outcome.status, outcome.reason) == ("aborted", "aborted by the operator")
    assert engine.state is RunState.ABORTED
    assert "stop" in bench.log and "estop" not in bench.log
    assert not of(seen, ev.PointDone)
    (finished,) = of(seen, ev.RunFinished)
    assert (finished.status, finished.reason) == ("aborted", "aborted by the operator")


class RefusingController(FakeBench):
    """A controller that, as the real one, refuses a reset while it holds no interlock or e-stop,
    and refuses hydraulics high once ``refuse_high`` is set. It tapers out while nobody reads its
    frames, as a real one does."""

    refuse_high: bool = False

    def read_status(self) -> FakeStatus:
        """With the stream stopped, each read lets the controller taper on by one block."""
        if not self.streaming:
            self._wave = self._wave[self.block :]
        return super().read_status()

    def reset_interlock(self) -> None:
        if not self.estopped:
            raise CommandRejectedError("RESET_INTERLOCK refused: the controller holds no interlock")
        super().reset_interlock()

    def set_hydraulics(self, level: str) -> None:
        if level == "high" and self.refuse_high:
            raise CommandRejectedError("HYDRAULICS_HIGH refused: the controller is off")
        super().set_hydraulics(level)


@pytest.mark.parametrize(
    "fault",
    ["refused command", "own interlock"],
)
def test_a_reset_after_a_stop_the_controller_did_not_see_returns_the_engine_to_hydraulics_low(fault):
    """A failed sequence (a refused command) or an interlock of the engine's own leaves the
    controller with nothing to release: the reset switches it to hydraulics low instead of
    sending a reset it would refuse, and the engine can start again."""
    bench = RefusingController(force_per_m=2e6)  # 2 mm: 4 kN, beyond the force limit below
    engine, _ = make_engine(bench, force_limit_n=1000.0 if fault == "own interlock" else 20_000.0)
    bench.refuse_high = fault == "refused command"
    outcome = engine.run(sequence(Hydraulics("high"), grid()))
    assert outcome.status == ("failed" if fault == "refused command" else "interlocked")
    assert engine.state is (RunState.FAILED if fault == "refused command" else RunState.INTERLOCKED)
    engine.reset()
    assert engine.state is RunState.HYDRAULICS_LOW
    assert bench.hydraulics == "low" and "reset" not in bench.log
    bench.refuse_high = False
    bench.force_per_m = 0.0
    assert engine.run(sequence(Hydraulics("high"), grid())).status == "complete"


def test_a_reset_with_nothing_stopped_is_refused_and_changes_nothing():
    bench = RefusingController()
    engine, _ = make_engine(bench)
    engine.set_hydraulics("low")
    engine.set_hydraulics("high")
    with pytest.raises(TransitionRefusedError, match="nothing to reset while hydraulics high"):
        engine.reset()
    assert engine.state is RunState.HYDRAULICS_HIGH and bench.hydraulics == "high"


def _untrusting_gate(asked: list[tuple[str, str]]):
    def gate(run_id: str, kind: str) -> str | None:
        asked.append((run_id, kind))
        return "the free run's m_comp is not to be trusted" if kind == "dwell_grid" else None

    return gate


def test_a_run_gate_stops_the_sequence_before_the_steps_that_prepare_the_run_it_forbids():
    """The gate is asked before each step about the next measurement run, with its run id and kind;
    a reason stops the sequence there (aborted, the reason kept): the prompt and the hydraulics step
    that prepare the forbidden run are not reached, the run never starts, the actuator stays at rest,
    and a run the gate allows runs as before."""
    bench = FakeBench()
    engine, seen = make_engine(bench)
    asked: list[tuple[str, str]] = []
    fit = Prompt("fit", "Fit the wheel", action="fit_wheel")
    steps = (FreeRun(grid()), fit, Hydraulics("high"), grid(), FreeRun(grid()))
    outcome = engine.run(sequence(*steps), gate=_untrusting_gate(asked))
    assert outcome.status == "aborted"
    assert outcome.reason == "stopped before test-s003-dwell_grid: the free run's m_comp is not to be trusted"
    assert asked == [("test-s000-free_run", "free_run"), ("test-s003-dwell_grid", "dwell_grid")]
    assert engine.operator.asked == [] and bench.hydraulics != "high"
    assert [e.run_id for e in of(seen, ev.RunStarted)] == ["test-s000-free_run"]
    assert of(seen, ev.SequenceFinished)[-1].status == "aborted"


@pytest.mark.parametrize("go_on", [True, False])
def test_a_gate_that_asks_puts_its_reason_to_the_operator_once(go_on):
    """With ``gate_asks`` (the terminal UI) the gate's reason is a question: a yes lets the runs
    start, is recorded as a condition of the runs and is not asked again for the same reason; a no
    ends the sequence, aborted, before the run, naming the question."""
    engine, seen = make_engine(FakeBench())
    engine.operator = Answers() if go_on else Declines()
    steps = (FreeRun(grid()), grid(), grid(amplitude_mm=1.0))
    outcome = engine.run(sequence(*steps), gate=_untrusting_gate([]), gate_asks=True)
    question = "Before test-s001-dwell_grid: the free run's m_comp is not to be trusted. Go on anyway?"
    started = of(seen, ev.RunStarted)
    if go_on:
        assert outcome.status == "complete" and engine.operator.asked == [GO_ON_DESPITE]
        runs = ["test-s000-free_run", "test-s001-dwell_grid", "test-s002-dwell_grid"]
        assert [e.run_id for e in started] == runs
        assert started[1].conditions[GO_ON_DESPITE] is True
    else:
        assert (outcome.status, outcome.reason) == ("aborted", f"the operator declined: {question}")
        assert [e.run_id for e in started] == ["test-s000-free_run"]
