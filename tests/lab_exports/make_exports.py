"""Writes the lab-style CSV exports of this folder (README.md) as other acquisition systems write
them: text formatted line by line, never through the campaign writer. The signals are the steady
responses of the paper's Model 2 tyre on the shaker (and the bare sensor's ring after a hammer
blow), with a little measurement noise, so that the imported files analyse to known values.

Run from the repository root: ``python -m tests.lab_exports.make_exports`` (it rewrites the files).
"""

from __future__ import annotations

import shutil
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from scipy import signal

from bench.models.benches import TyreModel, free_run, shaker_bench
from bench.models.parameters import WfsSensor, paper_tyre

HERE = Path(__file__).resolve().parent
G_M_S2 = 9.80665
DWELL_RATE_HZ = 1000.0
DWELL_S = 0.6
AMPLITUDE_MM = 2.0
FREE_RUN_HZ = (5.0, 20.0, 40.0, 60.0)
GRID_HZ = (5.0, 15.0, 25.0, 32.0, 38.0, 45.0, 55.0, 65.0)
#: The hammer-tested sensor: not the analysis's 2200 Hz default, so its import shows.
SENSOR = WfsSensor(mass_kg=3.82, eigenfrequency_hz=2150.0, damping_ratio=0.02)
HAMMER_RATE_HZ = 20000.0
#: Noise of each quantity in SI units (m, N, m/s^2).
NOISE = {"z": 0.2e-6, "f_plate": 0.5, "f_wfs": 0.5, "a_hub": 0.02}
_RNG = np.random.default_rng(20)


def dwell(
    freq_hz: float, pressure_bar: float | None, n: int, rate_hz: float = DWELL_RATE_HZ
) -> dict[str, np.ndarray]:
    """``n`` samples at ``rate_hz`` of a steady dwell at ``freq_hz`` (2 mm), SI units: z, f_plate,
    f_wfs, a_hub; ``pressure_bar`` None: the free run without the wheel."""
    t = np.arange(n) / rate_hz
    phasor = AMPLITUDE_MM * 1e-3 * np.exp(2j * np.pi * freq_hz * t)
    if pressure_bar is None:
        responses = {"f_plate": free_run().frequency_response(freq_hz, outputs=["f_plate"])["f_plate"][0]}
        responses |= {"f_wfs": 0.0, "a_hub": 0.0}
    else:
        network = shaker_bench(TyreModel.WHEEL_TREAD, paper_tyre(pressure_bar))
        out = network.frequency_response(freq_hz, outputs=["f_plate", "f_wfs", "a_hub"])
        responses = {name: values[0] for name, values in out.items()}
    signals = {"z": np.imag(phasor)} | {name: np.imag(h * phasor) for name, h in responses.items()}
    return {name: values + NOISE[name] * _RNG.standard_normal(n) for name, values in signals.items()}


def still(n: int) -> dict[str, np.ndarray]:
    """``n`` samples of the bench at rest between two dwells: noise only."""
    return {name: sigma * _RNG.standard_normal(n) for name, sigma in NOISE.items()}


def write_lines(path: Path, lines: Sequence[str], encoding: str = "utf-8") -> None:
    path.write_bytes(("\r\n".join(lines) + "\r\n").encode(encoding))


def rows(columns: Sequence[np.ndarray], formats: Sequence[Callable[[float], str]]) -> list[tuple[str, ...]]:
    return [
        tuple(f(v) for f, v in zip(formats, values, strict=True)) for values in zip(*columns, strict=True)
    ]


def comma(decimals: int) -> Callable[[float], str]:
    """A number with a decimal comma and ``decimals`` decimals (a German locale's export)."""
    return lambda v: f"{v:.{decimals}f}".replace(".", ",")


def point(decimals: int) -> Callable[[float], str]:
    return lambda v: f"{v:.{decimals}f}"


# -- lab A: a Windows export per dwell, units row, ';' and decimal comma, ';' ending the data rows --


LAB_A_PREAMBLE = ["Messprogramm: Rad-Shaker Pruefstand 2", "Datum: 12.03.2026;Bediener: K. Weber", ""]


