"""What the reports say is what was done: m_comp and m_wheel are printed with 95 % intervals like
every other +/- (labelled so; the JSON keeps their standard uncertainties, named sigma); a
four-post sweep's declared amplitude is checked against the measured one and flagged when far off;
the sensor a four-post analysis took is credited to where it came from, not to a hammer test that
did not run."""

from __future__ import annotations

import re
from dataclasses import replace

import pytest

from bench.analysis import analyse_four_post
from bench.analysis.campaign import SensorSource
from bench.analysis.lsq import Z95
from bench.report.text import summary_lines


@pytest.fixture(scope="module")
def analysed(four_post, four_post_free_run, request):
    """The paper's four-post run analysed as the campaign analysis does without a hammer run."""
    from tests.analysis.conftest import same_tyre_campaign

    setup, sweep = four_post
    tyre = same_tyre_campaign(setup, request)
    kw = {"tyre": tyre, "wheel_mass_kg": 29.0, "sensor": setup.sensor}
    return (
        sweep,
        kw,
        analyse_four_post(sweep, four_post_free_run.records, sensor_source=SensorSource.DEFAULT.text, **kw),
    )


def test_m_comp_and_m_wheel_are_printed_with_their_95_percent_intervals(analysed):
    _, _, result = analysed
    text = "\n".join(summary_lines(result))
    m_comp = re.search(r"^post m_comp ([\d.]+) \+/- (\S+) kg \(95 %\) from", text, re.M)
    m_wheel = re.search(r"^m_wheel ([\d.]+) \+/- (\S+) kg \(95 %\) from the run", text, re.M)
    assert m_comp and m_wheel, text
    assert float(m_comp[2]) == pytest.approx(Z95 * result.post_free_run.plate.sigma_kg, rel=0.1)
    assert float(m_wheel[2]) == pytest.approx(Z95 * result.wheel_mass.sigma_kg, rel=0.05)


def test_the_sensor_is_credited_to_its_source_not_to_a_hammer_test_that_did_not_run(analysed):
    _, _, result = analysed
    given = result.quarter_car.taken_as_given
    assert (
        "sensor stiffness and damping (assumed: no hammer test in the campaign, none stated in the"
        in "; ".join(given)
    )
    assert not any("hammer test)" in g for g in given)


def test_the_declared_sweep_amplitude_is_checked_against_the_measured_one(analysed, four_post_free_run):
    sweep, kw, result = analysed
    # the ideal servo follows the 2 mm command: the envelope's median within 1 % of it
    assert result.measured_amplitude_m == pytest.approx(2e-3, rel=0.01)
    assert result.findings == ()
    assert "sweep displacement amplitude: measured 2 mm, declared 2 mm" in summary_lines(result)
    mislabelled = analyse_four_post(replace(sweep, amplitude_m=4e-3), four_post_free_run.records, **kw)
    (finding,) = mislabelled.findings
    assert finding.startswith(
        "sweep 0.1-30 Hz at 4 mm: measured displacement amplitude 2 mm (median over the sweep's middle half)"
        " against the declared 4 mm"
    )
    assert f"FLAG {finding}" in summary_lines(mislabelled)
