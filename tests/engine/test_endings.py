"""Every ending of a sequence on every step kind, table-driven, on the in-memory fake bench.

Each case runs a short sequence (the step under test between hydraulics steps), brings about one
ending at one moment of the step, and checks that the run (``RunFinished``) and the sequence
(``SequenceFinished`` and the outcome ``run`` returns) are marked with the ending's status and
reason, that every state change went through the table and was published, and that the engine is
left where a reset (for an e-stop, an interlock or a failure) and then a new run are allowed: the
same sequence, its cause cleared, runs again to its end.

A request (pause, abort, e-stop) or a fault behind an interlock comes at the same moment for every
ending of a kind: the third block of frames of the step's first excitation; for the hammer test,
the arming of its first capture (the strike prompt follows, the second blow's checkpoint then
acts); for a prompt, its answer; for a hydraulics or tare step, its command. A failing command is
due at a given call of it (the second point's START of a grid: mid-step), and the soft limits
refuse the steps' 3 mm points (a grid's second amplitude: mid-step). Combinations left out, and
why, are in :data:`EXCLUDED`. The cases run on the test's thread, in the engine's order, with a
counting clock: no sleep, no wall time. The two tests at the end make requests from other threads:
the pause and resume each waited for; the e-stop coming before or while the engine waits paused,
which ends the sequence alike.
"""

from __future__ import annotations

import itertools
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import pytest

from bench.engine import events as ev
from bench.engine.amplitude import AmplitudeControl
from bench.engine.channels import FrameChannels
from bench.engine.contracts import PlannedDrive, PlannedIteration
from bench.engine.engine import Engine
from bench.engine.interlocks import standard_interlocks
from bench.engine.points import SyncBits
from bench.engine.states import RunState
from bench.engine.timing import EngineTiming
from drivers.errors import CommandRejectedError, LimitError, LinkError, LinkTimeoutError
from drivers.setpoints import DriveSetpoint
from sequences import (
    AdaptiveDwell,
    DriveIteration,
    DwellGrid,
    FreeRun,
    HammerTest,
    Hydraulics,
    Prompt,
    RoadReplay,
    Sequence,
    SineDwell,
    Sweep,
    Tare,
)
from sequences.limits import BenchLimits
from tests.engine.fake_bench import ACTIVE_BIT, HOLD_BIT, FakeBench

RATE_HZ = 1000.0
#: soft limits the steps' 3 mm points lie beyond (their 1 mm points do not)
SOFT_LIMITS = BenchLimits(stroke_mm=2.5, displacement_interlock_mm=15.0)
#: the plate force per metre of displacement the adaptive grid's FRF needs (2 mm: 200 N, far below
#: the 20 kN force limit)
PLATE_N_PER_M = 1e5
START_REFUSED = "START refused: NOT_ALLOWED_IN_STATE"
NEEDS_RESET = (RunState.ESTOPPED, RunState.INTERLOCKED, RunState.FAILED)


def dwell_grid(adaptive: AdaptiveDwell | None = None) -> DwellGrid:
    return DwellGrid(
        freqs_hz=(5.0, 10.0),
        amplitudes_mm=(1.0, 3.0),
        settle_cycles=2,
        settle_min_s=0.1,
        measure_cycles=4,
        measure_min_s=0.3,
        taper_in_s=0.1,
        taper_out_s=0.1,
        adaptive=adaptive,
    )


@dataclass(frozen=True)
class Failure:
    """A device command that fails: its ``call``-th call (counted from 1) raises ``error``, and the
    sequence ends failed with ``reason``."""

    command: str
    call: int
    error: Exception
    reason: str


@dataclass(frozen=True)
class Kind:
    """A step kind under test: the step, the moment its endings are brought about (the ``nth``
    occurrence of ``moment``: a command of the fake bench by name, ``block`` for a block of frames
    while an excitation runs, ``answer`` for the operator's answer), and its failing commands by
    the device they go to ("actuator", "wfs")."""

    name: str
    step: object
    moment: str
    nth: int = 1
    excites: bool = False  # the step runs excitations: interlocks and soft limits apply
    failing: dict[str, Failure] = field(default_factory=dict)
    plate_n_per_m: float = 0.0  # the fake's plate force per metre of displacement
    runs_complete: int = 1  # the runs the step records when it completes (a drive iteration's: several)


