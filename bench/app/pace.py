"""The pace of a sequence: points done of the total, elapsed time and an ETA, from the engine's
events. The command line's status line and the terminal UI's Run screen both show these figures.

The ETA scales the sequence's remaining estimated duration by the rate observed so far: the seconds
of wall time per second of recorded samples. The simulated bench runs much faster than real time
(or paced, at real time), a real bench at real time plus its prompts and pauses; the observed rate
covers all of them without knowing which. Time spent waiting for the operator (a prompt open, the
sequence paused) is not the bench's pace: it counts in the elapsed time, never in the rate, so that
the ETA holds still while a person is awaited instead of growing.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

from bench.engine import events as ev
from bench.engine.states import RunState
from sequences.points import PointStatus


@dataclass(frozen=True)
class DoneBefore:
    """What a resumed campaign file holds done already of a sequence (what the engine skips):
    ``points`` and their share of the sequence's estimated duration (``estimated_s``)."""

    points: int = 0
    estimated_s: float = 0.0


#: A sequence started afresh: nothing done before.
NOTHING_DONE = DoneBefore()


class SequencePace:
    """Subscriber: the figures of a sequence under way (or ended).

    ``clock``: the wall clock (seconds), injectable for tests; ``done_before``: what a resumed
    campaign file holds done already (the engine skips it): its points count as done, its estimated
    duration is not ahead. Fed on the engine's thread, read from any: each figure is a plain number."""

    def __init__(
        self, *, clock: Callable[[], float] = time.monotonic, done_before: DoneBefore = NOTHING_DONE
    ) -> None:
        self.clock = clock
        self.done_before = done_before
        self.total_points = 0
        self.points_done = done_before.points
        self.estimated_s = 0.0
        self.recorded_s = 0.0
        self.started_s: float | None = None  # wall clock at the sequence's start
        self.ended_s: float | None = None  # wall clock at its end
        self._sample_rate_hz = 0.0
        self._waits: set[str] = set()  # what the operator is awaited for: "prompt", "paused"
        self._waiting_since_s: float | None = None
        self._waited_s = 0.0
        self._last_point_done_s: float | None = None  # working time at the last point done

    # -- figures ----------------------------------------------------------------------------

    @property
    def started(self) -> bool:
        return self.started_s is not None

    @property
    def ended(self) -> bool:
        return self.ended_s is not None

    @property
    def awaiting_operator(self) -> bool:
        return bool(self._waits)

    def _now_s(self) -> float:
        return self.ended_s if self.ended_s is not None else self.clock()

    @property
    def elapsed_s(self) -> float:
        """Wall time since the start (frozen at the end); 0 before it."""
        return 0.0 if self.started_s is None else self._now_s() - self.started_s

    @property
    def working_s(self) -> float:
        """The elapsed time less the time the operator was awaited."""
        waiting = 0.0 if self._waiting_since_s is None else self._now_s() - self._waiting_since_s
        return max(self.elapsed_s - self._waited_s - waiting, 0.0)

    @property
    def eta_s(self) -> float:
        """0 once ended; NaN until samples were recorded; else the larger of two estimates of the
        working time ahead: the remaining estimated duration times the observed working seconds per
        recorded second, and the points still to do times the working seconds per point done so far,
        less the time the point under way has run. The first alone runs out early when points last
        longer than planned (an adaptive grid's estimate holds every dwell at its shortest)."""
        if self.ended:
            return 0.0
        if self.recorded_s <= 0:
            return math.nan
        working_s = self.working_s
        ahead_s = self.estimated_s - self.done_before.estimated_s - self.recorded_s
        by_duration_s = max(ahead_s, 0.0) * working_s / self.recorded_s
        done_here = self.points_done - self.done_before.points
        if done_here <= 0 or self._last_point_done_s is None:
            return by_duration_s
        per_point_s = self._last_point_done_s / done_here
        under_way_s = working_s - self._last_point_done_s
        by_points_s = max(self.total_points - self.points_done, 0) * per_point_s - under_way_s
        return max(by_duration_s, by_points_s, 0.0)

    # -- events -----------------------------------------------------------------------------

    def _wait(self, what: str, waiting: bool) -> None:
        """Start or end a wait for the operator; the time counts once while any wait is open."""
        before = bool(self._waits)
        if waiting:
            self._waits.add(what)
        else:
            self._waits.discard(what)
        now_s = self.clock()
        if self._waits and not before:
            self._waiting_since_s = now_s
        elif before and not self._waits and self._waiting_since_s is not None:
            self._waited_s += now_s - self._waiting_since_s
            self._waiting_since_s = None

    def __call__(self, event: ev.Event) -> None:
        match event:
            case ev.SequenceStarted():
                self.total_points = event.total_points
                self.estimated_s = event.estimated_duration_s
                self.started_s = self.clock()
            case ev.RunStarted():
                self._sample_rate_hz = event.sample_rate_hz
            case ev.SamplesRecorded() if self._sample_rate_hz > 0:
                self.recorded_s += len(event) / self._sample_rate_hz
            case ev.PromptAsked():
                self._wait("prompt", True)
            case ev.PromptAnswered():
                self._wait("prompt", False)
            case ev.StateChanged() if RunState.PAUSED in (event.old, event.new):
                self._wait("paused", event.new is RunState.PAUSED)
            case ev.GridRefined():  # an adaptive grid's added points: the sequence counts its coarse ones
                self.total_points += len(event.added)
            case ev.PointDone() if event.status == PointStatus.DONE:
                self.points_done += 1
                self._last_point_done_s = self.working_s
            case ev.SequenceFinished():
                for what in tuple(self._waits):
                    self._wait(what, False)
                self.ended_s = self.clock()
