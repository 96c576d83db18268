"""A campaign's analysis as data: what the runs established so far, what each run's analysis gave,
and a whole file analysed. Plain containers of analysis results (no device, store or rendering):
the post-run analysis and ``wfsbench analyze`` fill them, :mod:`bench.report` renders them.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path
from typing import Any

from bench.analysis.drive_iteration import IterationResult
from bench.analysis.flags import Flag, FlagCode, flag, flags_of
from bench.analysis.records import DwellRecord, HammerRecord, SweepRecord
from bench.analysis.road_replay import RoadReplayResult
from bench.analysis.runs import FourPostResult, FreeRunResult, HammerResult, ShakerCampaignResult
from bench.models.parameters import WfsSensor


class SensorSource(StrEnum):
    """Where the sensor model an analysis used comes from: the campaign's hammer test, the bench
    configuration's ``[sensor]`` table, or the assumed default (neither)."""

    HAMMER_TEST = "hammer_test"
    CONFIGURATION = "configuration"
    DEFAULT = "default"

    @property
    def text(self) -> str:
        """How reports say it, after the sensor's figures."""
        return {
            SensorSource.HAMMER_TEST: "from the hammer test",
            SensorSource.CONFIGURATION: "from the bench configuration's [sensor]",
            SensorSource.DEFAULT: (
                "assumed: no hammer test in the campaign, none stated in the bench configuration"
            ),
        }[self]


#: Tyre pressures (bar) within a gauge's reading of each other: the same tyre for the analysis.
PRESSURE_MATCH_BAR = 0.05


class AnalysisStatus(StrEnum):
    """How far an analysis got: ``complete`` (everything the run is for), ``partial`` (what the data
    allows, with what it does not allow said: no tyre fit from fewer than four points), ``failed``
    (nothing: the reason is the analysis's error)."""

    COMPLETE = "complete"
    PARTIAL = "partial"
    FAILED = "failed"


class AnalysisKind(StrEnum):
    """What the analysis of a run gave, the name its results are stored under beside the run:
    ``hammer`` (the sensor), ``plate_mass`` (a free run's m_comp), ``track`` (a tracked resonance),
    ``shaker`` (a pressure's tyre identification), ``four_post`` (the quarter car), ``sweep`` (a
    sweep on the shaker: recorded, not analysed), ``road_replay`` (the compensated road),
    ``drive_iteration`` (one drive against its target), ``rig_identification`` (a drive iteration's
    broadband identification), or ``analysis`` when it failed."""

    HAMMER = "hammer"
    PLATE_MASS = "plate_mass"
    TRACK = "track"
    SHAKER = "shaker"
    FOUR_POST = "four_post"
    SWEEP = "sweep"
    ROAD_REPLAY = "road_replay"
    DRIVE_ITERATION = "drive_iteration"
    IDENTIFICATION = "rig_identification"
    FAILED = "analysis"


@dataclass(frozen=True)
class PlateMassRun:
    """A free run analysed: its ``run_id``, the ``plate`` it weighed (``"shaker plate"`` or
    ``"four-post post"``) and its ``result`` (m_comp)."""

    run_id: str
    plate: str
    result: FreeRunResult


@dataclass
class CampaignKnowledge:
    """What the campaign has established so far, for the analyses that follow; ``sensor`` and
    ``sensor_source``: the sensor model and where it comes from (the hammer test replaces what the
    configuration stated or the default assumed); ``road_replays``: each road replay analysed, by
    run id; ``drive_iterations``: each drive of a drive iteration analysed, by its run's id;
    ``plate_mass_kg``: the shaker plate's mass as the
    configuration states it (nominal: the shaker analysis takes it when the campaign has no free
    run); ``plate_masses``:
    every free run analysed, in order (whether or not a later run used it); ``analysed_runs``:
    the analyses of the runs it has taken in, by run id (a replay of the file takes these instead
    of analysing the runs again)."""

    sensor: WfsSensor
    wheel_mass_kg: float
    sensor_source: SensorSource = SensorSource.DEFAULT
    plate_mass_kg: float | None = None
    shaker_free_run: list[DwellRecord] = field(default_factory=list)
    post_free_run: list[DwellRecord] = field(default_factory=list)
    plate_masses: list[PlateMassRun] = field(default_factory=list)
    shaker: dict[float, ShakerCampaignResult] = field(default_factory=dict)
    hammer: HammerResult | None = None
    four_post: FourPostResult | None = None
    road_replays: dict[str, RoadReplayResult] = field(default_factory=dict)
    drive_iterations: dict[str, IterationResult] = field(default_factory=dict)
    analysed_runs: dict[str, RunAnalysis] = field(default_factory=dict)


