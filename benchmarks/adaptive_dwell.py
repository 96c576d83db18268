"""Adaptive stepped sine against the shipped fixed grid, on the simulated paper campaign.

Both shipped shaker campaigns (``paper_shaker.toml``, ``paper_shaker_adaptive.toml``) run through
the whole chain on the simulated bench (noise, the non-linear tyre, the servo-hydraulic actuator
with the engine's amplitude control), unpaced. From each campaign file, read back as any file:

- excitation time of the tyre grids: every point attempt from its first to its last active sample
  (tapers and the amplitude control's repeats included; the free run is the same in both);
- per tyre grid (pressure x amplitude): ``F_WFS / F_contact`` of the dwells (the analysis's fits and
  the free run's m_comp), read between measured points by linear interpolation in dB and phase,
  against the plant's exact response (the tyre linearised at each frequency for the grid's
  amplitude, as the simulator does) over the grid's 0.5-70 Hz: the largest magnitude (dB) and phase
  (degrees) errors, and the peak's error (largest measured point against the true maximum).

Unpaced, the simulated bench runs ahead of the engine by the frames buffered between them (the
pseudo-terminal and the reader's queue, a few tenths of a second of samples), so an adaptive
dwell's stop lands that much later in sample time than on a bench that runs in real time, where
the lead is a block or two. The excitation time is therefore also measured paced (real time) on
one grid of each campaign (2.5 bar, 2 mm).

    PYTHONPATH=. .venv/bin/python benchmarks/adaptive_dwell.py
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from bench.analysis.interpolation import GridError, grid_error
from bench.analysis.plate_mass import shaker_frfs
from bench.analysis.records import WHEEL_CHANNELS, fit_dwell_record
from bench.analysis.runs import analyse_free_run
from bench.app import run as app_run
from bench.app.plan import plan_sequence
from bench.config import Simulation, default_bench_config
from bench.models.setup import BenchSetup
from bench.store import open_campaign
from benchmarks.timing import run_benchmark
from sequences import DwellGrid, Sequence, crossover_amplitude_mm, load_sequence, shipped_file

FIXED, ADAPTIVE = "paper_shaker.toml", "paper_shaker_adaptive.toml"
BAND_STEP_HZ = 0.05


@dataclass(frozen=True)
class Campaign:
    name: str
    wall_s: float
    excitation_s: float  # the tyre grids' point attempts
    attempts: int
    points: int
    errors: dict[tuple[float, float], GridError]  # (pressure bar, amplitude mm) -> errors


def true_ratio(pressure_bar: float, grid: DwellGrid, nominal_mm: float, freqs_hz: np.ndarray) -> np.ndarray:
    setup = BenchSetup.paper_shaker(pressure_bar)
    out = np.empty(freqs_hz.size, complex)
    for i, f in enumerate(freqs_hz):
        used_mm, _ = crossover_amplitude_mm(f, nominal_mm, grid.max_velocity_mm_s, grid.max_acceleration_m_s2)
        response = setup.operating_network(f, used_mm * 1e-3).frequency_response(
            f, outputs=("f_wfs", "f_contact")
        )
        out[i] = response["f_wfs"][0] / response["f_contact"][0]
    return out


def one_grid(sequence: Sequence, label: str, amplitude_mm: float) -> Sequence:
    """The steps of the grid labelled ``label`` (from its hydraulics and pressure prompt on), at
    one amplitude."""
    i = next(k for k, s in enumerate(sequence.steps) if isinstance(s, DwellGrid) and s.label == label)
    steps = (*sequence.steps[i - 4 : i], replace(sequence.steps[i], amplitudes_mm=(amplitude_mm,)))
    return Sequence(f"{sequence.name}_{label}", sequence.description, steps, sequence.source)


def run_campaign(name: str, *, paced: bool = False) -> Campaign:
    """The shipped campaign unpaced, or paced its 2.5 bar grid at 2 mm (excitation time only)."""
    config = replace(default_bench_config("shaker"), simulation=Simulation(paced=paced))
    path = shipped_file(name)
    sequence = load_sequence(path, config.limits)
    if paced:
        sequence = one_grid(sequence, "2.5 bar", 2.0)
    plan = plan_sequence(sequence, config)
    grids = [s for s in sequence.steps if isinstance(s, DwellGrid)]
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "campaign.h5"
        start = time.perf_counter()
        outcome = app_run.run_campaign(plan, out)
        wall_s = time.perf_counter() - start
        assert outcome.status == "complete", outcome
        errors, excitation, attempts, points = {}, 0.0, 0, 0
        with open_campaign(out) as campaign:
            tyre_runs = [run for run in campaign.runs if run.kind == "dwell_grid"]
            for run in tyre_runs:
                excitation += sum(p.end_sample - p.start_sample for p in run.points) / run.sample_rate_hz
                attempts += len(run.points)
                points += sum(p.status == "done" for p in run.points)
            if paced:
                return Campaign(name, wall_s, excitation, attempts, points, {})
            free = next(run for run in campaign.runs if run.kind == "free_run")
            plate = analyse_free_run(free.dwell_records()).plate
            for run, grid in zip(tyre_runs, grids, strict=True):
                pressure = float(run.conditions["tyre_pressure_bar"])
                records = run.dwell_records()
                for nominal_mm in grid.amplitudes_mm:
                    mine = [r for r in records if abs(r.grid_amplitude_m - nominal_mm * 1e-3) < 1e-9]
                    fits = [fit_dwell_record(r, WHEEL_CHANNELS) for r in mine]
                    frf = shaker_frfs(fits, plate).wfs_per_contact
                    lo, hi = frf.freq_hz[0], frf.freq_hz[-1]
                    band = np.linspace(lo, hi, round((hi - lo) / BAND_STEP_HZ) + 1)
                    truth = true_ratio(pressure, grid, nominal_mm, band)
                    errors[pressure, nominal_mm] = grid_error(frf.freq_hz, frf.value, band, truth)
    return Campaign(name, wall_s, excitation, attempts, points, errors)


def print_times(what: str, fixed: Campaign, adaptive: Campaign) -> None:
    print(what)
    for c in (fixed, adaptive):
        print(
            f"  {c.name}: tyre grids {c.excitation_s:.1f} s of excitation, {c.points} points"
            f" ({c.attempts} attempts); run in {c.wall_s:.1f} s wall"
        )
    print(
        f"  adaptive excitation time: {100 * adaptive.excitation_s / fixed.excitation_s:.1f} %"
        " of the fixed grid's"
    )


def main() -> None:
    fixed, adaptive = run_campaign(FIXED), run_campaign(ADAPTIVE)
    print_times("whole campaign, unpaced:", fixed, adaptive)
    print_times(
        "2.5 bar grid at 2 mm, paced (real time):",
        run_campaign(FIXED, paced=True),
        run_campaign(ADAPTIVE, paced=True),
    )
    print(
        "grid (bar, mm) | max dB error fixed / adaptive | max deg error fixed / adaptive"
        " | peak height % | peak Hz"
    )
    worse = []
    for key, f in fixed.errors.items():
        a = adaptive.errors[key]
        print(
            f"{key[0]:g} bar {key[1]:g} mm | {f.max_db:.2f} / {a.max_db:.2f}"
            f" | {f.max_deg:.1f} / {a.max_deg:.1f}"
            f" | {100 * f.peak_height:+.2f} / {100 * a.peak_height:+.2f}"
            f" | {f.peak_hz:+.2f} / {a.peak_hz:+.2f} (true {f.true_peak_hz:.2f})"
        )
        if a.max_db > f.max_db or a.max_deg > f.max_deg or abs(a.peak_height) > abs(f.peak_height):
            worse.append(key)
    print(f"grids where the adaptive error is larger: {worse or 'none'}")


if __name__ == "__main__":
    run_benchmark(main)
