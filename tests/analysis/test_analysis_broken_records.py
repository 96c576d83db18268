"""Broken channels and mislabelled records: each is named with why, left out, and the rest of the
campaign is still analysed (the simulated linear shaker grid is the truth)."""

from dataclasses import replace

import numpy as np
import pytest

from bench.analysis import AnalysisInputError, analyse_shaker_campaign
from bench.report.text import summary_lines


def test_broken_and_mislabelled_dwells_are_rejected_by_name(shaker_linear, free_run):
    """A dead WFS channel (zeros: crashed in scipy without naming the record), a frozen one (120 N:
    gave k = 1000 N/m and m_T 17 kg), an actuator that did not move (|Z| 4e-8 m against 2 mm) and a
    37 Hz record labelled 34 Hz (passed as settled and ended the band at 31 Hz); one record declares
    2.0000001 mm (was a second '2 mm' group)."""
    setup = shaker_linear.plant.setup
    by_freq = {r.freq_hz: r for r in shaker_linear.records}
    wfs = "fz_wfs_n"
    broken = {
        10.0: replace(
            by_freq[10.0],
            channels={**by_freq[10.0].channels, wfs: np.zeros_like(by_freq[10.0].channels[wfs])},
        ),
        14.0: replace(
            by_freq[14.0],
            channels={**by_freq[14.0].channels, wfs: np.full_like(by_freq[14.0].channels[wfs], 120.0)},
        ),
        18.0: replace(by_freq[18.0], channels={name: 2e-5 * x for name, x in by_freq[18.0].channels.items()}),
        34.0: replace(by_freq[37.0], freq_hz=34.0),
        50.0: replace(by_freq[50.0], amplitude_m=2.0000001e-3),
    }
    records = [broken.get(f, r) for f, r in by_freq.items()]
    result = analyse_shaker_campaign(records, free_run.records, wheel_mass_kg=29.0, sensor=setup.sensor)
    assert list(result.amplitudes) == [2e-3]
    amp = result.nearest(2e-3)
    rejected = dict(line.split(": ", 1) for line in amp.rejected)
    assert set(rejected) == {f"dwell 2 mm at {f:g} Hz" for f in (10, 14, 18, 34)}
    assert "'fz_wfs_n' carries no signal" in rejected["dwell 2 mm at 10 Hz"]
    assert "'fz_wfs_n' carries no signal" in rejected["dwell 2 mm at 14 Hz"]
    assert "measured displacement amplitude" in rejected["dwell 2 mm at 18 Hz"]
    assert "mislabelled" in rejected["dwell 2 mm at 34 Hz"]
    assert len(amp.fits) == len(records) - 4
    fit = amp.identification.best_fit.tyre
    assert fit.stiffness_n_per_m == pytest.approx(setup.tyre.stiffness_n_per_m, rel=0.02)
    assert fit.tread_mass_kg == pytest.approx(setup.tyre.tread_mass_kg, rel=0.03)
    assert amp.valid_band_compensated.upper_hz == 70.0
    flags = [line for line in summary_lines(result) if line.startswith("FLAG rejected: ")]
    assert len(flags) == 4


def test_a_grid_with_every_dwell_broken_names_them(shaker_linear, free_run):
    setup = shaker_linear.plant.setup
    dead = [
        replace(r, channels={**r.channels, "fz_wfs_n": 0 * r.channels["fz_wfs_n"]})
        for r in shaker_linear.records
    ]
    with pytest.raises(AnalysisInputError, match=r"2 mm: every dwell was rejected \(dwell 2 mm at 0.5 Hz: "):
        analyse_shaker_campaign(dead, free_run.records, wheel_mass_kg=29.0, sensor=setup.sensor)