def lab_a(folder: Path) -> None:
    """A free run whose files have no WFS nor hub channel (no wheel), a dwell grid at 2.5 bar with
    the hub acceleration in m/s² and the wheel angle in °, cp1252, a three-line preamble."""
    free_header = ["Weg", "F_Platte"]
    grid_header = ["Weg", "F_Platte", "Fz", "a_Nabe", "Winkel"]
    units = ["mm", "kN", "kN", "m/s²", "°"]
    n = round(DWELL_S * DWELL_RATE_HZ)
    for kind, freqs, header in (("free", FREE_RUN_HZ, free_header), ("grid_2.5bar", GRID_HZ, grid_header)):
        for freq_hz in freqs:
            s = dwell(freq_hz, None if kind == "free" else 2.5, n)
            columns = [s["z"] * 1e3, s["f_plate"] * 1e-3, s["f_wfs"] * 1e-3, s["a_hub"], np.full(n, 90.0)]
            formats = [comma(4), comma(5), comma(5), comma(3), comma(1)]
            k = len(header)
            lines = [*LAB_A_PREAMBLE, ";".join(header), ";".join(units[:k])]
            lines += [";".join(row) + ";" for row in rows(columns[:k], formats[:k])]
            write_lines(folder / f"{kind}_{freq_hz:02.0f}hz.csv", lines, "cp1252")
    mapping = [
        "# Lab A: one file per dwell, exported by a Windows acquisition program (cp1252)",
        "[source]",
        'name = "lab_a"',
        "[csv]",
        'delimiter = ";"',
        'decimal = ","',
        "skip_lines = 3",
        "units_row = true",
        'encoding = "cp1252"',
        "[time]",
        f"sample_rate_hz = {DWELL_RATE_HZ:g}",
        "[channels]  # units from the files' units row",
        'z_base_m = { column = "Weg" }',
        'f_plate_n = { column = "F_Platte" }',
        'fz_wfs_n = { column = "Fz" }',
        'a_hub_m_s2 = { column = "a_Nabe", unit = "m/s²" }',
        'angle_rad = { column = "Winkel" }',
        "",
        "[[runs]]",
        'kind = "free_run"',
        *_dwell_points("free", FREE_RUN_HZ),
        "",
        "[[runs]]",
        'kind = "dwell_grid"',
        "tyre_pressure_bar = 2.5",
        *_dwell_points("grid_2.5bar", GRID_HZ),
    ]
    write_lines(folder / "mapping.toml", mapping)


def _dwell_points(prefix: str, freqs: Sequence[float]) -> list[str]:
    out = []
    for freq_hz in freqs:
        out += ["[[runs.points]]", f'file = "{prefix}_{freq_hz:02.0f}hz.csv"', f"freq_hz = {freq_hz:g}"]
        out += [f"amplitude_mm = {AMPLITUDE_MM:g}"]
    return out


# -- lab B: one continuous file per run, ',' ending every line, units in brackets ------------------

LAB_B_RATE_HZ = 500.0
LAB_B_DWELL_S = 0.8
GAP_S = 0.2