def excitation_failures(start_call: int) -> dict[str, Failure]:
    """An excitation step's failures: the controller refuses START (of the ``start_call``-th point,
    mid-step for a grid), or the WFS does not answer the run's stream start."""
    return {
        "actuator": Failure("start", start_call, CommandRejectedError(START_REFUSED), START_REFUSED),
        "wfs": Failure(
            "start_stream", 1, LinkTimeoutError("no reply to 'START'"), "link error: no reply to 'START'"
        ),
    }


def excitation(
    name: str, step: object, *, points: int, plate_n_per_m: float = 0.0, runs_complete: int = 1
) -> Kind:
    """An excitation step, its endings brought about 3 blocks into its first excitation; the
    actuator's failure comes at the second point's START of a step of several points."""
    failures = excitation_failures(2 if points > 1 else 1)
    return Kind(name, step, "block", 3, True, failures, plate_n_per_m, runs_complete)


ADAPTIVE = AdaptiveDwell(min_hold_cycles=2, min_hold_s=0.3, max_hold_s=2.0, max_added_points=2)
KINDS = (
    excitation("sine_dwell", SineDwell(10.0, 3.0, taper_in_s=0.1, taper_out_s=0.1), points=1),
    excitation("dwell_grid", dwell_grid(), points=4),
    excitation("adaptive_dwell_grid", dwell_grid(ADAPTIVE), points=4, plate_n_per_m=PLATE_N_PER_M),
    excitation("free_run", FreeRun(dwell_grid()), points=4),
    excitation("sweep", Sweep(1.0, 10.0, 3.0, 3.0, taper_in_s=0.5, taper_out_s=0.5), points=1),
    excitation("road_replay", RoadReplay(file="drive.csv", taper_in_s=0.5, taper_out_s=0.5), points=1),
    excitation(
        "drive_iteration",
        DriveIteration(target="target.csv", identification_s=3.0, max_iterations=1, response="post_force"),
        points=1,
        plate_n_per_m=PLATE_N_PER_M,
        runs_complete=2,  # the identification's run and its one iteration's
    ),
    Kind(
        "hammer",
        HammerTest(200.0, blows=2),
        "arm_capture",
        failing={"wfs": Failure("wait_capture", 2, LinkTimeoutError("no capture"), "link error: no capture")},
    ),
    Kind("prompt", Prompt("wheel", "Remove the wheel", action="remove_wheel"), "answer"),
    Kind(
        "hydraulics",
        Hydraulics("high"),
        "set_hydraulics",
        failing={
            "actuator": Failure(
                "set_hydraulics",
                1,
                CommandRejectedError("controller refused HYDRAULICS_HIGH: NOT_ALLOWED_IN_STATE"),
                "controller refused HYDRAULICS_HIGH: NOT_ALLOWED_IN_STATE",
            )
        },
    ),
    Kind(
        "tare",
        Tare(),
        "tare",
        failing={
            "wfs": Failure(
                "tare", 1, LinkTimeoutError("no reply to 'TARE'"), "link error: no reply to 'TARE'"
            )
        },
    ),
)
NO_EXCITATION = tuple(kind.name for kind in KINDS if not kind.excites)


class Operator:
    """Answers every prompt with its target; ``on_answer`` is called first, and ``decline`` makes
    the next confirmation a no."""

    def __init__(self) -> None:
        self.on_answer: Callable[[], None] | None = None
        self.decline = False

    def answer(self, prompt: Prompt) -> object:
        if self.on_answer is not None:
            self.on_answer()
        if self.decline and prompt.answer == "confirm":
            self.decline = False
            return False
        return prompt.check_answer(prompt.target if prompt.target is not None else True)


@dataclass
class Case:
    """One sequence on one engine, and the moment its ending is brought about."""

    kind: Kind
    bench: FakeBench
    engine: Engine
    operator: Operator
    seen: list
    at_moment: list[Callable[[], None]] = field(default_factory=list)
    count: int = 0

    def occurred(self, what: str) -> None:
        """Count ``what``; at the kind's moment, act."""
        if what != self.kind.moment:
            return
        self.count += 1
        if self.count == self.kind.nth:
            for act in self.at_moment:
                act()

    def of(self, kind: type) -> list:
        return [e for e in self.seen if isinstance(e, kind)]


