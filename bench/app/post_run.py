"""The analysis after each run, as a subscriber: results stored beside the run and published.

What is analysed after which run (the paper's procedure):

- hammer test: the sensor's eigenfrequency, damping and stiffness (the sensor model from then on);
- free run without a wheel: the plate mass m_comp (kept for the shaker dwells that follow);
- dwell grids with the wheel: the tyre identification and the compensation, over every complete grid
  of the campaign at the same tyre pressure, once that pressure's grids are done (the next run is of
  another kind or pressure, or the sequence ends);
- four-post sweep: m_wheel, the quarter car and the valid bands, with the post's own free run and the
  tyre identified on the shaker at the pressure nearest the one the sweep's run records (its
  ``set_tyre_pressure`` prompt; a run that records none is not analysed against a guessed tyre),
  or the configured tyre when the campaign has no shaker identification.

The records are read back from the campaign file with the store's reader, exactly as any other file
that follows the schema would be analysed. An analysis that fails is reported as a flagged result;
it never stops the campaign.

:class:`RunAnalyser` analyses one run with what the runs before it established;
:func:`replay_campaign` takes a file's complete runs through it in order. The subscriber
:class:`PostRunAnalysis` replays the runs a file holds already when it starts, then analyses each
run as it completes; ``wfsbench analyze`` (:mod:`bench.app.analyze`) replays a whole file. Both
start from :func:`initial_knowledge` unless they are given what earlier runs established.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bench.analysis.campaign import CampaignKnowledge, PlateMassRun, RunAnalysis
from bench.analysis.runs import (
    ShakerCampaignResult,
    analyse_four_post,
    analyse_free_run,
    analyse_hammer,
    analyse_shaker_campaign,
)
from bench.analysis.validation import AnalysisInputError
from bench.config import BenchConfig
from bench.engine import events as ev
from bench.models.parameters import WfsSensor
from bench.report.text import summary_lines
from bench.store import CampaignFile, RunView, open_campaign

log = logging.getLogger(__name__)

#: Tyre pressures (bar) within a gauge's reading of each other: the same tyre for the analysis.
PRESSURE_MATCH_BAR = 0.05
#: The WFS's eigenfrequency assumed until a hammer test of this campaign measured it (the paper's
#: sensor rings at about 2.2 kHz).
DEFAULT_SENSOR_EIGENFREQUENCY_HZ = 2200.0


def initial_knowledge(config: BenchConfig) -> CampaignKnowledge:
    """What a campaign knows before its first run: the configuration's masses and the sensor's
    assumed eigenfrequency."""
    return CampaignKnowledge(
        sensor=WfsSensor(mass_kg=config.masses.sensor_kg, eigenfrequency_hz=DEFAULT_SENSOR_EIGENFREQUENCY_HZ),
        wheel_mass_kg=config.masses.wheel_below_sensor_kg,
    )


class PostRunAnalysis:
    """Subscriber: analyses each complete run of ``campaign_path`` and publishes the result."""

    def __init__(
        self,
        campaign_path: Path,
        publish: Callable[[ev.Event], None],
        knowledge: CampaignKnowledge,
    ) -> None:
        """``knowledge`` starts from the configuration's masses and sensor; the runs the campaign
        file holds already (an earlier sequence, or before a resume) are analysed again at once,
        without publishing, so that what they established holds for the runs to come."""
        self.campaign_path = campaign_path
        self.publish = publish
        self.analyser = RunAnalyser(knowledge)
        self._pending_grid: tuple[str, object] | None = None  # (run id, tyre pressure) not analysed yet
        self._started: tuple[str, str, object] = ("", "", None)  # the run being recorded: id, kind, pressure
        with open_campaign(campaign_path) as campaign:
            known = set(knowledge.analysed_runs)
            for outcome in replay_campaign(campaign, self.analyser):
                if outcome.error and outcome.run_id not in known:
                    log.warning("earlier run %s not analysed: %s", outcome.run_id, outcome.error)

    def __call__(self, event: ev.Event) -> None:
        """Dwell grids wait until the next run shows that their pressure's grids are done (another
        kind of run, another pressure, or the end of the sequence); every other run is analysed as
        soon as it is complete."""
        if isinstance(event, ev.RunStarted):
            pressure = event.conditions.get("tyre_pressure_bar")
            pending = self._pending_grid
            if pending is not None and (event.kind != "dwell_grid" or pressure != pending[1]):
                self._analyse_pending_grid()
            self._started = (event.run_id, event.kind, pressure)
        elif isinstance(event, ev.SequenceFinished) and self._pending_grid is not None:
            self._analyse_pending_grid()
        elif isinstance(event, ev.RunFinished) and event.status == "complete":
            run_id, kind, pressure = self._started
            if kind == "dwell_grid":
                self._pending_grid = (run_id, pressure)
            else:
                self._report(run_id)

    def _analyse_pending_grid(self) -> None:
        run_id, _ = self._pending_grid
        self._pending_grid = None
        self._report(run_id)

    def _report(self, run_id: str) -> None:
        """Analyse run ``run_id`` from the file and publish the result (a failure as a flag)."""
        with open_campaign(self.campaign_path) as campaign:
            outcome = self.analyser.analyse(campaign.run(run_id), campaign)
        if outcome.error:
            log.warning("analysis of %s failed: %s", run_id, outcome.error)
        self.publish(
            ev.AnalysisDone(
                run_id, outcome.name, outcome.lines, {"summary": "\n".join(outcome.lines), **outcome.results}
            )
        )


class RunAnalyser:
    """Analyses runs one after another, each with what the runs before it established
    (``knowledge``: the sensor from the hammer test, the free runs' records, the shaker
    identification per tyre pressure)."""

    def __init__(self, knowledge: CampaignKnowledge) -> None:
        self.knowledge = knowledge

    def analyse(self, run: RunView, campaign: CampaignFile) -> RunAnalysis:
        """Analyse ``run`` of ``campaign``; a failure is returned as a flagged analysis. The
        knowledge keeps the analysis (:attr:`CampaignKnowledge.analysed_runs`)."""
        try:
            name, lines, results = self._analyse(run, campaign)
            outcome = RunAnalysis(run.run_id, run.kind, name, tuple(lines), results)
        except (AnalysisInputError, ValueError) as exc:
            outcome = RunAnalysis(
                run.run_id,
                run.kind,
                "analysis",
                (f"FLAG analysis failed: {exc}",),
                {"error": str(exc)},
                error=str(exc),
            )
        self.knowledge.analysed_runs[run.run_id] = outcome
        return outcome

    def _analyse(self, run: RunView, campaign: CampaignFile) -> tuple[str, list[str], dict[str, Any]]:
        k = self.knowledge
        if run.kind == "hammer":
            result = analyse_hammer(run.hammer_record(), sensor_mass_kg=k.sensor.mass_kg)
            k.hammer = result
            k.sensor = WfsSensor(
                mass_kg=k.sensor.mass_kg,
                eigenfrequency_hz=result.eigenfrequency_hz,
                damping_ratio=result.damping_ratio_log_decrement,
            )
            return (
                "hammer",
                summary_lines(result),
                {
                    "eigenfrequency_hz": result.eigenfrequency_hz,
                    "damping_ratio": result.damping_ratio_log_decrement,
                },
            )
        if run.kind == "free_run":
            records = run.dwell_records()
            result = analyse_free_run(records)
            if run.conditions.get("bench") == "four_post":
                k.post_free_run = records
                k.plate_masses.append(PlateMassRun(run.run_id, "four-post post", result))
            else:
                k.shaker_free_run = records
                k.plate_masses.append(PlateMassRun(run.run_id, "shaker plate", result))
            return (
                "plate_mass",
                summary_lines(result),
                {
                    "m_comp_kg": result.plate.mass_kg,
                    "m_comp_sigma_kg": result.plate.sigma_kg,
                },
            )
        if run.kind == "dwell_grid":
            return self._shaker(run, campaign)
        if run.kind == "sweep":
            return self._four_post(run)
        raise ValueError(f"no analysis for a {run.kind} run")

    def _shaker(self, run: RunView, campaign: CampaignFile) -> tuple[str, list[str], dict[str, Any]]:
        k = self.knowledge
        if not k.shaker_free_run:
            raise ValueError("no free run without the wheel in this campaign yet: m_comp unknown")
        pressure = run.conditions.get("tyre_pressure_bar")
        if pressure is None:
            raise ValueError("no tyre pressure was answered before this grid")
        records = [
            record
            for other in campaign.runs
            if other.kind == "dwell_grid"
            and other.status == "complete"
            and other.conditions.get("tyre_pressure_bar") == pressure
            for record in other.dwell_records()
        ]
        result = analyse_shaker_campaign(
            records, k.shaker_free_run, wheel_mass_kg=k.wheel_mass_kg, sensor=k.sensor
        )
        k.shaker[float(pressure)] = result
        return "shaker", summary_lines(result), {"tyre_pressure_bar": float(pressure)}

    def _four_post(self, run: RunView) -> tuple[str, list[str], dict[str, Any]]:
        k = self.knowledge
        if run.conditions.get("bench") != "four_post":
            note = (
                "sweep on the shaker bench: recorded, not analysed (the shaker's identification comes"
                " from its dwell grids; the sweep analysis is the four-post bench's)"
            )
            return "sweep", [note], {}
        if not k.post_free_run:
            raise ValueError("no free run of the post in this campaign yet: its m_comp is unknown")
        pressure = run.conditions.get("tyre_pressure_bar")
        if not k.shaker:
            raise ValueError(
                "the four-post analysis needs the tyre below the sensor: run the shaker campaign"
                " (its dwell grids) into the same campaign file first"
            )
        identified_bar, tyre = shaker_result_at(k.shaker, pressure)
        notes = [f"tyre at {pressure:g} bar: shaker identification at {identified_bar:g} bar"]
        if abs(identified_bar - pressure) > PRESSURE_MATCH_BAR:
            notes.append(
                f"FLAG no shaker identification at the car's {pressure:g} bar: the nearest, at"
                f" {identified_bar:g} bar, describes a tyre of another stiffness"
            )
        result = analyse_four_post(
            run.sweep_record(), k.post_free_run, tyre=tyre, wheel_mass_kg=k.wheel_mass_kg, sensor=k.sensor
        )
        k.four_post = result
        lines = summary_lines(result)
        return (
            "four_post",
            [lines[0], *notes, *lines[1:]],
            {
                "m_wheel_kg": result.wheel_mass.mass_kg,
                **({"tyre_pressure_bar": float(pressure)} if pressure is not None else {}),
            },
        )


def _grids_end(run: RunView, following: list[RunView]) -> bool:
    """Whether the dwell grid ``run`` is the last of its tyre pressure before ``following``."""
    pressure = run.conditions.get("tyre_pressure_bar")
    return (
        not following
        or following[0].kind != "dwell_grid"
        or (following[0].conditions.get("tyre_pressure_bar") != pressure)
    )


def replay_campaign(campaign: CampaignFile, analyser: RunAnalyser) -> list[RunAnalysis]:
    """The analyses of the complete runs of ``campaign`` in the order they began, as they would
    have been analysed while the campaign ran: each dwell grid together with the grids of its tyre
    pressure that follow it directly, after the last of them. Runs that did not complete are not
    analysed; a run the analyser's knowledge has taken in already (analysed while the campaign ran,
    or carried from an earlier sequence) gives the analysis it holds, without analysing it again."""
    complete = [run for run in campaign.runs if run.status == "complete"]
    known = analyser.knowledge.analysed_runs
    return [
        known[run.run_id] if run.run_id in known else analyser.analyse(run, campaign)
        for i, run in enumerate(complete)
        if run.kind != "dwell_grid" or _grids_end(run, complete[i + 1 : i + 2])
    ]


def shaker_result_at(
    shaker: dict[float, ShakerCampaignResult], pressure_bar: float | None
) -> tuple[float, ShakerCampaignResult]:
    """The shaker campaign result (and its pressure, bar) for a tyre at ``pressure_bar``: the one
    at the nearest pressure. The tyre's stiffness changes with its pressure (250 / 390 / 420 kN/m at
    1.5 / 2.5 / 3.5 bar), so a run that records no pressure (no ``set_tyre_pressure`` prompt before
    it) gets none: ValueError, which names the pressures identified."""
    if not shaker:
        raise ValueError("no shaker identification in this campaign yet")
    known = ", ".join(f"{p:g}" for p in sorted(shaker))
    if pressure_bar is None:
        raise ValueError(
            "the four-post run records no tyre pressure (no set_tyre_pressure prompt before its"
            f" sweep): which shaker identification ({known} bar) describes its tyre is unknown"
        )
    nearest = min(shaker, key=lambda p: abs(p - pressure_bar))
    return nearest, shaker[nearest]
