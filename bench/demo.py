"""``wfsbench demo``: the paper's shaker campaign on the simulated bench, summarised.

For each tyre pressure, the model predicts where the WFS over-reads the contact force most (the
tread resonance); the simulated bench then dwells there and at 5 Hz with every sensor effect on,
and the ratio of the WFS force to the plate-mass-corrected shaker force is printed beside the
model's prediction.
"""

from __future__ import annotations

import numpy as np

from bench.models.benches import TyreModel
from bench.models.parameters import PAPER_TYRE_STIFFNESS_N_PER_M
from bench.models.setup import BenchSetup
from simulators.plant import PlantSimulator, SensorRealism, SineDwell

AMPLITUDE_M = 0.002
SETTLE_S = 3.0
CYCLES = 40


def _amplitude(signal: np.ndarray, freq_hz: float, rate_hz: float) -> complex:
    """Complex amplitude over the last CYCLES whole cycles (orthogonal projection)."""
    n = round(CYCLES * rate_hz / freq_hz)
    t = np.arange(n) / rate_hz
    return 2 * np.mean(signal[-n:] * np.exp(-2j * np.pi * freq_hz * t))


def run_demo(seed: int = 1) -> list[str]:
    lines = [
        "wfs-bench demo: shaker bench, Model 2 tyre (non-linear), 2 mm sine dwells, simulated bench",
        f"{'pressure':>8} {'freq':>7} {'|F_WFS/F_contact|':>18} {'model':>7} {'phase':>7} {'model':>7}",
    ]
    for pressure_bar in sorted(PAPER_TYRE_STIFFNESS_N_PER_M):
        setup = BenchSetup.paper_shaker(pressure_bar, TyreModel.WHEEL_TREAD)
        plant = PlantSimulator(setup, realism=SensorRealism(seed=seed))
        freqs = np.linspace(20.0, 60.0, 161)
        model = [plant.exact_response(f, AMPLITUDE_M) for f in freqs]
        peak_hz = float(freqs[np.argmax([abs(r["f_wfs"] / r["f_contact"]) for r in model])])
        for freq_hz in (5.0, peak_hz):
            dwell = SineDwell(freq_hz, AMPLITUDE_M, hold_s=SETTLE_S + CYCLES / freq_hz, taper_out_s=0)
            rec = plant.simulate(dwell)
            rate = plant.output_rate_hz
            accel = -((2 * np.pi * freq_hz) ** 2) * _amplitude(rec["z_base_m"], freq_hz, rate)
            contact = _amplitude(rec["f_plate_n"], freq_hz, rate) - setup.rig.plate_mass_kg * accel
            measured = _amplitude(rec["fz_wfs_n"], freq_hz, rate) / contact
            truth = plant.exact_response(freq_hz, AMPLITUDE_M)
            expected = truth["f_wfs"] / truth["f_contact"]
            lines.append(
                f"{pressure_bar:>6.1f} bar {freq_hz:>5.1f} Hz {abs(measured):>16.2f} {abs(expected):>7.2f}"
                f" {np.angle(measured, deg=True):>6.0f}° {np.angle(expected, deg=True):>6.0f}°"
            )
    return lines
