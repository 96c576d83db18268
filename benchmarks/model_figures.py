"""The figures docs/physics.md quotes of the models and the simulated plant, computed from their
closed forms: the quarter car's modes and mass split, the shaker's tread-resonance peaks (linear and
with the non-linear tyre), a road's linearisation of the tyre, the four-post sweeps' stroke
velocity, the acquisition's anti-alias filter, and the servo-hydraulic actuator's resonance,
damping, gain margin, uncorrected amplitude errors and flow limit.

Everything is a frequency response, an eigenvalue or a describing-function balance of the models in
``bench/models`` and ``simulators/plant``: no time simulation, no bench, the same output on every
run (a few seconds).

    PYTHONPATH=. .venv/bin/python benchmarks/model_figures.py
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy.signal import freqz

from bench.models.benches import TyreModel, quarter_car, shaker_bench
from bench.models.parameters import (
    PAPER_TYRE_STIFFNESS_N_PER_M,
    DamperNonlinearity,
    Suspension,
    TyreNonlinearity,
    paper_tyre,
)
from bench.models.road import road_drive
from bench.models.setup import BenchKind, BenchSetup
from bench.simulated_road import TYRE_GRID_POINTS
from benchmarks.documented import Documented
from simulators.plant import PlantSimulator, ServoActuator
from simulators.plant.excitation import SampledDrive
from simulators.plant.sensors import Decimator

#: Closed forms: every run prints the same figures.
DOCUMENTED = Documented(
    tables_in="docs/physics.md",
    quoted={
        "quarter car: ": "docs/physics.md",
        "mass split: ": "docs/physics.md",
        "shaker, Model 2: ": "docs/physics.md",
        "shaker, Model 1: ": "docs/physics.md",
        "non-linear tyre: ": "docs/physics.md",
        "road, deflection: ": "docs/physics.md",
        "road, equivalent sine: ": "docs/physics.md",
        "road, statistical tyre: ": "docs/physics.md",
        "four-post sweeps: ": "docs/physics.md",
        "anti-alias filter: ": "docs/physics.md",
        "oil column: ": "docs/physics.md",
        "loop damping: ": "docs/physics.md",
        "loop gain: ": "docs/physics.md",
        "static error: ": "docs/physics.md",
        "flow limit: ": "docs/physics.md",
    },
)
PRESSURES_BAR = sorted(PAPER_TYRE_STIFFNESS_N_PER_M)
#: The largest loop gain the gain margin's search tries, as a multiple of the configured one.
MAX_LOOP_GAIN_FACTOR = 10
#: The shaker's band, finely enough for a peak's height to 1e-4 and its frequency to 0.01 Hz.
FREQ_HZ = np.arange(0.5, 70.0 + 1e-9, 0.01)
#: The amplitude control's table: uncorrected error at 2 mm at these frequencies.
TABLE_FREQ_HZ = (1.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0)
ACTUATOR = ServoActuator()
#: The road of ``benchmarks/road_validation.py``'s class C case at 60 km/h, on its car (the demo's
#: four-post corner).
ROAD = {"speed_km_h": 60.0, "duration_s": 20.0, "sample_rate_hz": 1000.0, "seed": 5}
ROAD_CAR = BenchSetup.paper_quarter_car(2.5, model=TyreModel.WHEEL_TREAD)


def _ratio(network, freq_hz=FREQ_HZ) -> np.ndarray:
    r = network.frequency_response(freq_hz, outputs=("f_wfs", "f_contact"))
    return r["f_wfs"] / r["f_contact"]


def _range(values, digits: int) -> str:
    low, high = f"{min(values):.{digits}f}", f"{max(values):.{digits}f}"
    return low if low == high else f"{low}-{high}"


def quarter_car_modes() -> None:
    """Body and wheel modes of the quarter car at 2.5 bar per tyre model, and the mass split."""
    modes = {m: quarter_car(m, paper_tyre(2.5)).eigenfrequencies_hz() for m in TyreModel}
    body = [f[0] for f in modes.values()]
    wheel1, wheel3 = modes[TyreModel.WHEEL][1], modes[TyreModel.WHEEL_TREAD_SIDEWALL][1]
    print(
        f"quarter car: a body mode at {_range(body, 2)} Hz, a wheel mode at {wheel1:.1f} Hz (Model 1)"
        f" to {wheel3:.1f} Hz (Model 3) at 2.5 bar"
    )
    s = Suspension()
    split = s.unsprung_mass_above_kg / (s.unsprung_mass_above_kg + paper_tyre(2.5).wheel_mass_kg)
    print(f"mass split: a mass split above/below the sensor of {100 * split:.0f} %")


def shaker_peaks() -> None:
    """The tread resonance of Model 2 on the shaker per pressure; Model 1's distance from 1."""
    peaks, at_70, phase, model1 = [], [], [], []
    for p in PRESSURES_BAR:
        h = _ratio(shaker_bench(TyreModel.WHEEL_TREAD, paper_tyre(p)))
        i = int(np.argmax(np.abs(h)))
        peaks.append(f"{abs(h[i]):.1f}x at {FREQ_HZ[i]:.1f} Hz")
        at_70.append(abs(h[-1]))
        phase.append(abs(np.degrees(np.angle(h[-1] / h[0]))))
        h1 = _ratio(shaker_bench(TyreModel.WHEEL, paper_tyre(p)))
        model1.append(np.max(np.abs(np.abs(h1) - 1)))
    pressures = " / ".join(f"{p:g}" for p in PRESSURES_BAR)
    print(
        f"shaker, Model 2: peaks of {', '.join(peaks)} for {pressures} bar, a phase change through the"
        f" peak of {_range(phase, 0)} degrees from 0.5 to 70 Hz, {_range(at_70, 2)} at 70 Hz"
    )
    print(f"shaker, Model 1: stays within {100 * max(model1):.1f} % of 1")


