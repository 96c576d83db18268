"""The lab-style exports of ``tests/lab_exports`` (its README): each imports and, where it holds a free
run and a grid or a hammer capture, analyses to the values its signals were made with; each faulty
export is refused naming the file, the line and the column, or the mapping key. One continuous file
per run imports as its points cut into one file each would, into a campaign file of the same size."""

from __future__ import annotations

import math
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from bench.cli.exit_codes import ExitCode
from bench.cli.main import main
from bench.store import open_campaign
from tests.test_csv_import import analysed

EXPORTS = Path(__file__).resolve().parent / "lab_exports"
PLATE_KG = 12.0


def imported(lab: str, folder: Path, capsys) -> tuple[Path, str]:
    """``lab``'s export imported into ``folder``; the file and what the command printed."""
    out = folder / f"{lab}.h5"
    assert main(["import-csv", str(EXPORTS / lab / "mapping.toml"), "--out", str(out)]) == ExitCode.OK
    return out, capsys.readouterr().out


def stiffness_n_per_m(knowledge, pressure_bar: float) -> float:
    (amplitude,) = knowledge.shaker[pressure_bar].amplitudes.values()
    return amplitude.identification.best_fit.tyre.stiffness_n_per_m


def test_lab_a_units_row_decimal_comma_and_a_free_run_without_wfs_column(tmp_path, capsys):
    path, printed = imported("lab_a", tmp_path, capsys)
    assert (
        "lab_a-r000-free_run (free_run, 4 points from 4 files, without fz_wfs_n, a_hub_m_s2, angle_rad:"
        in printed
    )
    with open_campaign(path) as campaign:
        free, grid = campaign.runs
        assert sorted(free.channels) == ["f_plate_n", "z_base_m"]
        assert sorted(grid.channels) == ["a_hub_m_s2", "angle_rad", "f_plate_n", "fz_wfs_n", "z_base_m"]
        np.testing.assert_allclose(grid.channels["angle_rad"], math.pi / 2, rtol=1e-7)  # 90,0 °
        first = (EXPORTS / "lab_a" / "grid_2.5bar_05hz.csv").read_text("cp1252").splitlines()[5]
        fields = first.rstrip(";").split(";")  # Weg [mm], F_Platte [kN], Fz [kN], a_Nabe [m/s²]
        expected = [float(f.replace(",", ".")) * k for f, k in zip(fields, (1e-3, 1e3, 1e3, 1), strict=False)]
        names = ("z_base_m", "f_plate_n", "fz_wfs_n", "a_hub_m_s2")
        assert [float(grid.channels[n][0]) for n in names] == pytest.approx(expected, rel=1e-6, abs=1e-9)
    knowledge = analysed(path)
    assert knowledge.shaker[2.5].free_run.plate.mass_kg == pytest.approx(PLATE_KG, rel=1e-3)
    assert stiffness_n_per_m(knowledge, 2.5) == pytest.approx(390e3, rel=5e-3)


def _split_into_dwells(folder: Path, out: Path) -> None:
    """lab B's continuous files cut into one file per point (each with the header) and the mapping
    that imports them: what the points' times in lab B's mapping describe."""
    lab_b = tomllib.loads((folder / "mapping.toml").read_text())
    rate_hz = 500.0
    mapping = ["[source]", 'name = "lab_b"', "[time]", f"sample_rate_hz = {rate_hz:g}", "[channels]"]
    mapping += [f"{name} = {{ column = {spec['column']!r} }}" for name, spec in lab_b["channels"].items()]
    for run in lab_b["runs"]:
        lines = (folder / run["file"]).read_text("utf-8-sig").splitlines()
        mapping += ["[[runs]]", f"kind = {run['kind']!r}"]
        mapping += [f"tyre_pressure_bar = {run['tyre_pressure_bar']}"] if "tyre_pressure_bar" in run else []
        for j, point in enumerate(run["points"]):
            name = f"{run['file'][:-4]}_{j}.csv"
            first, last = (round(point[key] * rate_hz) for key in ("start_s", "end_s"))
            (out / name).write_text("\n".join([lines[0], *lines[1 + first : 1 + last]]) + "\n")
            mapping += ["[[runs.points]]", f'file = "{name}"', f"freq_hz = {point['freq_hz']}"]
            mapping += [f"amplitude_mm = {point['amplitude_mm']}"]
            mapping += [f"hold_start_s = {point['hold_start_s'] - point['start_s']}"]
    (out / "mapping.toml").write_text("\n".join(mapping) + "\n")


