"""Model choice and compensated band for Model-3 tyres whose sidewall mode lies just above the band.

The paper's non-linear tyre at 2.5 bar on the simulated shaker, 2 mm dwells on the standard grid
(0.5-70 Hz), with a sidewall whose mode with the rim held, ``sqrt((L + U) / m_sw) / 2 pi``, lies
above the grid's top; analysed as the bench analyses a grid (:func:`analyse_shaker_campaign` with
the free run). Per tyre: the model chosen, how many findings, Model 2's and the chosen model's
reduced chi^2, what the chosen fit does not determine and the compensated valid band. Summary: how
often each model is chosen, how often the compensated band reaches the grid's top, and the ranges
of the reduced chi^2, and the line docs/analysis.md quotes (``summary (docs/analysis.md): ``).

    PYTHONPATH=. .venv/bin/python benchmarks/sidewall_above_band.py          # 48 tyres x seeds
    PYTHONPATH=. .venv/bin/python benchmarks/sidewall_above_band.py --wide   # 96 tyres, one seed
    PYTHONPATH=. .venv/bin/python benchmarks/sidewall_above_band.py --linear # the 48 on a linear tyre
"""

from __future__ import annotations

import argparse
import itertools
import time
from collections import Counter
from dataclasses import replace

import numpy as np

from bench.analysis import analyse_shaker_campaign
from bench.models.benches import TyreModel
from bench.models.setup import BenchSetup
from bench.simulated_campaign import FREE_RUN_GRID_HZ, SHAKER_GRID_HZ, simulate_dwells
from benchmarks.documented import Documented

#: The default set (48 tyres, about 45 s; seeded, so the same counts and chi^2 every run) is quoted;
#: ``--wide`` (96 tyres) takes twice that and is not run by the tests.
DOCUMENTED = Documented(quoted={"summary (docs/analysis.md): ": "docs/analysis.md"})

AMPLITUDE_M = 2e-3
#: (sidewall modes in Hz, sidewall masses in kg, upper spring's share of L + U, seeds)
DEFAULT_CASES = ((80.0, 85.0, 90.0, 95.0), (0.5, 1.0), (0.03, 0.3), (1, 2, 3))
WIDE_CASES = ((72.0, 75.0, 80.0, 85.0, 90.0, 95.0), (0.5, 1.0, 2.0, 4.0), (0.03, 0.1, 0.3, 0.7), (16,))


def _setup(mode_hz: float, sidewall_kg: float, upper_share: float, nonlinear: bool = True) -> BenchSetup:
    total = sidewall_kg * (2 * np.pi * mode_hz) ** 2
    setup = BenchSetup.paper_shaker(2.5, model=TyreModel.WHEEL_TREAD_SIDEWALL, nonlinear=nonlinear)
    return setup.with_tyre(
        replace(
            setup.tyre,
            sidewall_mass_kg=sidewall_kg,
            sidewall_lower_stiffness_n_per_m=total * (1 - upper_share),
            sidewall_upper_stiffness_n_per_m=total * upper_share,
        )
    )


def _exponent(x: float) -> str:
    """``x`` to two significant digits as ``2.3e4`` (the document's way of writing it)."""
    mantissa, exponent = f"{x:.1e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--wide", action="store_true", help="the 96-tyre grid with one seed")
    parser.add_argument(
        "--linear", action="store_true", help="the same sidewalls on the linear tyre (no rubber friction)"
    )
    args = parser.parse_args()
    modes, masses, shares, seeds = WIDE_CASES if args.wide else DEFAULT_CASES
    free = simulate_dwells(BenchSetup.paper_free_run(), FREE_RUN_GRID_HZ, 2e-3, seed=11)
    top_hz = float(SHAKER_GRID_HZ[-1])
    chosen: Counter[str] = Counter()
    flagged = reaching_top = 0
    chi2_model2: list[float] = []
    chi2_chosen: list[float] = []
    cpu_s = 0.0
    for mode_hz, mass_kg, share, seed in itertools.product(modes, masses, shares, seeds):
        setup = _setup(mode_hz, mass_kg, share, nonlinear=not args.linear)
        records = simulate_dwells(setup, SHAKER_GRID_HZ, AMPLITUDE_M, seed=seed)
        start = time.process_time()
        result = analyse_shaker_campaign(records, free, wheel_mass_kg=29.0, sensor=setup.sensor)
        cpu_s += time.process_time() - start
        amp = result.nearest(AMPLITUDE_M)
        ident, band = amp.identification, amp.valid_band_compensated
        best = ident.best_fit
        chosen[f"Model {int(ident.best)}"] += 1
        flagged += bool(ident.findings)
        reaching_top += band.upper_hz == top_hz
        chi2_model2.append(ident.fits[TyreModel.WHEEL_TREAD].reduced_chi2)
        chi2_chosen.append(best.reduced_chi2)
        print(
            f"mode {mode_hz:g} Hz, sidewall {mass_kg:g} kg, upper {share:.0%}, seed {seed}:"
            f" Model {int(ident.best)}, {len(ident.findings)} findings, reduced chi^2 Model 2"
            f" {ident.fits[TyreModel.WHEEL_TREAD].reduced_chi2:.3g}, chosen {best.reduced_chi2:.3g},"
            f" not determined {', '.join(best.undetermined) or 'none'}; compensated"
            f" {band.lowest_hz:g}-{band.upper_hz:g} Hz ({band.limited_by})"
            + (f"; {len(amp.unsettled)} dwells not settled" if amp.unsettled else ""),
            flush=True,
        )
    n = sum(chosen.values())
    print(
        f"\n{n} tyres: {', '.join(f'{k} {v}' for k, v in sorted(chosen.items()))}; {flagged} with findings;"
        f" compensated band to {top_hz:g} Hz in {reaching_top}"
    )
    print(
        f"reduced chi^2: Model 2 {min(chi2_model2):.3g}-{max(chi2_model2):.3g},"
        f" chosen {min(chi2_chosen):.3g}-{max(chi2_chosen):.3g}; analysis {cpu_s:.1f} s CPU"
        f" ({cpu_s / n:.2f} s per tyre)"
    )
    print(
        f"summary (docs/analysis.md): {n} runs: Model 2 chosen in {chosen['Model 2']}, Model 3 in"
        f" {chosen['Model 3']}, flagged in {flagged}, the compensated band up to {top_hz:g} Hz in"
        f" {reaching_top}; reduced"
        f" chi^2 of Model 2 {_exponent(min(chi2_model2))}-{_exponent(max(chi2_model2))}, of the chosen"
        f" model {min(chi2_chosen):.2g}-{max(chi2_chosen):.2g}"
    )


if __name__ == "__main__":
    main()
