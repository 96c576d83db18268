"""The shipped sequence files load against the default limits, with the points and durations the
paper's campaign implies (counted here from the campaign's description, not from the library)."""

import math
import re
from pathlib import Path

import numpy as np
import pytest

from bench.config import default_bench_config
from bench.simulated_campaign import FREE_RUN_GRID_HZ, SHAKER_GRID_HZ
from drivers.setpoints import DwellSetpoint, SweepSetpoint
from sequences import (
    BenchLimits,
    DwellGrid,
    FreeRun,
    HammerTest,
    Prompt,
    Sweep,
    load_sequence,
    parse_sequence,
    shipped_file,
    shipped_files,
)
from sequences.limits import TYRE_PRESSURE_RANGE_BAR
from sequences.steps import STEP_TYPES
from tests.documented import assert_documented

LIMITS = BenchLimits()
SETTLE_CYCLES, SETTLE_MIN_S, MEASURE_CYCLES, MEASURE_MIN_S, TAPER_S = 2, 0.2, 2, 1.0, 0.3


def _dwell_s(
    freq_hz: float, taper_s: float = TAPER_S, settle_min_s=SETTLE_MIN_S, measure_min_s=MEASURE_MIN_S
):
    return (
        2 * taper_s
        + max(SETTLE_CYCLES / freq_hz, settle_min_s)
        + max(MEASURE_CYCLES / freq_hz, measure_min_s)
    )


def _load(name: str, kind: str = "shaker"):
    return load_sequence(shipped_file(name), default_bench_config(kind).limits)


def test_paper_shaker_campaign():
    sequence = _load("paper_shaker.toml")
    free_run, *grids = [s for s in sequence.steps if isinstance(s, FreeRun | DwellGrid)]
    assert isinstance(free_run, FreeRun)
    assert np.array_equal(free_run.grid.freqs_hz, FREE_RUN_GRID_HZ) and free_run.grid.amplitudes_mm == (2,)
    assert len(grids) == 3
    for grid in grids:
        assert np.array_equal(grid.freqs_hz, SHAKER_GRID_HZ) and grid.amplitudes_mm == (1, 2, 5)
    pressures = [
        s.target for s in sequence.steps if isinstance(s, Prompt) and s.action == "set_tyre_pressure"
    ]
    assert pressures == [1.5, 2.5, 3.5]
    actions = [s.action for s in sequence.steps if isinstance(s, Prompt)]
    assert actions.index("remove_wheel") < actions.index("fit_wheel") < actions.index("set_tyre_pressure")
    assert sequence.points() == 13 + 3 * 3 * 22
    dwells_s = sum(_dwell_s(f) for f in FREE_RUN_GRID_HZ) + 9 * sum(_dwell_s(f) for f in SHAKER_GRID_HZ)
    hydraulics_s, tares_s = 9 * 3.0, 3 * 2.0
    assert sequence.estimated_duration_s == pytest.approx(dwells_s + hydraulics_s + tares_s, rel=1e-12)
    assert sequence.estimated_duration_with_operator_s == pytest.approx(
        sequence.estimated_duration_s + 5 * 60.0
    )


def test_paper_shaker_crossover_is_recorded_and_within_the_files_maxima():
    sequence = _load("paper_shaker.toml")
    grid = next(s for s in sequence.steps if isinstance(s, DwellGrid))
    limited = {d.freq_hz: d for d in grid.dwells() if d.requested_amplitude_mm is not None}
    # Only the 5 mm grid from 50 Hz up: velocity first, acceleration from 53 Hz (= 500 / (2 pi 1.5))
    assert sorted(limited) == [50, 55, 60, 65, 70]
    assert {d.requested_amplitude_mm for d in limited.values()} == {5}
    assert limited[50].amplitude_limited_by == "velocity"
    assert limited[50].amplitude_mm == pytest.approx(1500 / (2 * math.pi * 50), abs=1e-4)
    assert limited[70].amplitude_limited_by == "acceleration"
    assert limited[70].amplitude_mm == pytest.approx(500e3 / (2 * math.pi * 70) ** 2, abs=1e-4)
    for dwell in grid.dwells():
        assert 2 * math.pi * dwell.freq_hz * dwell.amplitude_mm <= 1500
        assert (2 * math.pi * dwell.freq_hz) ** 2 * dwell.amplitude_mm * 1e-3 <= 500
    free_run = next(s for s in sequence.steps if isinstance(s, FreeRun))
    assert [d.freq_hz for d in free_run.dwells() if d.amplitude_limited_by] == [80, 90, 100]


def test_paper_four_post():
    sequence = _load("paper_four_post.toml", "four_post")
    (sweep,) = [s for s in sequence.steps if isinstance(s, Sweep)]
    assert (sweep.start_hz, sweep.end_hz, sweep.duration_s, sweep.amplitude_mm, sweep.law) == (
        0.1,
        30,
        60,
        2,
        "linear",
    )
    actions = [s.action for s in sequence.steps if isinstance(s, Prompt)]
    assert actions == ["car_off_posts", "car_on_posts", "set_tyre_pressure", "set_damper"]
    assert sequence.points() == 10 + 1
    free_run = next(s for s in sequence.steps if isinstance(s, FreeRun))
    dwells_s = sum(_dwell_s(f) for f in free_run.grid.freqs_hz)
    assert sequence.estimated_duration_s == pytest.approx(dwells_s + 60 + 5 * 3.0 + 2.0, rel=1e-12)


