"""Duration estimates printed the same way, with the same label, by ``wfsbench check`` and the run log:
seconds under a minute (never ``0.0 min``), minutes above, always called bench time."""

from __future__ import annotations

import pytest

from bench.app.check import check_lines
from bench.app.durations import duration_text, sequence_estimate_text
from bench.app.run_log import RunLog
from bench.config import default_bench_config
from bench.dry_run import dry_run
from bench.engine import events as ev
from sequences import load_sequence, shipped_file


@pytest.mark.parametrize(
    ("seconds", "text"),
    [(0.0, "0 s"), (2.9, "3 s"), (29.2, "29 s"), (59.4, "59 s"), (59.6, "1.0 min"), (513.7, "8.6 min")],
)
def test_a_duration_under_a_minute_is_in_seconds(seconds, text):
    assert duration_text(seconds) == text


def test_check_the_run_log_and_the_terminal_ui_print_the_estimate_with_the_same_words():
    """The hammer sequence: 3 captures of 0.3 s, a hydraulics ramp and nothing else (2.9 s), which
    the run log printed as ``0.0 min of excitation``; the terminal UI printed ``0.0 min`` too."""
    config = default_bench_config()
    sequence = load_sequence(shipped_file("hammer.toml"), config.limits)
    assert sequence.estimated_duration_s == pytest.approx(2.9)
    expected = "3 points; about 3 s of bench time, about 4.0 min with the operator's answers"
    assert sequence_estimate_text(sequence) == expected
    assert expected in check_lines(sequence, config, dry_run(sequence, config))
    started = ev.SequenceStarted(
        sequence.name,
        "",
        "",
        sequence.points(),
        sequence.estimated_duration_s,
        sequence.estimated_duration_with_operator_s,
    )
    assert RunLog.line(started) == f"sequence {sequence.name}: {expected}"
