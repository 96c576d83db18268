"""Wall time to analyse the data volume of the paper's whole campaign, end to end.

Campaign: 9 shaker dwell grids (1 / 2 / 5 mm x 1.5 / 2.5 / 3.5 bar, 22 frequencies 0.5-70 Hz), the
free run (13 frequencies 1-100 Hz), a four-post sweep (0.1-30 Hz over 60 s) with the post's own
free run, and a hammer test (10 kHz). The records are simulated first (not timed); the analysis
then runs the top-level API: one shaker campaign per pressure (dwell fits, m_comp, contact-force
correction, Models 1-3 per amplitude, amplitude dependence, compensator design, valid bands), the
four-post run with the 2.5 bar campaign as its tyre (m_comp of the post, m_wheel, compensation,
sweep FRFs, valid bands, quarter car with its body and wheel modes), and the hammer blow. The
baseline, timed in the same run, is a plain numpy FFT of every recorded channel (the same data
volume). Each time is the best of ``--repeats``; the Model 1-3 identifications alone (every
grid's ``identify_shaker`` on the FRFs the analysis made) are timed the same way, as their share.
``--campaign FILE`` also times ``analyze_campaign`` of a campaign file (the demo's: the post-run
analysis path, the file's reading included). The lines marked ``(docs/analysis.md)`` are the
figures of the analysed campaign that document quotes (seeded: the same every run).

Run: ``OMP_NUM_THREADS=1 PYTHONPATH=. .venv/bin/python benchmarks/analysis_speed.py [--repeats N]
[--campaign wfsbench-demo/campaign.h5]`` (one core, as the target states). To compare with other
code, put an export of it first on ``PYTHONPATH`` and run this same script.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from bench.analysis.runs import analyse_four_post, analyse_hammer, analyse_shaker_campaign
from bench.analysis.tyre_fit import identify_shaker
from bench.app.analyze import analyze_campaign
from bench.models.setup import BenchSetup
from bench.report.text import summary_lines
from bench.simulated_campaign import simulate_paper_campaign
from benchmarks.documented import Documented
from benchmarks.timing import best_time_s

#: One timed run is enough for the quoted figures, which are the analysis's, not its times.
DOCUMENTED = Documented(
    arguments=("--repeats", "1"),
    quoted={
        prefix: "docs/analysis.md"
        for prefix in (
            "model peak (docs/analysis.md): ",
            "four-post bands (docs/analysis.md): ",
            "raw band's end (docs/analysis.md): ",
            "loss on the post (docs/analysis.md): ",
        )
    },
)


def simulate_campaign():
    c = simulate_paper_campaign(seed=1)
    return c.shaker, c.shaker_free_run, (c.post_free_run, c.four_post), c.hammer


def analyse_campaign(grids, free, four_post, hammer):
    sensor = BenchSetup.paper_hammer().sensor
    campaigns = {
        p: analyse_shaker_campaign(records, free, wheel_mass_kg=29.0, sensor=sensor)
        for p, records in grids.items()
    }
    post_free, sweep = four_post
    car = analyse_four_post(sweep, post_free, tyre=campaigns[2.5], wheel_mass_kg=29.0, sensor=sensor)
    return campaigns, car, analyse_hammer(hammer, sensor_mass_kg=sensor.mass_kg)


def baseline(grids, free, four_post, hammer):
    """A plain FFT of every recorded channel: the cheapest look at the same data."""
    records = [r for g in grids.values() for r in g] + free + four_post[0] + [four_post[1], hammer]
    arrays = [x for r in records for x in r.channels.values()]
    for a in arrays:
        np.fft.rfft(a)
    return sum(a.size for a in arrays)


def identify_every_grid(campaigns) -> None:
    """Models 1-3 of every grid again, from the FRFs the analysis made."""
    for c in campaigns.values():
        for r in c.amplitudes.values():
            identify_shaker(
                r.frfs.wfs_per_z,
                r.frfs.contact_per_z,
                wheel_mass_kg=c.wheel_mass_kg,
                sensor=c.sensor,
                errors=r.frfs.errors,
            )


def documented_lines(campaigns, car) -> list[str]:
    """The figures docs/analysis.md quotes: the 2.5 bar, 2 mm grid's model peak against its largest
    measured point; the four-post valid bands; the phase of the raw ratio where its band ends; the
    tyre's loss on the post (a friction force over the loss element's deflection) at the lowest and
    the most deflected bin the quarter car uses, against the shaker's constant hysteretic loss."""
    amplitude = campaigns[2.5].nearest(2e-3)
    peak, (top_hz, top) = amplitude.model_peak, amplitude.largest_measured_ratio
    bands = (
        ("raw", car.valid_band_raw),
        ("hub acceleration", car.valid_band_hub_compensated),
        ("model-compensated", car.valid_band_model_compensated),
    )
    raw = car.wfs_per_contact
    at = int(np.argmin(np.abs(raw.freq_hz - car.valid_band_raw.upper_hz)))
    value, sigma = raw.value[at], raw.sigma[at]
    # 95 % of the phase: the component of the complex uncertainty across the phasor, 1.96 sigma/sqrt 2
    phase_ci95_deg = np.degrees(1.96 * sigma / np.sqrt(2) / abs(value))
    fit = car.quarter_car
    f = fit.friction.freq_hz
    used = f[(f >= fit.band_hz[0]) & (f <= fit.band_hz[1])]
    deflection = fit.friction.deflection_m(used)
    lowest, most = used[0], used[int(np.argmax(deflection))]
    loss = fit.friction.loss_n_per_m(np.array([lowest, most])) / 1e3
    return [
        f"model peak (docs/analysis.md): measured {top:.3g} at {top_hz:g} Hz, model {peak.height:.3g}"
        f" +/- {peak.height_ci95:.2g} at {peak.freq_hz:.2f} Hz",
        "four-post bands (docs/analysis.md): "
        + ", ".join(f"{name} {b.lowest_hz:.4g}-{b.upper_hz:.4g} Hz" for name, b in bands),
        f"raw band's end (docs/analysis.md): at {raw.freq_hz[at]:.4g} Hz measures"
        f" {np.degrees(np.angle(value)):.2f} +/- {phase_ci95_deg:.2f} deg",
        f"loss on the post (docs/analysis.md): the deflection grows from"
        f" {1e3 * deflection[0]:.2g} mm at {lowest:.2g} Hz (the lowest bin used) to"
        f" {1e3 * deflection.max():.2g} mm at {most:.2g} Hz, past the wheel mode, and the loss falls"
        f" from {loss[0]:.3g} to {loss[1]:.2g} kN/m"
        f" ({fit.rubber.hysteretic_damping_n_per_m / 1e3:.2g} kN/m on the shaker at 2 mm)",
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3, help="timed runs; the best counts")
    parser.add_argument("--campaign", type=Path, help="a campaign file to analyse as a whole too")
    args = parser.parse_args()
    repeats = args.repeats
    data = simulate_campaign()
    n_samples = baseline(*data)
    t_base = best_time_s(lambda: baseline(*data), repeats)
    campaigns, car, hammer = analyse_campaign(*data)
    t_analysis = best_time_s(lambda: analyse_campaign(*data), repeats)
    t_fits = best_time_s(lambda: identify_every_grid(campaigns), repeats)
    print(f"data volume: {n_samples} samples ({n_samples * 8 / 1e6:.1f} MB as float64)")
    print(f"baseline numpy FFT of every channel: {1e3 * t_base:.1f} ms")
    print(
        f"analysis end to end: {t_analysis:.3f} s ({t_analysis / t_base:.0f}x the FFT baseline; target < 2 s)"
    )
    print(f"of which the 9 grids' Model 1-3 identifications: {t_fits:.3f} s")
    if args.campaign is not None:
        t_file = best_time_s(lambda: analyze_campaign(args.campaign), repeats)
        print(f"analyze_campaign of {args.campaign}: {t_file:.3f} s")
    k = {
        p: c.nearest(2e-3).identification.best_fit.tyre.stiffness_n_per_m / 1e3 for p, c in campaigns.items()
    }
    print("k at 10 Hz, 2 mm [kN/m]: " + ", ".join(f"{p} bar {v:.1f}" for p, v in k.items()))
    print("\n".join(["", "2.5 bar shaker campaign:", *summary_lines(campaigns[2.5])]))
    print("\n".join(["", *summary_lines(car), "", *summary_lines(hammer)]))
    print("\n".join(["", *documented_lines(campaigns, car)]))


if __name__ == "__main__":
    main()
