"""``wfsbench show FILE``: what a campaign file holds, read without changing a byte of it.

:func:`campaign_summary` gathers, as one JSON-ready mapping (schema ``wfs-bench-show``, version
:data:`VERSION`, docs/cli.md): the file's origin, the test metadata, the specimen as configured,
and every run in the order it began with its kind, status and reason, points done of planned,
conditions (tyre pressure, wheel fitted, amplitudes, frequency span) and the analyses stored
beside it with when. :func:`summary_lines` words it for a person.

Read-only by construction: the file is opened read-only (HDF5 then writes nothing, and the file's
bytes and modification time stay as they were), no lock is taken (no lock file is created) and
nothing is written beside it. A file a process is writing is refused
(:class:`~bench.store.schema.CampaignInUseError`, naming the process where its writer lock says):
without SWMR (docs/hdf5.md), HDF5 promises a reader nothing while the writer flushes, so what a
reader saw could mix two flushes; the writer's own progress display shows a running campaign.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bench import locks
from bench.analysis.campaign import AnalysisKind
from bench.app.analyze import CampaignFileError, sequences_run, stored_config
from bench.config import BenchConfig
from bench.report.metadata import metadata_lines
from bench.store import CampaignFile, RunView, StoreError, open_campaign
from bench.store.schema import CampaignInUseError, campaign_key
from sequences import (
    DriveIteration,
    DwellGrid,
    FreeRun,
    HammerTest,
    RoadReplay,
    Sequence,
    SequenceError,
    SineDwell,
    Step,
    Sweep,
    TrackedDwell,
)
from sequences.loader import step_from_fields
from sequences.metadata import LABELS
from sequences.points import PointStatus
from sequences.runs import EventKind, RunKind

SCHEMA = "wfs-bench-show"
#: Version 1 only gains keys; renaming or removing one, or changing its meaning, makes version 2.
VERSION = 1


def campaign_summary(path: str | Path) -> dict[str, Any]:
    """What the campaign file at ``path`` holds (module docstring); :class:`StoreError` naming the
    file when it is no campaign file (missing, not HDF5, another layout, truncated, damaged), a
    :class:`CampaignInUseError` when a process is writing it."""
    path = Path(path)
    holder = locks.holder_of(campaign_key(path))  # only looks: creates no lock file
    if holder is not None:
        raise CampaignInUseError(path, holder, "show it once that has finished")
    with open_campaign(path) as campaign:
        try:
            return _summary(campaign)
        except (OSError, RuntimeError, KeyError) as err:  # HDF5 failing on a damaged object
            raise StoreError(path, "", f"damaged: {err}") from err


def _summary(campaign: CampaignFile) -> dict[str, Any]:
    try:
        config, source = stored_config(campaign.path, campaign.config_toml, campaign.config_name)
        config_problem = ""
    except CampaignFileError as err:
        config, source, config_problem = None, campaign.config_name or "stored", str(err)
    return {
        "schema": SCHEMA,
        "version": VERSION,
        "file": str(campaign.path),
        "schema_version": campaign.schema_version,
        "software_version": campaign.software_version,
        "created": campaign.created,
        "sequence_name": campaign.sequence_name,
        "sequences": [
            {"name": name, "runs": n} for name, n in sequences_run(run.run_id for run in campaign.runs)
        ],
        "configuration": source,
        "configuration_error": config_problem or None,
        "metadata": dict(campaign.metadata),
        "specimen": _specimen(config),
        "runs": [_run(run) for run in campaign.runs],
    }


def _specimen(config: BenchConfig | None) -> dict[str, Any] | None:
    """What the stored configuration says stands on the bench (None: it cannot be read)."""
    if config is None:
        return None
    s = config.specimen
    return {
        "bench": config.kind,
        "tyre_model": s.tyre_model,
        "tyre_nonlinear": s.nonlinear,
        "tyre_pressure_bar": s.tyre_pressure_bar,
        "wheel_fitted": s.wheel_fitted,
        "wheel_below_sensor_kg": config.masses.wheel_below_sensor_kg,
        "sensor_kg": config.masses.sensor_kg,
    }


#: The excitation of a run: its nominal amplitudes (mm) and frequency span (Hz; None: a hammer blow).
Excitation = tuple[list[float], list[float] | None]


def _planned(run: RunView) -> tuple[int, Excitation] | None:
    """The points the run's step plans and its excitation, None when the run's ``step`` is no step
    of the vocabulary (a CSV import's description, another writer's, values of the wrong type)."""
    try:
        step = step_from_fields(run.step, f"{run.path}:/runs/{run.run_id}@step")
        return Sequence("", "", (step,)).points(), _step_excitation(step)
    except (SequenceError, TypeError, ValueError):
        return None


def _step_excitation(step: Step) -> Excitation:
    if step.run_kind is None:
        raise ValueError(f"a {step.kind} step records no run")
    return EXCITATIONS[step.run_kind](step)


def _dwells_excitation(step: SineDwell | DwellGrid | FreeRun) -> Excitation:
    """The grid's nominal amplitudes (before a bench limit lowered any) and its frequency span."""
    dwells = step.dwells()
    freqs = [float(d.freq_hz) for d in dwells]
    amplitudes = sorted({float(d.requested_amplitude_mm or d.amplitude_mm) for d in dwells})
    return amplitudes, [min(freqs), max(freqs)]


