"""The braille plot's decimation and drawing, against closed forms."""

from __future__ import annotations

import numpy as np

from bench.tui.plot import LABEL_CELLS, Series, column_ranges, render_plot, tick_label


def test_dense_sine_keeps_its_envelope_in_every_column() -> None:
    """5000 samples of a 50 Hz sine over 1 s into 40 dot columns: an inner column spans 1/39 s,
    1.28 periods, so its min and max are the sine's -1 and +1 (within 1 - cos(pi/100) at 100
    samples a period), not an alias; the end columns span half as much."""
    t = np.arange(5000) / 5000
    lo, hi = column_ranges(t, np.sin(2 * np.pi * 50 * t), (0.0, 1.0), 40)
    tolerance = 1 - np.cos(np.pi / 100)
    assert np.allclose(lo[1:-1], -1, atol=tolerance) and np.allclose(hi[1:-1], 1, atol=tolerance)


def test_sparse_points_are_joined_by_straight_lines() -> None:
    """Two points at the ends of 11 columns: the columns between follow the line, each reaching
    its neighbour's value so that the drawn line has no gaps."""
    lo, hi = column_ranges(np.array([0.0, 10.0]), np.array([0.0, 10.0]), (0.0, 10.0), 11)
    assert np.allclose(lo[1:], np.arange(10)) and np.allclose(hi[1:], np.arange(1, 11))
    assert lo[0] == hi[0] == 0.0


def test_rendered_plot_has_its_size_and_marks_the_extremes() -> None:
    x = np.linspace(0, 1, 200)
    lines = render_plot([Series("ramp", x, 3 * x, "red")], width=30, height=4, y_label="N")
    text = ["".join(seg.text for seg in line) for line in lines]
    assert [len(row) for row in text] == [30] * 4
    assert text[0].startswith("       3") and text[-1].startswith("       0")
    plot = [row[LABEL_CELLS:] for row in text]
    # the ramp rises left to right: the top row's dots are at the right, the bottom row's at the left
    assert plot[0][-1] != "\u2800" and plot[0][0] == "\u2800"
    assert plot[-1][0] != "\u2800" and plot[-1][-1] == "\u2800"


def test_axis_labels_are_rounded_to_what_the_axis_resolves() -> None:
    """A phase from -167.9 deg up to 0.0003842 deg reads -168 and 0 at its ends (not 0.0003842);
    small ranges keep their digits, and no label is wider than its cells."""
    x = np.linspace(1.0, 2.0, 50)
    phase = np.linspace(0.0003842, -167.9, 50)
    lines = render_plot([Series("phase", x, phase, "cyan")], 40, 8, "deg")
    labels = ["".join(s.text for s in line)[:LABEL_CELLS].strip() for line in lines]
    assert (labels[0], labels[-1]) == ("0", "-168")
    assert tick_label(0.9995, 12.8) == "1" and tick_label(13.8, 12.8) == "13.8"
    assert tick_label(0.0003842, 0.0004) == "0.000384"
    assert tick_label(-0.009429, 168.0) == "0"  # never "-0"
    for value, span in ((1.2e9, 2e9), (-1e-5, 3e-5), (12345.6, 100.0), (2.5, 0.0)):
        assert len(tick_label(value, span)) <= LABEL_CELLS - 1, (value, span)
