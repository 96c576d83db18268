"""A busy host is not a silent link: the engine judges the WFS link's silence at the port and
records a host stall (the port left unread) as what it is, stopping the run only when frames were
lost to it. On the fake bench, whose port reports how long the engine waited on it."""

from __future__ import annotations

from bench.engine import events as ev
from bench.engine.states import RunState
from tests.engine.fake_bench import FakeBench
from tests.engine.test_engine import grid, make_engine, of, sequence


def _stall_at_block(bench: FakeBench, seen: list, unread_s: float, lost: int) -> None:
    """The 10th block's bytes waited ``unread_s`` at the port; ``lost`` frames overran it meanwhile."""

    def stall(b: FakeBench) -> None:
        if len(of(seen, ev.SamplesRecorded)) == 9:
            b.unread_s, b.lost_in_stall = unread_s, lost

    bench.on_block = stall


def test_a_host_stall_without_loss_is_recorded_and_the_run_goes_on():
    bench = FakeBench()
    engine, seen = make_engine(bench)
    _stall_at_block(bench, seen, unread_s=1.3, lost=0)
    assert engine.run(sequence(grid())).status == "complete"
    (stall,) = of(seen, ev.HostStalled)
    assert (stall.run_id, stall.stalled_s, stall.frames_lost) == ("test-s000-dwell_grid", 1.3, 0)
    assert not of(seen, ev.InterlockTripped)


def test_a_host_stall_that_lost_frames_stops_the_run_as_a_host_stall_never_a_link_loss():
    bench = FakeBench()
    engine, seen = make_engine(bench)
    _stall_at_block(bench, seen, unread_s=2.0, lost=1955)
    outcome = engine.run(sequence(grid()))
    assert outcome.status == "interlocked" and engine.state is RunState.INTERLOCKED
    assert outcome.reason.startswith("host stalled: the host left the WFS port unread for 2.00 s")
    assert "1955 frames were lost" in outcome.reason and "link lost" not in outcome.reason
    (stall,) = of(seen, ev.HostStalled)
    assert stall.frames_lost == 1955
    assert [t.name for t in of(seen, ev.InterlockTripped)] == ["host stalled"]


def test_a_short_unread_spell_is_no_stall():
    """Below ``host_stall_s`` (0.05 s by default) a late read is the ordinary jitter of a busy host."""
    bench = FakeBench()
    engine, seen = make_engine(bench)
    _stall_at_block(bench, seen, unread_s=0.04, lost=0)
    assert engine.run(sequence(grid())).status == "complete"
    assert not of(seen, ev.HostStalled)