def _sweep_excitation(step: Sweep) -> Excitation:
    return [float(step.amplitude_mm)], [float(step.start_hz), float(step.end_hz)]


def _tracked_dwell_excitation(step: TrackedDwell) -> Excitation:
    """The search's band (the track follows the resonance found in it)."""
    return [float(step.amplitude_mm)], [float(step.search_start_hz), float(step.search_end_hz)]


def _no_excitation(step: HammerTest | RoadReplay) -> Excitation:
    """A blow or a road: no amplitude or frequency span of a sine."""
    return [], None


def _iteration_excitation(step: DriveIteration) -> Excitation:
    """A drive computed from the rig's response: no amplitude stated, the band it is matched in."""
    return [], [float(step.band_hz[0]), float(step.band_hz[1])]


#: The excitation each kind of run's step states (tests/test_run_kind_tables.py: every kind is here).
EXCITATIONS: dict[RunKind, Callable[[Any], Excitation]] = {
    RunKind.DWELL_GRID: _dwells_excitation,
    RunKind.FREE_RUN: _dwells_excitation,
    RunKind.SWEEP: _sweep_excitation,
    RunKind.TRACKED_DWELL: _tracked_dwell_excitation,
    RunKind.ROAD_REPLAY: _no_excitation,
    RunKind.DRIVE_ITERATION: _iteration_excitation,
    RunKind.HAMMER: _no_excitation,
}


def _recorded_excitation(run: RunView) -> Excitation:
    """The excitation of a run whose step is of no known form: a sweep's from its step's
    ``start_hz``, ``end_hz`` and ``amplitude_mm`` (which every sweep record has), else from the
    points it did (their nominal amplitudes, their frequencies)."""
    if run.kind == RunKind.SWEEP and all(
        isinstance(run.step.get(k), int | float) for k in ("start_hz", "end_hz")
    ):
        amplitude = run.step.get("amplitude_mm")
        amplitudes = [float(amplitude)] if isinstance(amplitude, int | float) else []
        return amplitudes, [float(run.step["start_hz"]), float(run.step["end_hz"])]
    done = [p for p in run.points if p.status == PointStatus.DONE]
    nominal = {
        p.requested_amplitude_mm if math.isfinite(p.requested_amplitude_mm) else p.amplitude_mm for p in done
    }
    freqs = [p.freq_hz for p in done if p.freq_hz > 0]
    amplitudes = sorted(a for a in nominal if math.isfinite(a) and a > 0)
    return amplitudes, [min(freqs), max(freqs)] if freqs else None


