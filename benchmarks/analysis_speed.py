"""Wall time to analyse the data volume of the paper's whole campaign, end to end.

Campaign: 9 shaker dwell grids (1 / 2 / 5 mm x 1.5 / 2.5 / 3.5 bar, 22 frequencies 0.5-70 Hz), the
free run (13 frequencies 1-100 Hz), a four-post sweep (0.1-30 Hz over 60 s) and a hammer test
(10 kHz). The records are simulated first (not timed); the analysis then fits every dwell, finds
m_comp, corrects the contact force, identifies Models 1-3 per grid and the amplitude dependence per
pressure, designs the model compensator, estimates m_wheel, compensates the four-post run, computes
its sweep FRFs and valid bands, identifies the quarter car above the sensor (with its body and wheel
modes), and analyses the hammer blow. The baseline, timed in the same run,
is a plain numpy FFT of every recorded channel (the same data volume).

Run: ``OMP_NUM_THREADS=1 python benchmarks/analysis_speed.py`` (one core, as the target states).
"""

from __future__ import annotations

import time

import numpy as np

from bench.analysis.compensation import (
    advance_acceleration,
    design_model_compensator,
    estimate_wheel_mass,
    hub_acceleration_compensation,
)
from bench.analysis.dwell import dwell_frf, fit_dwell
from bench.analysis.fir import apply_aligned, double_differentiator
from bench.analysis.frf import valid_band
from bench.analysis.hammer import analyse_hammer
from bench.analysis.plate_mass import identify_plate_mass, shaker_frfs
from bench.analysis.quarter_car_fit import fit_quarter_car, four_post_frfs
from bench.analysis.sweep import sweep_frfs
from bench.analysis.tyre_fit import amplitude_dependence, identify_shaker
from bench.models.benches import TyreModel
from bench.models.setup import BenchKind, BenchSetup
from simulators.plant import HalfSinePulse, PlantSimulator, SensorRealism, SineDwell, Sweep

FS = 1000.0
SHAKER_HZ = np.r_[0.5, 1, 2, 4, 7, 10, 14, 18, 22, 25, 28, 31, 34, 37, 40, 43, 46, 50, 55, 60, 65, 70]
FREE_HZ = np.r_[1, 2, 5, 10, 20, 30, 40, 50, 60, 70, 80, 90, 100]
CHANNELS = ("z_base_m", "f_plate_n", "fz_wfs_n", "a_hub_m_s2")


def _dwells(setup, freqs, amplitude, seed):
    plant = PlantSimulator(setup, realism=SensorRealism(seed=seed))
    runs = []
    for f in freqs:
        hold = max(1.0, 2.2 / f + 0.2)
        rec = plant.simulate(SineDwell(float(f), amplitude, hold, taper_in_s=0.3, taper_out_s=0.3))
        runs.append((float(f), hold, {c: rec[c] for c in CHANNELS}))
    return runs


def simulate_campaign():
    grids = {
        (p, a): _dwells(BenchSetup.paper_shaker(p), SHAKER_HZ, a, seed=i)
        for i, (p, a) in enumerate((p, a) for p in (1.5, 2.5, 3.5) for a in (1e-3, 2e-3, 5e-3))
    }
    free = _dwells(BenchSetup.paper_free_run(), FREE_HZ, 2e-3, seed=99)
    qc = BenchSetup.paper_quarter_car(2.5, model=TyreModel.WHEEL_TREAD)  # the shaker campaign's tyre
    post_free = _dwells(BenchSetup(BenchKind.FREE_RUN, rig=qc.rig), FREE_HZ, 2e-3, seed=98)
    sweep = PlantSimulator(qc, realism=SensorRealism(seed=7)).simulate(Sweep(0.1, 30.0, 60.0, 2e-3))
    hammer_setup = BenchSetup.paper_hammer()
    hammer = PlantSimulator(hammer_setup, output_rate_hz=10 * FS).simulate(
        HalfSinePulse(amplitude=3000.0, width_s=1.5e-4, delay_s=0.02, record_s=0.3)
    )
    return grids, free, (post_free, sweep), (hammer_setup, hammer)


def _fit_grid(runs):
    return [fit_dwell(ch, FS, f, start_s=0.5, stop_s=0.3 + hold) for f, hold, ch in runs]


