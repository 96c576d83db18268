"""Coverage of the quarter car's 95 % intervals over noise seeds on the simulated four-post bench.

Each seed is a whole independent campaign of the paper's corner at 2.5 bar (non-linear tyre, Model
2 or 3 as the truth): the shaker's free run and 2 mm dwell grid of the same tyre, the post's free
run and the 0.1-30 Hz sweep at 2 mm, all with their own noise, analysed as the bench analyses them
(:func:`analyse_shaker_campaign`, then :func:`analyse_four_post` with that shaker campaign). Per
fitted suspension parameter and for the body and wheel modes: in how many seeds the 95 % interval
holds the simulator's value, the mean and rms of the error in units of the interval's half-width
(a correct interval: about 0.5 rms, 95 % covered), and the mean error in percent (a bias shows as
a mean error near its rms). The simulator's modes are those of its car with the tyre's stiffness
rise at each mode (its friction only damps them); its tyre's friction force is 4 N.

    PYTHONPATH=. .venv/bin/python benchmarks/quarter_car_coverage.py --seeds 20 --model 2

Its last line sums up what docs/analysis.md quotes (``--model 3`` prints the same for that car).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bench.analysis import analyse_shaker_campaign
from bench.analysis.quarter_car_fit import quarter_car_modes
from bench.analysis.runs import analyse_four_post
from bench.analysis.shaker_models import RubberTerms
from bench.models.benches import TyreModel
from bench.models.setup import BenchKind, BenchSetup
from bench.simulated_campaign import (
    FREE_RUN_GRID_HZ,
    PAPER_SWEEP,
    SHAKER_GRID_HZ,
    simulate_dwells,
    simulate_sweep,
)
from benchmarks.documented import Documented

#: Seeded campaigns: the same figures every run (about 45 s for the Model 2 car's 20 seeds).
DOCUMENTED = Documented(
    ("--seeds", "20", "--model", "2"), quoted={"summary (docs/analysis.md): ": "docs/analysis.md"}
)

AMPLITUDE_M = 2e-3
#: The fitted parameter of each field of the simulator's suspension.
PARAMETERS = {
    "unsprung_mass_above_kg": "unsprung_mass_above_kg",
    "suspension_stiffness_n_per_m": "stiffness_n_per_m",
    "suspension_damping_ns_per_m": "damping_ns_per_m",
    "body_mass_kg": "body_mass_kg",
}
MODES = ("body_frequency_hz", "wheel_frequency_hz")
FRICTION = "tyre_friction_force_n"


def truth_of(car: BenchSetup) -> dict[str, float]:
    """The simulator's suspension parameters and modes, by the names of the fit's."""
    rise = RubberTerms(stiffness_rise_per_decade=car.nonlinearity.stiffness_rise_per_decade)
    (body_hz, _), (wheel_hz, _) = quarter_car_modes(car.model, car.tyre, car.suspension, car.sensor, rise)
    return {
        **{name: getattr(car.suspension, field) for name, field in PARAMETERS.items()},
        MODES[0]: body_hz,
        MODES[1]: wheel_hz,
        FRICTION: car.nonlinearity.friction_force_n,
    }


def campaign_errors(model: TyreModel, seed: int) -> tuple[dict[str, tuple[float, float]], float]:
    """One independent campaign: per suspension parameter and mode (error, 95 % half-width)
    against the simulator, and the reduced chi^2 of the quarter car's fit."""
    car = BenchSetup.paper_quarter_car(2.5, model=model)
    shaker = BenchSetup.paper_shaker(2.5, model=model, nonlinear=True)
    free = simulate_dwells(BenchSetup.paper_free_run(), FREE_RUN_GRID_HZ, 2e-3, seed=1000 + seed)
    grid = simulate_dwells(shaker, SHAKER_GRID_HZ, AMPLITUDE_M, seed=2000 + seed)
    tyre = analyse_shaker_campaign(grid, free, wheel_mass_kg=shaker.tyre.wheel_mass_kg, sensor=shaker.sensor)
    post_rig = BenchSetup(BenchKind.FREE_RUN, rig=car.rig)
    post = simulate_dwells(post_rig, FREE_RUN_GRID_HZ, 2e-3, seed=3000 + seed)
    sweep = simulate_sweep(car, PAPER_SWEEP, seed=4000 + seed)
    fit = analyse_four_post(
        sweep, post, tyre=tyre, wheel_mass_kg=car.tyre.wheel_mass_kg, sensor=car.sensor
    ).quarter_car
    found = {
        **{name: (fit.values[name], fit.ci95[name]) for name in PARAMETERS},
        MODES[0]: (fit.body_frequency_hz, fit.body_frequency_ci95_hz),
        MODES[1]: (fit.wheel_frequency_hz, fit.wheel_frequency_ci95_hz),
        FRICTION: (fit.values[FRICTION], fit.ci95[FRICTION]),
    }
    truth = truth_of(car)
    return {name: (value - truth[name], half) for name, (value, half) in found.items()}, fit.reduced_chi2


