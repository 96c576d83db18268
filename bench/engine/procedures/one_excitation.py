"""A run that is one excitation (a sweep, a road replay): excited whole until done, its one point
published as it ends."""

from __future__ import annotations

from collections.abc import Callable

from bench.engine.points import ExcitationSpan
from bench.engine.recording import PointInterruptedError, RunRecording
from bench.engine.run_context import RunContext
from drivers.setpoints import DriveSetpoint, SweepSetpoint
from sequences.points import PointStatus


def run_one_excitation(
    context: RunContext,
    recording: RunRecording,
    setpoint: SweepSetpoint | DriveSetpoint,
    planned_s: float,
    publish: Callable[[str, int, ExcitationSpan], None],
) -> None:
    """A run that is one excitation (a sweep, a road replay), its point published with
    ``publish(status, attempt, span)``: a pause interrupts it (``interrupted``), and on resume it
    runs again whole, from its start, until it is ``done``."""
    attempt = 0
    while True:
        context.checkpoint()
        attempt += 1
        try:
            span = recording.excite(setpoint, planned_s=planned_s)
        except PointInterruptedError as interrupted:
            publish(PointStatus.INTERRUPTED, attempt, interrupted.span)
            context.wait_paused()
            continue
        publish(PointStatus.DONE, attempt, span)
        return


def publish_whole(
    context: RunContext,
    recording: RunRecording,
    commanded: tuple[float, float],
    span: ExcitationSpan,
    *,
    status: str,
    attempt: int,
    **measured: object,
) -> None:
    """The one point (index 0) of a run that is one excitation (a sweep, a road replay), as
    ``commanded``: at a frequency (a sweep's start) and an amplitude (mm), over ``span``, its
    ``status`` and ``attempt``; ``measured``: what the excitation showed (its achieved amplitude, a notch)."""
    freq_hz, amplitude_mm = commanded
    context.publish(
        recording.point_done(
            0,
            freq_hz,
            amplitude_mm,
            span,
            status=status,
            attempt=attempt,
            requested_amplitude_mm=amplitude_mm,
            commanded_amplitude_mm=amplitude_mm,
            **measured,
        )
    )
