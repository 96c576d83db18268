"""An adaptive dwell grid run: each dwell held until its online verdicts, and points added where
the response calls for them (:mod:`bench.engine.refinement`)."""

from __future__ import annotations

from dataclasses import replace

from bench.engine import events as ev
from bench.engine.procedures.dwell_point import run_point
from bench.engine.recording import RunRecording
from bench.engine.refinement import next_point
from bench.engine.run_context import MeasurementRun, RunContext
from bench.engine.stops import RunStoppedError


def run_adaptive_grid(context: RunContext, run: MeasurementRun) -> None:
    """An adaptive grid, amplitude by amplitude: the grid's frequencies (points 0, 1, ... in grid
    order), then the points the refinement adds (numbered on after the grid's), each announced
    with a :class:`~bench.engine.events.GridRefined` event before it runs.

    A resumed run skips the grid's done points; its refinement starts from the points measured
    since the resume."""
    grid, held = run.step, run.held
    recorded = context.channels.recorded
    output, input_ = recorded.resolve(grid.adaptive.output), recorded.resolve(grid.adaptive.input)
    if output is None or input_ is None:
        missing = [name for name in (grid.adaptive.output, grid.adaptive.input) if not recorded.resolve(name)]
        raise RunStoppedError.fail(
            f"adaptive grid: the bench records no channel {', '.join(missing)}"
            f" (it has {', '.join(recorded.names)})"
        )
    plan = replace(grid.adaptive, output=output, input=input_)
    coarse = len(grid.freqs_hz)
    added_index = max(coarse * len(grid.amplitudes_mm), max(held.done_points, default=-1) + 1)
    with RunRecording(context, run) as recording:
        gains = context.amplitude_control.servo_gains()
        for a, nominal_mm in enumerate(grid.amplitudes_mm):
            measured: dict[float, complex] = {}
            for k, freq_hz in enumerate(grid.freqs_hz):
                if a * coarse + k not in held.done_points:
                    dwell = grid.dwell_at(freq_hz, nominal_mm)
                    verdict = run_point(context, recording, a * coarse + k, dwell, plan=plan, gains=gains)
                    measured[freq_hz] = verdict.frf
            for _ in range(plan.max_added_points):
                added = next_point(tuple(measured), tuple(measured.values()), plan)
                if added is None:
                    break
                context.publish(ev.GridRefined(run.run_id, nominal_mm, ((added.freq_hz, added.reason),)))
                dwell = grid.dwell_at(added.freq_hz, nominal_mm)
                verdict = run_point(
                    context, recording, added_index, dwell, plan=plan, added_reason=added.reason, gains=gains
                )
                measured[added.freq_hz] = verdict.frf
                added_index += 1
