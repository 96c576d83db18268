"""One run's analysis with what the runs before it established, wherever it runs.

What is analysed after which run (the paper's procedure):

- hammer test: the sensor's eigenfrequency, damping and stiffness (the sensor model from then on;
  before it, the sensor the bench configuration states in ``[sensor]``, or the assumed default);
- free run without a wheel: the plate mass m_comp (kept for the shaker dwells that follow; a
  campaign without one takes the configured plate mass, nominal, and says what an error in it does);
- dwell grids with the wheel: the tyre identification and the compensation, over every complete grid
  of the campaign at the same tyre pressure, once that pressure's grids are done (the next run is of
  another kind or pressure, or the sequence ends);
- four-post sweep: m_wheel, the quarter car and the valid bands, with the post's own free run and the
  tyre identified on the shaker at the pressure nearest the one the sweep's run records (its
  ``set_tyre_pressure`` prompt; a run that records none is not analysed against a guessed tyre),
  or the configured tyre when the campaign has no shaker identification;
- road replay: the WFS force raw, hub-acceleration compensated (m_wheel and the accelerometer's lag
  of the four-post sweep, else the configured wheel mass) and model-compensated (the compensation
  ``wfsbench compensate`` builds from the campaign, at the run's tyre pressure; without one the
  analysis is partial and says why) against the post's contact force (its free run's m_comp).

:func:`run_inputs` reads what a run's analysis needs from its campaign file (:class:`RunInputs`);
:class:`RunAnalyser` analyses it with what the runs before it established (an analysis that fails
is a flagged result, never an exception); :func:`runs_to_analyse` says which runs of a file are
analysed, in which order; :func:`replay_campaign` takes them through an analyser in this process
(``wfsbench analyze``, :mod:`bench.app.analyze`). While a campaign runs the analyser works in a
process of its own (:mod:`bench.app.analysis_process`, fed by :mod:`bench.app.post_run`). Both
start from :func:`initial_knowledge` unless they are given what earlier runs established.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bench.analysis.campaign import (
    PRESSURE_MATCH_BAR,
    AnalysisKind,
    CampaignKnowledge,
    PlateMassRun,
    RunAnalysis,
    SensorSource,
)
from bench.analysis.drive_iteration import IterationResult
from bench.analysis.flags import FlagCode, flag, flags_of
from bench.analysis.measurement_compensation import CompensationFilters
from bench.analysis.records import (
    HUB_ACCELERATION,
    WFS_FORCE,
    DwellRecord,
    HammerRecord,
    RoadReplayRecord,
    SweepRecord,
)
from bench.analysis.road_replay import OCTAVE_CENTRES_HZ, analyse_road_replay
from bench.analysis.runs import (
    FreeRunResult,
    ShakerCampaignResult,
    analyse_four_post,
    analyse_free_run,
    analyse_hammer,
    analyse_shaker_campaign,
    nominal_free_run,
)
from bench.analysis.tracking import TrackRecord, analyse_track
from bench.analysis.validation import AnalysisInputError
from bench.app.iteration_analysis import analyse_iteration_run
from bench.config import BenchConfig
from bench.models.parameters import WfsSensor
from bench.report.text import summary_lines
from bench.store import CampaignFile, RunView
from bench.store.measurement import Measurement
from bench.store.measurement_chain import CAMPAIGN_LAG, MeasurementChain, Stated
from sequences.runs import EventKind, RigKind, RunKind

#: The plate a four-post free run weighs, as :class:`PlateMassRun` names it.
POST_PLATE = "four-post post"
#: Where a nominal m_comp comes from, as reports name it.
NOMINAL_PLATE_SOURCE = "the bench configuration's masses.plate_kg"


def initial_knowledge(config: BenchConfig) -> CampaignKnowledge:
    """What a campaign knows before its first run: the configuration's masses and its sensor
    (:attr:`BenchConfig.wfs_sensor`: as stated, else assumed), until a hammer run measures it."""
    return CampaignKnowledge(
        sensor=config.wfs_sensor,
        wheel_mass_kg=config.masses.wheel_below_sensor_kg,
        sensor_source=SensorSource.CONFIGURATION if config.sensor.stated else SensorSource.DEFAULT,
        plate_mass_kg=config.masses.plate_kg if config.kind == RigKind.SHAKER else None,
    )


@dataclass(frozen=True)
class RunInputs:
    """What the analysis of one run reads from its campaign file, so that it can run where the file
    is not open (a process of its own): the run's ``run_id``, ``kind`` and ``conditions``, and its
    records: a hammer run's blow (``hammer``); a free run's dwells, or for a dwell grid the dwells
    of every complete grid of the campaign at its tyre pressure (``dwells``); a four-post sweep
    (``sweep``); a tracked dwell's looks (``track``); a road replay (``replay``; a drive
    iteration's run too, with its ``step`` and ``drive`` as recorded). ``read_error``: why
    the records could not be read (the analysis is then flagged). ``notes``: what the run's events
    say that its analysis must say too (the frames it lost on the WFS link, the limits it reached)."""

    run_id: str
    kind: str
    conditions: dict[str, Any]
    hammer: HammerRecord | None = None
    dwells: tuple[DwellRecord, ...] = ()
    sweep: SweepRecord | None = None
    track: TrackRecord | None = None
    replay: RoadReplayRecord | None = None
    step: dict[str, Any] = dataclasses.field(default_factory=dict)
    drive: dict[str, Any] = dataclasses.field(default_factory=dict)
    read_error: str = ""
    notes: tuple[str, ...] = ()


def run_event_notes(run: RunView) -> tuple[str, ...]:
    """What ``run``'s events say that its analysis must say too: the frames it lost on the WFS link
    (:func:`lost_frames_note`) and each limit it reached (a ``limit`` event: an amplitude excursion,
    a response limit's alarm), flagged."""
    limits = tuple(
        flag(FlagCode.LIMIT_REACHED, f"limit reached: {e.text}")
        for e in run.events
        if e.kind == EventKind.LIMIT
    )
    lost = lost_frames_note(run)
    return ((lost,) if lost else ()) + limits


def lost_frames_note(run: RunView) -> str:
    """What ``run`` lost on the WFS link, from its ``gap`` events and its points table (empty: no
    frame was lost)."""
    gaps = [e for e in run.events if e.kind == EventKind.GAP]
    if not gaps:
        return ""
    lost = sum(int(e.fields.get("missing", 0)) for e in gaps)
    in_holds = [p for p in run.points if p.status == "done" and p.frames_missing]
    held = (
        f"; {len(in_holds)} done point{'s' if len(in_holds) != 1 else ''}' holds missed frames"
        if in_holds
        else ""
    )
    return (
        f"{lost} frame{'s' if lost != 1 else ''} lost on the WFS link in {len(gaps)}"
        f" gap{'s' if len(gaps) != 1 else ''}{held}: the analysis fits the samples on their true"
        " times (the frame counter)"
    )


def run_inputs(run: RunView, campaign: CampaignFile) -> RunInputs:
    """Read what the analysis of ``run`` of ``campaign`` needs (:class:`RunInputs`), as
    :data:`INPUT_READERS` says for its kind."""
    inputs = RunInputs(run.run_id, run.kind, dict(run.conditions), notes=run_event_notes(run))
    try:
        return INPUT_READERS[RunKind(run.kind)](run, campaign, inputs)
    except (AnalysisInputError, ValueError) as exc:
        return dataclasses.replace(inputs, read_error=str(exc))


def _read_hammer(run: RunView, campaign: CampaignFile, inputs: RunInputs) -> RunInputs:
    return dataclasses.replace(inputs, hammer=run.hammer_record())


def _read_free_run(run: RunView, campaign: CampaignFile, inputs: RunInputs) -> RunInputs:
    return dataclasses.replace(inputs, dwells=tuple(run.dwell_records()))


def _read_grids(run: RunView, campaign: CampaignFile, inputs: RunInputs) -> RunInputs:
    """Every complete grid of the campaign at the run's tyre pressure (none without one: the
    analysis says that no pressure was answered)."""
    pressure = inputs.conditions.get("tyre_pressure_bar")
    if pressure is None:
        return inputs
    grids = [
        other
        for other in campaign.runs
        if other.kind == RunKind.DWELL_GRID
        and other.status == "complete"
        and other.conditions.get("tyre_pressure_bar") == pressure
    ]
    dwells = tuple(record for grid in grids for record in grid.dwell_records())
    return dataclasses.replace(inputs, dwells=dwells)


def _read_sweep(run: RunView, campaign: CampaignFile, inputs: RunInputs) -> RunInputs:
    """A four-post sweep's record; a sweep on the shaker is not analysed, so nothing is read."""
    if inputs.conditions.get("bench") != RigKind.FOUR_POST:
        return inputs
    return dataclasses.replace(inputs, sweep=run.sweep_record())


def _read_track(run: RunView, campaign: CampaignFile, inputs: RunInputs) -> RunInputs:
    return dataclasses.replace(inputs, track=run.track_record())


def _read_road_replay(run: RunView, campaign: CampaignFile, inputs: RunInputs) -> RunInputs:
    return dataclasses.replace(inputs, replay=run.road_replay_record())


def _read_drive_iteration(run: RunView, campaign: CampaignFile, inputs: RunInputs) -> RunInputs:
    return dataclasses.replace(
        inputs, replay=run.road_replay_record(), step=dict(run.step), drive=dict(run.drive)
    )


#: What the analysis of each kind of run reads from its campaign file (one entry per kind:
#: tests/test_run_kind_tables.py).
INPUT_READERS: dict[RunKind, Callable[[RunView, CampaignFile, RunInputs], RunInputs]] = {
    RunKind.HAMMER: _read_hammer,
    RunKind.FREE_RUN: _read_free_run,
    RunKind.DWELL_GRID: _read_grids,
    RunKind.SWEEP: _read_sweep,
    RunKind.TRACKED_DWELL: _read_track,
    RunKind.ROAD_REPLAY: _read_road_replay,
    RunKind.DRIVE_ITERATION: _read_drive_iteration,
}


#: What an analysis of one run gives: its name (``plate_mass``, ``shaker`` ...), its text lines and
#: the scalar results stored beside the run.
Analysed = tuple[AnalysisKind, list[str], dict[str, Any]]


class RunAnalyser:
    """Analyses runs one after another, each with what the runs before it established
    (``knowledge``: the sensor from the hammer test, the free runs' records, the shaker
    identification per tyre pressure)."""

    def __init__(self, knowledge: CampaignKnowledge) -> None:
        self.knowledge = knowledge

    def analyse(self, run: RunInputs) -> RunAnalysis:
        """Analyse ``run`` (its records read by :func:`run_inputs`); a failure is returned as a
        flagged analysis. The knowledge keeps the analysis (:attr:`CampaignKnowledge.analysed_runs`)."""
        try:
            if run.read_error:
                raise ValueError(run.read_error)
            name, lines, results = self._analyse(run)
            outcome = RunAnalysis(
                run.run_id, run.kind, name, tuple(lines), results, omitted=self._omitted(name, run)
            )
        except (AnalysisInputError, ValueError) as exc:
            outcome = RunAnalysis.failed(run.run_id, run.kind, str(exc))
        if run.notes:  # said after the analysis's first line, whatever it found
            outcome = dataclasses.replace(outcome, lines=(*outcome.lines[:1], *run.notes, *outcome.lines[1:]))
        outcome = dataclasses.replace(outcome, flags=flags_of(outcome.lines))
        self.knowledge.analysed_runs[run.run_id] = outcome
        return outcome

    def _omitted(self, name: AnalysisKind, run: RunInputs) -> tuple[str, ...]:
        """What the analysis ``name`` of ``run`` could not give, with why: a grid's amplitudes with
        too few dwells for a tyre fit, a road replay's model-compensated force."""
        if name is AnalysisKind.ROAD_REPLAY:
            replay = self.knowledge.road_replays[run.run_id]
            return () if replay.identification else (f"model-compensated force: {replay.model_omitted}",)
        if name is not AnalysisKind.SHAKER:
            return ()
        result = self.knowledge.shaker[float(run.conditions["tyre_pressure_bar"])]
        return tuple(f"{r.label}: no tyre fit: {r.why}" for r in result.ratios_only.values())

    def _analyse(self, run: RunInputs) -> Analysed:
        """The analysis :data:`ANALYSES` names for the run's kind."""
        return ANALYSES[RunKind(run.kind)](self, run)

    def _hammer(self, run: RunInputs) -> Analysed:
        """The sensor's eigenfrequency and damping: the sensor model from then on."""
        k = self.knowledge
        if run.hammer is None:
            raise ValueError("no hammer blow was read for this run")
        result = analyse_hammer(run.hammer, sensor_mass_kg=k.sensor.mass_kg)
        k.hammer = result
        k.sensor = WfsSensor(
            mass_kg=k.sensor.mass_kg,
            eigenfrequency_hz=result.eigenfrequency_hz,
            damping_ratio=result.damping_ratio_log_decrement,
        )
        k.sensor_source = SensorSource.HAMMER_TEST
        results = {
            "eigenfrequency_hz": result.eigenfrequency_hz,
            "damping_ratio": result.damping_ratio_log_decrement,
        }
        return AnalysisKind.HAMMER, summary_lines(result), results

    def _free_run(self, run: RunInputs) -> Analysed:
        """The plate mass m_comp of the shaker's plate or the four-post's post."""
        k = self.knowledge
        records = list(run.dwells)
        result = analyse_free_run(records)
        if run.conditions.get("bench") == RigKind.FOUR_POST:
            k.post_free_run = records
            k.plate_masses.append(PlateMassRun(run.run_id, POST_PLATE, result))
        else:
            k.shaker_free_run = records
            k.plate_masses.append(PlateMassRun(run.run_id, "shaker plate", result))
        results = {"m_comp_kg": result.plate.mass_kg, "m_comp_sigma_kg": result.plate.sigma_kg}
        return AnalysisKind.PLATE_MASS, summary_lines(result), results

    def _track(self, run: RunInputs) -> Analysed:
        """A tracked dwell's resonance over its looks."""
        if run.track is None:
            raise ValueError("no looks of the tracked dwell were read for this run")
        result = analyse_track(run.track)
        results = {
            "first_hz": result.first_hz,
            "last_hz": result.last_hz,
            "drift_hz_per_s": result.drift_hz_per_s,
            "verdict": result.verdict,
            "reason": result.reason,
        }
        return AnalysisKind.TRACK, result.summary_lines(), results

    def _shaker(self, run: RunInputs) -> Analysed:
        k = self.knowledge
        pressure = run.conditions.get("tyre_pressure_bar")
        if pressure is None:
            raise ValueError("no tyre pressure was answered before this grid")
        result = analyse_shaker_campaign(
            list(run.dwells),
            k.shaker_free_run or self._nominal_plate(),
            wheel_mass_kg=k.wheel_mass_kg,
            sensor=k.sensor,
            sensor_source=k.sensor_source.text,
        )
        k.shaker[float(pressure)] = result
        return AnalysisKind.SHAKER, summary_lines(result), {"tyre_pressure_bar": float(pressure)}

    def _nominal_plate(self) -> FreeRunResult:
        """m_comp of a campaign without a free run: the configured plate mass, nominal."""
        if self.knowledge.plate_mass_kg is None:
            raise ValueError(
                "no free run without the wheel in this campaign yet, and no shaker plate mass"
                " configured (masses.plate_kg): m_comp unknown"
            )
        return nominal_free_run(self.knowledge.plate_mass_kg, NOMINAL_PLATE_SOURCE)

    def _road_replay(self, run: RunInputs) -> Analysed:
        k = self.knowledge
        record = run.replay
        if record is None:
            raise ValueError("no road replay record was read for this run")
        posts = [p for p in k.plate_masses if p.plate == POST_PLATE]
        if not posts:
            raise ValueError("no free run of the post in this campaign yet: its m_comp is unknown")
        mass_kg, delay_s = k.wheel_mass_kg, 0.0
        if k.four_post is not None:
            wheel = k.four_post.wheel_mass
            mass_kg, delay_s = wheel.mass_kg, wheel.accelerometer_delay_s
        filters, omitted = self._replay_compensation(run)
        result = analyse_road_replay(
            record,
            plate=posts[-1].result.plate,
            wheel_mass_kg=mass_kg,
            accelerometer_delay_s=delay_s,
            filters=filters,
            model_omitted=omitted,
        )
        k.road_replays[run.run_id] = result
        results: dict[str, Any] = {
            "drive_source": result.source,
            "span_s": result.span_s,
            "m_comp_kg": result.plate_mass_kg,
            "m_wheel_kg": result.wheel_mass_kg,
            "contact_rms_n": result.contact_rms_n,
            "octave_centres_hz": list(OCTAVE_CENTRES_HZ),
        }
        for name, errors in result.errors.items():
            results[f"rms_error_{name}_n"] = errors.rms_n
            results[f"octave_rms_error_{name}_n"] = list(errors.octave_rms_n)
        return AnalysisKind.ROAD_REPLAY, result.summary_lines(), results

    def _drive_iteration(self, run: RunInputs) -> Analysed:
        """One run of a drive iteration: the identification's drive and response, or a drive's
        response against the target (:func:`bench.app.iteration_analysis.analyse_iteration_run`)."""
        if run.replay is None:
            raise ValueError("no drive iteration record was read for this run")
        analysed = analyse_iteration_run(run.run_id, run.replay, run.step, run.drive)
        if isinstance(analysed, IterationResult):
            self.knowledge.drive_iterations[run.run_id] = analysed
            results = {
                "iteration": analysed.iteration,
                "rms_error_pct": analysed.rms_error_pct,
                "octave_error_pct": list(analysed.octave_error_pct),
                "damage_ratio": analysed.damage_ratio,
                "in_band_pct": analysed.in_band_pct,
                "stop_rules_met": analysed.stop_rules_met,
            }
            return AnalysisKind.DRIVE_ITERATION, analysed.summary_lines(), results
        lines, results = analysed
        return AnalysisKind.IDENTIFICATION, lines, results

    def _replay_compensation(self, run: RunInputs) -> tuple[CompensationFilters | None, str]:
        """The model compensation of a road replay at its rate, as ``wfsbench compensate`` builds it
        from the campaign, or None and why there is none."""
        from bench.app.compensate import CompensationRefusedError, prepare_compensation

        record = run.replay
        assert record is not None
        pressure = run.conditions.get("tyre_pressure_bar")
        if pressure is None:
            return None, "the run records no tyre pressure (no set_tyre_pressure prompt before it)"
        names = (WFS_FORCE, HUB_ACCELERATION)
        channels = {name: np.asarray(record.channels[name], dtype=float) for name in names}
        chain = MeasurementChain()
        if self.knowledge.four_post is not None:  # the replay's hub accelerometer is the one it measured
            chain = MeasurementChain(hub_lag_ms=Stated(CAMPAIGN_LAG, "a road replay of this campaign"))
        measurement = Measurement(run.run_id, record.sample_rate_hz, channels, float(pressure), chain=chain)
        campaign = _CampaignSoFar(Path("the campaign"), self.knowledge)
        try:
            return prepare_compensation(campaign, measurement, float(pressure)).filters, ""
        except CompensationRefusedError as exc:
            return None, str(exc)

    def _four_post(self, run: RunInputs) -> Analysed:
        k = self.knowledge
        if run.conditions.get("bench") != RigKind.FOUR_POST:
            note = (
                "sweep on the shaker bench: recorded, not analysed (the shaker's identification comes"
                " from its dwell grids; the sweep analysis is the four-post bench's)"
            )
            return AnalysisKind.SWEEP, [note], {}
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
                flag(
                    FlagCode.NO_TYRE_AT_PRESSURE,
                    f"no shaker identification at the car's {pressure:g} bar: the nearest, at"
                    f" {identified_bar:g} bar, describes a tyre of another stiffness",
                )
            )
        assert run.sweep is not None
        result = analyse_four_post(
            run.sweep,
            k.post_free_run,
            tyre=tyre,
            wheel_mass_kg=k.wheel_mass_kg,
            sensor=k.sensor,
            sensor_source=k.sensor_source.text,
        )
        k.four_post = result
        lines = summary_lines(result)
        return (
            AnalysisKind.FOUR_POST,
            [lines[0], *notes, *lines[1:]],
            {
                "m_wheel_kg": result.wheel_mass.mass_kg,
                **({"tyre_pressure_bar": float(pressure)} if pressure is not None else {}),
            },
        )


