"""Response limits with graded actions on the in-memory fake bench: each action does what it says.

The fake bench's plate force is ``force_per_m`` times its displacement, so a 2 mm dwell at
``force_per_m`` = 2e5 N/m gives 400 N of plate force: above an alarm level of 300 N, below an abort
level of 500 N; 3e5 N/m (600 N) passes the abort level too.
"""

from __future__ import annotations

import pytest

from bench.engine import events as ev
from bench.engine.channels import FrameChannels
from bench.engine.engine import Engine
from bench.engine.interlocks import standard_interlocks
from bench.engine.states import RunState
from sequences.channels import Role
from sequences.limits import BenchLimits
from sequences.response_limits import LimitAction, LimitProfile, ResponseLimit
from tests.engine.fake_bench import FakeBench
from tests.engine.test_engine import grid, make_engine, of, sequence

FLAT = LimitProfile((1.0, 100.0), (300.0, 300.0))
ABORT = LimitProfile((1.0, 100.0), (500.0, 500.0))


def limited(
    bench: FakeBench, alarm: LimitAction, abort: LimitAction, *, alarm_profile=FLAT, **actions
) -> tuple[Engine, list]:
    engine, seen = make_engine(bench)
    limit = ResponseLimit("plate", Role.PLATE_FORCE, alarm_profile, ABORT, alarm, abort)
    engine.interlocks = standard_interlocks(
        FrameChannels().recorded, BenchLimits(stroke_mm=15.0), actions=actions, response_limits=(limit,)
    )
    return engine, seen


def test_indicate_records_the_alarm_once_per_excitation_and_the_run_goes_on():
    bench = FakeBench(force_per_m=2e5)
    engine, seen = limited(bench, LimitAction.INDICATE, LimitAction.INTERLOCK)
    outcome = engine.run(sequence(grid((5.0, 10.0))))
    assert outcome.status == "complete"
    reached = of(seen, ev.LimitReached)
    assert [(r.name, r.action) for r in reached] == [("plate alarm", "indicate")] * 2  # one per dwell
    assert "f_plate_n reached 4" in reached[0].reason and "beyond the 300 N there" in reached[0].reason
    assert [p.status for p in of(seen, ev.PointDone)] == ["done", "done"]


def test_a_profile_is_read_at_the_excitations_frequency():
    """Low only above 12 Hz: the 5 Hz dwell passes, the 20 Hz one raises the alarm."""
    bench = FakeBench(force_per_m=2e5)
    profile = LimitProfile((1.0, 12.0, 15.0, 100.0), (1000.0, 1000.0, 300.0, 300.0))
    engine, seen = limited(bench, LimitAction.INDICATE, LimitAction.INTERLOCK, alarm_profile=profile)
    assert engine.run(sequence(grid((5.0, 20.0)))).status == "complete"
    (reached,) = of(seen, ev.LimitReached)
    assert "at 20 Hz" in reached.reason


def test_hold_pauses_the_sequence_and_the_point_is_repeated_on_resume():
    bench = FakeBench(force_per_m=2e5)
    engine, seen = limited(bench, LimitAction.HOLD, LimitAction.INTERLOCK)

    def operator_at_the_bench(b: FakeBench) -> None:
        if engine.state is RunState.PAUSED:  # the operator lowers what caused it, and resumes
            b.force_per_m = 1e5
            engine.request_resume()

    bench.on_block = operator_at_the_bench
    assert engine.run(sequence(grid((10.0,)))).status == "complete"
    assert [(r.name, r.action) for r in of(seen, ev.LimitReached)] == [("plate alarm", "hold")]
    assert [p.status for p in of(seen, ev.PointDone)] == ["interrupted", "done"]
    states = [c.new for c in of(seen, ev.StateChanged)]
    assert RunState.PAUSED in states and states[-1] is RunState.FINISHED


def test_stop_tapers_out_and_ends_the_sequence_aborted():
    bench = FakeBench(force_per_m=3e5)
    engine, seen = limited(bench, LimitAction.INDICATE, LimitAction.STOP)
    outcome = engine.run(sequence(grid((10.0, 20.0))))
    assert outcome.status == "aborted"
    assert outcome.reason.startswith("plate abort (stop): f_plate_n reached")
    assert "stop" in bench.log  # tapered out
    assert not of(seen, ev.InterlockTripped)
    assert engine.state is RunState.ABORTED  # no reset needed: the next sequence may start


def test_interlock_ends_the_sequence_interlocked():
    bench = FakeBench(force_per_m=3e5)
    engine, seen = limited(bench, LimitAction.INDICATE, LimitAction.INTERLOCK)
    outcome = engine.run(sequence(grid((10.0,))))
    assert outcome.status == "interlocked"
    (tripped,) = of(seen, ev.InterlockTripped)
    assert tripped.name == "plate abort"
    assert engine.state is RunState.INTERLOCKED


def test_the_alarm_acts_below_the_abort_level_and_the_most_severe_acts_first():
    """600 N passes both levels in the same block: the abort's interlock acts, not the alarm's hold."""
    bench = FakeBench(force_per_m=3e5)
    engine, seen = limited(bench, LimitAction.HOLD, LimitAction.INTERLOCK)
    assert engine.run(sequence(grid((10.0,)))).status == "interlocked"
    assert not of(seen, ev.LimitReached)


@pytest.mark.parametrize(("action", "status"), [("stop", "aborted"), ("interlock", "interlocked")])
def test_a_graded_interlock_takes_its_configured_action(action, status):
    """The bench's own plate-force limit (``[actions] force_limit``) at 300 N against 400 N."""
    bench = FakeBench(force_per_m=2e5)
    engine, _ = make_engine(bench)
    engine.interlocks = standard_interlocks(
        FrameChannels().recorded,
        BenchLimits(stroke_mm=15.0, force_n=300.0, force_interlock_n=600.0),
        actions={"force_limit": LimitAction(action)},
    )
    outcome = engine.run(sequence(grid((10.0,))))
    assert outcome.status == status and "force limit" in outcome.reason
