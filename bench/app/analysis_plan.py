"""What a sequence's runs will not let the analysis give, said before anything runs (``wfsbench
check``), from the steps alone and the bench configuration.

The post-run analysis (:mod:`bench.app.run_analysis`) needs, besides a run's own records: for a
dwell grid on the shaker the tyre's pressure (a ``set_tyre_pressure`` prompt before it) and the
plate mass m_comp (a free run before it, else the configured plate mass, nominal), and at least
:data:`~bench.analysis.records.MIN_FIT_POINTS` frequencies per amplitude and pressure for a tyre
fit (fewer give the measured ratios only); for a four-post sweep the post's free run, the tyre's
pressure and the tyre's shaker identification, which only an earlier sequence run into the same
campaign file can give; for a road replay the same (its contact force is the post's plate force
corrected with m_comp, its model compensation the tyre's shaker identification at its pressure:
without one it gives the raw and hub-acceleration compensated forces only). A shaker's grid on a
bench without a hub accelerometer is analysed with the clamped hub taken as not moving. A sweep on
the shaker is recorded, not analysed. A campaign file that holds runs already (another sequence's)
may supply what a step lacks here: each line says so.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from bench.analysis.records import MIN_FIT_POINTS
from bench.config import BenchConfig
from sequences import DwellGrid, FreeRun, Prompt, RoadReplay, Sequence, SineDwell, Sweep
from sequences.channels import Role
from sequences.runs import RigKind, RunKind
from sequences.steps import PromptAction

#: What a campaign file the sequence runs into may hold already.
_UNLESS_IN_FILE = "unless the campaign file it runs into holds one already"


class _Walk:
    """The steps in order, with what the runs before each established."""

    def __init__(self, config: BenchConfig) -> None:
        self.config = config
        self.free_run = False
        self.pressure_bar: float | None = None
        self.lines: list[str] = []
        #: per (pressure, grid amplitude in mm): the steps and the frequencies they dwell at
        self.grid_points: dict[tuple[float, float], tuple[list[int], set[float]]] = {}

    def weighed(self, index: int, step: FreeRun) -> None:
        """A free run: the runs after it have a measured m_comp."""
        self.free_run = True

    def grid(self, index: int, step: DwellGrid | SineDwell) -> None:
        """A dwell grid: the tyre fit on the shaker (a four-post bench's grid is recorded only)."""
        if self.config.kind != RigKind.SHAKER:
            return
        key = f"steps[{index}] {step.kind}"
        if self.pressure_bar is None:
            self.lines.append(
                f"{key}: no analysis: no set_tyre_pressure prompt before it (the tyre fit needs the"
                " tyre's pressure)"
            )
            return
        if not self.config.channels.bound(Role.HUB_ACCELERATION):
            self.lines.append(
                f"{key}: the bench records no hub acceleration: the clamped hub is taken as not moving"
                " (the compensated ratio without its hub term); whether it moved is not checked"
            )
        if not self.free_run:
            self.lines.append(
                f"{key}: no free run before it: m_comp will be the configured plate mass"
                f" {self.config.masses.plate_kg:g} kg (masses.plate_kg), nominal, not measured,"
                f" {_UNLESS_IN_FILE}"
            )
        for dwell in step.dwells():
            amplitude_mm = dwell.requested_amplitude_mm or dwell.amplitude_mm
            steps, freqs = self.grid_points.setdefault((self.pressure_bar, amplitude_mm), ([], set()))
            if index not in steps:
                steps.append(index)
            freqs.add(dwell.freq_hz)

    def sweep(self, index: int, step: Sweep) -> None:
        key = f"steps[{index}] {step.kind}"
        if self.config.kind == RigKind.SHAKER:
            self.lines.append(f"{key}: recorded, not analysed (the sweep analysis is the four-post bench's)")
            return
        if not self.free_run:
            self.lines.append(
                f"{key}: no analysis: no free run of the post before it (its m_comp), {_UNLESS_IN_FILE}"
            )
        if self.pressure_bar is None:
            self.lines.append(
                f"{key}: no analysis: no set_tyre_pressure prompt before it (which shaker identification"
                " describes the tyre)"
            )
        self.lines.append(
            f"{key}: the four-post analysis needs the tyre's shaker identification: run the shaker"
            " campaign into the same campaign file first"
        )

    def needs_nothing(self, index: int, step: object) -> None:
        """A run whose analysis needs nothing from the runs before it (a hammer test, a tracked
        dwell's resonance, a drive iteration's errors against its target)."""

    def replay(self, index: int, step: RoadReplay) -> None:
        key = f"steps[{index}] {step.kind}"
        if not self.free_run:
            self.lines.append(
                f"{key}: no analysis: no free run of the post before it (its m_comp corrects the post's"
                f" contact force), {_UNLESS_IN_FILE}"
            )
        why = (
            "no set_tyre_pressure prompt before it"
            if self.pressure_bar is None
            else f"it needs the tyre's shaker identification at {self.pressure_bar:g} bar"
        )
        self.lines.append(
            f"{key}: the model-compensated force: {why}; without it the raw and hub-acceleration"
            f" compensated forces only, {_UNLESS_IN_FILE}"
        )

    def too_few_points(self) -> list[str]:
        lines = []
        for (bar, amplitude_mm), (steps, freqs) in self.grid_points.items():
            if len(freqs) < MIN_FIT_POINTS:
                lines.append(
                    f"{', '.join(f'steps[{i}]' for i in steps)} at {bar:g} bar, {amplitude_mm:g} mm:"
                    f" {len(freqs)} frequencies: no tyre fit (at least {MIN_FIT_POINTS} needed): the"
                    " measured ratios only (grids at this pressure already in the campaign file count too)"
                )
        return lines


def analysis_limits(sequence: Sequence, config: BenchConfig) -> list[str]:
    """One line per analysis the sequence's runs will not allow (or allow only in part), each
    naming the step, what is missing and what would make it possible; empty when every run can be
    analysed in full."""
    walk = _Walk(config)
    for index, step in enumerate(sequence.steps):
        if isinstance(step, Prompt) and step.action == PromptAction.SET_TYRE_PRESSURE:
            walk.pressure_bar = float(step.target)
        elif step.run_kind is not None:
            ANALYSIS_NEEDS[step.run_kind](walk, index, step)
    return walk.lines + walk.too_few_points()


#: What each kind of run needs of the runs before it, said as it walks past them
#: (tests/test_run_kind_tables.py: every kind is here).
ANALYSIS_NEEDS: dict[RunKind, Callable[[_Walk, int, Any], None]] = {
    RunKind.FREE_RUN: _Walk.weighed,
    RunKind.DWELL_GRID: _Walk.grid,
    RunKind.SWEEP: _Walk.sweep,
    RunKind.ROAD_REPLAY: _Walk.replay,
    RunKind.DRIVE_ITERATION: _Walk.needs_nothing,
    RunKind.TRACKED_DWELL: _Walk.needs_nothing,
    RunKind.HAMMER: _Walk.needs_nothing,
}
