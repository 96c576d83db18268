"""A plain-text log of a run's events, one line each: for the command line and for log files."""

from __future__ import annotations

import math
from collections.abc import Callable

from bench.app.durations import estimate_text
from bench.engine import events as ev


class RunLog:
    """Subscriber: writes one line per meaningful event to ``write``."""

    def __init__(self, write: Callable[[str], None]) -> None:
        self.write = write

    def __call__(self, event: ev.Event) -> None:
        line = self.line(event)
        if line is not None:
            self.write(line)

    @staticmethod
    def line(event: ev.Event) -> str | None:  # noqa: PLR0911 - one line per event type
        match event:
            case ev.SequenceStarted():
                estimate = estimate_text(
                    event.total_points, event.estimated_duration_s, event.estimated_with_operator_s
                )
                return f"sequence {event.sequence_name}: {estimate}"
            case ev.RunStarted():
                return f"run {event.run_id} ({event.kind})"
            case ev.PointDone():
                achieved = (
                    f", achieved {event.achieved_amplitude_mm:.3f} mm"
                    if math.isfinite(event.achieved_amplitude_mm)
                    else ""
                )
                note = f" ({event.note})" if event.note else ""
                u = f"{event.magnitude_uncertainty_pct:.2f} % / {event.phase_uncertainty_deg:.2f} deg"
                u = f", u {u}" if math.isfinite(event.magnitude_uncertainty_pct) else ""  # a track has none
                verdict = f"; {event.verdict}{u}" if event.verdict else ""
                at = f"at {event.freq_hz:g} Hz" if event.freq_hz > 0 else "(broadband: a drive, a blow)"
                return (
                    f"  point {event.index} {at}: {event.status},"
                    f" commanded {event.commanded_amplitude_mm:.3f} mm{achieved}{note}{verdict}"
                )
            case ev.GridRefined():
                return "\n".join(f"  + point at {f:g} Hz ({reason})" for f, reason in event.added)
            case ev.PromptAnswered():
                unit = f" {event.unit}" if event.unit else ""
                return f"prompt {event.prompt_id}: {event.text} -> {event.answer}{unit}"
            case ev.InterlockTripped():
                return f"INTERLOCK {event.name}: {event.reason}"
            case ev.LimitReached():
                return f"LIMIT {event.text}"
            case ev.HostStalled() if event.frames_lost or not event.counted:  # none lost: in the file only
                return event.text
            case ev.RunFinished():
                return f"run {event.run_id}: {event.status}{': ' + event.reason if event.reason else ''}"
            case ev.AnalysisDone():  # may arrive after the next run's start: it names its run
                heading = f"analysis of run {event.run_id} ({event.name}):"
                return "\n".join([heading, *(f"  {line}" for line in event.summary)])
            case ev.SequenceFinished():
                return f"sequence {event.status}{': ' + event.reason if event.reason else ''}"
        return None
