"""One point of a dwell run: its attempts, repeated with a corrected command while the achieved
amplitude is off, each published as it ends.

The dwell grids, the free run, the adaptive grid's dwells and a tracked dwell's search all run their
points here; a tracked dwell's track publishes its one point here too.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from bench.engine import events as ev
from bench.engine.amplitude import ServoGains, amplitude_mm
from bench.engine.amplitude_hold import HeldAmplitude
from bench.engine.contracts import Notch
from bench.engine.online import DwellVerdict, OnlineDwell
from bench.engine.points import ExcitationSpan
from bench.engine.procedures.held_amplitude import held_amplitude
from bench.engine.recording import PointInterruptedError, RunRecording
from bench.engine.run_context import RunContext
from bench.engine.tracking import TrackWatch
from drivers.setpoints import DwellSetpoint
from sequences import AdaptiveDwell, FreeRun, SineDwell
from sequences.points import PointStatus


@dataclass(frozen=True)
class PointPlan:
    """What a point's attempts share: its index, dwell, nominal amplitude and why it was added."""

    index: int
    dwell: SineDwell
    requested_mm: float
    added_reason: str = ""
    notch: Notch | None = None


def run_point(
    context: RunContext,
    recording: RunRecording,
    index: int,
    dwell: SineDwell,
    *,
    plan: AdaptiveDwell | None = None,
    added_reason: str = "",
    gains: ServoGains | None = None,
) -> DwellVerdict | None:
    """One dwell, repeated with a corrected command while the achieved amplitude is off.

    With ``plan`` the hold lasts until the dwell's online verdicts (at most ``max_hold_s``) and
    the kept attempt's verdict is returned. With ``gains`` the first command is the one the
    servo gains measured so far expect to reach the target (within the command limit), and
    every attempt adds its gain. Where a response would pass a response limit's notch level the
    dwell's amplitude is lowered to what the notching allows (its nominal one recorded as
    requested)."""
    notch = None
    if context.notching is not None:
        specimen = not isinstance(recording.step, FreeRun)
        notch = context.notching.dwell(
            dwell.freq_hz, dwell.amplitude_mm, context.conditions, specimen=specimen
        )
    if notch is not None:
        nominal = dwell.requested_amplitude_mm or dwell.amplitude_mm
        dwell = replace(dwell, amplitude_mm=notch.amplitude_mm, requested_amplitude_mm=nominal)
    command_mm, corrections, attempt = dwell.amplitude_mm, 0, 0
    if gains is not None:
        command_mm = min(
            gains.command_mm(dwell.freq_hz, dwell.amplitude_mm),
            context.amplitude_control.command_cap_mm(dwell.amplitude_mm),
        )
    requested = dwell.requested_amplitude_mm or dwell.amplitude_mm
    hold_s = dwell.hold_s if plan is None else plan.max_hold_s
    while True:
        context.checkpoint()
        attempt += 1
        started = ev.PointStarted(
            recording.run_id, index, attempt, dwell.freq_hz, command_mm, dict(context.conditions)
        )
        context.publish(started)
        setpoint = DwellSetpoint(
            dwell.freq_hz,
            command_mm,
            dwell_s=hold_s,
            taper_in_s=dwell.taper_in_s,
            taper_out_s=dwell.taper_out_s,
            mean_mm=context.mean_mm(dwell.mean_mm),
        )
        watch = (
            None
            if plan is None
            else OnlineDwell(
                dwell.freq_hz,
                context.sample_rate_hz,
                plan,
                context.channels.displacement,
                present=context.frames_present,
            )
        )
        held = None
        if plan is None:
            held = held_amplitude(
                context, recording, dwell, index=index, attempt=attempt, command_mm=command_mm
            )
        point = PointPlan(index, dwell, requested, added_reason, notch)
        planned_s = dwell.taper_in_s + hold_s + dwell.taper_out_s
        span = excite_point(
            context,
            recording,
            point,
            attempt,
            setpoint,
            command_mm=command_mm,
            planned_s=planned_s,
            watch=watch,
            held=held,
        )
        if span is None:
            continue
        verdict = None if watch is None else watch.verdict()
        sent_mm = command_mm
        if verdict is None:  # held within the dwell, the hold is the part after the last update's ramp
            command_mm = command_mm if held is None else held.command_mm
        achieved, lost = _measured(context, recording, span, dwell, verdict)
        if not lost:  # nothing is learnt from what the bench did not see
            if gains is not None:
                gains.record(dwell.freq_hz, command_mm, achieved)
            recording.check_excursion(dwell.amplitude_mm, achieved, f"point {index} attempt {attempt}")
        decision = context.amplitude_control.decide(
            dwell.amplitude_mm, command_mm, achieved, corrections, refusal=lost
        )
        status = PointStatus.DONE if decision.keep else PointStatus.REPEATED
        publish_point(
            context,
            recording,
            point,
            attempt,
            status,
            command_mm=sent_mm,
            span=span,
            achieved_mm=achieved,
            note="; ".join(n for n in (held.refusal if held else "", decision.note) if n),
            verdict=verdict,
            held=held,
        )
        if decision.keep:
            return verdict
        command_mm, corrections = decision.corrected_mm, corrections + 1


