"""The log frequency axes of the report's figures label enough frequencies to read: 1-2-5 per decade
over wide bands, finer over a band of about a decade (the four-post's hub band, about 2.3-28 Hz, is
labelled below 5 Hz too, where 1-2-5 gave only 5, 10 and 20 Hz)."""

from __future__ import annotations

import pytest

from bench.report.axes import FrequencyLocator
from bench.report.figures import four_post_hub_figure, four_post_ratios_figure


@pytest.mark.parametrize(
    ("low_hz", "high_hz", "ticks_hz"),
    [
        (0.1, 30.0, [0.1, 0.2, 0.5, 1, 2, 5, 10, 20]),
        (0.5, 100.0, [0.5, 1, 2, 5, 10, 20, 50, 100]),
        (2.3, 28.0, [3, 5, 7, 10, 20]),
        (12.0, 38.0, [15, 20, 25, 30, 35]),
    ],
)
def test_frequency_ticks_are_1_2_5_or_finer_when_that_labels_too_few(low_hz, high_hz, ticks_hz):
    assert FrequencyLocator().tick_values(low_hz, high_hz) == pytest.approx(ticks_hz, rel=1e-12)


def test_the_four_post_figures_label_frequencies_below_5_hz(four_post_analysis):
    """The drawn figures: the labels shown inside the view of the shared frequency axis."""
    _, result = four_post_analysis
    for figure in (four_post_hub_figure(result), four_post_ratios_figure(result)):
        figure.canvas.draw()
        phase = figure.axes[-1]
        low, high = phase.get_xlim()
        labelled = [float(t.get_text()) for t in phase.get_xticklabels() if t.get_text()]
        labelled = [f for f in labelled if low <= f <= high]
        assert len(labelled) >= 5, labelled
        assert min(labelled) < 5, (labelled, low, high)
