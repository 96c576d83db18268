"""``wfsbench demo``: the paper's whole campaign on the simulated bench, analysed as a lab would.

1. Hammer test of the bare sensor: its eigenfrequency and damping give the sensor model.
2. Free run without a wheel: the shaker plate's mass m_comp.
3. Shaker dwells at 1.5 / 2.5 / 3.5 bar and 1 / 2 / 5 mm: Models 1-3 identified per amplitude,
   the model-based compensator, and the valid band of the raw and the compensated WFS force.
4. Four-post sweep of one corner at 2.5 bar, with the post's own free run: m_wheel, the quarter car,
   and the valid band raw / hub-acceleration compensated / model compensated.

The simulated plant has sensor noise, quantisation and the non-linear tyre on; the analysis sees
only what a real bench records.
"""

from __future__ import annotations

import time

from bench.analysis.runs import analyse_four_post, analyse_hammer, analyse_shaker_campaign
from bench.models.benches import TyreModel
from bench.models.parameters import Tyre, WfsSensor
from bench.simulated_campaign import simulate_paper_campaign

#: Weighed on the scales, as in the paper: sensor 3.82 kg, wheel with adaption and sensor 29 kg.
SENSOR_MASS_KG = 3.82
WHEEL_MASS_KG = 29.0


def _band(band) -> str:
    return f"{band.upper_hz:5.1f} Hz" if band.determined else "not determined"


def run_demo(seed: int = 1) -> list[str]:
    """Simulate and analyse the campaign; return the report's lines."""
    start = time.perf_counter()
    campaign = simulate_paper_campaign(seed)
    simulated_s = time.perf_counter() - start

    start = time.perf_counter()
    hammer = analyse_hammer(campaign.hammer, sensor_mass_kg=SENSOR_MASS_KG)
    sensor = WfsSensor(
        mass_kg=SENSOR_MASS_KG,
        eigenfrequency_hz=hammer.eigenfrequency_hz,
        damping_ratio=hammer.damping_ratio_log_decrement,
    )
    shaker = {
        pressure: analyse_shaker_campaign(
            records, campaign.shaker_free_run, wheel_mass_kg=WHEEL_MASS_KG, sensor=sensor
        )
        for pressure, records in campaign.shaker.items()
    }
    car = analyse_four_post(
        campaign.four_post,
        campaign.post_free_run,
        tyre=shaker[2.5],
        wheel_mass_kg=WHEEL_MASS_KG,
        sensor=sensor,
    )
    analysed_s = time.perf_counter() - start

    truth = campaign.quarter_car.tyre
    lines = [
        "wfs-bench demo: the paper's campaign on the simulated bench (noise, quantisation, non-linear tyre)",
        f"simulated in {simulated_s:.1f} s, analysed in {analysed_s:.1f} s",
        "",
        *hammer.summary_lines(),
        "",
        "shaker bench, Model 2 per amplitude (k at its reference frequency, 10 Hz; max over the dwells):",
        f"{'pressure':>8} {'amplitude':>9} {'k kN/m':>8} {'m_T kg':>7} {'d Ns/m':>7}"
        f" {'max |F_WFS/F_c|':>16} {'raw band':>9} {'compensated':>12}",
    ]
    for pressure, result in shaker.items():
        for amplitude_m, r in result.amplitudes.items():
            tyre: Tyre = r.identification.fits[TyreModel.WHEEL_TREAD].tyre
            lines.append(
                f"{pressure:>6.1f} bar {1e3 * amplitude_m:>6.0f} mm {tyre.stiffness_n_per_m / 1e3:>8.1f}"
                f" {tyre.tread_mass_kg:>7.2f} {tyre.damping_ns_per_m:>7.1f}"
                f" {max(abs(r.frfs.wfs_per_contact.value)):>16.1f} {_band(r.valid_band_raw):>9}"
                f" {_band(r.valid_band_compensated):>12}"
            )
    lines += [
        f"(simulator's nominal tyre at 2.5 bar: k {truth.stiffness_n_per_m / 1e3:.0f} kN/m,"
        f" m_T {truth.tread_mass_kg:g} kg, viscous d {truth.damping_ns_per_m:g} Ns/m plus rubber friction)",
        "",
        "2.5 bar in full:",
        *shaker[2.5].summary_lines(),
        "",
        *car.summary_lines(),
    ]
    return lines
