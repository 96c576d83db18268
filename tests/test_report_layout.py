"""The report reads top-down: the summary of the selected model per pressure and amplitude (kN/m,
Ns/m, kg with 95 % intervals) and the valid bands first, then the flags and figures, the full tables
in an appendix; each run's heading names its tyre pressure; text wraps; the shaker figures give
each amplitude its own panels and draw the valid bands as strips along the frequency axis. On the
smoke campaign (one 2 mm grid at 2.5 bar)."""

from __future__ import annotations

import re

import pytest
from matplotlib.patches import Rectangle

from bench.app.analyze import analyze_campaign
from bench.report.figures import BAND_STRIP, shaker_compensated_figure
from bench.report.html import report_html


@pytest.fixture(scope="module")
def analysis(smoke_campaign):
    return analyze_campaign(smoke_campaign)


def test_the_summary_comes_first_and_the_full_tables_last(analysis):
    html = report_html(analysis, [])
    headings = re.findall(r"<h[12][^>]*>([^<]+)</h[12]>", html)
    assert headings[1:4] == ["Summary: tyre, sensor and valid bands", "Flags", "Figures"]
    assert headings[4] == "Appendix: the full tables"
    assert headings.index("Identified tyre parameters, every model (95 % intervals)") > 4
    summary = re.search(r"Summary: tyre, sensor and valid bands</h2>(.*?)<h2>", html, re.S).group(1)
    header = re.findall(r"<th>([^<]*)</th>", summary)
    assert header[3:6] == ["k (kN/m, ± 95 %)", "d (Ns/m, ± 95 %)", "m_T (kg, ± 95 %)"]
    row = re.findall(r"<td[^>]*>([^<]*)</td>", summary)[:9]
    fit = analysis.knowledge.shaker[2.5].amplitudes[2e-3].identification.best_fit
    assert row[:3] == ["2.5 bar", "2 mm", f"Model {int(fit.model)}"]
    k, ci = (float(x) for x in row[3].split(" ± "))
    # the simulated tyre at 2.5 bar: 390 kN/m; the cell shows the fit in kN/m to its interval's digit
    assert k == pytest.approx(fit.values["stiffness_n_per_m"] / 1e3, abs=ci / 10)
    assert ci == pytest.approx(fit.ci95["stiffness_n_per_m"] / 1e3, rel=0.05)
    amp = analysis.knowledge.shaker[2.5].amplitudes[2e-3]
    for cell, band in ((row[6], amp.valid_band_raw), (row[7], amp.valid_band_compensated)):
        if band.determined:  # from, to and why it ends
            assert cell == f"{band.lowest_hz:.3g}-{band.upper_hz:.3g} Hz ({band.limited_by})"
        else:
            assert cell == "not determined"
    assert amp.valid_band_compensated.determined  # the smoke grid's compensated band is drawn below


def test_every_run_heading_names_its_tyre_pressure_and_text_wraps(analysis):
    html = report_html(analysis, [])
    assert re.findall(r"<h3>([^<]+)</h3>", html) == [
        "smoke-s003-free_run (free_run: plate_mass; no wheel on the bench)",
        "smoke-s009-dwell_grid (dwell_grid: shaker; tyre at 2.5 bar)",
        "smoke-s010-sweep (sweep: sweep; tyre at 2.5 bar)",
    ]
    assert "white-space: pre-wrap" in html and "overflow-x: auto" not in html.split("div.wide")[0]


def test_the_valid_bands_are_strips_along_the_frequency_axis(analysis):
    result = analysis.knowledge.shaker[2.5]
    amp = result.amplitudes[2e-3]
    figure = shaker_compensated_figure(2.5, result)
    mag = figure.axes[0]
    strips = [p for p in mag.patches if isinstance(p, Rectangle)]
    placed = [(i, b) for i, b in enumerate((amp.valid_band_raw, amp.valid_band_compensated)) if b.determined]
    assert len(strips) == len(placed) >= 1
    for strip, (i, band) in zip(strips, placed, strict=True):
        x0, x1 = strip.get_x(), strip.get_x() + strip.get_width()
        assert (x0, x1) == pytest.approx((band.lowest_hz, band.upper_hz))
        # in axes coordinates vertically: at the bottom, raw below model-compensated
        assert strip.get_y() == pytest.approx(i * BAND_STRIP) and strip.get_height() == pytest.approx(
            BAND_STRIP
        )
