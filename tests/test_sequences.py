"""The step vocabulary and its validation as a Python API: derived timing, the crossover, prompts,
and the same problems whether a sequence is built in Python or read from a file."""

import dataclasses
import math

import pytest

from sequences import (
    AnswerError,
    BenchLimits,
    DwellGrid,
    FreeRun,
    HammerTest,
    Hydraulics,
    MeanPosition,
    Prompt,
    Sequence,
    SequenceError,
    SineDwell,
    Sweep,
    Tare,
    crossover_amplitude_mm,
    dump_sequence,
    parse_sequence,
    step_fields,
    validate,
)

LIMITS = BenchLimits()


def _keys(error: SequenceError) -> list[str]:
    return [p.key for p in error.problems]


def test_dwell_timing_takes_cycles_or_the_minimum_whichever_is_longer():
    low = SineDwell(
        0.5,
        2.0,
        settle_cycles=2,
        settle_min_s=0.2,
        measure_cycles=3,
        measure_min_s=1.0,
        taper_in_s=0.3,
        taper_out_s=0.4,
    )
    assert low.settle_s == pytest.approx(4.0) and low.measure_s == pytest.approx(6.0)
    assert low.hold_s == pytest.approx(10.0) and low.duration_s == pytest.approx(10.7)
    high = dataclasses.replace(low, freq_hz=50.0)
    assert high.settle_s == 0.2 and high.measure_s == 1.0 and high.duration_s == pytest.approx(1.9)
    assert low.amplitude_m == pytest.approx(2e-3) and low.estimated_duration_s == low.duration_s


def test_grid_order_and_count():
    grid = DwellGrid((1.0, 2.0, 3.0), (1.0, 2.0))
    assert [(d.freq_hz, d.amplitude_mm) for d in grid.dwells()] == [
        (1.0, 1.0),
        (2.0, 1.0),
        (3.0, 1.0),
        (1.0, 2.0),
        (2.0, 2.0),
        (3.0, 2.0),
    ]
    by_freq = dataclasses.replace(grid, order="frequency-major")
    assert [(d.freq_hz, d.amplitude_mm) for d in by_freq.dwells()][:3] == [(1.0, 1.0), (1.0, 2.0), (2.0, 1.0)]
    assert grid.estimated_duration_s == pytest.approx(sum(d.duration_s for d in grid.dwells()))


def test_crossover_lowers_the_amplitude_and_records_why():
    # 5 mm: 2 pi f A = 1500 mm/s at f = 47.75 Hz; (2 pi f)^2 A = 500 m/s^2 at f = 50.33 Hz, and the
    # acceleration limit takes over from the velocity limit at f = a / (2 pi v) = 53.05 Hz.
    grid = DwellGrid((46.0, 50.0, 70.0), (1.0, 5.0), max_velocity_mm_s=1500.0, max_acceleration_m_s2=500.0)
    dwells = {(d.freq_hz, d.requested_amplitude_mm or d.amplitude_mm): d for d in grid.dwells()}
    full = dwells[(46.0, 5.0)]
    assert (
        full.amplitude_mm == 5.0 and full.requested_amplitude_mm is None and full.amplitude_limited_by is None
    )
    at_50 = dwells[(50.0, 5.0)]
    assert at_50.amplitude_limited_by == "velocity" and at_50.requested_amplitude_mm == 5.0
    assert at_50.amplitude_mm == pytest.approx(1500.0 / (2 * math.pi * 50.0), abs=1e-4)
    at_70 = dwells[(70.0, 5.0)]
    assert at_70.amplitude_limited_by == "acceleration"
    assert at_70.amplitude_mm == pytest.approx(500e3 / (2 * math.pi * 70.0) ** 2, abs=1e-4)
    assert dwells[(70.0, 1.0)].amplitude_mm == 1.0  # 193 m/s^2, 440 mm/s: untouched
    for d in grid.dwells():  # rounded down: never above the maximum it was derived from
        assert 2 * math.pi * d.freq_hz * d.amplitude_mm <= 1500.0
        assert (2 * math.pi * d.freq_hz) ** 2 * d.amplitude_mm * 1e-3 <= 500.0


