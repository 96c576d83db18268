"""The bench's state as the monitor shows it, made from the engine's events.

:class:`BenchView` is what the terminal UI's top line, Bench and Run screens show, kept from the same
definitions (:mod:`bench.app.bench_status`: state tones, lamps, the point under way;
:class:`~bench.app.pace.SequencePace`: points, elapsed, ETA; :class:`~bench.app.live_trace.LiveTrace`:
the live values; :class:`~bench.app.run_log.RunLog`: each event's line) and laid out as the JSON of
``/api/state`` (docs/monitor.md). It is fed on the monitor's own thread, never the engine's.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from typing import Any

from bench.analysis.campaign import RunAnalysis
from bench.analysis.flags import flags_of
from bench.app.analysis_record import parse_record
from bench.app.bench_status import interlock_lamps, is_reset, point_text, state_tone
from bench.app.live_trace import LiveTrace
from bench.app.pace import NOTHING_DONE, DoneBefore, SequencePace
from bench.app.run_log import RunLog
from bench.engine import events as ev
from bench.engine.states import RunState
from bench.store.typed import TypedFormatError

#: Event lines kept for the page (the oldest are dropped; each has its number, so a viewer knows
#: what it missed).
EVENTS_KEPT = 100
#: Version of the state's JSON layout (docs/monitor.md): a new member needs no new version.
STATE_FORMAT = 1


def finite(value: float) -> float | None:
    """A number for JSON: None for NaN or infinity (strict JSON has neither)."""
    return value if math.isfinite(value) else None


def analysis_entry(analysis: RunAnalysis) -> dict[str, Any]:
    """A run's analysis as the state lists it: its kind, status and why, its flags by code (as the
    analysis JSON lists them, docs/analysis-json.md) and its lines."""
    return {
        "run_id": analysis.run_id,
        "analysis": str(analysis.name),
        "status": str(analysis.status),
        "why": analysis.error or "; ".join(analysis.omitted),
        "flags": [{"code": str(flag.code), "flag": flag.line} for flag in analysis.flags],
        "summary": list(analysis.lines),
    }


def analysis_done_entry(event: ev.AnalysisDone) -> dict[str, Any]:
    """The analysis an event announces, from the record it carries (its flags typed there); without
    one (the analysis process lost first), from the event itself."""
    try:
        return analysis_entry(parse_record(event.record).outcome)
    except TypedFormatError:
        flags = [{"code": str(flag.code), "flag": flag.line} for flag in flags_of(event.summary)]
        why, lines = event.why, list(event.summary)
        return {
            "run_id": event.run_id,
            "analysis": event.name,
            "status": event.status,
            "why": why,
            "flags": flags,
            "summary": lines,
        }


class EventLines:
    """The events as the run log says them, numbered from 1, the last :data:`EVENTS_KEPT` kept."""

    def __init__(self) -> None:
        self.count = 0
        self.kept: deque[tuple[int, str]] = deque(maxlen=EVENTS_KEPT)

    def add(self, text: str) -> None:
        for line in text.splitlines():
            self.count += 1
            self.kept.append((self.count, line))

    def as_json(self) -> list[dict[str, Any]]:
        return [{"n": n, "text": text} for n, text in self.kept]


class BenchView:
    """The state of a bench under way. ``bench``: which bench (for people); ``interlocks``: every
    interlock the engine can trip (a lamp each); ``trace``: the live values' buffer (None: none);
    ``counters``: reads the WFS link's counters (called on the monitor's thread)."""

    def __init__(
        self,
        bench: str,
        state: RunState,
        interlocks: tuple[str, ...],
        trace: LiveTrace | None,
        counters: Callable[[], dict[str, int]],
    ) -> None:
        self.bench = bench
        self.state = state.value
        self.interlocks = interlocks
        self.trace = trace
        self._counters = counters
        self.pace = SequencePace()
        self.done_before = NOTHING_DONE
        self.sequence: dict[str, str] | None = None  # name, status, reason
        self.run: str | None = None
        self.step: str | None = None
        self.prompt: str | None = None
        self.tripped: dict[str, str] = {}
        self.failure: str | None = None
        self.runs: dict[str, dict[str, str]] = {}  # run id -> kind, status, reason
        self.analyses: dict[str, dict[str, Any]] = {}
        self.lines = EventLines()
        self._newest: ev.SamplesRecorded | None = None  # the newest block not yet in the trace

    def launched(self, done_before: DoneBefore) -> None:
        """The next sequence resumes a file holding ``done_before`` (its points count as done)."""
        self.done_before = done_before

    def apply(self, event: ev.Event) -> None:  # noqa: PLR0912 - one branch an event kind
        """Take one event of the engine's bus."""
        if isinstance(event, ev.SamplesRecorded):  # the most frequent: first, and nothing else
            self._newest = event  # only the newest block is shown: copied once per state, not per block
            self.pace(event)
            return
        if isinstance(event, ev.SequenceStarted):
            self.pace = SequencePace(done_before=self.done_before)
            self.done_before = NOTHING_DONE
            self.sequence = {"name": event.sequence_name, "status": "running", "reason": ""}
            self.runs, self.analyses, self.tripped, self.failure = {}, {}, {}, None
        self.pace(event)
        line = RunLog.line(event)
        if line is not None:
            self.lines.add(line)
        match event:
            case ev.StateChanged():
                self.state = event.new.value
                if is_reset(event):
                    self.tripped.clear()
                    self.failure = None
            case ev.RunStarted():
                self.run, self.step = event.run_id, f"run {event.run_id} ({event.kind})"
                self.runs[event.run_id] = {"kind": event.kind, "status": "running", "reason": ""}
            case ev.PointStarted():
                self.step = f"{event.run_id}  {point_text(event)}"
            case ev.PromptAsked():
                self.prompt = event.text
                self.lines.add(f"prompt {event.prompt_id}: {event.text}")
            case ev.PromptAnswered():
                self.prompt = None
            case ev.InterlockTripped():
                self.tripped[event.name] = event.reason
            case ev.RunFinished():
                self.runs.setdefault(event.run_id, {"kind": "", "status": "", "reason": ""}).update(
                    status=event.status, reason=event.reason
                )
            case ev.AnalysisDone():
                self.analyses[event.run_id] = analysis_done_entry(event)
            case ev.SequenceFinished():
                name = self.sequence["name"] if self.sequence else "the sequence"
                self.sequence = {"name": name, "status": event.status, "reason": event.reason}
                why = f": {event.reason}" if event.reason else ""
                self.step, self.prompt = f"{name} {event.status}{why}; no point under way", None
                if event.status == "failed":
                    self.failure = event.reason
                self.lines.add(f"sequence {name}: {event.status}{why}")

    def snapshot(self) -> dict[str, Any]:
        """The state as ``/api/state`` gives it (docs/monitor.md), without its update number."""
        pace = self.pace
        return {
            "format": STATE_FORMAT,
            "source": "bench",
            "bench": self.bench,
            "state": self.state,
            "tone": state_tone(self.state).value,
            "sequence": self.sequence,
            "run": self.run,
            "step": self.step,
            "prompt": self.prompt,
            "points_done": pace.points_done,
            "points_planned": pace.total_points,
            "points_done_before": pace.done_before.points,
            "elapsed_s": round(pace.elapsed_s, 1),
            "eta_s": None if pace.ended else finite(round(pace.eta_s, 1)),
            "awaiting_operator": pace.awaiting_operator,
            "live": self._live(),
            "lamps": [
                {"text": lamp.text, "ok": lamp.ok}
                for lamp in interlock_lamps(self.interlocks, self.tripped, failure=self.failure)
            ],
            "counters": self._counters(),
            "runs": [{"run_id": run_id, **run} for run_id, run in self.runs.items()],
            "analyses": list(self.analyses.values()),
            "events": self.lines.as_json(),
            "events_total": self.lines.count,
        }

    def _live(self) -> dict[str, Any] | None:
        """The newest live values (standard names, SI units), their age and run; None before any."""
        trace, newest = self.trace, self._newest
        if trace is not None and newest is not None:
            trace.append(dict(newest.columns), newest.run_id)
            self._newest = None
        values = trace.latest() if trace is not None else {}
        if not values:
            return None
        age_s = trace.age_s()
        return {
            "values": {name: finite(value) for name, value in values.items()},
            "age_s": None if age_s is None else round(age_s, 2),
            "run": trace.last_run,
        }
