"""A drive iteration: the rig identified with a broadband drive, then drives played and corrected
until the matched response follows the target (docs/engine.md, *Drive iteration*; the numerics:
:mod:`bench.analysis.drive_iteration`).

Each drive is a run of its own, ``<step's run id>-iNN`` (``-i00`` the identification, ``-i01`` the
first drive from the inverse), recorded with its drive as a road replay's is, its samples too (the
drive attribute's ``samples_mm``: every drive stays readable, and the last one can be exported as a
drive file that a road replay plays, ``wfsbench export --format drive``): the drive is
dry-run sample by sample on the bench model against the post's limits (the plan's check), uploaded
to the controller's drive memory (confirmed by CRC-32) once the run has begun, then played once as
the run's one point. A drive the dry run refuses is refused before its upload, naming the iteration,
the sample and the limit, and ends the sequence (failed): the runs before it stay complete. So does
an abort, an e-stop, an interlock or a lost link during a run: that run ends as a road replay's
does, and the iterations before it keep their drives and records.

After each run the response is computed from its channels as the analysis computes it and compared
with the target over the drive's hold less the step's settling time at each end (the span the
corrections act on): the iteration stops once the rms error in the step's error band is below its
limit and, for a target with a 95 % band, enough samples lie inside the band; else after the step's
largest count of iterations. A resume computes the drives again from the runs the file holds and
plays from the first run that is not complete (docs/engine.md, *Drive iteration*).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, replace

import numpy as np

from bench.analysis.drive_iteration import (
    RESPONSE_CHANNELS,
    IterationErrors,
    compared_span,
    corrected_drive,
    estimate_frf,
    inverse_drive,
    iteration_errors,
    regularised_inverse,
    rig_response,
    stop_rules_met,
)
from bench.engine.contracts import PlannedIteration
from bench.engine.points import ExcitationSpan
from bench.engine.procedures.one_excitation import run_one_excitation
from bench.engine.procedures.road_replay import publish_drive
from bench.engine.recording import RunRecording
from bench.engine.run_context import MeasurementRun, RecordedRun, RunContext
from bench.engine.run_ids import iteration_run_id
from bench.engine.stops import RunStoppedError
from drivers.setpoints import DriveSetpoint
from sequences import DriveIteration
from sequences.channels import role_of_standard_name


@dataclass(frozen=True)
class _Played:
    """A drive as played: its samples (mm, before the tapers) and the response over them."""

    drive_mm: np.ndarray
    response: np.ndarray


def run_drive_iteration(context: RunContext, run: MeasurementRun) -> None:
    """The identification, the first drive from the inverse, then corrected drives until a stop rule
    holds (module docstring)."""
    plan, step = run.drive, run.step
    if not isinstance(plan, PlannedIteration) or not isinstance(step, DriveIteration):
        raise RunStoppedError.fail(f"drive iteration {run.run_id}: no target was planned for it")
    if plan.check is None:
        raise RunStoppedError.fail(f"drive iteration {run.run_id}: its drives were not dry-run")
    if not getattr(context.actuator, "drive_files", False):
        raise RunStoppedError.fail(
            f"drive iteration {run.run_id}: the controller plays no drive file"
            " (docs/protocols.md, *Drive files*)"
        )
    fs, band = plan.sample_rate_hz, tuple(step.band_hz)
    identified = _drive_run(context, run, plan, 0, plan.identification)
    span = _span(plan.identification, step)
    frf = estimate_frf(identified.drive_mm[span], identified.response[span], fs)
    inverse = regularised_inverse(frf, band, step.regularisation)
    target = plan.target - np.mean(plan.target)
    drive_mm = inverse_drive(inverse, target, fs)
    for iteration in range(1, step.max_iterations + 1):
        setpoint = DriveSetpoint(drive_mm, fs, step.taper_in_s, step.taper_out_s)
        refusals = plan.check(setpoint)
        if refusals:
            raise RunStoppedError.fail(
                f"drive iteration {run.run_id}, iteration {iteration}: its drive is refused before upload:"
                f" {refusals[0]}"
            )
        played = _drive_run(context, run, plan, iteration, setpoint)
        span = _span(setpoint, step)
        errors = _errors(played.response[span], plan, span, step)
        if stop_rules_met(errors, step.rms_error_pct, step.in_band_pct):
            return
        error = np.zeros_like(target)
        response = played.response[span] - np.mean(played.response[span])
        error[span] = target[span] - np.mean(target[span]) - response
        drive_mm = corrected_drive(drive_mm, error, inverse, fs, step.gain)


def _span(setpoint: DriveSetpoint, step: DriveIteration) -> slice:
    """The drive's samples compared and corrected: between its tapers, less the settling time."""
    fs = setpoint.sample_rate_hz
    return compared_span(setpoint.n_samples, fs, step.taper_in_s, step.taper_out_s, step.settle_s)


