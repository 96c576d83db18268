"""A tracked dwell run: a search for the resonance of an output over an input (adaptive dwells),
then one dwell that follows the resonance by frequency updates (:mod:`bench.engine.tracking`)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from bench.engine import events as ev
from bench.engine.procedures.dwell_point import PointPlan, excite_point, publish_point, run_point
from bench.engine.recording import RunRecording
from bench.engine.run_context import MeasurementRun, RunContext
from bench.engine.stops import RunStoppedError
from bench.engine.tracking import GLIDE_S, Resonance, TrackWatch, TrackWindow, find_resonance
from drivers.errors import CommandRejectedError, LimitError
from drivers.setpoints import DwellSetpoint, FrequencyUpdate
from sequences import SineDwell, TrackedDwell
from sequences.points import PointStatus, Verdict


def run_tracked_dwell(context: RunContext, run: MeasurementRun) -> None:
    """A tracked dwell: its search (points 0 .. n-1, adaptive dwells measuring the ratio), the
    resonance found, then the track (point n). A resumed run searches again: the resonance
    moves. A search that finds no resonance ends the sequence (aborted) with the reason."""
    step = run.step
    recorded = context.channels.recorded
    output, input_ = recorded.resolve(step.output), recorded.resolve(step.input)
    if output is None or input_ is None:
        missing = [name for name in (step.output, step.input) if not recorded.resolve(name)]
        raise RunStoppedError.fail(
            f"tracked dwell: the bench records no channel {', '.join(missing)}"
            f" (it has {', '.join(recorded.names)})"
        )
    if not getattr(context.actuator, "frequency_updates", False):
        raise RunStoppedError.fail(
            "tracked dwell: the controller takes no frequency update (docs/protocols.md, *Frequency updates*)"
        )
    plan = replace(step.search_plan(), output=output, input=input_)
    with RunRecording(context, run) as recording:
        freqs = step.search_freqs_hz()
        frfs, gains = [], context.amplitude_control.servo_gains()
        for k, freq_hz in enumerate(freqs):
            dwell = SineDwell(
                freq_hz,
                step.amplitude_mm,
                taper_in_s=step.taper_in_s,
                taper_out_s=step.taper_out_s,
                mean_mm=step.mean_mm,
            )
            frfs.append(run_point(context, recording, k, dwell, plan=plan, gains=gains).frf)
        resonance = find_resonance(np.array(freqs), np.array(frfs))
        if resonance is None:
            raise RunStoppedError.abort(
                f"tracked dwell {run.run_id}: no resonance of {output} / {input_} within"
                f" {freqs[0]:g}-{freqs[-1]:g} Hz (the largest ratio at an end of the search)"
            )
        channels = (output, input_, context.channels.displacement)
        _track(context, recording, step, resonance, index=len(freqs), channels=channels)


def _track(
    context: RunContext,
    recording: RunRecording,
    step: TrackedDwell,
    resonance: Resonance,
    *,
    index: int,
    channels: tuple[str, str, str],
) -> None:
    """The track (point ``index``): one dwell at the resonance until its length or a stop rule
    (repeated whole after a pause), every look at the ``channels`` (output, input, displacement)
    published; its point records the resonance found, the verdict
    (tracked, or stopped with the reason) and the last look's resonance as achieved."""
    attempt = 0
    while True:
        context.checkpoint()
        attempt += 1
        started = ev.PointStarted(
            recording.run_id, index, attempt, resonance.freq_hz, step.amplitude_mm, dict(context.conditions)
        )
        context.publish(started)

        def update(freq_hz: float) -> str | None:
            try:
                context.actuator.update_frequency(FrequencyUpdate(freq_hz, GLIDE_S))
            except LimitError as exc:
                return f"refused by the soft limits: {exc}"
            except CommandRejectedError as exc:
                return str(exc)
            return None

        def looked(window: TrackWindow) -> None:
            context.publish(
                ev.ResonanceTracked(
                    recording.run_id,
                    index,
                    window.sample,
                    window.drive_hz,
                    window.resonance_hz,
                    abs(window.ratio),
                    float(np.degrees(np.angle(window.ratio))),
                    window.damping_ratio,
                )
            )

        watch = TrackWatch(
            step,
            resonance,
            sample_rate_hz=context.sample_rate_hz,
            channels=channels,
            hold_bit=context.sync_bits.hold,
            present=context.frames_present,
            update=update,
            on_window=looked,
        )
        setpoint = DwellSetpoint(
            resonance.freq_hz,
            step.amplitude_mm,
            dwell_s=0.0,
            taper_in_s=step.taper_in_s,
            taper_out_s=step.taper_out_s,
            mean_mm=context.mean_mm(step.mean_mm),
        )
        # the track's length in cycles ends later at a lower frequency: allow for its band
        track_s = step.track_length_s * (1 + step.freq_band_pct / 100)
        planned_s = step.taper_in_s + track_s + step.taper_out_s
        dwell = SineDwell(resonance.freq_hz, step.amplitude_mm)
        point = PointPlan(index, dwell, step.amplitude_mm)
        span = excite_point(
            context,
            recording,
            point,
            attempt,
            setpoint,
            command_mm=step.amplitude_mm,
            planned_s=planned_s,
            watch=watch,
        )
        if span is None:
            continue
        publish_point(
            context,
            recording,
            point,
            attempt,
            PointStatus.DONE,
            command_mm=step.amplitude_mm,
            span=span,
            note=watch.reason,
            tracked=Verdict.STOPPED if watch.reason else Verdict.TRACKED,
        )
        return