def test_crossover_without_maxima_keeps_the_amplitude():
    assert crossover_amplitude_mm(70.0, 5.0, None, None) == (5.0, None)


def test_free_run_is_the_grids_dwells():
    grid = DwellGrid((10.0, 20.0), (2.0,))
    assert FreeRun(grid).dwells() == grid.dwells()
    assert FreeRun(grid).estimated_duration_s == grid.estimated_duration_s


def test_sequence_counts_points_and_durations():
    sequence = Sequence(
        "s",
        "",
        (
            Hydraulics("low"),
            Hydraulics("high"),
            Prompt(
                "p",
                "Set 2.5 bar",
                answer="number",
                unit="bar",
                minimum=0.5,
                maximum=4.5,
                action="set_tyre_pressure",
                target=2.5,
            ),
            Tare(),
            DwellGrid((10.0, 20.0), (1.0, 2.0)),
            Sweep(1.0, 30.0, 10.0, 1.0),
            HammerTest(200.0, blows=3),
            MeanPosition(2.0),
        ),
    )
    validate(sequence, LIMITS)
    assert sequence.points() == 4 + 1 + 3
    grid_s = 4 * (0.3 + 0.2 + 1.0 + 0.3)  # 2 cycles are shorter than the minima at 10 and 20 Hz
    expected = 2 * 3.0 + 0.0 + 2.0 + grid_s + 10.0 + 3 * 0.3 + 2.0
    assert sequence.estimated_duration_s == pytest.approx(expected)
    assert sequence.estimated_duration_with_operator_s == pytest.approx(expected + 4 * 60.0)
    assert [type(s) for s in sequence.measurement_steps()] == [DwellGrid, Sweep, HammerTest]