@dataclass(frozen=True)
class RunAnalysis:
    """What the analysis of one run gave: ``name`` (what was analysed, :class:`AnalysisKind`), the
    text ``lines``, the scalar ``results`` stored beside the run, ``error`` (empty
    when the analysis succeeded), ``omitted``: what the data did not allow, each with why
    (empty when the analysis gave everything the run is for), and ``flags``: the flags among its
    lines, typed (:func:`~bench.analysis.flags.flags_of`). The result objects go into the
    analyser's knowledge."""

    run_id: str
    kind: str
    name: AnalysisKind
    lines: tuple[str, ...]
    results: dict[str, Any]
    error: str = ""
    omitted: tuple[str, ...] = ()
    flags: tuple[Flag, ...] = ()

    @property
    def status(self) -> AnalysisStatus:
        """Failed with an error, partial with something omitted, else complete."""
        if self.error:
            return AnalysisStatus.FAILED
        return AnalysisStatus.PARTIAL if self.omitted else AnalysisStatus.COMPLETE

    @classmethod
    def failed(cls, run_id: str, kind: str, reason: str) -> RunAnalysis:
        """The analysis of a run that failed for ``reason``: a flag, the reason as its result."""
        lines = (flag(FlagCode.ANALYSIS_FAILED, f"analysis failed: {reason}"),)
        return cls(run_id, kind, AnalysisKind.FAILED, lines, {"error": reason}, reason, flags=flags_of(lines))


@dataclass(frozen=True)
class CampaignAnalysis:
    """A campaign file analysed: where it came from (``path``, ``software_version``,
    ``sequence_name``, ``config_source``: the stored configuration's name, or ``"defaults"``),
    the masses taken as given, what the runs established (``knowledge``: sensor, plate masses'
    records, shaker results per pressure, hammer and four-post results), each analysed run in
    order (``runs``), the runs not analysed because they did not complete (``skipped``: run id
    and status), the hammer blow's record (``hammer_record``, for its figure; None without a
    hammer run) and the four-post sweep's (``sweep_record``, likewise). ``sequences``: every
    sequence whose runs the file holds, as (name in its run ids,
    number of runs) in the order they ran: the one that created the file (``sequence_name``) and
    those appended to it later. ``metadata``: the campaign's test metadata (field -> text, empty
    when not given; :mod:`sequences.metadata`). ``run_pressures_bar``: the tyre pressure each run
    records (its ``set_tyre_pressure`` answer), by run id; a run without one is absent.
    ``source``: where the runs' analyses come from, as a reader says it (the records the analysis
    stored after each run, or a refit and why); ``stored``: whether they are the stored records;
    ``records``: the records of the runs analysed here (run id -> the record's text), which a file
    without them can keep (:func:`~bench.app.analyze.store_reanalysis`)."""

    path: Path
    software_version: str
    sequence_name: str
    config_source: str
    sensor_mass_kg: float
    wheel_mass_kg: float
    knowledge: CampaignKnowledge
    runs: tuple[RunAnalysis, ...]
    skipped: tuple[tuple[str, str], ...]
    hammer_record: HammerRecord | None
    sequences: tuple[tuple[str, int], ...] = ()
    sweep_record: SweepRecord | None = None
    metadata: Mapping[str, str] = field(default_factory=dict)
    run_pressures_bar: dict[str, float] = field(default_factory=dict)
    source: str = ""
    stored: bool = False
    records: dict[str, str] = field(default_factory=dict)

    @property
    def status(self) -> AnalysisStatus:
        """``complete`` when every run's analysis is complete, else ``partial`` (runs that did not
        complete are not analysed and do not count)."""
        done = all(run.status is AnalysisStatus.COMPLETE for run in self.runs)
        return AnalysisStatus.COMPLETE if done else AnalysisStatus.PARTIAL

    @property
    def not_complete(self) -> tuple[RunAnalysis, ...]:
        """The runs whose analysis failed or is partial, in order."""
        return tuple(run for run in self.runs if run.status is not AnalysisStatus.COMPLETE)