def make_case(kind: Kind) -> Case:
    bench = FakeBench(force_per_m=kind.plate_n_per_m)
    operator = Operator()
    engine = Engine(
        bench,
        bench,
        operator,
        channels=FrameChannels(),
        interlocks=standard_interlocks(
            FrameChannels().recorded,
            BenchLimits(stroke_mm=15.0, force_n=20_000.0, force_interlock_n=25_000.0),
        ),
        sync_bits=SyncBits(ACTIVE_BIT, HOLD_BIT),
        sample_rate_hz=RATE_HZ,
        amplitude_control=AmplitudeControl(tolerance=0.02, max_corrections=3),
        timing=EngineTiming(status_period_s=0.0),
        clock=itertools.count(0.0, 0.001).__next__,
    )
    case = Case(kind, bench, engine, operator, [])
    engine.bus.subscribe(case.seen.append)
    bench.on_call = lambda b, name: case.occurred(name)
    bench.on_block = lambda b: case.occurred("block") if len(b._wave) else None
    operator.on_answer = lambda: case.occurred("answer")
    return case


#: The road replay's drive: a 5 Hz sine of 3 mm for 3 s at the bench's rate (3 mm: beyond the
#: soft limits' stroke, as the other steps' second amplitude).
DRIVE = DriveSetpoint(3.0 * np.sin(2 * np.pi * 5.0 * np.arange(3001) / RATE_HZ), RATE_HZ, 0.5, 0.5)


def drives_of(kind: Kind) -> dict[int, PlannedDrive | PlannedIteration]:
    """The planned drive of a road replay under test, or a drive iteration's target (the post's
    force of the fake's plate on the drive) with the drive as its identification (at its index in
    :func:`sequence_of`)."""
    if isinstance(kind.step, RoadReplay):
        return {1: PlannedDrive(DRIVE, {"source": "a 5 Hz sine"})}
    if isinstance(kind.step, DriveIteration):
        target_n = PLATE_N_PER_M * 1e-3 * DRIVE.samples_mm
        record = {"target": "a 5 Hz sine's plate force", "target_sha256": "0" * 64}
        return {1: PlannedIteration(target_n, None, RATE_HZ, DRIVE, 0.0, record, check=lambda drive: ())}
    return {}


def sequence_of(kind: Kind) -> Sequence:
    """The step under test between hydraulics high (before an excitation) and low: the step after it
    is the checkpoint where a request made during a step without excitation acts."""
    before = (Hydraulics("high"),) if kind.excites else ()
    return Sequence(
        name="endings", description="", steps=(*before, kind.step, Hydraulics("low")), source="<test>"
    )


@dataclass(frozen=True)
class Ending:
    """An ending: how it is brought about (``arm(case)``), the status and reason it records (the
    reason exact, or its start when it ends with "..."; a device's failure records the kind's own),
    the state it leaves, and the kinds it applies to."""

    name: str
    arm: Callable[[Case], None]
    status: str
    reason: str
    state: RunState
    applies: Callable[[Kind], bool] = lambda kind: True
    device: str = ""  # the device whose command fails

    def reason_of(self, kind: Kind) -> str:
        return kind.failing[self.device].reason if self.device else self.reason


def at_moment(act: Callable[[Case], None]) -> Callable[[Case], None]:
    return lambda case: case.at_moment.append(lambda: act(case))


def pause_then_resume(case: Case) -> None:
    def resume_once_paused(event: object) -> None:
        if isinstance(event, ev.StateChanged) and event.new is RunState.PAUSED:
            case.engine.request_resume()

    case.engine.bus.subscribe(resume_once_paused)
    case.at_moment.append(case.engine.request_pause)


def interlock(name: str, fault: Callable[[FakeBench], None]) -> Ending:
    return Ending(
        name,
        at_moment(lambda case: fault(case.bench)),
        "interlocked",
        f"{name}: ...",
        RunState.INTERLOCKED,
        lambda kind: kind.excites,
    )