@pytest.mark.parametrize(
    ("step", "key", "text"),
    [
        (
            SineDwell(40.0, 30.0),
            "steps[0].amplitude_mm",
            "30 mm is above the 25 mm stroke (allowed 0 < amplitude_mm <= 25 mm)",
        ),
        (SineDwell(40.0, 20.0, mean_mm=10.0), "steps[0].amplitude_mm", "less |mean_mm| 10"),
        (
            SineDwell(150.0, 1.0),
            "steps[0].freq_hz",
            "150 Hz is above the bench's highest frequency (allowed 0.1 <= freq_hz <= 100 Hz)",
        ),
        (
            SineDwell(10.0, 0.0),
            "steps[0].amplitude_mm",
            "0 mm is not above 0 (allowed 0 < amplitude_mm <= 25 mm)",
        ),
        (SineDwell(10.0, True), "steps[0].amplitude_mm", "expected a number, got True (bool)"),
        (SineDwell(10.0, "2"), "steps[0].amplitude_mm", "expected a number, got '2' (str)"),
        (SineDwell(math.nan, 2.0), "steps[0].freq_hz", "nan is not a finite number"),
        (
            SineDwell(10.0, 2.0, taper_in_s=0.01),
            "steps[0].taper_in_s",
            "0.01 s is below the controller's shortest taper (allowed taper_in_s >= 0.1 s)",
        ),
        (
            SineDwell(10.0, 2.0, measure_cycles=0, measure_min_s=0),
            "steps[0].measure_min_s",
            "nothing to measure",
        ),
        (SineDwell(70.0, 5.0), "steps[0].amplitude_mm", "peak velocity of 2199 mm/s"),
        (DwellGrid((), (1.0,)), "steps[0].freqs_hz", "no values"),
        (DwellGrid((10.0, 10.0), (1.0,)), "steps[0].freqs_hz[1]", "already in the grid"),
        (DwellGrid((10.0, 70.0), (1.0, 5.0)), "steps[0].amplitudes_mm[1]", "at 70 Hz"),
        (DwellGrid((10.0,), (1.0,), order="random"), "steps[0].order", "not one of"),
        (DwellGrid((10.0,), (1.0,), max_velocity_mm_s=-1.0), "steps[0].max_velocity_mm_s", "not above 0"),
        (FreeRun(DwellGrid((10.0, math.inf), (2.0,))), "steps[0].freqs_hz[1]", "inf is not a finite number"),
        (Sweep(0.1, 30.0, 1.5, 2.0), "steps[0].duration_s", "leaves no sweep after the tapers"),
        (Sweep(5.0, 5.0, 10.0, 2.0), "steps[0].end_hz", "end_hz != start_hz"),
        (Sweep(1.0, 30.0, 10.0, 2.0, law="exp"), "steps[0].law", "'exp' is not one of ['linear', 'log']"),
        (Sweep(1.0, 100.0, 10.0, 5.0), "steps[0].amplitude_mm", "highest frequency"),
        (HammerTest(30_000.0), "steps[0].trigger_level_n", "above the WFS range"),
        (
            HammerTest(200.0, pre_trigger_s=0.5, capture_s=0.3),
            "steps[0].pre_trigger_s",
            "nothing after the trigger",
        ),
        (HammerTest(200.0, blows=2.0), "steps[0].blows", "expected an integer"),
        (HammerTest(200.0, capture_s=5.0), "steps[0].capture_s", "capture buffer"),
        (Hydraulics("max"), "steps[0].level", "not one of ['off', 'low', 'high']"),
        (MeanPosition(40.0), "steps[0].mean_mm", "above the stroke"),
        (
            Prompt("p", "Set", answer="number", action="set_tyre_pressure"),
            "steps[0].target",
            "needs the pressure",
        ),
        (
            Prompt("p", "Set", answer="confirm", action="set_tyre_pressure", target=2.5),
            "steps[0].answer",
            "needs answer = 'number'",
        ),
        (
            Prompt("p", "Set", answer="number", unit="bar", minimum=0.5, maximum=4.5, target=9.0),
            "steps[0].target",
            "9 bar is above the prompt's maximum (allowed 0.5 <= target <= 4.5 bar)",
        ),
        (
            Prompt("p", "Set", answer="number", unit="bar", minimum=0.5, target=0.2),
            "steps[0].target",
            "0.2 bar is below the prompt's minimum (allowed target >= 0.5 bar)",
        ),
        (
            Prompt("p", "Set", answer="number", unit="bar", minimum=5.0, maximum=4.5, target=2.5),
            "steps[0].minimum",
            "5 is not below maximum 4.5 (allowed minimum < maximum)",
        ),
        (
            Prompt("p", "Pick", answer="choice", choices=("a", "b"), target="c"),
            "steps[0].target",
            "'c' is not one of",
        ),
        (Prompt("p", "Pick", answer="choice", choices=("a",)), "steps[0].choices", "at least two"),
        (Prompt("p", "", answer="confirm"), "steps[0].text", "non-empty string"),
        (Prompt("p", "Go", action="fly"), "steps[0].action", "'fly' is not one of"),
        ("hydraulics high", "steps[0]", "is not a step"),
    ],
)
def test_validate_names_the_key_and_the_range(step, key, text):
    with pytest.raises(SequenceError) as info:
        validate(Sequence("bad", "", (step,)), LIMITS)
    assert info.value.key == key
    assert text in info.value.message
    assert str(info.value).startswith(f"<script>: {key}: ")


def test_a_prompt_with_its_minimum_above_its_maximum_has_that_one_problem():
    """The range itself is wrong: the target is not checked against it (it would read ``5 <= target
    <= 4.5``)."""
    prompt = Prompt("p", "Set", answer="number", unit="bar", minimum=5.0, maximum=4.5, target=2.5)
    with pytest.raises(SequenceError) as info:
        validate(Sequence("bad", "", (prompt,)), LIMITS)
    assert [str(p) for p in info.value.problems] == [
        "<script>: steps[0].minimum: 5 is not below maximum 4.5 (allowed minimum < maximum)"
    ]


def test_every_problem_is_reported_first_one_in_the_str():
    sequence = Sequence(
        "",
        "",
        (
            SineDwell(150.0, 30.0),
            Tare(),
            Prompt("a", "x"),
            Prompt("a", "y"),
            Sweep(1.0, 30.0, 10.0, 1.0, law="exp"),
        ),
    )
    with pytest.raises(SequenceError) as info:
        validate(sequence, LIMITS)
    assert _keys(info.value) == [
        "sequence.name",
        "steps[0].freq_hz",
        "steps[0].amplitude_mm",
        "steps[3].id",
        "steps[4].law",
    ]
    lines = str(info.value).splitlines()
    assert lines[0] == str(info.value.problems[0]) and lines[1] == "  and 4 more:"
    assert "already used by steps[2]" in info.value.problems[3].message


