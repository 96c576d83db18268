"""Dwell runs: a single sine dwell, a dwell grid and a free run, one point per dwell; an adaptive
grid is handed to :mod:`bench.engine.procedures.adaptive_grid`."""

from __future__ import annotations

from bench.engine.procedures.adaptive_grid import run_adaptive_grid
from bench.engine.procedures.dwell_point import run_point
from bench.engine.recording import RunRecording
from bench.engine.run_context import MeasurementRun, RunContext
from sequences import DwellGrid, SineDwell


def run_dwell_grid(context: RunContext, run: MeasurementRun) -> None:
    """A single sine dwell or a dwell grid (recorded alike): an adaptive grid is refined as it
    runs, any other runs its dwells as they are."""
    if isinstance(run.step, DwellGrid) and run.step.adaptive is not None:
        run_adaptive_grid(context, run)
    else:
        run_dwells(context, run)


def run_dwells(context: RunContext, run: MeasurementRun) -> None:
    """The step's fixed-timing dwells in order (a single dwell: itself), the done ones of a resumed
    run skipped."""
    step = run.step
    dwells = (step,) if isinstance(step, SineDwell) else step.dwells()
    # held within the dwell, each point starts with the command the gains measured so far
    # expect: an update costs the hold again, a good first command none
    gains = None if context.amplitude_hold is None else context.amplitude_control.servo_gains()
    with RunRecording(context, run) as recording:
        for index, dwell in enumerate(dwells):
            if index not in run.held.done_points:
                run_point(context, recording, index, dwell, gains=gains)