def failing(device: str) -> Ending:
    def arm(case: Case) -> None:
        failure = case.kind.failing[device]
        case.bench.faults[failure.command] = (failure.call, failure.error)

    return Ending(
        f"{device} error", arm, "failed", "", RunState.FAILED, lambda kind: device in kind.failing, device
    )


def refuse_setpoints(case: Case) -> None:
    case.bench.limits = SOFT_LIMITS


def decline_next_confirmation(case: Case) -> None:
    case.operator.decline = True


ENDINGS = (
    Ending("complete", lambda case: None, "complete", "", RunState.FINISHED),
    Ending("pause then resume", pause_then_resume, "complete", "", RunState.FINISHED),
    Ending(
        "abort",
        at_moment(lambda case: case.engine.request_abort()),
        "aborted",
        "aborted by the operator",
        RunState.ABORTED,
    ),
    Ending(
        "declined prompt",
        at_moment(decline_next_confirmation),
        "aborted",
        "the operator declined: ...",
        RunState.ABORTED,
        lambda kind: kind.name in ("prompt", "hammer"),
    ),
    Ending(
        "e-stop",
        at_moment(lambda case: case.engine.request_estop()),
        "e-stopped",
        "e-stop",
        RunState.ESTOPPED,
    ),
    interlock("actuator link lost", lambda bench: setattr(bench, "link_down", True)),
    interlock("controller interlock", lambda bench: setattr(bench, "estopped", True)),
    interlock("WFS link lost", lambda bench: setattr(bench, "silent", True)),
    interlock("WFS overload", lambda bench: setattr(bench, "overload", True)),
    interlock("displacement limit", lambda bench: setattr(bench, "offset_m", 0.02)),  # 20 mm > 15 mm
    interlock("force limit", lambda bench: setattr(bench, "force_per_m", 2e7)),  # 3 mm: 60 kN > 20 kN
    interlock("excitation watchdog", lambda bench: setattr(bench, "stuck_active", True)),
    failing("actuator"),
    failing("wfs"),
    Ending(
        "refused setpoint",
        refuse_setpoints,
        "failed",
        "setpoint refused by the soft limits: amplitude_mm=3.0...",  # the adaptive grid's 3.0000000171
        RunState.FAILED,
        lambda kind: kind.excites,
    ),
)

#: (kind, ending) pairs not run, and why.
EXCLUDED = {
    **{
        (kind, ending.name): "interlocks are checked while an excitation runs, and this step runs none"
        for kind in NO_EXCITATION
        for ending in ENDINGS
        if ending.status == "interlocked"
    },
    **{(kind, "refused setpoint"): "the step writes no setpoint" for kind in NO_EXCITATION},
    **{
        (kind.name, "declined prompt"): "the step asks nothing"
        for kind in KINDS
        if kind.name not in ("prompt", "hammer")
    },
    ("hammer", "actuator error"): "the hammer test sends the actuator nothing",
    ("prompt", "actuator error"): "a prompt sends a device nothing: the operator answers",
    ("prompt", "wfs error"): "a prompt sends a device nothing: the operator answers",
    ("hydraulics", "wfs error"): "a hydraulics step sends the WFS nothing",
    ("tare", "actuator error"): "a tare sends the actuator nothing",
}
CASES = [
    pytest.param(kind, ending, id=f"{kind.name}-{ending.name}")
    for kind in KINDS
    for ending in ENDINGS
    if ending.applies(kind)
]


def test_every_combination_is_run_or_excluded_with_its_reason():
    run = {(kind.name, ending.name) for kind in KINDS for ending in ENDINGS if ending.applies(kind)}
    every = {(kind.name, ending.name) for kind in KINDS for ending in ENDINGS}
    assert run.isdisjoint(EXCLUDED)
    assert run | set(EXCLUDED) == every


def matches(reason: str, expected: str) -> bool:
    return reason.startswith(expected[:-3]) if expected.endswith("...") else reason == expected