def _errors(
    response: np.ndarray, plan: PlannedIteration, span: slice, step: DriveIteration
) -> IterationErrors:
    u95 = plan.u95[span] if plan.u95 is not None else None
    band = (float(step.error_band_hz[0]), float(step.error_band_hz[1]))
    target = plan.target[span]
    return iteration_errors(
        response, target, plan.sample_rate_hz, band, sn_exponent=step.sn_exponent, u95=u95
    )


def _source(plan: PlannedIteration, step: DriveIteration, iteration: int) -> str:
    """What a drive is, as its run records it (``show`` states it)."""
    if iteration == 0:
        return (
            f"identification: {step.identification} drive, {step.identification_rms_mm:g} mm rms,"
            f" {step.identification_s:g} s, {step.band_hz[0]:g}-{step.band_hz[1]:g} Hz"
        )
    return f"iteration {iteration}: {step.response.replace('_', ' ')} against {plan.record['target']}"


def _drive_run(
    context: RunContext, run: MeasurementRun, plan: PlannedIteration, iteration: int, setpoint: DriveSetpoint
) -> _Played:
    """The run of ``iteration``: read from the resumed campaign file where it is complete there (its
    drive, computed again from the runs before it, must be the one it played: the same CRC-32),
    else played (an interrupted run of it goes on after what it recorded)."""
    run_id = iteration_run_id(run.run_id, iteration)
    resume = run.resume
    recorded = resume.recorded_drive(run_id) if resume is not None else None
    if recorded is None:
        held = RecordedRun()
        if resume is not None:
            held = RecordedRun(frozenset(resume.completed_points(run_id)), resume.recorded_samples(run_id))
        return _play(context, run, plan, iteration, setpoint, held=held)
    crc32 = f"{setpoint.crc32:08x}"
    if recorded.drive.get("crc32") != crc32:
        raise RunStoppedError.fail(
            f"drive iteration {run.run_id}, iteration {iteration}: its drive computed again from the runs"
            f" before it is not the one run {run_id} played (CRC-32 {crc32} now,"
            f" {recorded.drive.get('crc32')} in the file): the target, the bench configuration or the"
            " software changed since"
        )
    response = rig_response(run.step.response, recorded.channels, plan.sample_rate_hz, plan.plate_mass_kg)
    return _Played(setpoint.samples_mm.astype(float), response)


def _play(
    context: RunContext,
    run: MeasurementRun,
    plan: PlannedIteration,
    iteration: int,
    setpoint: DriveSetpoint,
    *,
    held: RecordedRun,
) -> _Played:
    """Play ``setpoint`` as the run of ``iteration`` (after what ``held`` says it recorded already):
    uploaded once the run has begun, played once, its response computed from the run's channels
    over the drive's point (as the analysis reads it)."""
    step = run.step
    setpoint = replace(setpoint, mean_mm=context.mean_mm(step.mean_mm))
    names = {
        standard: context.channels.recorded.name_of(role_of_standard_name(standard))
        for standard in RESPONSE_CHANNELS[step.response]
    }
    record = {
        **plan.record,
        "source": _source(plan, step, iteration),
        "iteration": iteration,
        "samples": setpoint.n_samples,
        "sample_rate_hz": setpoint.sample_rate_hz,
        "crc32": f"{setpoint.crc32:08x}",
        "samples_mm": setpoint.samples_mm,
        "sha256": hashlib.sha256(np.asarray(setpoint.samples_mm, dtype="<f4").tobytes()).hexdigest(),
    }
    this = MeasurementRun(iteration_run_id(run.run_id, iteration), step, held, None)
    upload = RunRecording(
        context,
        this,
        drive=record,
        before_stream=lambda: context.actuator.load_drive(setpoint),
        keep=tuple(names.values()),
    )
    spans: list[ExcitationSpan] = []
    with upload as recording:

        def publish(status: str, attempt: int, span: ExcitationSpan) -> None:
            spans.append(span)
            publish_drive(context, recording, setpoint, span, status=status, attempt=attempt)

        run_one_excitation(context, recording, setpoint, setpoint.duration_s, publish)
        start, stop = spans[-1].start, spans[-1].end
        lost = recording.frames_lost_between(start, stop)
        if lost:
            raise RunStoppedError.fail(
                f"drive iteration {run.run_id}, iteration {iteration}: the link lost {lost} frames of its"
                " response: it cannot be compared with the target"
            )
        channels = {standard: recording.kept_between(name, start, stop) for standard, name in names.items()}
    response = rig_response(step.response, channels, plan.sample_rate_hz, plan.plate_mass_kg)
    return _Played(setpoint.samples_mm.astype(float), response)