def analyse_campaign(grids, free, four_post, hammer):
    plate = identify_plate_mass(dwell_frf(_fit_grid(free), "f_plate_n", "z_base_m"))
    sensor = BenchSetup.paper_hammer().sensor
    idents = {}
    for pressure in (1.5, 2.5, 3.5):
        per_amp = {}
        for amp in (1e-3, 2e-3, 5e-3):
            frfs = shaker_frfs(_fit_grid(grids[(pressure, amp)]), plate)
            per_amp[amp] = (frfs.wfs_per_z, frfs.contact_per_z)
            idents[(pressure, amp)] = identify_shaker(*per_amp[amp], wheel_mass_kg=29.0, sensor=sensor)
        first = idents[(pressure, 1e-3)]
        amplitude_dependence(
            per_amp,
            wheel_mass_kg=29.0,
            sensor=sensor,
            stiffness_rise=first.frequency_dependent_stiffness,
            hysteretic=first.hysteretic_damping,
        )
    fit = idents[(2.5, 2e-3)].best_fit
    comp = design_model_compensator(fit.model, fit.tyre, sensor, fit.rubber, band_hz=80.0)
    post_free, rec = four_post
    post = identify_plate_mass(dwell_frf(_fit_grid(post_free), "f_plate_n", "z_base_m"))
    taps, lat = double_differentiator(FS, band_hz=120.0)
    a_contact = apply_aligned(taps, rec["z_base_m"], lat)
    f_contact = rec["f_plate_n"] - post.mass_kg * a_contact
    keep = slice(lat, -lat)
    mass = estimate_wheel_mass(
        f_contact[keep], rec["fz_wfs_n"][keep], rec["a_hub_m_s2"][keep], FS, a_contact=a_contact[keep]
    )
    acc = advance_acceleration(rec["a_hub_m_s2"], FS, mass.accelerometer_delay_s)
    forces = {
        "raw": rec["fz_wfs_n"],
        "accel": hub_acceleration_compensation(rec["fz_wfs_n"], acc, mass.mass_kg),
        "model": comp.apply(rec["fz_wfs_n"], acc),
    }
    keep = slice(lat, -max(lat, comp.latency_samples))
    frfs = sweep_frfs(
        rec["z_base_m"][keep],
        {"contact": f_contact[keep], **{k: v[keep] for k, v in forces.items()}},
        FS,
        band_hz=(0.3, 30.0),
    )
    c = frfs["contact"].frf
    bands = {
        k: valid_band(c.freq_hz, frfs[k].frf.value / c.value, c.reliable & frfs[k].frf.reliable)
        for k in forces
    }
    car = fit_quarter_car(
        four_post_frfs(rec, FS, post, band_hz=(0.3, 30.0)),
        model=fit.model,
        tyre=fit.tyre,
        sensor=sensor,
        rubber=fit.rubber,
    )
    hsetup, hrec = hammer
    hres = analyse_hammer(hrec["fz_wfs_n"], 10 * FS, hsetup.sensor.mass_kg, hammer_n=hrec["f_hammer_n"])
    return plate, idents, mass, bands, car, hres


def baseline(grids, free, four_post, hammer):
    """A plain FFT of every recorded channel: the cheapest look at the same data."""
    arrays = [ch[c] for runs in (*grids.values(), free, four_post[0]) for _, _, ch in runs for c in CHANNELS]
    arrays += [four_post[1][c] for c in CHANNELS] + [hammer[1]["fz_wfs_n"], hammer[1]["f_hammer_n"]]
    for a in arrays:
        np.fft.rfft(a)
    return sum(a.size for a in arrays)


def main() -> None:
    data = simulate_campaign()
    t0 = time.perf_counter()
    n_samples = baseline(*data)
    t_base = time.perf_counter() - t0
    t0 = time.perf_counter()
    plate, idents, mass, bands, car, hres = analyse_campaign(*data)
    t_analysis = time.perf_counter() - t0
    print(f"data volume: {n_samples} samples ({n_samples * 8 / 1e6:.1f} MB as float64)")
    print(f"baseline numpy FFT of every channel: {1e3 * t_base:.1f} ms")
    print(
        f"analysis end to end: {t_analysis:.3f} s ({t_analysis / t_base:.0f}x the FFT baseline; target < 2 s)"
    )
    print(
        f"m_comp {plate.mass_kg:.3f} kg, m_wheel {mass.mass_kg:.2f} kg,"
        f" hammer f_n {hres.eigenfrequency_hz:.0f} Hz"
    )
    k = {p: idents[(p, 2e-3)].best_fit.tyre.stiffness_n_per_m / 1e3 for p in (1.5, 2.5, 3.5)}
    print("k at 10 Hz, 2 mm [kN/m]: " + ", ".join(f"{p} bar {v:.1f}" for p, v in k.items()))
    print("four-post valid bands: " + ", ".join(f"{n} {b.upper_hz:.1f} Hz" for n, b in bands.items()))
    s = car.suspension
    print(
        f"quarter car: m_h {s.unsprung_mass_above_kg:.2f} kg, k_s {s.stiffness_n_per_m / 1e3:.2f} kN/m,"
        f" d_s {s.damping_ns_per_m:.0f} Ns/m, m_B {s.body_mass_kg:.1f} kg;"
        f" body {car.body_frequency_hz:.3f} Hz, wheel {car.wheel_frequency_hz:.2f} Hz,"
        f" reduced chi^2 {car.reduced_chi2:.1f}, not determined: {list(car.undetermined) or 'none'}"
    )


if __name__ == "__main__":
    main()
