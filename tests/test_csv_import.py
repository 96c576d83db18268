"""``wfsbench import-csv``: a simulated campaign exported as another acquisition system would (German
column names, kN, mm, g, a millisecond time column, ';' and a decimal comma), imported with a
mapping file and analysed, gives the parameters of the direct analysis; garbage CSV files are
refused naming the file, the line and the column, and leave no file behind."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from bench.analysis.campaign import CampaignKnowledge
from bench.app.run_analysis import RunAnalyser, replay_campaign
from bench.cli.exit_codes import ExitCode
from bench.cli.main import main
from bench.models.parameters import WfsSensor
from bench.store import open_campaign
from bench.store.csv_import import ImportLimits, import_campaign
from bench.store.csv_mapping import ImportMapping, MappingError, load_mapping
from bench.store.csv_read import CsvError, CsvTable, read_csv
from tests.commands import wfsbench

ROOT = Path(__file__).resolve().parents[1]
G_M_S2 = 9.80665
#: The default shaker bench's frequency range and the shipped sequences' tyre pressure prompts' range.
SHAKER_LIMITS = ImportLimits(
    min_freq_hz=0.1, max_freq_hz=100.0, min_tyre_pressure_bar=0.5, max_tyre_pressure_bar=4.5
)
#: The other system's columns: header -> (schema channel, factor from SI to the column's unit).
FOREIGN = {
    "Weg [mm]": ("z_base_m", 1e3),
    "F_Platte [kN]": ("f_plate_n", 1e-3),
    "Fz [kN]": ("fz_wfs_n", 1e-3),
    "a_Nabe [g]": ("a_hub_m_s2", 1 / G_M_S2),
}


def _decimal_comma(value: float) -> str:
    return f"{value:.10g}".replace(".", ",")


def export_point(run, point, path: Path) -> None:
    """One point of ``run`` as the other system writes it: ``Zeit [ms]`` then the foreign columns."""
    columns = [
        np.asarray(run.channels[channel][point.start_sample : point.end_sample], dtype=float) * factor
        for channel, factor in FOREIGN.values()
    ]
    lines = [";".join(["Zeit [ms]", *FOREIGN])]
    for i in range(point.end_sample - point.start_sample):
        lines.append(";".join([str(i), *(_decimal_comma(c[i]) for c in columns)]))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def export_campaign(original: Path, folder: Path) -> Path:
    """Every run of ``original`` as CSV files (one per point) and the mapping that imports them."""
    mapping = [
        "[source]",
        'name = "lab_b"',
        'bench = "shaker"',
        "[csv]",
        'delimiter = ";"',
        'decimal = ","',
        "[time]",
        'column = "Zeit [ms]"',  # the unit from the header's brackets
        "[channels]",
        'z_base_m = { column = "Weg [mm]", unit = "mm" }',
        'f_plate_n = { column = "F_Platte [kN]" }',  # the unit from the header
        'fz_wfs_n = { column = "Fz [kN]", unit = "kN", scale = 1.0 }',
        'a_hub_m_s2 = { column = "a_Nabe [g]", unit = "g" }',
    ]
    with open_campaign(original) as campaign:
        for r, run in enumerate(campaign.runs):
            done = sorted((p for p in run.points if p.status == "done"), key=lambda p: p.index)
            mapping += ["[[runs]]", f'kind = "{run.kind}"', f'id = "{run.run_id}"']
            if "tyre_pressure_bar" in run.conditions:
                mapping.append(f"tyre_pressure_bar = {run.conditions['tyre_pressure_bar']!r}")
            if run.kind == "sweep":
                (point,) = done
                export_point(run, point, folder / f"run{r}.csv")
                step = run.step
                mapping += [
                    f'file = "run{r}.csv"',
                    *(
                        f"{key} = {float(step[key])!r}"
                        for key in ("start_hz", "end_hz", "duration_s", "amplitude_mm")
                    ),
                ]
                continue
            for point in done:
                name = f"run{r}_point{point.index}.csv"
                export_point(run, point, folder / name)
                fs = run.sample_rate_hz
                mapping += [
                    "[[runs.points]]",
                    f'file = "{name}"',
                    f"freq_hz = {point.freq_hz!r}",
                    f"amplitude_mm = {point.amplitude_mm!r}",
                    f"hold_start_s = {(point.hold_start_sample - point.start_sample) / fs!r}",
                    f"hold_end_s = {(point.hold_end_sample - point.start_sample) / fs!r}",
                ]
                if math.isfinite(point.requested_amplitude_mm):
                    mapping.append(f"requested_amplitude_mm = {point.requested_amplitude_mm!r}")
    path = folder / "mapping.toml"
    path.write_text("\n".join(mapping) + "\n")
    return path


def analysed(path: Path) -> CampaignKnowledge:
    """The whole file analysed as the post-run analysis replays a campaign, from the same start."""
    knowledge = CampaignKnowledge(
        sensor=WfsSensor(mass_kg=3.82, eigenfrequency_hz=2200.0), wheel_mass_kg=29.0
    )
    with open_campaign(path) as campaign:
        replay_campaign(campaign, RunAnalyser(knowledge))
    return knowledge


def test_a_campaign_exported_to_foreign_csv_and_imported_gives_the_same_parameters(smoke_campaign, tmp_path):
    mapping = export_campaign(smoke_campaign, tmp_path)
    imported = tmp_path / "imported.h5"
    run = wfsbench("import-csv", str(mapping), "--out", str(imported))
    assert run.returncode == ExitCode.OK, run.stderr

    with open_campaign(smoke_campaign) as original, open_campaign(imported) as copy:
        assert [r.run_id for r in copy.runs] == [r.run_id for r in original.runs]
        for a, b in zip(original.runs, copy.runs, strict=True):
            assert (b.kind, b.status, b.sample_rate_hz) == (a.kind, "complete", a.sample_rate_hz)
            assert b.conditions.get("tyre_pressure_bar") == a.conditions.get("tyre_pressure_bar")
        sweep_a, sweep_b = (
            original.run("smoke-s010-sweep").sweep_record(),
            copy.run("smoke-s010-sweep").sweep_record(),
        )
        for channel, _ in FOREIGN.values():  # float32 through 10 digits and back: the very same numbers
            np.testing.assert_array_equal(sweep_b.channels[channel], sweep_a.channels[channel])

    direct, via_csv = analysed(smoke_campaign), analysed(imported)
    m_comp_kg = direct.shaker[2.5].free_run.plate.mass_kg
    assert math.isclose(via_csv.shaker[2.5].free_run.plate.mass_kg, m_comp_kg, rel_tol=1e-6)
    (amp_direct,) = direct.shaker[2.5].amplitudes.values()
    (amp_csv,) = via_csv.shaker[2.5].amplitudes.values()
    assert amp_csv.identification.best == amp_direct.identification.best
    compared = 0
    for model, fit in amp_direct.identification.fits.items():
        other = amp_csv.identification.fits[model]
        assert other.lsq.values.keys() == fit.lsq.values.keys()
        for name, value in fit.lsq.values.items():
            assert math.isclose(other.lsq.values[name], value, rel_tol=1e-6, abs_tol=1e-9 * abs(value)), (
                model,
                name,
            )
            compared += 1
    assert compared >= 10
    peak_direct, peak_csv = amp_direct.model_peak, amp_csv.model_peak
    if peak_direct is not None:
        assert math.isclose(peak_csv.freq_hz, peak_direct.freq_hz, rel_tol=1e-6)


# -- garbage ----------------------------------------------------------------------------------------

MAPPING = """\
[source]
name = "lab_b"