def test_hammer():
    sequence = _load("hammer.toml")
    (hammer,) = sequence.measurement_steps()
    assert isinstance(hammer, HammerTest) and hammer.blows == 3
    assert sequence.points() == 3
    assert sequence.estimated_duration_s == pytest.approx(2.0 + 3 * 0.3)


def test_smoke_runs_in_seconds():
    sequence = _load("smoke.toml")
    assert sequence.points() == 3 + 4 + 1
    excitation_s = sum(_dwell_s(f, 0.2, 0.1, 0.5) for f in (10, 30, 60, 10, 30, 40, 50)) + 5.0
    assert excitation_s < 15.0
    steps_s = [s.estimated_duration_s for s in sequence.measurement_steps()]
    assert sum(steps_s) == pytest.approx(excitation_s)
    assert any(isinstance(s, Prompt) and s.action == "set_tyre_pressure" for s in sequence.steps)


@pytest.mark.parametrize(
    ("name", "kind"),
    [
        ("paper_shaker.toml", "shaker"),
        ("paper_shaker_adaptive.toml", "shaker"),
        ("smoke.toml", "shaker"),
        ("paper_four_post.toml", "four_post"),
    ],
)
def test_every_shipped_setpoint_passes_the_drivers_limits(name, kind):
    """What the sequence validator accepts, the actuator client's own check accepts too."""
    config = default_bench_config(kind)
    sequence = load_sequence(shipped_file(name), config.limits)
    for step in sequence.measurement_steps():
        if isinstance(step, Sweep):
            SweepSetpoint(
                step.start_hz,
                step.end_hz,
                step.duration_s,
                step.amplitude_mm,
                step.law,
                step.taper_in_s,
                step.taper_out_s,
                step.mean_mm,
            ).registers(config.limits)
            continue
        adaptive = getattr(step, "adaptive", None)
        for d in step.dwells():
            hold_s = d.hold_s if adaptive is None else adaptive.max_hold_s
            DwellSetpoint(
                d.freq_hz, d.amplitude_mm, hold_s, d.taper_in_s, d.taper_out_s, d.mean_mm
            ).registers(config.limits)


@pytest.mark.parametrize(
    ("name", "kind"),
    [
        ("paper_shaker.toml", "shaker"),
        ("paper_shaker_adaptive.toml", "shaker"),
        ("paper_four_post.toml", "four_post"),
    ],
)
def test_shipped_pressure_prompts_accept_the_plausible_tyre_pressures(name, kind):
    """The range an imported campaign's pressure is checked against is the one the prompts accept."""
    prompts = [
        step
        for step in _load(name, kind).steps
        if isinstance(step, Prompt) and step.action == "set_tyre_pressure"
    ]
    assert prompts
    assert {(p.minimum, p.maximum) for p in prompts} == {TYRE_PRESSURE_RANGE_BAR}


def test_every_example_in_the_format_document_is_a_valid_sequence():
    """docs/sequences.md shows a complete example of every step type; each one loads."""
    text = (Path(__file__).resolve().parents[1] / "docs" / "sequences.md").read_text(encoding="utf-8")
    kinds = set()
    for block in re.findall(r"```toml\n(.*?)```", text, re.S):
        header = "" if "[sequence]" in block else '[sequence]\nname = "example"\n'
        sequence = parse_sequence(header + block, "docs/sequences.md", LIMITS)
        kinds |= {step.kind for step in sequence.steps}
    assert kinds == set(STEP_TYPES)
    (example,) = re.findall(r"```python\n(.*?)```", text, re.S)
    exec(compile(example, "docs/sequences.md", "exec"), {})  # the Python API example runs


def test_the_shipped_files_are_listed_from_the_package():
    names = shipped_files()
    assert names == tuple(sorted(p.name for p in shipped_file("smoke.toml").parent.glob("*.toml")))
    expected = {"smoke.toml", "paper_shaker.toml", "paper_shaker_adaptive.toml", "paper_four_post.toml"}
    assert expected <= set(names)


@pytest.mark.parametrize("name", ["paper_shaker.toml", "paper_four_post.toml", "hammer.toml", "smoke.toml"])
def test_the_format_document_quotes_each_fixed_files_points_and_bench_time(name):
    """docs/sequences.md's table of shipped files: the points and estimated bench time of each file
    whose points are fixed (the adaptive file's depend on its verdicts), as ``wfsbench check``
    counts them."""
    sequence = _load(name)
    row = f"| {sequence.points()} | {sequence.estimated_duration_s:.0f} s"
    print(f"\n  {name}: {row}")
    assert_documented("docs/sequences.md", row)
