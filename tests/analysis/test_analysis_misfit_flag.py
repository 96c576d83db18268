"""A chosen fit whose misfit noise alone gives in fewer than 1 % of fits is flagged: its parameters
may be biased beyond its intervals, which hold the noise alone (``lsq.MISFIT_FLAG_EXCEEDANCE``).

The case that asked for it: the paper's non-linear tyre with a 1 kg sidewall whose mode, with the rim
held, lies at 123 Hz. Its friction acts on the upper sidewall, whose deflection grows towards the
mode, which Model 3's constant hysteretic term cannot follow; the fitted viscous damping takes up the
difference and misses the simulator's 80 Ns/m by 1.7-3.7 half-widths in every seed, so the 95 %
intervals of k, d and m_T together hold the truth in none. No interval can hold a value that a
model leaves out: the fit is flagged instead, in every seed. Flagged when the misfit was far outside
the noise (noise alone: under 0.1 % of fits), 19 of the 20 seeds were; the 20th fit's misfit, 0.35 %,
is outside it. A model that describes the data is flagged once in a hundred fits
(``test_analysis_coverage.py`` counts them over its 100 seeds)."""

from dataclasses import replace

import numpy as np
import pytest

from bench.analysis import analyse_shaker_campaign
from bench.analysis.lsq import MISFIT_FLAG_EXCEEDANCE, OUTSIDE_NOISE_QUANTILE
from bench.models.benches import TyreModel
from bench.models.setup import BenchSetup
from bench.simulated_campaign import FREE_RUN_GRID_HZ, SHAKER_GRID_HZ, simulate_dwells
from tests.documented import assert_documented

SEEDS = 20
#: The sidewall's mode with the rim held, ``sqrt((L + U) / m_sw) / 2 pi``, and its mass; the lower
#: spring (to the tread) takes 70 % of ``L + U``.
SIDEWALL_MODE_HZ, SIDEWALL_KG = 123.0, 1.0
PARAMETERS = ("stiffness_n_per_m", "damping_ns_per_m", "tread_mass_kg")


def _sidewall_123_hz() -> BenchSetup:
    setup = BenchSetup.paper_shaker(2.5, model=TyreModel.WHEEL_TREAD_SIDEWALL, nonlinear=True)
    total = SIDEWALL_KG * (2 * np.pi * SIDEWALL_MODE_HZ) ** 2
    return setup.with_tyre(
        replace(
            setup.tyre,
            sidewall_mass_kg=SIDEWALL_KG,
            sidewall_lower_stiffness_n_per_m=0.7 * total,
            sidewall_upper_stiffness_n_per_m=0.3 * total,
        )
    )


@pytest.mark.validation
def test_a_non_linear_model_3_tyre_is_covered_or_flagged_in_every_seed():
    """Coverage of at least 85 % of the seeds (k, d and m_T each inside its interval), or the fit
    flagged in every seed: the issue's rule. The second holds; the first does not (d is covered in
    none), which is why the flag must fire."""
    setup = _sidewall_123_hz()
    truth = setup.tyre
    covered = dict.fromkeys(PARAMETERS, 0)
    all_covered = flagged = 0
    exceedances = []
    for seed in range(SEEDS):
        free = simulate_dwells(BenchSetup.paper_free_run(), FREE_RUN_GRID_HZ, 2e-3, seed=1000 + seed)
        grid = simulate_dwells(setup, SHAKER_GRID_HZ, 2e-3, seed=2000 + seed)
        identification = (
            analyse_shaker_campaign(grid, free, wheel_mass_kg=truth.wheel_mass_kg, sensor=setup.sensor)
            .nearest(2e-3)
            .identification
        )
        fit = identification.best_fit
        assert identification.best is TyreModel.WHEEL_TREAD_SIDEWALL
        inside = {n: abs(fit.values[n] - getattr(truth, n)) <= fit.ci95[n] for n in PARAMETERS}
        for name, ok in inside.items():
            covered[name] += ok
        all_covered += all(inside.values())
        exceedances.append(fit.misfit_exceedance)
        biased = [f for f in identification.findings if "biased beyond their 95 % intervals" in f]
        flagged += bool(biased)
        assert bool(biased) == (fit.misfit_exceedance < MISFIT_FLAG_EXCEEDANCE)
    print(f"\n  covered {covered}, all three {all_covered}, flagged {flagged} of {SEEDS}")
    print(f"  noise alone gives each misfit in {min(exceedances):.2g} to {max(exceedances):.2g} of fits")
    assert all_covered >= 0.85 * SEEDS or flagged == SEEDS, (covered, flagged)
    assert_documented(
        "docs/analysis.md",
        f"a non-linear Model-3 tyre with a 123 Hz sidewall: k, d and m_T covered in"
        f" {'/'.join(str(c) for c in covered.values())} of {SEEDS} seeds, flagged in {flagged} of {SEEDS}",
    )
    # the former threshold: far outside the noise (noise alone gives the misfit in under 0.1 % of fits)
    far_outside = sum(e < 1 - OUTSIDE_NOISE_QUANTILE for e in exceedances)
    print(f"  far outside the noise (the former threshold): {far_outside} of {SEEDS}")
    assert_documented(
        "docs/analysis.md",
        f"At the old threshold ({100 * (1 - OUTSIDE_NOISE_QUANTILE):.1f} %) {far_outside} of the {SEEDS}"
        " were flagged",
    )