[csv]
delimiter = ";"
decimal = ","

[time]
sample_rate_hz = 1000

[channels]
z_base_m = { column = "Weg [mm]", unit = "mm" }
f_plate_n = { column = "F_Platte [kN]" }

[[runs]]
kind = "free_run"
[[runs.points]]
file = "free.csv"
freq_hz = 10
amplitude_mm = 2
"""
GOOD_CSV = "Weg [mm];F_Platte [kN]\n0,5;1,25\n0,75;1,5\n1;1,75\n"

#: kind of garbage -> (the CSV text, what the error names after the folder, the mapping's column)
GARBAGE = {
    "missing column": (
        "Weg [mm];F_Plate [kN]\n0,5;1,25\n",
        "free.csv: line 1, column 'F_Platte [kN]': missing: a free_run run needs f_plate_n"
        " (the header has: Weg [mm], F_Plate [kN])",
    ),
    "text in a number": (
        "Weg [mm];F_Platte [kN]\n0,5;1,25\n0,75;n/a\n",
        "free.csv: line 3, column 'F_Platte [kN]': 'n/a' is not a number",
    ),
    "a point where the decimal mark is a comma": (
        "Weg [mm];F_Platte [kN]\n0,5;1,25\n0.75;1,5\n",
        "free.csv: line 3, column 'Weg [mm]': '0.75': a '.' where the decimal mark is ','",
    ),
    "ragged row": (
        "Weg [mm];F_Platte [kN]\n0,5;1,25\n0,75;1,5;2\n",
        "free.csv: line 3: 3 fields where the header has 2",
    ),
    "unknown unit in the header": (
        "Weg [mm];F_Platte [kp]\n0,5;1,25\n",
        "free.csv: line 1, column 'F_Platte [kp]': unknown unit 'kp'",
        "F_Platte [kp]",
    ),
    "a force float32 cannot hold": (
        "Weg [mm];F_Platte [kN]\n0,5;1,25\n0,75;1e36\n",
        "free.csv: line 3, column 'F_Platte [kN]': '1e36' is 1e+39 in SI units (its unit and scale applied)",
    ),
    "a damaged cell": (
        "Weg [mm];F_Platte [kN]\n0,5;1e300\n",
        "free.csv: line 2, column 'F_Platte [kN]': '1e300' is 1e+303 in SI units",
    ),
    "empty file": ("", "free.csv: line 1: empty file: no header line"),
    "header only": ("Weg [mm];F_Platte [kN]\n", "free.csv: line 2: no data rows after the header"),
}


@pytest.mark.parametrize("case", GARBAGE.values(), ids=GARBAGE.keys())
def test_garbage_csv_is_refused_with_file_line_and_column_and_leaves_nothing(tmp_path, capsys, case):
    text, named, *column = case
    (tmp_path / "mapping.toml").write_text(
        MAPPING.replace("F_Platte [kN]", *column, 1) if column else MAPPING
    )
    (tmp_path / "free.csv").write_text(text)
    out = tmp_path / "imported.h5"
    code = main(["import-csv", str(tmp_path / "mapping.toml"), "--out", str(out)])
    assert code == ExitCode.INVALID
    assert f"error: {tmp_path}/{named}" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "free.csv",
        "mapping.toml",
    ]  # no output, no temporary


def test_a_bad_file_late_in_the_campaign_leaves_nothing_either(tmp_path):
    """The first run's file is good, the second run's is not: refused before anything is written."""
    two_runs = (
        MAPPING
        + '[[runs]]\nkind = "free_run"\n[[runs.points]]\nfile = "bad.csv"\nfreq_hz = 30\namplitude_mm = 2\n'
    )
    (tmp_path / "mapping.toml").write_text(two_runs)
    (tmp_path / "free.csv").write_text(GOOD_CSV)
    (tmp_path / "bad.csv").write_text(GOOD_CSV + "1,25;x\n")
    with pytest.raises(CsvError, match=r"bad\.csv: line 5, column 'F_Platte \[kN\]': 'x' is not a number"):
        import_campaign(
            load_mapping(tmp_path / "mapping.toml"),
            tmp_path / "out.h5",
            limits=SHAKER_LIMITS,
            config_toml="",
            software_version="t",
        )
    assert not any(p.suffix == ".h5" or p.name.startswith(".") for p in tmp_path.iterdir())


def test_a_good_file_imports_with_its_units_converted(tmp_path, capsys):
    (tmp_path / "mapping.toml").write_text(MAPPING)
    (tmp_path / "free.csv").write_text(GOOD_CSV)
    out = tmp_path / "imported.h5"
    assert main(["import-csv", str(tmp_path / "mapping.toml"), "--out", str(out)]) == ExitCode.OK
    assert (
        f"imported lab_b-r000-free_run (free_run, 1 point from 1 file); file {out}" in capsys.readouterr().out
    )
    with open_campaign(out) as campaign:
        (run,) = campaign.runs
        assert (run.run_id, run.kind, run.status) == ("lab_b-r000-free_run", "free_run", "complete")
        np.testing.assert_allclose(run.channels["z_base_m"], [0.5e-3, 0.75e-3, 1e-3], rtol=1e-7)
        np.testing.assert_allclose(run.channels["f_plate_n"], [1250, 1500, 1750], rtol=1e-7)
        assert {s.name: s.unit for s in run.channel_specs} == {"z_base_m": "m", "f_plate_n": "N"}
        (point,) = run.points
        assert (point.freq_hz, point.amplitude_mm, point.start_sample, point.end_sample) == (10, 2, 0, 3)
    # an existing campaign file is never replaced
    assert main(["import-csv", str(tmp_path / "mapping.toml"), "--out", str(out)]) == ExitCode.INVALID


BAD_MAPPINGS = {
    "unknown unit": (('unit = "mm"', 'unit = "inch"'), "channels.z_base_m.unit: unknown unit 'inch'"),
    "unit of another quantity": (
        ('unit = "mm"', 'unit = "kN"'),
        "channels.z_base_m.unit: kN is not a unit of m",
    ),
    "no rate nor time column": (
        ("sample_rate_hz = 1000", ""),
        "time: give either sample_rate_hz or a time column",
    ),
    "a frequency as text": (
        ("freq_hz = 10", 'freq_hz = "10"'),
        "runs[0].points[0].freq_hz: expected a number",
    ),
    "unknown run kind": (('kind = "free_run"', 'kind = "hamer"'), "runs[0].kind: 'hamer' is not one of"),
    "unknown key": (('decimal = ","', 'decimal = ","\nquote = "x"'), "csv.quote: unknown key"),
    "a negative frequency": (
        ("freq_hz = 10", "freq_hz = -10"),
        "runs[0].points[0].freq_hz: -10 is out of range (allowed > 0)",
    ),
    "a duplicate key": (
        ("freq_hz = 10", "freq_hz = 10\nfreq_hz = 12"),
        "runs[0].points[0].freq_hz: line ",
    ),
}


@pytest.mark.parametrize("case", BAD_MAPPINGS.values(), ids=BAD_MAPPINGS.keys())
def test_a_bad_mapping_is_refused_naming_the_key(tmp_path, case):
    (old, new), named = case
    assert old in MAPPING
    (tmp_path / "mapping.toml").write_text(MAPPING.replace(old, new, 1))
    with pytest.raises(MappingError) as refused:
        load_mapping(tmp_path / "mapping.toml")
    assert str(refused.value).startswith(f"{tmp_path}/mapping.toml: {named}")


def read_first(mapping: ImportMapping) -> CsvTable:
    """The first point's file of the mapping's first run, read as that run maps it."""
    run = mapping.runs[0]
    return read_csv(run.points[0].file, mapping.dialect, run.timing, run.channels)


def test_a_time_column_that_does_not_step_evenly_is_refused_at_its_line(tmp_path):
    timed = MAPPING.replace("sample_rate_hz = 1000", 'column = "t [s]"')
    (tmp_path / "mapping.toml").write_text(timed)
    (tmp_path / "free.csv").write_text(
        "t [s];Weg [mm];F_Platte [kN]\n0;1;1\n0,001;1;1\n0,003;1;1\n0,004;1;1\n"
    )
    with pytest.raises(CsvError, match=r"free\.csv: line 3, column 't \[s\]': time steps unevenly"):
        read_first(load_mapping(tmp_path / "mapping.toml"))
    (tmp_path / "free.csv").write_text("t [s];Weg [mm];F_Platte [kN]\n0;1;1\n0,002;1;1\n0,004;1;1\n")
    assert read_first(load_mapping(tmp_path / "mapping.toml")).sample_rate_hz == pytest.approx(500)


def test_the_documented_example_mapping_loads_as_described(tmp_path):
    text = (ROOT / "docs" / "import.md").read_text()
    example = re.search(r"`mapping.toml`, beside the CSV files:\n\n```toml\n(.*?)```", text, re.S).group(1)
    (tmp_path / "mapping.toml").write_text(example)
    mapping = load_mapping(tmp_path / "mapping.toml")
    assert (mapping.name, mapping.bench, mapping.dialect.delimiter, mapping.dialect.decimal) == (
        "lab_b_2019",
        "shaker",
        ";",
        ",",
    )
    hammer, free, grid, continuous, _ = mapping.runs
    assert (free.timing.column, free.timing.unit) == ("Zeit [ms]", "ms")
    assert {c.channel: (c.column, c.unit, c.scale) for c in grid.channels}["fz_wfs_n"] == (
        "Fz [kN]",
        "kN",
        -1.0,
    )
    assert [(r.run_id, r.kind, r.tyre_pressure_bar, len(r.points), len(r.files)) for r in mapping.runs] == [
        ("lab_b_2019-r000-hammer", "hammer", None, 1, 1),
        ("lab_b_2019-r001-free_run", "free_run", None, 2, 2),
        ("lab_b_2019-grid-2.5bar", "dwell_grid", 2.5, 2, 2),
        ("lab_b_2019-r003-dwell_grid", "dwell_grid", 3.5, 2, 1),
        ("lab_b_2019-r004-sweep", "sweep", 2.5, 1, 1),
    ]
    assert (hammer.timing.sample_rate_hz, [c.channel for c in hammer.channels]) == (
        20e3,
        ["fz_wfs_n", "f_hammer_n"],
    )
    assert grid.points[1].requested_amplitude_mm == 2
    assert free.points[0].file == tmp_path / "free_10hz.csv"
    assert [(p.file.name, p.start_s, p.end_s, p.hold_start_s) for p in continuous.points] == [
        ("grid_3.5bar.csv", 1.0, 4.0, 1.5),
        ("grid_3.5bar.csv", 5.0, 8.0, None),
    ]


def test_every_problem_of_a_mapping_is_reported_in_the_order_of_the_file(tmp_path):
    """Three problems in three tables: one error, one line each, as the file orders them (the csv
    table comes before the runs), though the reader checks the runs' kind before their points."""
    text = MAPPING.replace('kind = "free_run"', 'kind = "swep"').replace("freq_hz = 10", 'freq_hz = "10"')
    (tmp_path / "mapping.toml").write_text(text.replace('decimal = ","', 'decimal = ","\nfoo = 1'))
    with pytest.raises(MappingError) as refused:
        load_mapping(tmp_path / "mapping.toml")
    path = tmp_path / "mapping.toml"
    assert str(refused.value).splitlines() == [
        f"{path}: csv.foo: unknown key (allowed: delimiter, decimal, skip_lines, units_row, encoding)",
        "  and 2 more:",
        f"  {path}: runs[0].kind: 'swep' is not one of dwell_grid, free_run, sweep, hammer",
        f"  {path}: runs[0].points[0].freq_hz: expected a number, got '10'",
    ]
    keys = [key for key, _ in refused.value.problems]
    assert keys == ["csv.foo", "runs[0].kind", "runs[0].points[0].freq_hz"]