def excite_point(
    context: RunContext,
    recording: RunRecording,
    point: PointPlan,
    attempt: int,
    setpoint: DwellSetpoint,
    *,
    command_mm: float,
    planned_s: float,
    watch: OnlineDwell | TrackWatch | None = None,
    held: HeldAmplitude | None = None,
) -> ExcitationSpan | None:
    """Excite attempt ``attempt`` at ``point`` (``setpoint``, its amplitude ``command_mm``) and
    return its span. An attempt a pause interrupted is published as ``interrupted``, and None
    returned once the pause is over: the point is tried again."""
    try:
        return recording.excite(setpoint, planned_s=planned_s, watch=watch, held=held)
    except PointInterruptedError as interrupted:
        status, span = PointStatus.INTERRUPTED, interrupted.span
        publish_point(context, recording, point, attempt, status, command_mm=command_mm, span=span)
        context.wait_paused()
        return None


def _measured(
    context: RunContext,
    recording: RunRecording,
    span: ExcitationSpan,
    dwell: SineDwell,
    verdict: DwellVerdict | None,
) -> tuple[float, str]:
    """The amplitude (mm) an attempt achieved over its hold (the adaptive dwell's measured part,
    or the hold after its settling time), and why it may not be decided on (empty: it may):
    frames lost, or none of its hold left to measure because they were."""
    if verdict is not None:
        achieved = 1e3 * abs(verdict.displacement_m)
        present, span_samples = verdict.frames_present, verdict.span_samples
    else:
        fit = recording.achieved_fit(span, dwell)
        achieved = amplitude_mm(fit)
        present, span_samples = (0, 0) if fit is None else (fit.frames_present, fit.span_samples)
    if span_samples:
        lost = context.frames_present.refusal_of(present, span_samples, dwell.freq_hz, context.sample_rate_hz)
    else:
        missing = recording.frames_missing_between(span.hold_start, span.hold_end)
        lost = f"holds no cycle: {missing} frames lost" if missing else ""
    return achieved, f"the hold's measurement {lost}" if lost else ""


def publish_point(
    context: RunContext,
    recording: RunRecording,
    point: PointPlan,
    attempt: int,
    status: str,
    *,
    command_mm: float,
    span: ExcitationSpan,
    achieved_mm: float = float("nan"),
    note: str = "",
    verdict: DwellVerdict | None = None,
    held: HeldAmplitude | None = None,
    tracked: str | None = None,
) -> None:
    """Publish attempt ``attempt`` at ``point``, with its ``status``, the amplitude commanded
    (``command_mm``) and achieved, its ``span`` and ``note``, and what an adaptive dwell's
    ``verdict``, a ``held`` amplitude, a notch or a track's verdict (``tracked``) add."""
    adaptive: dict[str, object] = {}  # what an adaptive dwell, a held amplitude or a notch adds
    if point.notch is not None:
        adaptive = {
            "notched_by": point.notch.limit,
            "notch_start_hz": point.notch.start_hz,
            "notch_end_hz": point.notch.end_hz,
            "notch_amplitude_mm": point.notch.amplitude_mm,
        }
    if held is not None and held.updates:
        adaptive |= {
            "amplitude_updates": held.updates,
            "held_amplitude_mm": held.command_mm,
        }
    if tracked is not None:
        adaptive |= {"verdict": tracked}
    if verdict is not None:
        measure_start = -1
        if np.isfinite(verdict.measure_start_s):
            measured_after = round(verdict.measure_start_s * context.sample_rate_hz)  # in sample times
            measure_start = recording.sample_at(span.hold_start, measured_after)
        adaptive |= {
            "verdict": verdict.verdict,
            "settle_s": verdict.settle_s,
            "measure_start_sample": min(measure_start, span.hold_end),
            "magnitude_uncertainty_pct": verdict.magnitude_uncertainty_pct,
            "phase_uncertainty_deg": verdict.phase_uncertainty_deg,
        }
    context.publish(
        recording.point_done(
            point.index,
            point.dwell.freq_hz,
            point.dwell.amplitude_mm,
            span,
            status=status,
            attempt=attempt,
            requested_amplitude_mm=point.requested_mm,
            commanded_amplitude_mm=command_mm,
            achieved_amplitude_mm=achieved_mm,
            note=note,
            added_reason=point.added_reason,
            **adaptive,
        )
    )
