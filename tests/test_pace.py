"""The pace of a sequence (what the command line's status line and the terminal UI's Run screen
show): the ETA holds still while the operator is awaited, counts down inside a long point, and both
clocks stop when the sequence ends."""

from __future__ import annotations

import math

import numpy as np

from bench.app.pace import SequencePace
from bench.engine import events as ev
from bench.engine.states import RunState, Trigger

RUN_ID = "seq-s002-dwell_grid"
RATE_HZ = 100.0


class FakeClock:
    def __init__(self) -> None:
        self.now_s = 100.0

    def __call__(self) -> float:
        return self.now_s


def samples(seconds: float) -> ev.SamplesRecorded:
    return ev.SamplesRecorded(RUN_ID, 0, {"status": np.zeros(round(seconds * RATE_HZ), np.uint16)})


def point_done(index: int) -> ev.PointDone:
    return ev.PointDone(
        index, 10.0, 2.0, 0, 100, 200, 300, status="done", attempt=1, requested_amplitude_mm=2.0,
        commanded_amplitude_mm=2.0, achieved_amplitude_mm=2.0, run_id=RUN_ID,
    )  # fmt: skip


def started(clock: FakeClock, points: int = 4, estimated_s: float = 40.0) -> SequencePace:
    """A sequence of ``points`` estimated at ``estimated_s``, paced at real time (1 wall s per
    recorded s), its first point done after 10 s."""
    pace = SequencePace(clock=clock)
    pace(ev.SequenceStarted("seq", "", "", points, estimated_s))
    pace(ev.RunStarted(RUN_ID, "dwell_grid", {}, {"tyre_pressure_bar": 2.5}, (), RATE_HZ))
    clock.now_s += 10.0
    pace(samples(10.0))
    pace(point_done(0))
    return pace


def test_the_eta_holds_still_while_a_prompt_waits_and_the_elapsed_time_runs_on():
    clock = FakeClock()
    pace = started(clock)
    assert math.isclose(pace.eta_s, 30.0)
    pace(ev.PromptAsked("pressure", "Set the pressure"))
    assert pace.awaiting_operator
    for _ in range(5):  # 25 s of a technician at the gauge
        clock.now_s += 5.0
        assert math.isclose(pace.eta_s, 30.0), pace.eta_s
    assert math.isclose(pace.elapsed_s, 35.0)
    pace(ev.PromptAnswered("pressure", "Set the pressure", 2.5, "bar"))
    assert not pace.awaiting_operator and math.isclose(pace.working_s, 10.0)
    clock.now_s += 5.0
    pace(samples(5.0))
    assert math.isclose(pace.eta_s, 25.0)


def test_a_pause_is_not_the_bench_s_pace():
    clock = FakeClock()
    pace = started(clock)
    pace(ev.StateChanged(RunState.PAUSING, RunState.PAUSED, Trigger.CHECKPOINT))
    clock.now_s += 60.0
    assert math.isclose(pace.eta_s, 30.0)
    pace(ev.StateChanged(RunState.PAUSED, RunState.RUNNING, Trigger.RESUME))
    assert math.isclose(pace.working_s, 10.0) and math.isclose(pace.elapsed_s, 70.0)


def test_the_eta_counts_down_inside_a_point_longer_than_planned():
    """Points of 10 s against an estimate of 1 s each: the points' pace rules, and it counts down
    while the next point runs instead of standing still until it is done."""
    clock = FakeClock()
    pace = started(clock, points=4, estimated_s=4.0)
    assert math.isclose(pace.eta_s, 30.0)
    etas = []
    for _ in range(4):
        clock.now_s += 2.0
        pace(samples(2.0))
        etas.append(pace.eta_s)
    assert np.allclose(etas, [28.0, 26.0, 24.0, 22.0]), etas


def test_both_clocks_stop_when_the_sequence_ends():
    clock = FakeClock()
    pace = started(clock)
    pace(ev.PromptAsked("fit_wheel", "Fit the wheel"))
    clock.now_s += 3.0
    pace(ev.SequenceFinished("aborted", "aborted by the operator"))
    clock.now_s += 100.0
    assert pace.ended and not pace.awaiting_operator
    assert math.isclose(pace.elapsed_s, 13.0) and math.isclose(pace.working_s, 10.0)
    assert pace.eta_s == 0.0
