"""``wfsbench check``: a sequence validated and dry-run on a bench, without opening any device.

Lists the steps with their points and estimated durations, the sequence's totals, what the runs
will not let the analysis give (:mod:`bench.app.analysis_plan`), the largest predicted loads of the
bench model with the point where each occurs, and every refusal.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

from bench.app.analysis_plan import analysis_limits
from bench.app.durations import sequence_estimate_text
from bench.config import BenchConfig
from bench.dry_run import DryRun
from sequences import (
    DriveIteration,
    DwellGrid,
    FreeRun,
    HammerTest,
    Prompt,
    RoadReplay,
    Sequence,
    SineDwell,
    Sweep,
    TrackedDwell,
)
from sequences.runs import RunKind
from sequences.steps import Step


def step_line(index: int, step: Step) -> str:
    """One line that says what a step does."""
    if step.run_kind is not None:
        what = RUN_DESCRIPTIONS[step.run_kind](step)
    elif isinstance(step, Prompt):
        what = f"ask: {step.text}"
    else:
        what = ", ".join(f"{f.name}={getattr(step, f.name)}" for f in dataclasses.fields(step)) or "-"
    return f"steps[{index}] {step.kind}: {what} (~{step.estimated_duration_s:.0f} s)"


def _dwells_text(step: SineDwell | DwellGrid | FreeRun) -> str:
    dwells = step.dwells()
    freqs = sorted({d.freq_hz for d in dwells})
    amplitudes = sorted({d.requested_amplitude_mm or d.amplitude_mm for d in dwells})
    lowered = sum(d.amplitude_limited_by is not None for d in dwells)
    limited = f", {lowered} lowered by a bench limit" if lowered else ""
    if len(dwells) == 1:
        return f"dwell {freqs[0]:g} Hz at {amplitudes[0]:g} mm{limited}"
    return (
        f"{len(dwells)} dwells {freqs[0]:g}-{freqs[-1]:g} Hz at"
        f" {' / '.join(f'{a:g}' for a in amplitudes)} mm{limited}"
    )


def _sweep_text(step: Sweep) -> str:
    return (
        f"{step.law} sweep {step.start_hz:g}-{step.end_hz:g} Hz in {step.duration_s:g} s"
        f" at {step.amplitude_mm:g} mm"
    )


def _tracked_dwell_text(step: TrackedDwell) -> str:
    return (
        f"search {step.search_points} dwells {step.search_start_hz:g}-{step.search_end_hz:g} Hz at"
        f" {step.amplitude_mm:g} mm for the resonance of {step.output} / {step.input}, then track it"
        f" for {step.track_length_s:g} s"
    )


def _road_replay_text(step: RoadReplay) -> str:
    if step.generated:
        return (
            f"ISO 8608 class {step.road_class} road at {step.speed_km_h:g} km/h for"
            f" {step.duration_s:g} s (seed {step.seed}), on {step.mean_mm:g} mm"
        )
    cut = f", its first {step.duration_s:g} s" if step.duration_s else ""
    column = f" ({step.channel})" if step.channel else ""
    return f"drive file {step.file}{column}{cut}, on {step.mean_mm:g} mm"


def _drive_iteration_text(step: DriveIteration) -> str:
    channel = f" ({step.target_channel})" if step.target_channel else ""
    cut = f", its first {step.duration_s:g} s" if step.duration_s else ""
    judged, corrected = step.error_band_hz, step.band_hz
    return (
        f"iterate a drive until the {step.response.replace('_', ' ')} matches {step.target}{channel}{cut}"
        f" in {judged[0]:g}-{judged[1]:g} Hz (corrected in {corrected[0]:g}-{corrected[1]:g} Hz):"
        f" {step.identification} identification at {step.identification_rms_mm:g} mm rms for"
        f" {step.identification_s:g} s, then at most {step.max_iterations} iterations (gain {step.gain:g})"
        f" to below {step.rms_error_pct:g} % rms error, on {step.mean_mm:g} mm"
    )


def _hammer_text(step: HammerTest) -> str:
    return f"{step.blows} blows, trigger {step.trigger_level_n:g} N, {step.capture_s:g} s captures"


#: What each kind of run's step does, in words (tests/test_run_kind_tables.py: every kind is here).
RUN_DESCRIPTIONS: dict[RunKind, Callable[[Any], str]] = {
    RunKind.DWELL_GRID: _dwells_text,
    RunKind.FREE_RUN: _dwells_text,
    RunKind.SWEEP: _sweep_text,
    RunKind.TRACKED_DWELL: _tracked_dwell_text,
    RunKind.ROAD_REPLAY: _road_replay_text,
    RunKind.DRIVE_ITERATION: _drive_iteration_text,
    RunKind.HAMMER: _hammer_text,
}


def check_lines(sequence: Sequence, config: BenchConfig, dry: DryRun) -> list[str]:
    """The check's report, refusals last."""
    lines = [f"sequence {sequence.name} ({sequence.source}) on the {config.kind} bench ({config.source})"]
    lines += [f"  {step_line(i, step)}" for i, step in enumerate(sequence.steps)]
    lines.append(sequence_estimate_text(sequence))
    limits = analysis_limits(sequence, config)
    if limits:
        lines.append(f"ANALYSIS LIMITED ({len(limits)}): what the runs will not let the analysis give:")
        lines += [f"  - {limit}" for limit in limits]
    else:
        lines.append("analysis: every run can be analysed in full")
    if dry.points:
        for quantity, unit, limit in (
            ("actuator_force_n", "N", config.limits.force_n),
            ("wfs_load_n", "N", config.limits.wfs_force_n),
            ("acceleration_m_s2", "m/s^2", config.limits.acceleration_m_s2),
            ("velocity_mm_s", "mm/s", config.limits.velocity_mm_s),
        ):
            worst = max(dry.points, key=lambda p, q=quantity: getattr(p, q))
            lines.append(
                f"largest {quantity}: {getattr(worst, quantity):.5g} {unit} at {worst.label}"
                f" (limit {limit:g} {unit})"
            )
    if dry.refusals:
        lines.append(
            f"REFUSED ({len(dry.refusals)}): steps this bench cannot do, points beyond its limits:"
        )
        lines += [f"  {refusal}" for refusal in dry.refusals]
    else:
        lines.append("every point within the bench's limits: nothing refused")
    return lines