def test_lab_b_one_continuous_file_per_run_imports_only_its_points(tmp_path, capsys):
    path, printed = imported("lab_b", tmp_path, capsys)
    assert "lab_b-r001-dwell_grid (dwell_grid, 8 points from 1 file)" in printed
    per_dwell = tmp_path / "per_dwell"
    per_dwell.mkdir()
    _split_into_dwells(EXPORTS / "lab_b", per_dwell)
    split = per_dwell / "split.h5"
    assert main(["import-csv", str(per_dwell / "mapping.toml"), "--out", str(split)]) == ExitCode.OK
    with open_campaign(path) as campaign, open_campaign(split) as other:
        for run, twin in zip(campaign.runs, other.runs, strict=True):
            assert run.n_samples == 400 * len(run.points)  # 0.8 s a point at 500 Hz; not the rest between
            assert [(p.start_sample, p.hold_start_sample, p.end_sample) for p in run.points] == [
                (p.start_sample, p.hold_start_sample, p.end_sample) for p in twin.points
            ]
            for name in run.channels:
                np.testing.assert_array_equal(run.channels[name], twin.channels[name])
    assert path.stat().st_size == pytest.approx(split.stat().st_size, rel=0.1)
    knowledge = analysed(path)
    assert knowledge.shaker[1.5].free_run.plate.mass_kg == pytest.approx(PLATE_KG, rel=1e-3)
    assert stiffness_n_per_m(knowledge, 1.5) == pytest.approx(250e3, rel=5e-3)


def test_lab_c_hammer_capture_gives_the_sensor_and_a_clamped_hub_needs_no_accelerometer(tmp_path, capsys):
    path, _ = imported("lab_c", tmp_path, capsys)
    with open_campaign(path) as campaign:
        hammer, free, grid = campaign.runs
        assert (hammer.kind, hammer.sample_rate_hz, free.sample_rate_hz) == (
            "hammer",
            pytest.approx(20e3),
            1e3,
        )
        assert {s.name: s.role for s in hammer.channel_specs} == {
            "fz_wfs_n": "wfs_fz",
            "f_hammer_n": "hammer_force",
        }
        assert hammer.hammer_record().channels["f_hammer_n"].max() == pytest.approx(400, rel=0.05)
        records = grid.dwell_records()
        assert len(records) == 8 and all(
            sorted(r.channels) == ["f_plate_n", "fz_wfs_n", "z_base_m"] for r in records
        )
    knowledge = analysed(path)
    assert knowledge.hammer.eigenfrequency_hz == pytest.approx(2150, rel=2e-3)
    assert knowledge.sensor.eigenfrequency_hz == knowledge.hammer.eigenfrequency_hz  # the analysis takes it
    assert knowledge.hammer.damping_ratio_log_decrement == pytest.approx(0.02, rel=0.05)


#: case folder -> what the error says after "error: " (the folder's path before each file name)
REFUSED = {
    "units_row_disagrees": "export.csv: line 2, column 'F_Platte': the file gives the unit N, the mapping kN",
    "unknown_unit": "export.csv: line 2, column 'F_Platte': unknown unit 'kp' (known: N, kN,",
    "free_run_without_plate_force": "export.csv: line 1, column 'F_Platte': missing: a free_run run needs"
    " f_plate_n (the header has: Weg, Fz)",
    "ragged_row": "export.csv: line 5: 1 field where the header has 2",
    "decimal_point": "export.csv: line 4, column 'Weg': '0.2': a '.' where the decimal mark is ','",
    "grid_without_tyre_pressure": "mapping.toml: runs[0].tyre_pressure_bar: missing: a dwell grid is analysed"
    " with the other grids of its tyre pressure (give it in bar)",
    "continuous_points_overlap": "mapping.toml: runs[0].points[1].start_s: 0.003 s lies inside the part of"
    " export.csv that runs[0].points[0] holds (0 s to 0.004 s)",
}


@pytest.mark.parametrize("case", REFUSED, ids=REFUSED)
def test_a_faulty_export_is_refused_naming_file_line_and_column_or_key(tmp_path, capsys, case):
    folder = EXPORTS / "refused" / case
    out = tmp_path / "refused.h5"
    assert main(["import-csv", str(folder / "mapping.toml"), "--out", str(out)]) == ExitCode.INVALID
    assert capsys.readouterr().err.startswith(f"error: {folder}/{REFUSED[case]}")
    assert not out.exists()


def test_every_export_of_the_corpus_is_tested():
    folders = {p.name for p in EXPORTS.iterdir() if p.is_dir() and not p.name.startswith("__")}
    assert folders == {"lab_a", "lab_b", "lab_c", "refused"}
    assert {p.name for p in (EXPORTS / "refused").iterdir()} == set(REFUSED)
    listed = re.findall(r"^\| `(\w+)/` \|", (EXPORTS / "README.md").read_text(), re.M)
    assert set(listed) == folders
