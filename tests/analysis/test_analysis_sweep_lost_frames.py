"""A four-post sweep that lost frames on the WFS link: analysed on its true sample times.

The paper's 0.1-30 Hz sweep over 60 s (linear: 0.498 Hz/s). Two stretches are cut out of the record
as a link would lose them (1 s from 20 s, 10 Hz, and 0.35 s from 45 s, 22.5 Hz), the record keeping
each sample's true offset (the frame counter). The record is gated around each stretch (all
channels alike), and the bins swept there, with the gate's main lobe, are left out of every FRF;
the coherence test leaves out some more near them. Every bin kept of WFS Fz over the contact force
equals the whole record's within three standard uncertainties of their difference, at least 60 % of
the whole record's bins are kept, and the finding names the stretches. Read as contiguous, the same
samples would put every bin after the first stretch 0.5 Hz off; the analysis refuses that record as
shorter than the sweep it claims.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from bench.analysis.runs import analyse_four_post
from bench.analysis.validation import AnalysisInputError
from tests.analysis.conftest import same_tyre_campaign

LOST_S = ((20.0, 1.0), (45.0, 0.35))


def _cut(sweep, lost_s=LOST_S):
    fs = sweep.sample_rate_hz
    n = len(next(iter(sweep.channels.values())))
    keep = np.ones(n, bool)
    for start_s, length_s in lost_s:
        keep[round(start_s * fs) : round((start_s + length_s) * fs)] = False
    offsets = np.flatnonzero(keep)
    channels = {name: np.asarray(x)[keep] for name, x in sweep.channels.items()}
    return replace(sweep, channels=channels, sample_offsets=offsets), replace(sweep, channels=channels)


@pytest.fixture(scope="module")
def analysed(four_post, four_post_free_run, request):
    setup, sweep = four_post
    tyre = same_tyre_campaign(setup, request)

    def analyse(record):
        return analyse_four_post(
            record,
            four_post_free_run.records,
            tyre=tyre,
            wheel_mass_kg=setup.tyre.wheel_mass_kg,
            sensor=setup.sensor,
        )

    lossy, contiguous = _cut(sweep)
    return analyse(sweep), analyse(lossy), contiguous, analyse


def test_the_bins_swept_while_frames_were_lost_are_left_out(analysed):
    whole, lossy, _, _ = analysed
    f = lossy.wfs_per_contact.freq_hz
    assert np.array_equal(f, whole.wfs_per_contact.freq_hz)
    usable = lossy.wfs_per_contact.reliable
    for start_s, length_s in LOST_S:  # 0.1 Hz + 0.4983 Hz/s x t
        lo, hi = (0.1 + (30 - 0.1) / 60 * t for t in (start_s, start_s + length_s))
        assert not usable[(f >= lo) & (f <= hi)].any()
    both = usable & whole.wfs_per_contact.reliable
    # most of what the whole record gives is kept (the coherence test leaves out more bins near the
    # stretches, where the gate's sidelobes reach bins of little energy)
    assert both.sum() >= 0.6 * whole.wfs_per_contact.reliable.sum(), f[
        whole.wfs_per_contact.reliable & ~usable
    ]
    h, s = lossy.wfs_per_contact.value[both], lossy.wfs_per_contact.sigma[both]
    h0, s0 = whole.wfs_per_contact.value[both], whole.wfs_per_contact.sigma[both]
    off = np.abs(h - h0) / (np.hypot(s, s0) + 1e-3 * np.abs(h0) / 3)
    assert np.all(off <= 3), list(zip(f[both][off > 3].round(2), off[off > 3].round(1), strict=True))
    (finding,) = [x for x in lossy.findings if "frames lost on the WFS link" in x]
    assert "1350 frames lost" in finding and "19.95-21.05 s" in finding and "44.95-45.40 s" in finding


def test_read_as_contiguous_the_same_samples_are_refused(analysed):
    """The samples after the first stretch, read one after another, would be 1 s early: the record
    is 1.35 s shorter than the 60 s sweep it claims, and refused."""
    _, _, contiguous, analyse = analysed
    with pytest.raises(AnalysisInputError, match=r"the record is 58\.65 s long but the sweep takes 60 s"):
        analyse(contiguous)