#: The analysis of each kind of run: its name, its text and its scalars, what it established kept in
#: the analyser's knowledge (one entry per kind: tests/test_run_kind_tables.py).
ANALYSES: dict[RunKind, Callable[[RunAnalyser, RunInputs], Analysed]] = {
    RunKind.HAMMER: RunAnalyser._hammer,
    RunKind.FREE_RUN: RunAnalyser._free_run,
    RunKind.DWELL_GRID: RunAnalyser._shaker,
    RunKind.SWEEP: RunAnalyser._four_post,
    RunKind.TRACKED_DWELL: RunAnalyser._track,
    RunKind.ROAD_REPLAY: RunAnalyser._road_replay,
    RunKind.DRIVE_ITERATION: RunAnalyser._drive_iteration,
}


@dataclass(frozen=True)
class _CampaignSoFar:
    """The campaign as a compensation takes it (:class:`bench.app.compensate.IdentifiedCampaign`)."""

    path: Path
    knowledge: CampaignKnowledge


def _grids_end(run: RunView, following: list[RunView]) -> bool:
    """Whether the dwell grid ``run`` is the last of its tyre pressure before ``following``."""
    pressure = run.conditions.get("tyre_pressure_bar")
    return (
        not following
        or following[0].kind != RunKind.DWELL_GRID
        or (following[0].conditions.get("tyre_pressure_bar") != pressure)
    )