def nonlinear_tyre() -> None:
    """The 1 / 2 / 5 mm curves of the non-linear tyre at 2.5 bar: their peaks, and how far apart
    they lie away from the tread resonance (below 30 Hz and above 50 Hz)."""
    setup = BenchSetup.paper_shaker(2.5, nonlinear=True)
    amplitudes_m = (0.001, 0.002, 0.005)

    def curve(freq_hz: np.ndarray, amplitude_m: float) -> np.ndarray:
        return np.array([abs(_ratio(setup.operating_network(f, amplitude_m), f)[0]) for f in freq_hz])

    near = np.arange(36.0, 46.0 + 1e-9, 0.02)
    peaks = [curve(near, a).max() for a in amplitudes_m]
    away = np.concatenate([np.arange(0.5, 30.0 + 1e-9, 0.5), np.arange(50.0, 70.0 + 1e-9, 0.5)])
    curves = np.array([curve(away, a) for a in amplitudes_m])
    spread = np.max(curves.max(axis=0) / curves.min(axis=0)) - 1
    print(
        f"non-linear tyre: peaks {' / '.join(f'{p:.1f}x' for p in peaks)} at 2.5 bar, and agree within"
        f" {100 * spread:.1f} % below 30 Hz and above 50 Hz"
    )


def road_linearisation() -> None:
    """Class C at 60 km/h on the demo's corner: the tyre linearised statistically for the road's
    density, against the equivalent sine of the sampled road that the plant would linearise at."""
    drive = road_drive("C", **ROAD)
    car, law = ROAD_CAR, TyreNonlinearity()
    f = np.linspace(drive.band_hz[0], drive.band_hz[1], TYRE_GRID_POINTS)
    psd = drive.temporal_psd_m2_per_hz(f)
    weight = np.gradient(f) * psd
    r = car.network().frequency_response(f, outputs=("z_base", "z_rim"))
    deflection2 = np.abs(r["z_base"] - r["z_rim"]) ** 2 * weight
    sigma_x, sigma_v = np.sqrt(deflection2.sum()), np.sqrt(np.sum(deflection2 * (2 * np.pi * f) ** 2))
    print(f"road, deflection: {sigma_v / (2 * np.pi * sigma_x):.1f} Hz on class C at 60 km/h")
    statistical = car.broadband_tyre(f, psd)
    friction = statistical.damping_ns_per_m - car.tyre.damping_ns_per_m
    sine = SampledDrive(drive.displacement_m, drive.sample_rate_hz)
    at_sine = car.linear_tyre(sine.equivalent_frequency_hz, sine.amplitude)
    sine_friction = at_sine.damping_ns_per_m - car.tyre.damping_ns_per_m
    print(
        f"road, equivalent sine: the tyre at {sine.equivalent_frequency_hz:.1f} Hz, with"
        f" {sine_friction / friction:.1f} times this friction damping (class C at 60 km/h, 20 s of road,"
        f" seed 5: {sine_friction:.1f} against {friction:.1f} Ns/m)"
    )
    k = statistical.stiffness_n_per_m
    k_f = [car.tyre.stiffness_n_per_m * law.stiffness_factor(x) for x in np.linspace(10.0, 40.0, 31)]
    off = max(abs(k / x - 1) for x in k_f)
    print(
        f"road, statistical tyre: stiffness ({k / 1e3:.1f} kN/m) is within {100 * off:.1f} % of the"
        f" tyre's k(f) from 10 to 40 Hz ({min(k_f) / 1e3:.1f}-{max(k_f) / 1e3:.1f} kN/m), and its damping"
        f" ({statistical.damping_ns_per_m:.1f} Ns/m)"
    )


