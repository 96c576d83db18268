"""The shaker figures draw intervals a magnitude and a phase can have: a magnitude interval that
reaches zero runs to the bottom of a log axis (never below zero), a phase interval stays on the
-180..180 deg axis (wrapped), whatever the points' uncertainty."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from bench.analysis import analyse_shaker_campaign
from bench.report.figures import (
    phase_half_width_deg,
    shaker_compensated_figure,
    shaker_figure,
)


@pytest.fixture(scope="module")
def uncertain_campaign(shaker_linear, free_run):
    """The linear paper tyre at 2.5 bar with the measured ratio's uncertainty made as large as an
    m_comp of +/- 3 kg made it (sigma 6x the ratio at the peak, as in a file whose free run had the
    wheel on): the intervals of the points near the peak hold zero."""
    setup = shaker_linear.plant.setup
    result = analyse_shaker_campaign(
        shaker_linear.records, free_run.records, wheel_mass_kg=setup.tyre.wheel_mass_kg, sensor=setup.sensor
    )
    amplitude_m, amp = next(iter(result.amplitudes.items()))
    ratio = amp.frfs.wfs_per_contact
    sigma = np.where(ratio.magnitude > 3, 6.0 * ratio.magnitude, ratio.sigma)
    frfs = replace(amp.frfs, wfs_per_contact=replace(ratio, sigma=sigma))
    compensated = replace(amp.compensated_per_contact, sigma=sigma)
    amp = replace(amp, frfs=frfs, compensated_per_contact=compensated)
    return replace(result, amplitudes={amplitude_m: amp})


def _bar_ends(ax) -> np.ndarray:
    """The y of every end of every interval drawn (error bars and vertical lines)."""
    ends = [seg[:, 1] for coll in ax.collections for seg in coll.get_segments()]
    return np.concatenate(ends)


@pytest.mark.parametrize("draw", [shaker_figure, shaker_compensated_figure])
def test_intervals_stay_on_a_log_magnitude_axis_and_a_wrapped_phase_axis(uncertain_campaign, draw):
    figure = draw(2.5, uncertain_campaign)
    figure.canvas.draw()
    mag, phase = figure.axes
    assert mag.get_yscale() == "log"
    bottom, top = mag.get_ylim()
    assert 0 < bottom < top
    ends = _bar_ends(mag)
    assert np.all(ends >= bottom * (1 - 1e-12)), ends.min()
    # the axis is set by the points and models, not stretched by an interval of 6x the peak
    peak = max(np.max(a.frfs.wfs_per_contact.magnitude) for a in uncertain_campaign.amplitudes.values())
    assert top <= 2 * peak
    low, high = phase.get_ylim()
    assert -200 <= low < -180 and 180 < high <= 200
    phase_ends = _bar_ends(phase)
    assert np.all(np.abs(phase_ends) <= 180 + 1e-9), (phase_ends.min(), phase_ends.max())
    assert np.any(phase_ends == -180) and np.any(phase_ends == 180)  # the uncertain points: any phase


def test_phase_interval_is_the_circle_of_95_percent_radius_around_the_point():
    magnitude = np.array([1.0, 1.0, 1.0, 0.0])
    sigma = np.array([0.0, 0.5 / 1.96, 1.0 / 1.96, 1.0])
    assert phase_half_width_deg(magnitude, sigma) == pytest.approx([0.0, 30.0, 180.0, 180.0])