@pytest.mark.parametrize(("kind", "ending"), CASES)
def test_every_ending_is_marked_and_leaves_the_engine_ready_to_run_again(kind: Kind, ending: Ending):
    case = make_case(kind)
    ending.arm(case)
    reason = ending.reason_of(kind)

    outcome = case.engine.run(sequence_of(kind), drives=drives_of(kind))

    assert outcome.status == ending.status, outcome.reason
    assert matches(outcome.reason, reason), outcome.reason
    (finished,) = case.of(ev.SequenceFinished)
    assert (finished.status, finished.reason) == (outcome.status, outcome.reason)
    assert case.engine.state is ending.state
    started, runs = case.of(ev.RunStarted), case.of(ev.RunFinished)
    assert [r.run_id for r in runs] == [r.run_id for r in started]  # every run begun is marked ended
    if kind.excites:  # ended in its first excitation, or complete
        assert len(runs) == (kind.runs_complete if outcome.status == "complete" else 1)
    for run in runs:
        assert (run.status, run.reason) == (outcome.status, outcome.reason)
    changes = case.of(ev.StateChanged)
    assert changes[0].old is RunState.IDLE and changes[-1].new is case.engine.state
    assert all(a.new is b.old for a, b in itertools.pairwise(changes))  # each change published, in order
    if ending.name == "pause then resume":
        assert [c.new for c in changes[1:4]] == [RunState.PAUSING, RunState.PAUSED, RunState.RUNNING]
        if kind.excites:  # the point under way was tapered out, and repeated
            assert "interrupted" in [p.status for p in case.of(ev.PointDone)]
    if ending.status == "interlocked":
        assert [t.name for t in case.of(ev.InterlockTripped)] == [ending.name]

    case.bench.clear_faults()  # the cause cleared, the actuator at rest
    case.bench.force_per_m = kind.plate_n_per_m
    case.operator.on_answer = None
    if case.engine.state in NEEDS_RESET:
        case.engine.reset()
        assert case.engine.state is RunState.HYDRAULICS_LOW
    assert case.engine.run(sequence_of(kind), drives=drives_of(kind)).status == "complete"
    assert case.engine.state is RunState.FINISHED


def test_a_soft_limit_refusal_is_no_link_error():
    assert issubclass(LimitError, ValueError) and not issubclass(LimitError, LinkError)


@pytest.mark.parametrize("role", ["output", "input"])
def test_an_adaptive_grid_naming_a_channel_the_bench_does_not_record_fails_and_leaves_the_engine_resettable(
    role,
):
    plan = AdaptiveDwell(min_hold_cycles=2, min_hold_s=0.3, max_hold_s=2.0, **{role: "f_elsewhere_n"})
    kind = next(k for k in KINDS if k.name == "adaptive_dwell_grid")
    case = make_case(kind)
    steps = (Hydraulics("high"), dwell_grid(plan), Hydraulics("low"))
    outcome = case.engine.run(Sequence(name="endings", description="", steps=steps, source="<test>"))
    assert outcome.status == "failed"
    assert outcome.reason.startswith("adaptive grid: the bench records no channel f_elsewhere_n")
    assert case.engine.state is RunState.FAILED
    assert not case.of(ev.RunStarted)  # refused before its run began: nothing moved
    case.engine.reset()
    assert case.engine.run(sequence_of(kind), drives=drives_of(kind)).status == "complete"


@dataclass(frozen=True)
class Unsupported:
    """A step of a kind the engine does not run (a sequence built in Python reaches it unvalidated)."""

    kind: ClassVar[str] = "unsupported"
    estimated_duration_s: float = 0.0


def test_an_unsupported_step_fails_the_sequence_and_leaves_the_engine_resettable():
    case = make_case(KINDS[0])
    steps = (Hydraulics("high"), Unsupported(), Hydraulics("low"))
    outcome = case.engine.run(Sequence(name="endings", description="", steps=steps, source="<test>"))
    assert (outcome.status, outcome.reason) == ("failed", "step 1: Unsupported is not supported")
    assert case.engine.state is RunState.FAILED
    case.engine.reset()
    assert case.engine.run(sequence_of(KINDS[0]), drives=drives_of(KINDS[0])).status == "complete"