def sweep_stroke_velocity() -> None:
    """The four-post car's stroke velocity under a 2 mm sine at any frequency in 0.5-70 Hz (the
    damper linear below its knee)."""
    car = replace(BenchSetup.paper_quarter_car(2.5), suspension=Suspension(damper=DamperNonlinearity()))
    r = car.network().frequency_response(FREQ_HZ, outputs=("z_body", "z_hub"))
    stroke = 2 * np.pi * FREQ_HZ * np.abs(r["z_body"] - r["z_hub"]) * 0.002
    i = int(np.argmax(stroke))
    print(f"four-post sweeps: at most {stroke[i]:.2f} m/s, at the wheel hop ({FREQ_HZ[i]:.1f} Hz)")


def anti_alias_filter() -> None:
    """The acquisition's decimation filter from 10 kHz to 1 kHz: flatness and stop-band gain."""
    taps = Decimator(10, 1).taps
    rate_hz = 10_000.0
    f, h = freqz(taps, worN=np.arange(0.0, 200.0 + 1e-9, 1.0), fs=rate_hz)
    flat = np.max(np.abs(np.abs(h) - 1))
    _, nyquist = freqz(taps, worN=[500.0], fs=rate_hz)
    exponent = math.floor(math.log10(flat))
    print(
        f"anti-alias filter: {taps.size} taps, flat to {flat / 10**exponent:.1f}e{exponent} up to"
        f" {f[-1]:.0f} Hz, {20 * np.log10(abs(nyquist[0])):.0f} dB at the 500 Hz output Nyquist frequency"
    )


def _loop_poles(actuator: ServoActuator, setup: BenchSetup) -> np.ndarray:
    network = setup.network()
    outputs = [o for o in ("z_base", "f_plate") if o in network.output_names]
    return np.linalg.eigvals(actuator.drive(network.state_space(outputs=outputs)).A)