def runs_to_analyse(campaign: CampaignFile) -> list[RunView]:
    """The complete runs of ``campaign`` to analyse, in the order they began, as they would have
    been analysed while the campaign ran: each dwell grid together with the grids of its tyre
    pressure that follow it directly, after the last of them. Runs that did not complete are not
    analysed."""
    complete = [run for run in campaign.runs if run.status == "complete"]
    return [
        run
        for i, run in enumerate(complete)
        if run.kind != RunKind.DWELL_GRID or _grids_end(run, complete[i + 1 : i + 2])
    ]


def replay_campaign(
    campaign: CampaignFile,
    analyser: RunAnalyser,
    analyse: Callable[[RunInputs], RunAnalysis] | None = None,
) -> list[RunAnalysis]:
    """The analyses of :func:`runs_to_analyse` of ``campaign``, in this process; a run the
    analyser's knowledge has taken in already (analysed while the campaign ran, or carried from an
    earlier sequence) gives the analysis it holds, without analysing it again. ``analyse``: how a
    run is analysed with the analyser (default :meth:`RunAnalyser.analyse`; one that also keeps
    its record: :func:`~bench.app.analysis_record.analyse_and_record`)."""
    known = analyser.knowledge.analysed_runs
    analyse = analyse or analyser.analyse
    return [
        known[run.run_id] if run.run_id in known else analyse(run_inputs(run, campaign))
        for run in runs_to_analyse(campaign)
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