def summary(truth: dict[str, float], rows: list[dict[str, tuple[float, float]]]) -> str:
    """The coverage in one sentence: k_s's mean error (percent and half-widths), how many seeds'
    intervals hold each parameter and mode, and the friction force's mean against the simulator's."""

    def covered(name: str) -> int:
        return sum(abs(row[name][0]) <= row[name][1] for row in rows)

    def mean_pct(name: str) -> float:
        return 100 * float(np.mean([row[name][0] for row in rows])) / truth[name]

    k_s, n = "suspension_stiffness_n_per_m", len(rows)
    k_units = float(np.mean([row[k_s][0] / row[k_s][1] for row in rows]))
    friction_half = 100 * float(np.mean([row[FRICTION][1] for row in rows])) / truth[FRICTION]
    return (
        f"k_s {mean_pct(k_s):+.2f} % ({k_units:+.2f} half-widths), covered in {covered(k_s)} of {n};"
        f" m_h, d_s and m_B in {covered('unsprung_mass_above_kg')}, {covered('suspension_damping_ns_per_m')}"
        f" and {covered('body_mass_kg')} of {n}; the body mode {mean_pct(MODES[0]):+.2f} % and the wheel"
        f" mode {mean_pct(MODES[1]):+.2f} %, in {covered(MODES[0])} and {covered(MODES[1])} of {n};"
        f" the friction force {truth[FRICTION] * (1 + mean_pct(FRICTION) / 100):.2f} N for the"
        f" simulator's {truth[FRICTION]:g} N ({mean_pct(FRICTION):+.1f} %, half-width"
        f" {friction_half:.1f} %), covered in {covered(FRICTION)} of {n}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20, help="independent campaigns (seeds 0..N-1)")
    parser.add_argument("--model", type=int, choices=(2, 3), default=2, help="the tyre model of the truth")
    args = parser.parse_args()
    model = TyreModel(args.model)
    truth = truth_of(BenchSetup.paper_quarter_car(2.5, model=model))
    rows: list[dict[str, tuple[float, float]]] = []
    start = time.perf_counter()
    for seed in range(args.seeds):
        errors, reduced_chi2 = campaign_errors(model, seed)
        rows.append(errors)
        print(
            f"seed {seed}: "
            + ", ".join(
                f"{name} {100 * e / truth[name]:+.3f} % ({e / half:+.2f} half-widths)"
                for name, (e, half) in errors.items()
            )
            + f"; reduced chi^2 {reduced_chi2:.3g}",
            flush=True,
        )
    print(f"\nModel {args.model} car, {args.seeds} seeds ({time.perf_counter() - start:.0f} s):")
    for name, true in truth.items():
        e = np.array([row[name][0] for row in rows])
        units = e / np.array([row[name][1] for row in rows])
        half_pct = 100 * np.mean([row[name][1] for row in rows]) / true
        print(
            f"  {name}: covered in {int(np.sum(np.abs(units) <= 1))} of {units.size};"
            f" error {100 * e.mean() / true:+.3f} % mean, half-width {half_pct:.3f} % mean;"
            f" in half-widths {units.mean():+.2f} mean, {np.sqrt(np.mean(units**2)):.2f} rms"
        )
    print(f"summary (docs/analysis.md): {summary(truth, rows)}")


if __name__ == "__main__":
    main()
