"""A road replay run: the planned drive uploaded to the controller, then played once as the run's
one point."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from bench.engine.points import ExcitationSpan
from bench.engine.procedures.one_excitation import publish_whole, run_one_excitation
from bench.engine.recording import RunRecording
from bench.engine.run_context import MeasurementRun, RunContext
from bench.engine.stops import RunStoppedError
from drivers.setpoints import DriveSetpoint


def run_road_replay(context: RunContext, run: MeasurementRun) -> None:
    """A road replay: the drive given to the controller once the run has begun, before its
    stream starts (an upload takes as long as the drive needs; a refused one ends the run), then
    played once as the run's one point, on the step's mean. A pause stops it with its taper and
    plays it again from its start on resume, as a sweep; an abort, an e-stop or a lost link end
    it as they end a sweep."""
    drive = run.drive
    if drive is None:
        raise RunStoppedError.fail(f"road replay {run.run_id}: no drive was planned for it")
    if not getattr(context.actuator, "drive_files", False):
        raise RunStoppedError.fail(
            f"road replay {run.run_id}: the controller plays no drive file (docs/protocols.md, *Drive files*)"
        )
    setpoint = replace(drive.setpoint, mean_mm=context.mean_mm(run.step.mean_mm))
    upload = RunRecording(
        context, run, drive=drive.record, before_stream=lambda: context.actuator.load_drive(setpoint)
    )
    with upload as recording:

        def publish(status: str, attempt: int, span: ExcitationSpan) -> None:
            publish_drive(context, recording, setpoint, span, status=status, attempt=attempt)

        run_one_excitation(context, recording, setpoint, setpoint.duration_s, publish)


def publish_drive(
    context: RunContext,
    recording: RunRecording,
    setpoint: DriveSetpoint,
    span: ExcitationSpan,
    *,
    status: str,
    attempt: int,
) -> None:
    """A drive's one point (a road replay's, a drive iteration's run's): its amplitude is the
    drive's largest sample about the mean, the achieved one the displacement's over the part between
    the tapers (a drive has no frequency: 0)."""
    z = recording.displacement_between(span.hold_start, span.hold_end)
    achieved_mm = 1e3 * float(np.max(np.abs(z - np.mean(z)))) if z.size else float("nan")
    achieved = {"achieved_amplitude_mm": achieved_mm}
    commanded = (0.0, setpoint.peak_mm)
    publish_whole(context, recording, commanded, span, status=status, attempt=attempt, **achieved)
