"""The command line's run log shows the refinement as it happens and each adaptive dwell's verdict;
each run's analysis under a heading that names its run."""

from __future__ import annotations

from dataclasses import replace

from bench.app.run_log import RunLog
from bench.engine import events as ev


def test_points_added_by_the_refinement_are_logged_with_their_reason() -> None:
    lines: list[str] = []
    log = RunLog(lines.append)
    log(ev.GridRefined("run", 2.0, ((40.613, "model peak: a single-mode fit puts the peak at 40.61 Hz"),)))
    assert lines == ["  + point at 40.613 Hz (model peak: a single-mode fit puts the peak at 40.61 Hz)"]


def test_an_adaptive_point_shows_its_verdict_and_uncertainty_a_fixed_one_does_not() -> None:
    fixed = ev.PointDone(
        3,
        40.0,
        2.0,
        0,
        300,
        1500,
        1800,
        status="done",
        attempt=1,
        requested_amplitude_mm=2.0,
        commanded_amplitude_mm=2.0,
        achieved_amplitude_mm=1.99,
        run_id="run",
    )
    adaptive = replace(
        fixed,
        index=9,
        freq_hz=40.6,
        hold_end_sample=800,
        end_sample=1100,
        verdict="target",
        settle_s=0.3,
        measure_start_sample=500,
        magnitude_uncertainty_pct=0.41,
        phase_uncertainty_deg=0.24,
    )
    assert RunLog.line(fixed) == "  point 3 at 40 Hz: done, commanded 2.000 mm, achieved 1.990 mm"
    assert RunLog.line(adaptive) == (
        "  point 9 at 40.6 Hz: done, commanded 2.000 mm, achieved 1.990 mm; target, u 0.41 % / 0.24 deg"
    )


def test_an_analysis_is_headed_by_the_run_it_analysed() -> None:
    """The analysis ends after its run, often after the next run started: its lines name their run."""
    done = ev.AnalysisDone("paper-s002-dwell_grid", "shaker", ("tyre 1.5 bar: k 210 N/mm",), {}, "complete")
    assert RunLog.line(done) == "analysis of run paper-s002-dwell_grid (shaker):\n  tyre 1.5 bar: k 210 N/mm"