def lab_b(folder: Path) -> None:
    """The free run and a dwell grid at 1.5 bar, each one continuous file with the bench at rest
    between the dwells; the points' times in the mapping; displacement in µm, acceleration in
    m/s², a time column in seconds, 500 Hz, UTF-8 with a byte-order mark."""
    header = ["Time [s]", "Disp [µm]", "Load cell [N]", "WFS Fz [N]", "Hub acc [m/s²]"]
    mapping = [
        "# Lab B: one continuous file per run, the points' times from the test log",
        "[source]",
        'name = "lab_b"',
        "[time]",
        'column = "Time [s]"',
        "[channels]  # units from the headers' brackets",
        'z_base_m = { column = "Disp [µm]" }',
        'f_plate_n = { column = "Load cell [N]" }',
        'fz_wfs_n = { column = "WFS Fz [N]" }',
        'a_hub_m_s2 = { column = "Hub acc [m/s²]" }',
    ]
    rate = LAB_B_RATE_HZ
    n_dwell, n_gap = round(LAB_B_DWELL_S * rate), round(GAP_S * rate)
    for name, freqs, pressure in (("free_run", FREE_RUN_HZ, None), ("grid_1.5bar", GRID_HZ, 1.5)):
        parts, points = [still(n_gap)], []
        for freq_hz in freqs:
            start = sum(len(p["z"]) for p in parts)
            parts += [dwell(freq_hz, pressure, n_dwell, rate), still(n_gap)]
            points += [
                "[[runs.points]]",
                f"freq_hz = {freq_hz:g}",
                f"amplitude_mm = {AMPLITUDE_MM:g}",
                f"start_s = {start / rate:g}",
                f"end_s = {(start + n_dwell) / rate:g}",
                f"hold_start_s = {start / rate + 0.1:g}",
            ]
        s = {name: np.concatenate([p[name] for p in parts]) for name in NOISE}
        t = np.arange(len(s["z"])) / rate
        columns = [t, s["z"] * 1e6, s["f_plate"], s["f_wfs"], s["a_hub"]]
        lines = [",".join(header) + ","]
        lines += [
            ",".join(row) + "," for row in rows(columns, [point(3), point(2), point(2), point(2), point(3)])
        ]
        write_lines(folder / f"{name}.csv", ["\ufeff" + lines[0], *lines[1:]])
        mapping += ["", "[[runs]]", f'kind = "{"free_run" if pressure is None else "dwell_grid"}"']
        mapping += [] if pressure is None else [f"tyre_pressure_bar = {pressure:g}"]
        mapping += [f'file = "{name}.csv"', *points]
    write_lines(folder / "mapping.toml", mapping)


# -- lab C: a hammer capture, and a clamped hub without accelerometer; tabs ------------------------


def hammer_capture() -> tuple[np.ndarray, np.ndarray]:
    """0.1 s at 20 kHz: a 0.2 ms half-sine blow of 400 N at 10 ms, and the bare sensor's force."""
    t = np.arange(round(0.1 * HAMMER_RATE_HZ)) / HAMMER_RATE_HZ
    pulse_s = 0.2e-3
    blow = np.where((t >= 0.01) & (t < 0.01 + pulse_s), 400.0 * np.sin(np.pi * (t - 0.01) / pulse_s), 0.0)
    k, c, m = SENSOR.stiffness_n_per_m, SENSOR.damping_ns_per_m, SENSOR.mass_kg
    fine = 20  # the blow resolved finer than the capture's samples
    t_fine = np.arange(len(t) * fine) / (HAMMER_RATE_HZ * fine)
    blow_fine = np.where(
        (t_fine >= 0.01) & (t_fine < 0.01 + pulse_s), 400.0 * np.sin(np.pi * (t_fine - 0.01) / pulse_s), 0.0
    )
    sensor = signal.StateSpace([[0, 1], [-k / m, -c / m]], [[0], [1 / m]], [[k, c]], [[0]])
    _, force, _ = signal.lsim(sensor, blow_fine, t_fine)
    force = force[::fine] + 0.2 * _RNG.standard_normal(len(t))
    return blow + 0.2 * _RNG.standard_normal(len(t)), force