SWEEP_RUN = """
[[runs]]
kind = "sweep"
tyre_pressure_bar = 2.5
file = "sweep.csv"
start_hz = 1
end_hz = 30
duration_s = 0.003
amplitude_mm = 1
"""

#: A change to MAPPING + SWEEP_RUN (3 rows a file at 1000 Hz: 3 ms) -> the problem named after the file.
IMPOSSIBLE = {
    "a frequency above the bench's": (
        ("freq_hz = 10", "freq_hz = 400"),
        "runs[0].points[0].freq_hz: 400 Hz is above the bench's maximum (allowed 0.1 <= freq_hz <= 100 Hz)",
    ),
    "a frequency below the bench's": (
        ("start_hz = 1", "start_hz = 0.05"),
        "runs[1].start_hz: 0.05 Hz is below the bench's minimum (allowed 0.1 <= start_hz <= 100 Hz)",
    ),
    "a frequency above half the sample rate": (
        ("sample_rate_hz = 1000", "sample_rate_hz = 50", "duration_s = 0.003", "duration_s = 0.06"),
        "runs[1].end_hz: 30 Hz is not below half the sample rate of sweep.csv (50 Hz)"
        " (allowed 0.1 <= end_hz < 25 Hz)",
    ),
    "a sweep's duration that is not its file's": (
        ("duration_s = 0.003", "duration_s = 0.006"),
        "runs[1].duration_s: 0.006 s does not match the 0.003 s of samples of sweep.csv"
        " (allowed 0.003 s, within one sample: 0.001 s)",
    ),
    "a tyre pressure no prompt accepts": (
        ("tyre_pressure_bar = 2.5", "tyre_pressure_bar = 25"),
        "runs[1].tyre_pressure_bar: 25 bar is outside what a set_tyre_pressure prompt accepts"
        " (allowed 0.5 <= tyre_pressure_bar <= 4.5 bar)",
    ),
    "a hold that ends beyond the file": (
        ("amplitude_mm = 2", "amplitude_mm = 2\nhold_end_s = 5"),
        "runs[0].points[0].hold_end_s: 5 s is beyond the 0.003 s of samples of free.csv"
        " (allowed hold_start_s < hold_end_s <= 0.003 s)",
    ),
    "a hold that starts beyond the file": (
        ("amplitude_mm = 2", "amplitude_mm = 2\nhold_start_s = 0.003"),
        "runs[0].points[0].hold_start_s: 0.003 s is beyond the 0.003 s of samples of free.csv"
        " (allowed 0 <= hold_start_s < 0.003 s)",
    ),
    "a four-post frequency, the four-post bench's default configuration": (
        ('name = "lab_b"', 'name = "lab_b"\nbench = "four_post"', "freq_hz = 10", "freq_hz = 60"),
        "runs[0].points[0].freq_hz: 60 Hz is above the bench's maximum (allowed 0.1 <= freq_hz <= 50 Hz)",
    ),
}