def test_a_sequence_needs_steps():
    with pytest.raises(SequenceError, match="at least one step"):
        validate(Sequence("empty", "", ()), LIMITS)


def test_python_and_file_give_the_same_problems():
    """One validation path: the file written from a bad Python sequence is refused identically."""
    sequence = Sequence(
        "mixed",
        "",
        (
            DwellGrid((10.0, 150.0, 70.0), (1.0, 5.0)),
            Sweep(1.0, 30.0, 10.0, "2"),
            Prompt("p", "Set", answer="number", minimum=0.5, maximum=4.5, action="set_tyre_pressure"),
            SineDwell(math.nan, 1.0),
        ),
    )
    with pytest.raises(SequenceError) as from_python:
        validate(sequence, LIMITS)
    with pytest.raises(SequenceError) as from_file:
        parse_sequence(dump_sequence(sequence), "mixed.toml", LIMITS)
    assert [(p.key, p.message) for p in from_file.value.problems] == [
        (p.key, p.message) for p in from_python.value.problems
    ]
    assert len(from_python.value.problems) == 6  # 5 mm at 70 Hz: velocity and acceleration


def test_a_valid_sequence_survives_the_file_round_trip():
    sequence = Sequence(
        "round trip",
        'quotes " and \\ and unicode: ±',
        (
            Hydraulics("low"),
            Hydraulics("high"),
            FreeRun(DwellGrid((10.0, 100.0), (2.0,), max_acceleration_m_s2=400.0, label="free")),
            Prompt(
                "d", "Damper?", answer="choice", choices=("soft", "firm"), action="set_damper", target="soft"
            ),
            SineDwell(12.5, 1.5, mean_mm=-2.0),
            Sweep(30.0, 0.5, 20.0, 1.0, law="log"),
            HammerTest(150.0, blows=2),
            MeanPosition(-3.0),
            Tare(),
        ),
    )
    validate(sequence, LIMITS)
    back = parse_sequence(dump_sequence(sequence), "<script>", LIMITS)
    assert back == sequence


def test_step_fields_is_flat_and_typed():
    grid = DwellGrid((10.0,), (2.0,), label="x")
    assert step_fields(FreeRun(grid))["type"] == "free_run"
    assert step_fields(FreeRun(grid))["freqs_hz"] == [10.0]
    limited = DwellGrid((70.0,), (5.0,), max_velocity_mm_s=1500.0).dwells()[0]
    assert step_fields(limited)["requested_amplitude_mm"] == 5.0
    assert step_fields(limited)["amplitude_limited_by"] == "velocity"


def test_prompt_answers():
    pressure = Prompt("p", "Set 2.5 bar", answer="number", unit="bar", minimum=0.5, maximum=4.5, target=2.5)
    assert pressure.check_answer("2.4") == 2.4 and pressure.check_answer(3) == 3.0
    for bad in ("abc", 5.0, True, math.nan, None):
        with pytest.raises(AnswerError, match=r"within 0.5..4.5 bar"):
            pressure.check_answer(bad)
    choice = Prompt("d", "Damper", answer="choice", choices=("soft", "firm"))
    assert choice.check_answer("firm") == "firm"
    with pytest.raises(AnswerError, match=r"\['soft', 'firm'\]"):
        choice.check_answer("hard")
    confirm = Prompt("c", "Fit the wheel")
    assert confirm.check_answer(True) is True and confirm.check_answer(" Yes ") is True
    assert confirm.check_answer("no") is False
    with pytest.raises(AnswerError, match="yes or no"):
        confirm.check_answer(1)


def test_hammer_strike_prompt_is_a_valid_prompt():
    hammer = HammerTest(200.0, blows=3)
    prompt = hammer.strike_prompt(2)
    assert prompt.action == "strike_hammer" and "2 of 3" in prompt.text
    validate(Sequence("h", "", (prompt,)), LIMITS)


def test_steps_are_frozen():
    dwell = SineDwell(10.0, 1.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        dwell.amplitude_mm = 2.0