def on_another_thread(request: Callable[[], object]) -> None:
    """Make ``request`` from a thread of its own (a front end's), and wait until it is made."""
    thread = threading.Thread(target=request)
    thread.start()
    thread.join()


def test_another_threads_pause_shows_at_once_and_is_published_on_the_engines_thread():
    """The state tells a front end at once that a pause is pending; its StateChanged, as every
    event, is published on the engine's thread, at the loop's next look, in the order made."""
    case = make_case(next(k for k in KINDS if k.name == "dwell_grid"))
    publishers: set[int] = set()
    case.engine.bus.subscribe(
        lambda event: publishers.add(threading.get_ident()) if isinstance(event, ev.StateChanged) else None
    )
    shown: list[tuple[RunState, RunState]] = []

    def pause() -> None:
        on_another_thread(case.engine.request_pause)
        shown.append((case.engine.state, case.of(ev.StateChanged)[-1].new))

    def resume_once_paused(event: object) -> None:
        if isinstance(event, ev.StateChanged) and event.new is RunState.PAUSED:
            on_another_thread(case.engine.request_resume)

    case.at_moment.append(pause)
    case.engine.bus.subscribe(resume_once_paused)
    assert case.engine.run(sequence_of(case.kind), drives=drives_of(case.kind)).status == "complete"
    assert shown == [(RunState.PAUSING, RunState.RUNNING)]  # pending at once, not yet published
    assert publishers == {threading.get_ident()}
    assert [c.new for c in case.of(ev.StateChanged)] == [
        RunState.RUNNING,
        RunState.PAUSING,
        RunState.PAUSED,
        RunState.RUNNING,
        RunState.FINISHED,
    ]


def test_an_estop_from_another_thread_ends_a_paused_sequence():
    """The paused loop waits on the table; the e-stop's change of state ends its wait."""
    case = make_case(next(k for k in KINDS if k.name == "dwell_grid"))
    estops: list[threading.Thread] = []

    def estop_once_paused(event: object) -> None:
        if isinstance(event, ev.StateChanged) and event.new is RunState.PAUSED:
            estops.append(threading.Thread(target=case.engine.request_estop))
            estops[0].start()  # not waited for: the loop may be waiting paused before it comes

    case.at_moment.append(case.engine.request_pause)
    case.engine.bus.subscribe(estop_once_paused)
    outcome = case.engine.run(sequence_of(case.kind), drives=drives_of(case.kind))
    estops[0].join()
    assert (outcome.status, outcome.reason) == ("e-stopped", "e-stop")
    assert case.engine.state is RunState.ESTOPPED
    (run,) = case.of(ev.RunFinished)
    assert (run.status, run.reason) == ("e-stopped", "e-stop")


@pytest.mark.parametrize("link_down", [True, False], ids=["link-lost", "link-up"])
def test_a_link_error_in_a_command_while_the_link_is_lost_ends_on_the_link_lost_interlock(link_down):
    """The connection drops as the grid's second START is sent: the write fails with a link error,
    and the sequence ends on the actuator link-lost interlock (what the check would have tripped a
    block later), naming the fault and the command's error, not as a failed command. The same error
    with the link up is a failed command."""
    kind = next(k for k in KINDS if k.name == "dwell_grid")
    case = make_case(kind)
    occurred = case.bench.on_call

    def drop_at_the_second_start(bench: FakeBench, name: str) -> None:
        occurred(bench, name)
        if name == "start" and bench.calls["start"] == 2:
            bench.link_down = link_down

    case.bench.on_call = drop_at_the_second_start
    case.bench.faults["start"] = (2, LinkTimeoutError("write registers 0..0: no reply"))
    outcome = case.engine.run(sequence_of(kind))
    if link_down:
        assert outcome.status == "interlocked"
        assert outcome.reason == "actuator link lost: connection dropped (write registers 0..0: no reply)"
        assert [t.name for t in case.of(ev.InterlockTripped)] == ["actuator link lost"]
    else:
        assert (outcome.status, outcome.reason) == ("failed", "link error: write registers 0..0: no reply")
        assert not case.of(ev.InterlockTripped)
    (run,) = case.of(ev.RunFinished)
    assert (run.status, run.reason) == (outcome.status, outcome.reason)