def _write_campaign_files(folder: Path, changes: tuple[str, ...]) -> Path:
    text = MAPPING + SWEEP_RUN
    for old, new in zip(changes[::2], changes[1::2], strict=True):
        assert old in text
        text = text.replace(old, new, 1)
    (folder / "mapping.toml").write_text(text)
    (folder / "free.csv").write_text(GOOD_CSV)
    (folder / "sweep.csv").write_text(GOOD_CSV)
    return folder / "mapping.toml"


def test_the_sweep_campaign_of_the_impossible_cases_imports_as_it_is(tmp_path):
    """The base of the cases below is good: a sweep's duration within one sample of its file's."""
    mapping = _write_campaign_files(tmp_path, ("duration_s = 0.003", "duration_s = 0.0039"))
    out = tmp_path / "imported.h5"
    assert main(["import-csv", str(mapping), "--out", str(out)]) == ExitCode.OK
    with open_campaign(out) as campaign:
        assert [r.kind for r in campaign.runs] == ["free_run", "sweep"]


@pytest.mark.parametrize("case", IMPOSSIBLE.values(), ids=IMPOSSIBLE.keys())
def test_impossible_mapped_values_are_refused_naming_the_key_and_the_range(tmp_path, capsys, case):
    changes, named = case
    mapping = _write_campaign_files(tmp_path, changes)
    out = tmp_path / "imported.h5"
    assert main(["import-csv", str(mapping), "--out", str(out)]) == ExitCode.INVALID
    assert capsys.readouterr().err == f"error: {mapping}: {named}\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["free.csv", "mapping.toml", "sweep.csv"]