def _run(run: RunView) -> dict[str, Any]:
    planned = _planned(run)
    points_planned, (amplitudes_mm, span_hz) = planned if planned else (None, _recorded_excitation(run))
    wheel = run.conditions.get("wheel_fitted")
    pressure = run.conditions.get("tyre_pressure_bar")
    is_number = isinstance(pressure, int | float) and not isinstance(pressure, bool)
    pressure = finite_or_none(pressure) if is_number else None
    return {
        "run_id": run.run_id,
        "kind": run.kind,
        "status": run.status,
        "reason": run.reason,
        "started": run.started,
        "finished": run.finished,
        "metadata": dict(run.metadata),
        "points_done": len({p.index for p in run.points if p.status == PointStatus.DONE}),
        "points_done_in_step": len(run.completed_point_indices()),
        "points_planned": points_planned,
        "tyre_pressure_bar": pressure,
        "wheel_fitted": wheel if isinstance(wheel, bool) else None,
        "amplitudes_mm": amplitudes_mm,
        "freq_span_hz": span_hz,
        "conditions": finite_or_none(run.conditions),
        "samples": run.n_samples,
        "sample_rate_hz": run.sample_rate_hz,
        "frames_lost": sum(int(e.fields.get("missing", 0)) for e in run.events if e.kind == EventKind.GAP),
        "gaps": sum(e.kind == EventKind.GAP for e in run.events),
        "resumes": run.resumes,
        "resumed_by": run.resumed_by,
        # a drive iteration's drive samples stay in the file (wfsbench export --format drive)
        "drive": {k: v for k, v in run.drive.items() if k != "samples_mm"} or None,
        "analyses": [{"name": name, "stored": run.result_stored(name) or None} for name in run.result_names],
        "iteration": _iteration(run),
    }


#: What ``show`` gives of a drive iteration's stored result (docs/analysis-json.md, ``iterations[]``).
ITERATION_KEYS = ("iteration", "rms_error_pct", "in_band_pct", "damage_ratio", "stop_rules_met")


def _iteration(run: RunView) -> dict[str, Any] | None:
    """A drive iteration's errors as the post-run analysis stored them, None for another run or
    one not analysed."""
    if AnalysisKind.DRIVE_ITERATION not in run.result_names:
        return None
    stored = run.results(AnalysisKind.DRIVE_ITERATION)
    return {key: finite_or_none(stored.get(key)) for key in ITERATION_KEYS}


def _iteration_line(done: dict[str, Any]) -> str:
    """A drive iteration's errors in words (a value not stored, or not a number: said so)."""

    def number(key: str, unit: str = "") -> str:
        value = done[key]
        return "not stored" if value is None else f"{value:.3g}{unit}"

    band = done["in_band_pct"]
    inside = "no band (a raw target)" if band is None else f"{band:.1f} % inside the target's band"
    stopped = "the step's stop rules met" if done["stop_rules_met"] else "the stop rules not met"
    return (
        f"iteration {done['iteration']}: rms error {number('rms_error_pct', ' %')} of the target's rms,"
        f" {inside}, damage ratio {number('damage_ratio')}; {stopped}"
    )


