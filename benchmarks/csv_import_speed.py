"""CSV import speed and campaign file size: one file per dwell against one continuous file per grid.

The same dwells (``--dwells`` of ``--dwell-s`` each at 1 kHz: displacement, plate force, WFS force,
hub acceleration and a time column, ``;`` and a decimal comma as a German export writes them) are
exported two ways: one CSV file per dwell (the baseline), and one continuous CSV file for the whole
grid with the bench at rest for ``--gap-s`` between the dwells and every point's start, hold and end
given in the mapping. Each is imported with ``import_campaign`` (mapping loaded, every file read
and checked, the campaign written), best of ``--repeat`` runs.

Figures: MB of CSV per second, CSV rows per second and the campaign file's size for each layout,
and the continuous file's time per MB and file size as ratios to the baseline's (the target: time
per MB within 2x, a file of about the same size). The continuous file holds the rest between the
dwells too, which is read and left out: its MB and rows count it.

Run: python benchmarks/csv_import_speed.py [--dwells 20] [--dwell-s 5] [--gap-s 1] [--repeat 3]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from bench.store.csv_import import ImportLimits, import_campaign
from bench.store.csv_mapping import load_mapping
from benchmarks.timing import best_time_s

RATE_HZ = 1000.0
HEADER = "Zeit [s];Weg [mm];F_Platte [kN];Fz [kN];a_Nabe [m/s²]"
MAPPING_HEAD = """\
[source]
name = "bench"
[csv]
delimiter = ";"
decimal = ","
[time]
column = "Zeit [s]"
[channels]
z_base_m = { column = "Weg [mm]" }
f_plate_n = { column = "F_Platte [kN]" }
fz_wfs_n = { column = "Fz [kN]" }
a_hub_m_s2 = { column = "a_Nabe [m/s²]" }
[[runs]]
kind = "dwell_grid"
tyre_pressure_bar = 2.5
"""
LIMITS = ImportLimits(
    min_freq_hz=0.1, max_freq_hz=100.0, min_tyre_pressure_bar=0.5, max_tyre_pressure_bar=4.5
)


def dwell_columns(freq_hz: float, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` rows of a noisy dwell at ``freq_hz``: mm, kN, kN, m/s^2 (as exported)."""
    t = np.arange(n) / RATE_HZ
    z = np.sin(2 * np.pi * freq_hz * t)
    columns = [2.0 * z, 0.5 * z, 0.7 * np.cos(2 * np.pi * freq_hz * t), 0.01 * z]
    return np.column_stack(columns) + 1e-4 * rng.standard_normal((n, 4))


def csv_lines(t0_s: float, block: np.ndarray) -> list[str]:
    """Rows as the export writes them: the time, then the columns with a decimal comma."""
    t = t0_s + np.arange(len(block)) / RATE_HZ
    text = [f"{ti:.3f};{a:.5f};{b:.5f};{c:.5f};{d:.4f}" for ti, (a, b, c, d) in zip(t, block, strict=True)]
    return [line.replace(".", ",") for line in text]


def write_layouts(folder: Path, dwells: int, dwell_s: float, gap_s: float) -> dict[str, Path]:
    """Both layouts of the same dwells under ``folder``; their mappings by layout name."""
    rng = np.random.default_rng(1)
    freqs = np.linspace(5.0, 70.0, dwells)
    n, gap = round(dwell_s * RATE_HZ), round(gap_s * RATE_HZ)
    blocks = [dwell_columns(f, n, rng) for f in freqs]
    per_dwell, per_grid = folder / "per_dwell", folder / "per_grid"
    per_dwell.mkdir()
    per_grid.mkdir()
    mapping = [MAPPING_HEAD]
    for k, (freq_hz, block) in enumerate(zip(freqs, blocks, strict=True)):
        (per_dwell / f"dwell_{k:02d}.csv").write_text("\n".join([HEADER, *csv_lines(0.0, block)]) + "\n")
        mapping.append(
            f'[[runs.points]]\nfile = "dwell_{k:02d}.csv"\nfreq_hz = {freq_hz:g}\namplitude_mm = 2\n'
        )
    (per_dwell / "mapping.toml").write_text("\n".join(mapping))
    lines, mapping, row = [HEADER], [MAPPING_HEAD, 'file = "grid.csv"'], 0
    rest = np.zeros((gap, 4))
    for freq_hz, block in zip(freqs, blocks, strict=True):
        for part in (rest, block):
            lines += csv_lines(row / RATE_HZ, part)
            row += len(part)
        start_s, end_s = (row - n) / RATE_HZ, row / RATE_HZ
        mapping.append(
            f"[[runs.points]]\nfreq_hz = {freq_hz:g}\namplitude_mm = 2\nstart_s = {start_s:g}\n"
            f"end_s = {end_s:g}\nhold_start_s = {start_s + 0.2:g}\n"
        )
    (per_grid / "grid.csv").write_text("\n".join(lines) + "\n")
    (per_grid / "mapping.toml").write_text("\n".join(mapping))
    return {"one file per dwell": per_dwell / "mapping.toml", "one file per grid": per_grid / "mapping.toml"}


def measure(mapping_path: Path, out: Path, repeat: int) -> dict[str, float]:
    """Best import time (s), the CSV's MB and rows, and the campaign file's size (MB)."""
    csv_files = list(mapping_path.parent.glob("*.csv"))
    megabytes = sum(p.stat().st_size for p in csv_files) / 1e6
    rows = sum(p.read_text().count("\n") - 1 for p in csv_files)

    def run() -> None:
        out.unlink(missing_ok=True)
        import_campaign(load_mapping(mapping_path), out, limits=LIMITS, config_toml="", software_version="b")

    seconds = best_time_s(run, repeat)
    return {"s": seconds, "mb": megabytes, "rows": rows, "h5_mb": out.stat().st_size / 1e6}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dwells", type=int, default=20)
    parser.add_argument("--dwell-s", type=float, default=5.0)
    parser.add_argument("--gap-s", type=float, default=1.0)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        layouts = write_layouts(folder, args.dwells, args.dwell_s, args.gap_s)
        figures = {
            name: measure(path, folder / f"{i}.h5", args.repeat)
            for i, (name, path) in enumerate(layouts.items())
        }
    base = figures["one file per dwell"]
    print(
        f"{args.dwells} dwells of {args.dwell_s:g} s at {RATE_HZ:g} Hz, {args.gap_s:g} s of rest between them"
    )
    print(f"{'layout':<20} {'CSV MB':>8} {'rows':>9} {'import s':>9} {'MB/s':>6} {'rows/s':>9} {'h5 MB':>7}")
    for name, f in figures.items():
        print(
            f"{name:<20} {f['mb']:8.2f} {f['rows']:9d} {f['s']:9.3f} {f['mb'] / f['s']:6.2f}"
            f" {f['rows'] / f['s']:9.0f} {f['h5_mb']:7.3f}"
        )
    grid = figures["one file per grid"]
    per_mb = (grid["s"] / grid["mb"]) / (base["s"] / base["mb"])
    print(f"one file per grid against one file per dwell: time per MB {per_mb:.2f}x (target <= 2x),")
    print(f"campaign file {grid['h5_mb'] / base['h5_mb']:.2f}x the size (target about 1x)")


if __name__ == "__main__":
    main()
