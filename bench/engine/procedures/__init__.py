"""The procedure of each run kind: how a measurement step drives the actuator and records its
points, looked up by its :class:`~sequences.runs.RunKind` in :data:`PROCEDURES`.

A procedure is given the run to make (:class:`~bench.engine.run_context.MeasurementRun`) and the
run's :class:`~bench.engine.run_context.RunContext`, never the engine: it records its stream
through a :class:`~bench.engine.recording.RunRecording` (a hammer test, which has none, publishes
its captures itself) and runs its dwells' points with
:func:`~bench.engine.procedures.dwell_point.run_point`. A new run kind's procedure goes in a module
of its own here, with its entry in the table (``tests/test_run_kind_tables.py`` fails without it).
"""

from __future__ import annotations

from collections.abc import Callable

from bench.engine.procedures.drive_iteration import run_drive_iteration
from bench.engine.procedures.dwells import run_dwell_grid, run_dwells
from bench.engine.procedures.hammer import run_hammer
from bench.engine.procedures.road_replay import run_road_replay
from bench.engine.procedures.sweep import run_sweep
from bench.engine.procedures.tracked_dwell import run_tracked_dwell
from bench.engine.run_context import MeasurementRun, RunContext
from sequences.runs import RunKind

#: How a run of a kind is made, given its context.
Procedure = Callable[[RunContext, MeasurementRun], None]

#: The procedure of each run kind.
PROCEDURES: dict[RunKind, Procedure] = {
    RunKind.DWELL_GRID: run_dwell_grid,
    RunKind.FREE_RUN: run_dwells,
    RunKind.SWEEP: run_sweep,
    RunKind.TRACKED_DWELL: run_tracked_dwell,
    RunKind.ROAD_REPLAY: run_road_replay,
    RunKind.DRIVE_ITERATION: run_drive_iteration,
    RunKind.HAMMER: run_hammer,
}
