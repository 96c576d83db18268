"""The chi^2 test against estimated uncertainties (``lsq.chi2_exceedance``) against a seeded
Monte-Carlo of what it describes: residual pairs whitened by variances estimated with a few degrees
of freedom each."""

import numpy as np
import pytest
from scipy.stats import chi2 as chi2_distribution

from bench.analysis.lsq import (
    chi2_beyond_noise,
    chi2_exceedance,
    chi2_far_outside_noise,
)
from tests.documented import assert_documented

DRAWS = 400_000


def whitened_chi2(rng: np.random.Generator, dof: int, noise_dof: int) -> np.ndarray:
    """Chi^2 of ``dof`` unit-variance residuals, each pair (and an odd one) divided by its own
    variance estimate of ``noise_dof`` degrees of freedom."""
    pairs, single = divmod(dof, 2)
    total = np.zeros(DRAWS)
    for numerator in [2] * pairs + [1] * single:
        estimate = rng.chisquare(noise_dof, DRAWS) / noise_dof
        total += rng.chisquare(numerator, DRAWS) / estimate
    return total


@pytest.mark.parametrize(("dof", "noise_dof"), [(5, 16), (2, 16), (39, 16), (4, 40)])
def test_the_exceedance_is_the_monte_carlo_one(dof, noise_dof):
    simulated = whitened_chi2(np.random.default_rng(dof * 100 + noise_dof), dof, noise_dof)
    for quantile in (0.5, 0.9, 0.99, 0.999):
        value = float(np.quantile(simulated, quantile))
        expected = 1 - quantile
        sigma = np.sqrt(expected * quantile / DRAWS)  # the simulated tail's binomial standard error
        assert chi2_exceedance(value, dof, noise_dof) == pytest.approx(expected, abs=4 * sigma)


def test_known_variances_give_the_chi2_distribution():
    for dof in (1, 5, 30):
        for value in chi2_distribution.ppf([0.5, 0.99, 0.999], dof):
            known = chi2_distribution.sf(value, dof)
            assert chi2_exceedance(value, dof, 10**6) == pytest.approx(known, rel=0.01)


def test_estimated_variances_widen_the_limit():
    """Three free-run points (5 degrees of freedom): the chi^2 distribution's 99.9 % quantile is
    passed by about 0.9 % of good fits when each variance has 16 degrees of freedom."""
    limit = chi2_distribution.ppf(0.999, 5)
    exceedance = chi2_exceedance(limit, 5, 16)
    assert 0.008 < exceedance < 0.011
    said = f"99.9 % quantile ({limit:.1f}) is exceeded by {100 * exceedance:.2f} % of good free runs"
    print(f"\n  {said}")
    assert_documented("docs/analysis.md", said)
    assert not chi2_far_outside_noise(limit, 5, 16)
    assert chi2_far_outside_noise(40.0, 5, 16) and not chi2_beyond_noise(40.0, 5, 16)
    assert chi2_beyond_noise(1e4, 5, 16)


def test_the_exceedance_falls_with_chi2_and_ends_at_zero():
    values = np.linspace(0, 500, 200)
    exceedance = [chi2_exceedance(v, 5, 16) for v in values]
    assert exceedance[0] == 1.0 and np.all(np.diff(exceedance) <= 0)
    assert chi2_exceedance(1e9, 5, 16) == 0.0
    assert chi2_exceedance(float("nan"), 5, 16) == 1.0