def actuator() -> None:
    """The servo-hydraulic actuator: its bare resonance, the damping and gain margin of its loop
    over every specimen, the uncorrected errors at 2 mm and the flow limit at 5 mm."""
    a = ACTUATOR
    plate_kg = BenchSetup.paper_free_run().rig.plate_mass_kg
    resonance = math.sqrt(a.oil_stiffness_n_per_m / (a.moving_mass_kg + plate_kg)) / (2 * math.pi)
    print(
        f"oil column: with the {plate_kg:.0f} kg plate the bare bench's oil-column resonance is"
        f" {resonance:.0f} Hz"
    )
    specimens = [BenchSetup.paper_free_run()] + [
        BenchSetup(kind, model, paper_tyre(p))
        for kind in (BenchKind.SHAKER, BenchKind.QUARTER_CAR)
        for model in TyreModel
        for p in PRESSURES_BAR
    ]
    damping: dict[bool, list[float]] = {False: [], True: []}  # by: Model 3
    unstable_from = {}
    for setup in specimens:
        poles = _loop_poles(a, setup)
        band = poles[(poles.imag > 0) & (np.abs(poles) > 2 * np.pi * 100) & (np.abs(poles) < 2 * np.pi * 300)]
        ratios = [r for r in -band.real / np.abs(band) if r < 0.5]  # the real-ish valve pole aside
        sidewall = setup.has_tyre and setup.model is TyreModel.WHEEL_TREAD_SIDEWALL
        damping[sidewall] += ratios
        gain = a.loop_gain_per_s
        while _loop_poles(replace(a, loop_gain_per_s=gain), setup).real.max() < 0:
            gain += 5.0
            if gain > MAX_LOOP_GAIN_FACTOR * a.loop_gain_per_s:
                raise SystemExit(f"the loop stays stable up to {gain:g} 1/s on {setup.kind}: no margin found")
        unstable_from[setup] = gain
    print(
        "loop damping: damps the loop's modes at 100-300 Hz to"
        f" {_range([100 * d for d in damping[False]], 0)} % (Model 3's sidewall modes:"
        f" {_range([100 * d for d in damping[True]], 0)} %)"
    )
    lowest = min(unstable_from.values())
    worst = sorted({int(s.model) for s, g in unstable_from.items() if g == lowest and s.has_tyre})
    print(
        f"loop gain: gain margin {lowest / a.loop_gain_per_s:.1f} on the worst specimen"
        f" (Model {', '.join(map(str, worst))}, either bench; unstable from {lowest:.0f} 1/s)"
    )
    k = paper_tyre(2.5).stiffness_n_per_m
    static = 1 / (1 + a.bleed_rate_per_s * k / (a.oil_stiffness_n_per_m * a.loop_gain_per_s)) - 1
    print(f"static error: {100 * static:.1f} % at 2.5 bar")

    rows = {
        "bare plate (free run)": BenchSetup.paper_free_run(),
        **{f"wheel, {p:g} bar": BenchSetup.paper_shaker(p) for p in PRESSURES_BAR},
        "quarter car, 2.5 bar": BenchSetup.paper_quarter_car(2.5),
    }
    print()
    print("| setup | " + " | ".join(f"{f:.0f} Hz" for f in TABLE_FREQ_HZ) + " |")
    print("|---" * (len(TABLE_FREQ_HZ) + 1) + "|")
    for label, setup in rows.items():
        plant = PlantSimulator(setup)
        errors = [100 * (abs(plant.base_gain(f, 0.002)) - 1) for f in TABLE_FREQ_HZ]
        cells = [f"{e:+.1f} %" if round(e, 1) != 0 else "0.0 %" for e in errors]
        print(f"| {label} | " + " | ".join(cells) + " |")
    print()

    wheel = PlantSimulator(BenchSetup.paper_shaker(2.5))
    achieved = []
    for f in (50.0, 70.0):
        load = complex(wheel.exact_response(f, 0.005)["f_plate"])
        flow = a.flow_factor(f, 0.005, load)
        achieved.append(f"{100 * abs(wheel.base_gain(f, 0.005)):.0f} % at {f:.0f} Hz (N = {flow:.2f})")
    print(
        f"flow limit: with the wheel at 2.5 bar, at 5 mm the achieved amplitude falls to {achieved[0]}"
        f" and {achieved[1]}"
    )


def main() -> None:
    quarter_car_modes()
    shaker_peaks()
    nonlinear_tyre()
    road_linearisation()
    sweep_stroke_velocity()
    anti_alias_filter()
    actuator()


if __name__ == "__main__":
    main()
