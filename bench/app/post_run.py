"""The analysis after each run, as a subscriber: results stored beside the run and published.

Which run is analysed when, and how, is :mod:`bench.app.run_analysis`'s; this subscriber decides
when a run is ready (dwell grids wait until their tyre pressure's grids are done), reads its records
from the campaign file and hands them to the analysis process (:mod:`bench.app.analysis_process`),
so that the numerical work never holds up the WFS reader, the heartbeat or the engine's loop. The
analyses come back while the next run is under way; each is published (an
:class:`~bench.engine.events.AnalysisDone`, which the recorder stores beside its run) from the
engine's thread at the next event, and at the sequence's end every analysis still under way is
waited for. The campaign's knowledge (the object given) is kept up to date with the process's.

Before a run that corrects its contact force with a plate mass starts, :meth:`PostRunAnalysis.gate`
(the engine's run gate) waits for the free runs' analyses and stops the sequence when the last free
run's m_comp is not to be trusted (docs/engine.md, "After each run").
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

from bench.analysis.campaign import CampaignKnowledge, RunAnalysis
from bench.analysis.runs import plate_mass_distrust
from bench.app.analysis_process import AnalysisProcess, AnalysisProcessError
from bench.app.kept_figures import DrawnFigures
from bench.app.run_analysis import run_inputs, runs_to_analyse
from bench.engine import events as ev
from bench.store import CampaignFile, open_campaign
from sequences.runs import RunKind

log = logging.getLogger(__name__)
#: What an analysis the process never made drew.
NO_FIGURES = DrawnFigures()


class PostRunAnalysis:
    """Subscriber: analyses each complete run of ``campaign_path`` and publishes the result.

    Use as a context manager: the analysis process runs for the ``with`` block."""

    def __init__(
        self,
        campaign_path: Path,
        publish: Callable[[ev.Event], None],
        knowledge: CampaignKnowledge,
    ) -> None:
        """``knowledge`` starts from the configuration's masses and sensor; the runs the campaign
        file holds already (an earlier sequence, or before a resume) and ``knowledge`` has not
        taken in are analysed again first, without publishing, so that what they established holds
        for the runs to come."""
        self.campaign_path = campaign_path
        self.publish = publish
        self.knowledge = knowledge
        self._process = AnalysisProcess(knowledge)
        self._pending_grid: tuple[str, object] | None = None  # (run id, tyre pressure) not analysed yet
        self._started: tuple[str, str, object] = ("", "", None)  # the run being recorded: id, kind, pressure
        self._sent: list[tuple[str, str, bool]] = []  # runs in the process: id, kind, whether published
        self._publishing = False

    def __enter__(self) -> PostRunAnalysis:
        self._process.__enter__()
        with open_campaign(self.campaign_path) as campaign:
            for run in runs_to_analyse(campaign):
                if run.run_id not in self.knowledge.analysed_runs:
                    self._send(run.run_id, campaign, publish=False)
        return self

    def __exit__(self, *exc: object) -> None:
        self._process.__exit__(*exc)

    def __call__(self, event: ev.Event) -> None:
        """Dwell grids wait until the next run shows that their pressure's grids are done (another
        kind of run, another pressure, or the end of the sequence); every other run is analysed as
        soon as it is complete. Analyses that came back are published first; at the sequence's end
        every one still under way is waited for."""
        self._take_results(wait=False)
        if isinstance(event, ev.RunStarted):
            pressure = event.conditions.get("tyre_pressure_bar")
            pending = self._pending_grid
            if pending is not None and (event.kind != RunKind.DWELL_GRID or pressure != pending[1]):
                self._send_pending_grid()
            self._started = (event.run_id, event.kind, pressure)
        elif isinstance(event, ev.SequenceFinished):
            if self._pending_grid is not None:
                self._send_pending_grid()
            self._take_results(wait=True)
        elif isinstance(event, ev.RunFinished) and event.status == "complete":
            run_id, kind, pressure = self._started
            if kind == RunKind.DWELL_GRID:
                self._pending_grid = (run_id, pressure)
            else:
                self._send_run(run_id)

    def gate(self, run_id: str, kind: str) -> str | None:
        """The engine's run gate (:class:`~bench.engine.contracts.RunGate`): before a run whose
        contact force is corrected with a free run's plate mass (a dwell grid, a sweep, a road
        replay), the analyses of the free runs sent are waited for (they take well under a second;
        the bench is at rest between runs), and a sequence whose last free run gives an m_comp not
        to be trusted (the plate did not move as a rigid mass, the mass is not physical:
        :func:`~bench.analysis.runs.plate_mass_distrust`)
        or could not be analysed stops before the run, with the reason."""
        if kind not in (RunKind.DWELL_GRID, RunKind.SWEEP, RunKind.ROAD_REPLAY):
            return None
        self._take_results(wait=True, until_kind=RunKind.FREE_RUN)
        free_runs = [a for a in self.knowledge.analysed_runs.values() if a.kind == RunKind.FREE_RUN]
        if not free_runs:
            return None
        last = free_runs[-1]
        if last.error:
            return f"the free run {last.run_id} could not be analysed ({last.error}): its m_comp is unknown"
        weighed = [p for p in self.knowledge.plate_masses if p.run_id == last.run_id]
        distrust = plate_mass_distrust(weighed[-1].result.plate) if weighed else ""
        if distrust:
            return (
                f"the free run {last.run_id} gives an m_comp not to be trusted: {distrust};"
                " the runs after it would correct their contact force with it (repeat the free run into a"
                " new campaign file: a resume of this one stops here again)"
            )
        return None

    def _send_pending_grid(self) -> None:
        run_id, _ = self._pending_grid
        self._pending_grid = None
        self._send_run(run_id)

    def _send_run(self, run_id: str) -> None:
        with open_campaign(self.campaign_path) as campaign:
            self._send(run_id, campaign, publish=True)

    def _send(self, run_id: str, campaign: CampaignFile, *, publish: bool) -> None:
        run = campaign.run(run_id)
        self._process.submit(run_inputs(run, campaign), draw=publish)
        self._sent.append((run_id, run.kind, publish))

    def _take_results(self, *, wait: bool, until_kind: str | None = None) -> None:
        """Publish the analyses that came back (when ``wait``: all of those sent, or with
        ``until_kind`` those up to the last run of that kind sent). Not re-entered from the
        publishing of one of them, so that every subscriber sees them in order."""
        if self._publishing:
            return
        self._publishing = True
        try:
            while self._sent and (until_kind is None or any(k == until_kind for _, k, _ in self._sent)):
                try:
                    result = self._process.next_result(None if wait else 0)
                except AnalysisProcessError as err:
                    self._lost(str(err))
                    return
                if result is None:
                    return
                self._done(result.outcome, result.record, result.figures)
        finally:
            self._publishing = False

    def _done(self, outcome: RunAnalysis, record: str = "", figures: DrawnFigures = NO_FIGURES) -> None:
        """Publish ``outcome`` with its ``record`` and the ``figures`` it changed (none for an
        analysis the process never made); a figure not drawn is logged (the report draws it)."""
        run_id, _, publish = self._sent.pop(0)
        if outcome.error:
            log.warning("analysis of %s failed: %s", run_id, outcome.error)
        for why in figures.failed:
            log.warning("analysis of %s: %s", run_id, why)
        if not record:
            log.warning("analysis of %s not kept as a record: readers will fit it again", run_id)
        if publish:
            results = {"summary": "\n".join(outcome.lines), **outcome.results}
            why = outcome.error or "; ".join(outcome.omitted)
            done = ev.AnalysisDone(
                run_id, outcome.name, outcome.lines, results, outcome.status, why, record, figures.kept
            )
            self.publish(done)

    def _lost(self, reason: str) -> None:
        """The analysis process is gone: every run sent and not answered is published as a
        flagged analysis."""
        while self._sent:
            run_id, kind, _ = self._sent[0]
            self._done(RunAnalysis.failed(run_id, kind, reason))
