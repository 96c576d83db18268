"""The four-post force ratio's reported uncertainty against its actual scatter over noise seeds.

The same simulated sweep (the paper's 0.1-30 Hz over 60 s at 2 mm; linear Model-2 tyre, so the
plant's exact F_WFS/F_contact comes from its network) recorded with 30 noise realisations (12 s). The
former estimate (ratio of two Welch FRFs) reported the right uncertainty on the low flank (the
first segment's Hann window weighs the 0.61 Hz bin 0.14), several times the scatter in the middle
of the band (the coherence counting the window's spread across a sweeping bin as noise) and
covered the truth in few of the bins above 27.5 Hz (biased there). The ratio over the whole record
(``sweep_ratio``): each test prints its band's coverage and sigma over scatter (``pytest -m
validation -s``) and asserts that docs/analysis.md says them.
"""

import numpy as np
import pytest

from bench.analysis.plate_mass import PlateMass
from bench.analysis.quarter_car_fit import four_post_frfs
from bench.models.benches import TyreModel
from bench.models.setup import BenchSetup
from bench.simulated_campaign import PAPER_SWEEP, simulate_sweep
from tests.documented import assert_documented

SEEDS = range(500, 530)
#: The analysed record is cut where the model compensator's window leaves it (its 160 taps at 1 kHz).
CUT_SAMPLES = 80
#: A complex error with circular Gaussian parts of total variance sigma^2 lies within this many
#: sigma with probability 95 % (|e|^2 / sigma^2 is exponential: P = 1 - exp(-r^2)).
RADIUS_95 = np.sqrt(np.log(20.0))
CHANNELS = ("z_base_m", "f_plate_n", "fz_wfs_n", "a_hub_m_s2")


@pytest.fixture(scope="module")
def ratios():
    """F_WFS/F_contact of every seed, its reported sigma, the bins and the exact ratio there."""
    setup = BenchSetup.paper_quarter_car(2.5, model=TyreModel.WHEEL_TREAD, nonlinear=False)
    plate = PlateMass(setup.rig.plate_mass_kg, 0.0, 0.0, len(SEEDS))  # its error is not at issue here
    values, sigmas = [], []
    for seed in SEEDS:
        sweep = simulate_sweep(setup, PAPER_SWEEP, seed=seed)
        rec = {c: sweep.channels[c][CUT_SAMPLES:-CUT_SAMPLES] for c in CHANNELS}
        ratio = four_post_frfs(rec, sweep.sample_rate_hz, plate, band_hz=(0.1, 30.0)).per_contact["f_wfs"]
        values.append(ratio.value)
        sigmas.append(ratio.sigma)
    f = ratio.freq_hz
    response = setup.network().frequency_response(f)
    return f, np.array(values), np.array(sigmas), response["f_wfs"] / response["f_contact"]


def _coverage_and_sigma_over_scatter(ratios, lo_hz: float, hi_hz: float) -> tuple[float, float, int]:
    """Share of (seed, bin) intervals holding the exact ratio, and the rms reported sigma over the
    rms scatter of the seeds about their mean (pooled over the bins in ``[lo_hz, hi_hz]``)."""
    f, h, sigma, exact = ratios
    sel = (f >= lo_hz) & (f <= hi_hz)
    h, sigma, exact = h[:, sel], sigma[:, sel], exact[sel]
    covered = float(np.mean(np.abs(h - exact) <= RADIUS_95 * sigma))
    n = h.shape[0]
    scatter = np.sqrt(np.mean(np.abs(h - h.mean(axis=0)) ** 2) * n / (n - 1))
    return covered, float(np.sqrt(np.mean(sigma**2)) / scatter), h.size


@pytest.mark.validation
def test_low_flank_intervals_cover_the_truth_and_are_not_wider_than_the_scatter(ratios):
    """0.45-1.15 Hz (6 bins, 180 intervals): coverage 95 % has a binomial sd of 1.6 %, so at least
    89 %; the scatter from 348 degrees of freedom has a relative sd of 3.8 %: sigma over scatter
    0.85-1.15 (seeds 500-529, 600-629, 700-729 gave coverage 95, 91, 94 %, ratio 1.01, 1.01, 0.95)."""
    covered, ratio, n = _coverage_and_sigma_over_scatter(ratios, 0.45, 1.15)
    assert n == 180
    assert covered >= 0.89, covered
    assert 0.85 <= ratio <= 1.15, ratio
    f, _, sigma, exact = ratios
    at = int(np.argmin(np.abs(f - 0.61)))
    relative = np.sqrt(np.mean(sigma[:, at] ** 2)) / abs(exact[at])
    assert relative < 0.03  # was 5.3 % (Welch ratio)
    said = (
        f"{100 * relative:.1f} % at {f[at]:.2f} Hz; at 0.45-1.15 Hz coverage {100 * covered:.0f} %"
        f" with sigma/scatter {ratio:.2f}"
    )
    print(f"\n  {said}")
    assert_documented("docs/analysis.md", said)


@pytest.mark.validation
def test_mid_band_intervals_cover_the_truth_and_are_not_wider_than_the_scatter(ratios):
    """2.2-27.5 Hz (6210 intervals: binomial sd 0.3 %): coverage 93-97 %; sigma over scatter
    0.95-1.1 (the residual of a ratio linear in frequency over three bins still holds a little of
    the ratio's curvature; the three seed sets gave 95 % and 1.00-1.02)."""
    covered, ratio, n = _coverage_and_sigma_over_scatter(ratios, 2.2, 27.5)
    assert n == 6210
    assert 0.93 <= covered <= 0.97, covered
    assert 0.95 <= ratio <= 1.1, ratio
    said = f"at 2.2-27.5 Hz {100 * covered:.0f} % with {ratio:.2f}"
    print(f"\n  {said}")
    assert_documented("docs/analysis.md", said)


@pytest.mark.validation
def test_top_flank_is_no_longer_biased_beyond_its_intervals(ratios):
    """27.5-29.2 Hz: the ratio of Welch FRFs covered the truth 7 % of the time there (its flank bias
    does not cancel where the ratio changes with frequency); now 89-93 % over 420 intervals (the end
    ramp leaves a bias below 0.1 %), so at least 85 %."""
    covered, _, _ = _coverage_and_sigma_over_scatter(ratios, 27.5, 29.2)
    assert covered >= 0.85, covered
    said = f"at 27.5-29.2 Hz {100 * covered:.0f} %"
    print(f"\n  {said}")
    assert_documented("docs/analysis.md", said)
