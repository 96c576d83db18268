"""The four-post valid bands' ends: the sweep's flank bias cancels in the force ratios, so their bands
start where the ratio's own uncertainty allows, not where the over-Z estimates stop; the summary says
why each end is where it is and where the flagged bins lie; one noisy bin does not end a band."""

import re

import numpy as np

from bench.analysis.frf import valid_band
from bench.report.text import summary_lines


def test_force_ratio_bands_reach_the_sweeps_ends(four_post_analysis):
    """The paper's 0.1-30 Hz sweep over 60 s: the bands began at 2.319 Hz whatever the sweep (the
    flank mask of the over-Z FRFs applied to the ratios), then at 0.73 Hz (the ratio of two Welch
    FRFs: 5.3 % uncertainty at 0.61 Hz, the first segment's Hann window weighing that bin 0.14), and
    the model-compensated band ended at 27.8 Hz. Now: from the 0.6104 Hz bin (the ratio over the
    whole record, 2-3 % there; the bin below has over 5 % or is unreliable over Z), and the
    model-compensated band to at least 29 Hz or a named limit."""
    _, result = four_post_analysis
    for band in (
        result.valid_band_raw,
        result.valid_band_hub_compensated,
        result.valid_band_model_compensated,
    ):
        assert band.lowest_hz <= 0.62, band
        assert re.fullmatch(
            r"the \d+ points below too uncertain to judge|\d+ unreliable points below",
            band.starts_at,
        ), band
    model = result.valid_band_model_compensated
    assert model.upper_hz >= 29.0 or model.limited_by in ("amplitude", "phase"), model
    text = "\n".join(summary_lines(result))
    raw = result.valid_band_raw
    assert f"raw {raw.lowest_hz:.4g}-" in text and f"(starts: {raw.starts_at}" in text
    assert "on the sweep's flanks 0.4883-2.197 Hz" in text and "low excitation or coherence 0.1221-" in text
    # the quarter car still uses only the bins reliable over Z (the flank bias is real there)
    assert result.quarter_car.band_hz[0] > 2.0


def test_one_unreliable_point_does_not_end_a_sweep_band():
    f = np.linspace(1, 10, 10)
    h = np.ones(10, complex)
    reliable = np.ones(10, bool)
    reliable[4] = False
    band = valid_band(f, h, reliable, max_gap_points=1)
    assert band.upper_hz == 10.0 and band.skipped_hz == (5.0,) and band.n_points == 9
    reliable[5] = False  # two in a row end it
    band = valid_band(f, h, reliable, max_gap_points=1)
    assert band.upper_hz == 4.0 and band.limited_by == "unreliable point" and band.skipped_hz == ()
    assert valid_band(f, h, reliable).upper_hz == 4.0  # dwell grids: any unreliable point ends it