def lab_c(folder: Path) -> None:
    """The bare sensor's hammer capture (20 kHz, its own time column and channels), the free run
    and a dwell grid at 3.5 bar with no hub accelerometer (the shaker clamps the hub): tabs."""
    blow, force = hammer_capture()
    t_ms = np.arange(len(blow)) / HAMMER_RATE_HZ * 1e3
    lines = ["t_ms\tHammer\tFz", "ms\tN\tN"]
    lines += ["\t".join(row) for row in rows([t_ms, blow, force], [point(2), point(1), point(1)])]
    write_lines(folder / "hammer.csv", lines)
    n = round(DWELL_S * DWELL_RATE_HZ)
    for kind, freqs, pressure in (("free", FREE_RUN_HZ, None), ("grid_3.5bar", GRID_HZ, 3.5)):
        for freq_hz in freqs:
            s = dwell(freq_hz, pressure, n)
            lines = ["z\tF_plate\tFz", "mm\tN\tN"]
            columns = [s["z"] * 1e3, s["f_plate"], s["f_wfs"]]
            lines += ["\t".join(row) for row in rows(columns, [point(4), point(2), point(2)])]
            write_lines(folder / f"{kind}_{freq_hz:02.0f}hz.csv", lines)
    mapping = [
        "# Lab C: the sensor's hammer test first, then the shaker with the hub clamped (no accelerometer)",
        "[source]",
        'name = "lab_c"',
        "[csv]",
        'delimiter = "\\t"',
        "units_row = true",
        "[time]",
        f"sample_rate_hz = {DWELL_RATE_HZ:g}",
        "[channels]",
        'z_base_m = { column = "z" }',
        'f_plate_n = { column = "F_plate" }',
        'fz_wfs_n = { column = "Fz" }',
        "",
        "[[runs]]",
        'kind = "hammer"',
        'file = "hammer.csv"',
        "[runs.time]",
        'column = "t_ms"',
        "[runs.channels]",
        'fz_wfs_n = { column = "Fz" }',
        'f_hammer_n = { column = "Hammer" }',
        "",
        "[[runs]]",
        'kind = "free_run"',
        *_dwell_points("free", FREE_RUN_HZ),
        "",
        "[[runs]]",
        'kind = "dwell_grid"',
        "tyre_pressure_bar = 3.5",
        *_dwell_points("grid_3.5bar", GRID_HZ),
    ]
    write_lines(folder / "mapping.toml", mapping)


# -- refused: small files, each with one fault a lab's export can have -----------------------------

FREE_MAPPING = """\
[source]
name = "refused"
[csv]
delimiter = ";"
decimal = ","
units_row = true
[time]
sample_rate_hz = 1000
[channels]
z_base_m = {{ column = "Weg" }}
f_plate_n = {{ column = "F_Platte"{plate_unit} }}
[[runs]]
kind = "{kind}"{run_keys}
[[runs.points]]
file = "export.csv"
freq_hz = 10
amplitude_mm = 2{point_keys}
"""
REFUSED = {
    "units_row_disagrees": ({"plate_unit": ', unit = "kN"'}, "Weg;F_Platte\nmm;N\n0,1;1,2\n0,2;1,3\n"),
    "unknown_unit": ({}, "Weg;F_Platte\nmm;kp\n0,1;1,2\n0,2;1,3\n"),
    "free_run_without_plate_force": ({}, "Weg;Fz\nmm;kN\n0,1;1,2\n0,2;1,3\n"),
    "ragged_row": ({}, "Weg;F_Platte\nmm;kN\n0,1;1,2\n0,2;1,3\n0,3\n0,4;1,5\n"),
    "decimal_point": ({}, "Weg;F_Platte\nmm;kN\n0,1;1,2\n0.2;1,3\n"),
    "grid_without_tyre_pressure": ({"kind": "dwell_grid"}, "Weg;F_Platte\nmm;kN\n0,1;1,2\n0,2;1,3\n"),
    "continuous_points_overlap": (
        {
            "point_keys": "\nend_s = 0.004\n[[runs.points]]\nfile = 'export.csv'\nfreq_hz = 20\n"
            "amplitude_mm = 2\nstart_s = 0.003"
        },
        "Weg;F_Platte\nmm;kN\n" + "".join(f"0,{i};1,{i}\n" for i in range(1, 7)),
    ),
}


def refused(folder: Path) -> None:
    for case, (keys, text) in REFUSED.items():
        (folder / case).mkdir(parents=True)
        values = {"plate_unit": "", "kind": "free_run", "run_keys": "", "point_keys": ""} | keys
        (folder / case / "mapping.toml").write_text(FREE_MAPPING.format(**values))
        (folder / case / "export.csv").write_text(text)


def main() -> None:
    for name, write in (("lab_a", lab_a), ("lab_b", lab_b), ("lab_c", lab_c), ("refused", refused)):
        folder = HERE / name
        shutil.rmtree(folder, ignore_errors=True)
        folder.mkdir()
        write(folder)


if __name__ == "__main__":
    main()