def test_a_time_column_in_the_wrong_unit_is_caught_by_the_sample_rate(tmp_path, capsys):
    """A millisecond column declared in seconds: 1 Hz sampling, the 10 Hz dwell above its half; and
    every impossible value of the file is in the one error, in the file's order."""
    mapping = _write_campaign_files(
        tmp_path,
        ("sample_rate_hz = 1000", 'column = "Zeit"\nunit = "s"', "duration_s = 0.003", "duration_s = 3"),
    )
    for name in ("free.csv", "sweep.csv"):
        (tmp_path / name).write_text("Zeit;Weg [mm];F_Platte [kN]\n0;0,5;1,25\n1;0,75;1,5\n2;1;1,75\n")
    assert main(["import-csv", str(mapping), "--out", str(tmp_path / "out.h5")]) == ExitCode.INVALID
    lines = capsys.readouterr().err.splitlines()
    assert lines == [
        f"error: {mapping}: runs[0].points[0].freq_hz: 10 Hz is not below half the sample rate of free.csv"
        " (1 Hz) (allowed 0.1 <= freq_hz < 0.5 Hz)",
        "  and 2 more:",
        f"  {mapping}: runs[1].start_hz: 1 Hz is not below half the sample rate of sweep.csv (1 Hz)"
        " (allowed 0.1 <= start_hz < 0.5 Hz)",
        f"  {mapping}: runs[1].end_hz: 30 Hz is not below half the sample rate of sweep.csv (1 Hz)"
        " (allowed 0.1 <= end_hz < 0.5 Hz)",
    ]


@pytest.mark.parametrize("encoding", ["", 'encoding = "UTF-8"\n'])
def test_a_csv_file_with_a_utf8_byte_order_mark_imports(tmp_path, encoding):
    """Spreadsheet programs start a UTF-8 CSV with EF BB BF: not part of the first column's name."""
    (tmp_path / "mapping.toml").write_text(MAPPING.replace("[time]", f"{encoding}[time]"))
    (tmp_path / "free.csv").write_bytes(b"\xef\xbb\xbf" + GOOD_CSV.encode())
    out = tmp_path / "imported.h5"
    assert main(["import-csv", str(tmp_path / "mapping.toml"), "--out", str(out)]) == ExitCode.OK
    with open_campaign(out) as campaign:
        np.testing.assert_allclose(campaign.runs[0].channels["z_base_m"], [0.5e-3, 0.75e-3, 1e-3], rtol=1e-7)
