"""A busy host is not a silent link: the engine judges the WFS link's silence at the port and
records a host stall (the port left unread) as what it is, stopping the run only when frames were
lost to it. On the fake bench, whose port reports how long the engine waited on it."""

from __future__ import annotations

import threading

import pytest

from bench.engine import events as ev
from bench.engine.interlocks import EXCITATION_WATCHDOG, HOST_STALLED, interlock_names
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


class _StopsBehindTheGap(FakeBench):
    """The frames still in flight when the stream is stopped: STOP is answered only once the block
    after the stall, with the frames the stall cost, was handed over (while the stream stops)."""

    def __init__(self) -> None:
        super().__init__()
        self.gap_sent = threading.Event()

    def get_all(self, timeout_s: float):
        block = super().get_all(timeout_s)
        if block is not None and block.gaps:
            self.gap_sent.set()
        return block

    def stop_stream(self) -> None:
        assert self.gap_sent.wait(5), "the block after the stall never came"
        super().stop_stream()


def test_a_host_stall_the_controller_tripped_on_first_keeps_the_frames_it_cost():
    """A host stopped for longer than the controller's watchdog finds the controller tripped when
    it resumes: the engine has read the stall's first block (the bytes the port kept) and the
    controller's interlock ends the run, before the block with the frames the stall cost. That
    block comes while the stream stops; the stall is recorded with them, and stops nothing more."""
    bench = _StopsBehindTheGap()
    engine, seen = make_engine(bench)

    def stall_then_trip(b: FakeBench) -> None:
        recorded = len(of(seen, ev.SamplesRecorded))
        if recorded == 9:  # the 10th block: the stall's, and the controller tripped meanwhile
            b.unread_s, b.estopped = 2.0, True
        elif recorded == 10:  # the next: after the frames the port could not keep
            b.lost_in_stall = 1955

    bench.on_block = stall_then_trip
    outcome = engine.run(sequence(grid()))
    assert outcome.status == "interlocked"
    assert outcome.reason == "controller interlock: estop"  # the controller named once
    assert [t.name for t in of(seen, ev.InterlockTripped)] == ["controller interlock"]
    (stall,) = of(seen, ev.HostStalled)
    assert (stall.stalled_s, stall.frames_lost) == (2.0, 1955)
    assert sum(m for s in of(seen, ev.SamplesRecorded) for _, m in s.gaps) == 1955


def _stuck_active(bench: FakeBench, seen: list) -> None:
    bench.stuck_active = True  # the controller's active output never falls: the point never ends


@pytest.mark.parametrize(
    ("cause", "name"),
    [
        (lambda bench, seen: _stall_at_block(bench, seen, unread_s=2.0, lost=10), HOST_STALLED),
        (_stuck_active, EXCITATION_WATCHDOG),
    ],
)
def test_the_interlocks_the_engine_trips_itself_are_named_for_the_lamps(cause, name):
    """The names the engine trips under besides its checks' are among those the UI lights a lamp
    for (:func:`interlock_names`)."""
    bench = FakeBench()
    engine, seen = make_engine(bench)
    cause(bench, seen)
    assert engine.run(sequence(grid())).status == "interlocked"
    (trip,) = of(seen, ev.InterlockTripped)
    assert trip.name == name and name in interlock_names(engine.interlocks)


class _Arriving(FakeBench):
    """Blocks that arrive when the test says (``arrivals``: the host's clock at each block, by
    block number from 1), as a host slow to resume reads them."""

    def __init__(self, arrivals: dict[int, float]) -> None:
        super().__init__()
        self.arrivals = arrivals
        self.blocks = 0

    def get_all(self, timeout_s: float):
        block = super().get_all(timeout_s)
        if block is not None:
            self.blocks += 1
            block.arrived_s = self.arrivals.get(self.blocks, 100.0 + self.blocks)
        return block


@pytest.mark.parametrize(("gap_block", "stalled"), [(11, True), (13, False)])
def test_the_gap_right_after_a_stall_is_its_however_late_the_host_reads_it(gap_block, stalled):
    """The stall's block (the 10th) arrives at 10 s, the next ones half a second apart (the host slow
    to resume): the gap in the block right after the stall's frames is the stall's (the device's
    clock says so), one 200 frames later is the link's and ends nothing."""
    bench = _Arriving({10: 10.0, 11: 10.5, 12: 11.0, 13: 11.5})
    engine, seen = make_engine(bench)

    def stall(b: FakeBench) -> None:
        recorded = len(of(seen, ev.SamplesRecorded))
        if recorded == 9:
            b.unread_s = 1.0
        elif recorded == gap_block - 1:
            b.lost_in_stall = 700

    bench.on_block = stall
    outcome = engine.run(sequence(grid()))
    stalls = of(seen, ev.HostStalled)
    assert [s.stalled_s for s in stalls] == [1.0]
    if stalled:
        assert outcome.status == "interlocked" and outcome.reason.startswith("host stalled: ")
        assert stalls[0].frames_lost == 700
    else:
        assert outcome.status == "complete" and stalls[0].frames_lost == 0
