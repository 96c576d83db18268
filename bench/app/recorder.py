"""The recorder: a subscriber that writes the engine's events into the campaign file.

Every block of samples is appended as it arrives (the store makes it durable at least every
second), every point attempt becomes a row of the run's points table, prompts and answers, state
changes and interlocks become events, and each run ends with its status and link counters. The
recorder is subscribed as critical: if the file cannot be written the run stops rather than go on
unrecorded.
"""

from __future__ import annotations

import logging

from bench.engine import events as ev
from bench.store import CampaignWriter, RunWriter, StoreError
from sequences.runs import EventKind

log = logging.getLogger(__name__)


class Recorder:
    """Writes one engine's events to ``campaign``; a run id present and incomplete is continued."""

    def __init__(self, campaign: CampaignWriter) -> None:
        self.campaign = campaign
        self._run: RunWriter | None = None
        self._finished: dict[str, RunWriter] = {}

    def __call__(self, event: ev.Event) -> None:
        match event:
            case ev.RunStarted():
                self._begin(event)
            case ev.SamplesRecorded():
                self._samples(event)
            case ev.PointDone():
                self._point(event)
            case ev.GridRefined():
                for freq_hz, reason in event.added:
                    self._event(
                        EventKind.REFINED, f"point added at {freq_hz:g} Hz: {reason}", freq_hz=freq_hz
                    )
            case ev.PromptAnswered():
                self._event(
                    EventKind.PROMPT,
                    event.text,
                    prompt_id=event.prompt_id,
                    answer=event.answer,
                    unit=event.unit,
                )
            case ev.StateChanged():
                self._event(
                    EventKind.STATE, f"{event.old.value} -> {event.new.value}", trigger=event.trigger.value
                )
            case (
                ev.InterlockTripped()
                | ev.HostStalled()
                | ev.AmplitudeChecked()
                | ev.LimitReached()
                | ev.ResonanceTracked()
            ):
                self._event(event.stored_as, event.text, **ev.stored_fields(event))
            case ev.RunFinished():
                self._finish(event)
            case ev.AnalysisDone():
                self._analysed(event)
            case ev.SequenceFinished():
                self.campaign.add_event(
                    EventKind.SEQUENCE_FINISHED, event.reason or event.status, status=event.status
                )
                self.campaign.flush()

    def _analysed(self, event: ev.AnalysisDone) -> None:
        """The run's analysis beside it: its results, its record and the figures it changed."""
        run = self._finished[event.run_id]
        for figure in event.figures:  # made durable with the record's flush: no flush of their own
            try:
                run.write_figure(figure.name, figure.png, figure.shows_sha256)
            except StoreError as exc:  # a kept figure spares the report its drawing: never the run's end
                log.warning("figure not kept: %s", exc)
        run.write_results(event.name, event.results)
        if event.record:
            run.write_analysis_record(event.record)

    def _begin(self, event: ev.RunStarted) -> None:
        if event.run_id in self.campaign.run_ids:
            self._run = self.campaign.continue_run(event.run_id)
            return
        self._run = self.campaign.begin_run(
            event.run_id,
            kind=event.kind,
            step=event.step,
            conditions=event.conditions,
            channels=event.channels,
            sample_rate_hz=event.sample_rate_hz,
            drive=event.drive,
        )

    def _samples(self, event: ev.SamplesRecorded) -> None:
        run = self._open_run(event.run_id)
        if event.first_sample != run.samples:  # the points' sample indices would miss their samples
            raise RuntimeError(
                f"run {event.run_id}: samples from {event.first_sample} on, but the file holds {run.samples}"
            )
        if not event.gaps:
            run.append(event.columns)
            return
        position = 0  # each gap's event is placed at the sample it came before
        for index, missing in event.gaps:
            if index > position:
                run.append({name: column[position:index] for name, column in event.columns.items()})
                position = index
            run.add_event(EventKind.GAP, f"{missing} frames lost on the WFS link", missing=missing)
        run.append({name: column[position:] for name, column in event.columns.items()})

    def _point(self, event: ev.PointDone) -> None:
        self._open_run(event.run_id).add_point(event)  # the event is the point attempt the file records

    def _event(self, kind: EventKind, text: str, **fields: object) -> None:
        """An event of the run being recorded, or of the campaign between runs."""
        if self._run is not None and self._run.is_open:
            self._run.add_event(kind, text, **fields)
        else:
            self.campaign.add_event(kind, text, **fields)

    def _finish(self, event: ev.RunFinished) -> None:
        run = self._open_run(event.run_id)
        run.set_link_counters(dict(event.link_counters))
        run.finish(event.status, event.reason)
        self._finished[event.run_id] = run
        self._run = None

    def _open_run(self, run_id: str) -> RunWriter:
        if self._run is None or self._run.run_id != run_id:
            raise RuntimeError(
                f"event for run {run_id!r} while {self._run and self._run.run_id!r} is recorded"
            )
        return self._run