def finite_or_none(value: Any) -> Any:
    """``value`` with every non-finite number as None (the JSON holds no NaN)."""
    if isinstance(value, dict):
        return {k: finite_or_none(v) for k, v in value.items()}
    if isinstance(value, list):
        return [finite_or_none(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _numbers(values: list[float], unit: str) -> str:
    return f"{' / '.join(f'{v:g}' for v in values)} {unit}"


def _points(run: dict[str, Any]) -> str:
    planned = run["points_planned"]
    done = f"{run['points_done']} of {planned}" if planned is not None else f"{run['points_done']}"
    text = f"points {done} done" + ("" if planned is not None else " (planned: not recorded)")
    if run["points_done_in_step"] != run["points_done"]:
        text += f" ({run['points_done_in_step']} with the run(s) it resumes)"
    return text


def _conditions(run: dict[str, Any]) -> str:
    parts = []
    if run["freq_span_hz"] is not None:
        low, high = run["freq_span_hz"]
        parts.append(f"{low:g} Hz" if low == high else f"{low:g}-{high:g} Hz")
    if run["amplitudes_mm"]:
        parts.append(f"at {_numbers(run['amplitudes_mm'], 'mm')}")
    pressure = run["tyre_pressure_bar"]
    parts.append(f"tyre {pressure:g} bar" if pressure is not None else "tyre pressure not recorded")
    wheel = {True: "wheel fitted", False: "wheel removed", None: "wheel not asked"}[run["wheel_fitted"]]
    return ", ".join([*parts, wheel])


def summary_lines(summary: dict[str, Any]) -> list[str]:
    """The summary as text: the file, its metadata and specimen, then one block per run."""
    runs = summary["runs"]
    sequences = ", ".join(
        f"{s['name']} ({s['runs']} run{'' if s['runs'] == 1 else 's'})" for s in summary["sequences"]
    )
    lines = [
        f"{summary['file']}: campaign file, schema version {summary['schema_version']}, written by"
        f" wfs-bench {summary['software_version']}, created {summary['created']}",
        f"sequence that created it: {summary['sequence_name']}; sequences run: {sequences or 'none'}",
        f"configuration: {summary['configuration']}",
        "metadata:",
        *metadata_lines(summary["metadata"]),
    ]
    specimen = summary["specimen"]
    if specimen is None:
        lines.append(f"specimen: unknown: {summary['configuration_error']}")
    else:
        lines.append(
            f"specimen as configured: {specimen['bench']} bench, tyre Model {specimen['tyre_model']}"
            f" ({'non-linear' if specimen['tyre_nonlinear'] else 'linear'}), wheel below the sensor"
            f" {specimen['wheel_below_sensor_kg']:g} kg, sensor {specimen['sensor_kg']:g} kg; before the"
            f" first prompt: {specimen['tyre_pressure_bar']:g} bar, wheel"
            f" {'fitted' if specimen['wheel_fitted'] else 'removed'}"
        )
    lines.append(f"runs ({len(runs)}):" if runs else "runs: none")
    for run in runs:
        why = f": {run['reason']}" if run["reason"] else ""
        lines.append(f"  {run['run_id']}  {run['kind']}  {run['status']}{why}")
        lines.append(f"    {_points(run)}; {_conditions(run)}")
        rate = run["sample_rate_hz"]
        lines.append(
            f"    {run['samples']} samples at {rate:g} Hz ({run['samples'] / rate:.1f} s);"
            f" started {run['started']}, finished {run['finished'] or '-'}"
        )
        if run["frames_lost"]:
            lines.append(
                f"    {run['frames_lost']} frames lost on the WFS link in {run['gaps']} gaps"
                " (each point's in its points table: frames_missing)"
            )
        who = run["metadata"]
        by = [f"{LABELS[k]} {who[k]}" for k in ("operator", "bench_id") if who.get(k)]
        if by:
            lines.append(f"    {'; '.join(by)}")
        if who.get("notes"):
            lines.append(f"    notes: {' / '.join(who['notes'].splitlines())}")
        if run["drive"]:
            drive = run["drive"]
            lines.append(f"    drive: {drive.get('source', '?')}; sha256 {drive.get('sha256', '?')}")
        if (done := run["iteration"]) is not None:
            lines.append(f"    {_iteration_line(done)}")
        for key, word in (("resumes", "resumes"), ("resumed_by", "resumed by")):
            if run[key]:
                lines.append(f"    {word} {run[key]}")
        analyses = [f"{a['name']} ({a['stored'] or 'stored at an unknown time'})" for a in run["analyses"]]
        lines.append(f"    analyses stored: {', '.join(analyses) or 'none'}")
    return lines
