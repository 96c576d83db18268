"""A hammer test run of the bare sensor: per blow, a triggered capture of Fz at the converter's
rate, recorded as one point; the run has no stream and no excitation."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from bench.engine import events as ev
from bench.engine.run_context import MeasurementRun, RunContext
from bench.engine.stops import RunOutcome
from sequences import step_fields
from sequences.channels import STANDARD_CHANNELS, Role

HAMMER_CHANNEL = replace(
    STANDARD_CHANNELS[Role.WFS_FZ],
    description="Fz of the bare sensor, triggered capture at the converter rate",
)


def run_hammer(context: RunContext, run: MeasurementRun) -> None:
    """Per blow: arm the triggered capture, ask for the blow, record the captured block.

    The blocks are recorded one after the other in the run's single Fz channel at the
    converter's rate; each blow is a point spanning its block, its hold from the trigger on."""
    step, run_id, held = run.step, run.run_id, run.held
    samples = held.samples
    started = False
    outcome = RunOutcome("complete")
    try:
        for blow in range(step.blows):
            if blow in held.done_points:
                continue
            context.checkpoint()
            context.acquisition.arm_capture(step.trigger_level_n, step.pre_trigger_s, step.capture_s)
            context.ask(step.strike_prompt(blow + 1))
            capture = context.acquisition.wait_capture(step.capture_s + context.timing.capture_timeout_s)
            if not started:
                started = True
                context.publish(
                    ev.RunStarted(
                        run_id,
                        step.kind,
                        step_fields(step),
                        dict(context.conditions),
                        (HAMMER_CHANNEL,),
                        capture.rate_hz,
                    )
                )
            n = len(capture.samples_n)
            columns = {HAMMER_CHANNEL.name: np.asarray(capture.samples_n, dtype=np.float32)}
            context.publish(ev.SamplesRecorded(run_id, samples, columns))
            trigger = samples + capture.pre_trigger_samples
            context.publish(
                ev.PointDone(blow, 0.0, 0.0, samples, trigger, samples + n, samples + n, run_id=run_id)
            )
            samples += n
    except BaseException as exc:
        outcome = context.end_run(exc)
        raise
    finally:
        if started:
            context.finish_run(run_id, outcome)
