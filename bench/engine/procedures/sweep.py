"""A sweep run: one linear or logarithmic sine sweep, notched where a response would pass a
response limit's notch level (if the actuator notches sweeps), recorded as the run's one point."""

from __future__ import annotations

import logging

import numpy as np

from bench.engine.contracts import Notch
from bench.engine.points import ExcitationSpan, sweep_time_s
from bench.engine.procedures.one_excitation import publish_whole, run_one_excitation
from bench.engine.recording import RunRecording
from bench.engine.run_context import MeasurementRun, RunContext
from drivers.setpoints import SweepNotch, SweepSetpoint
from sequences import Sweep

log = logging.getLogger(__name__)


def run_sweep(context: RunContext, run: MeasurementRun) -> None:
    """The sweep of ``run.step``, repeated whole from its start after a pause."""
    step = run.step
    notch = _sweep_notch(context, step)
    setpoint = SweepSetpoint(
        step.start_hz,
        step.end_hz,
        step.duration_s,
        step.amplitude_mm,
        spacing=step.law,
        taper_in_s=step.taper_in_s,
        taper_out_s=step.taper_out_s,
        mean_mm=context.mean_mm(step.mean_mm),
        notch=None if notch is None else SweepNotch(notch.start_hz, notch.end_hz, notch.amplitude_mm),
    )
    with RunRecording(context, run) as recording:

        def publish(status: str, attempt: int, span: ExcitationSpan) -> None:
            _publish_sweep(context, recording, setpoint, span, status=status, attempt=attempt, notch=notch)

        run_one_excitation(context, recording, setpoint, step.duration_s, publish)


def _sweep_notch(context: RunContext, step: Sweep) -> Notch | None:
    """The notch of a sweep where a response would pass a limit's notch level, if the actuator
    notches sweeps (a controller without the notch registers: none, the limits' actions guard)."""
    if context.notching is None:
        return None
    notch = context.notching.sweep(step, context.conditions)
    if notch is not None and not getattr(context.actuator, "sweep_notches", False):
        log.warning("the controller notches no sweep: %s would be notched by %s", step, notch.limit)
        return None
    return notch


def _publish_sweep(
    context: RunContext,
    recording: RunRecording,
    setpoint: SweepSetpoint,
    span: ExcitationSpan,
    *,
    status: str,
    attempt: int,
    notch: Notch | None,
) -> None:
    """The sweep's one point: ``done``, or ``interrupted`` by a pause (the sweep is repeated from
    its start on resume); a notched sweep with its notch and the amplitude reached within it."""
    notched = {}
    if notch is not None:
        t1, t2 = sorted(sweep_time_s(setpoint, f) for f in (notch.start_hz, notch.end_hz))
        first, last = (recording.sample_at(span.start, round(t * context.sample_rate_hz)) for t in (t1, t2))
        z = recording.displacement_between(first, min(last, span.end))
        notched = {
            "notched_by": notch.limit,
            "notch_start_hz": notch.start_hz,
            "notch_end_hz": notch.end_hz,
            "notch_amplitude_mm": notch.amplitude_mm,
            "achieved_amplitude_mm": 1e3 * float(np.ptp(z)) / 2 if z.size else float("nan"),
        }
    commanded = (setpoint.start_hz, setpoint.amplitude_mm)
    publish_whole(context, recording, commanded, span, status=status, attempt=attempt, **notched)
