"""The ``adaptive`` table of a dwell grid: loaded, written back, and refused key by key; the shipped
adaptive variant of the paper's shaker campaign."""

from __future__ import annotations

import textwrap

import pytest

from bench.config import default_bench_config
from sequences import (
    AdaptiveDwell,
    BenchLimits,
    DwellGrid,
    SequenceError,
    dump_sequence,
    load_sequence,
    parse_sequence,
    shipped_file,
)

LIMITS = BenchLimits()
GRID = """
[sequence]
name = "t"

[[steps]]
type = "dwell_grid"
freqs_hz = [5, 20, 40, 70]
amplitudes_mm = [1, 2]
"""


def _parse(adaptive: str, grid: str = GRID):
    return parse_sequence(grid + textwrap.dedent(adaptive), "t.toml", LIMITS)


def _problems(adaptive: str, grid: str = GRID) -> dict[str, str]:
    with pytest.raises(SequenceError) as info:
        _parse(adaptive, grid)
    return {p.key: p.message for p in info.value.problems}


def test_an_adaptive_table_loads_with_defaults_for_what_it_leaves_out_and_writes_back() -> None:
    sequence = _parse(
        """
        [steps.adaptive]
        plate_mass_kg = 12
        magnitude_target_pct = 0.3
        max_added_points = 6
        """
    )
    (grid,) = sequence.steps
    assert grid.adaptive == AdaptiveDwell(plate_mass_kg=12, magnitude_target_pct=0.3, max_added_points=6)
    again = parse_sequence(dump_sequence(sequence), "again.toml", LIMITS)
    assert again.steps == sequence.steps


@pytest.mark.parametrize(
    ("adaptive", "key", "text"),
    [
        ("max_points = 3", "steps[0].adaptive.max_points", "unknown key; allowed: output, input"),
        ("max_hold_s = 0.1\nmin_hold_s = 0.5", "steps[0].adaptive.max_hold_s", "allowed 0.5 <= max_hold_s"),
        ("max_hold_s = 7200", "steps[0].adaptive.max_hold_s", "3600"),
        ("magnitude_target_pct = 0", "steps[0].adaptive.magnitude_target_pct", "0 < magnitude_target_pct"),
        ("settle_tolerance = 0.9", "steps[0].adaptive.settle_tolerance", "settle_tolerance <= 0.5"),
        (
            "min_hold_cycles = 1",
            "steps[0].adaptive.min_hold_cycles",
            "1 is below the settling test's two windows (allowed min_hold_cycles >= 2)",
        ),
        ("max_added_points = 2.5", "steps[0].adaptive.max_added_points", "expected an integer"),
        (
            "plate_mass_kg = -1",
            "steps[0].adaptive.plate_mass_kg",
            "-1 kg is below 0 (allowed plate_mass_kg >= 0 kg)",
        ),
        ('output = ""', "steps[0].adaptive.output", "non-empty string"),
        ("interpolation_db = true", "steps[0].adaptive.interpolation_db", "expected a number"),
    ],
)
def test_bad_adaptive_values_are_refused_by_key(adaptive: str, key: str, text: str) -> None:
    problems = _problems("[steps.adaptive]\n" + adaptive)
    assert key in problems and text in problems[key], problems


def test_an_adaptive_table_belongs_to_an_amplitude_major_dwell_grid_only() -> None:
    assert (
        "amplitude-major"
        in _problems(
            "[steps.adaptive]\n",
            GRID.replace("amplitudes_mm = [1, 2]", 'amplitudes_mm = [1, 2]\norder = "frequency-major"'),
        )["steps[0].order"]
    )
    free_run = GRID.replace('type = "dwell_grid"', 'type = "free_run"')
    assert "only a dwell_grid" in _problems("[steps.adaptive]\n", free_run)["steps[0].adaptive"]
    assert "must be a table" in _problems("adaptive = 3\n")["steps[0].adaptive"]


def test_the_shipped_adaptive_campaign_is_the_fixed_one_with_coarse_adaptive_grids() -> None:
    limits = default_bench_config("shaker").limits
    fixed = load_sequence(shipped_file("paper_shaker.toml"), limits)
    adaptive = load_sequence(shipped_file("paper_shaker_adaptive.toml"), limits)
    fixed_grids = [s for s in fixed.steps if isinstance(s, DwellGrid)]
    grids = [s for s in adaptive.steps if isinstance(s, DwellGrid)]
    assert [g.label for g in grids] == [g.label for g in fixed_grids] == ["1.5 bar", "2.5 bar", "3.5 bar"]
    for grid, same in zip(grids, fixed_grids, strict=True):
        assert grid.adaptive is not None and same.adaptive is None
        assert grid.amplitudes_mm == same.amplitudes_mm
        assert (grid.max_velocity_mm_s, grid.max_acceleration_m_s2) == (1500, 500)
        assert (grid.taper_in_s, grid.taper_out_s) == (same.taper_in_s, same.taper_out_s)
        assert min(grid.freqs_hz) == 0.5 and max(grid.freqs_hz) == 70
        assert len(grid.freqs_hz) < len(same.freqs_hz)
    # the same prompts and other steps, in the same order
    assert [s.kind for s in adaptive.steps] == [s.kind for s in fixed.steps]
    # the estimate (every dwell at its shortest, the whole budget spent) is below the fixed grid's
    assert adaptive.estimated_duration_s < 0.6 * fixed.estimated_duration_s
