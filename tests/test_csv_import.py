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

from bench.app.campaign import plan_campaign, run_campaign
from bench.app.post_run import CampaignKnowledge, PostRunAnalysis
from bench.cli import EXIT_COMPLETE, EXIT_INVALID, main
from bench.models.parameters import WfsSensor
from bench.store import open_campaign
from bench.store.csv_import import CsvError, import_campaign, read_csv
from bench.store.csv_mapping import MappingError, load_mapping
from tests.test_campaign_cli import SMOKE, wfsbench

ROOT = Path(__file__).resolve().parents[1]
G_M_S2 = 9.80665
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
    PostRunAnalysis(path, lambda event: None, knowledge)
    return knowledge


@pytest.fixture(scope="module")
def smoke_campaign(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("original") / "smoke.h5"
    outcome = run_campaign(plan_campaign(SMOKE), path)
    assert outcome.status == "complete", outcome.reason
    return path


def test_a_campaign_exported_to_foreign_csv_and_imported_gives_the_same_parameters(smoke_campaign, tmp_path):
    mapping = export_campaign(smoke_campaign, tmp_path)
    imported = tmp_path / "imported.h5"
    run = wfsbench("import-csv", str(mapping), "--out", str(imported))
    assert run.returncode == EXIT_COMPLETE, run.stderr

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
        "free.csv: line 1, column 'F_Platte [kN]': missing (the header has: Weg [mm], F_Plate [kN])",
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
    assert code == EXIT_INVALID
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
            load_mapping(tmp_path / "mapping.toml"), tmp_path / "out.h5", config_toml="", software_version="t"
        )
    assert not any(p.suffix == ".h5" or p.name.startswith(".") for p in tmp_path.iterdir())


def test_a_good_file_imports_with_its_units_converted(tmp_path):
    (tmp_path / "mapping.toml").write_text(MAPPING)
    (tmp_path / "free.csv").write_text(GOOD_CSV)
    out = tmp_path / "imported.h5"
    assert main(["import-csv", str(tmp_path / "mapping.toml"), "--out", str(out)]) == EXIT_COMPLETE
    with open_campaign(out) as campaign:
        (run,) = campaign.runs
        assert (run.run_id, run.kind, run.status) == ("lab_b-r000-free_run", "free_run", "complete")
        np.testing.assert_allclose(run.channels["z_base_m"], [0.5e-3, 0.75e-3, 1e-3], rtol=1e-7)
        np.testing.assert_allclose(run.channels["f_plate_n"], [1250, 1500, 1750], rtol=1e-7)
        assert {s.name: s.unit for s in run.channel_specs} == {"z_base_m": "m", "f_plate_n": "N"}
        (point,) = run.points
        assert (point.freq_hz, point.amplitude_mm, point.start_sample, point.end_sample) == (10, 2, 0, 3)
    # an existing campaign file is never replaced
    assert main(["import-csv", str(tmp_path / "mapping.toml"), "--out", str(out)]) == EXIT_INVALID


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
    "unknown run kind": (('kind = "free_run"', 'kind = "hammer"'), "runs[0].kind: 'hammer' is not one of"),
    "unknown key": (('decimal = ","', 'decimal = ","\nquote = "x"'), "csv.quote: unknown key"),
}


@pytest.mark.parametrize("case", BAD_MAPPINGS.values(), ids=BAD_MAPPINGS.keys())
def test_a_bad_mapping_is_refused_naming_the_key(tmp_path, case):
    (old, new), named = case
    assert old in MAPPING
    (tmp_path / "mapping.toml").write_text(MAPPING.replace(old, new, 1))
    with pytest.raises(MappingError) as refused:
        load_mapping(tmp_path / "mapping.toml")
    assert str(refused.value).startswith(f"{tmp_path}/mapping.toml: {named}")


def test_a_time_column_that_does_not_step_evenly_is_refused_at_its_line(tmp_path):
    timed = MAPPING.replace("sample_rate_hz = 1000", 'column = "t [s]"')
    (tmp_path / "mapping.toml").write_text(timed)
    (tmp_path / "free.csv").write_text(
        "t [s];Weg [mm];F_Platte [kN]\n0;1;1\n0,001;1;1\n0,003;1;1\n0,004;1;1\n"
    )
    with pytest.raises(CsvError, match=r"free\.csv: line 3, column 't \[s\]': time steps unevenly"):
        read_csv(tmp_path / "free.csv", load_mapping(tmp_path / "mapping.toml"))
    (tmp_path / "free.csv").write_text("t [s];Weg [mm];F_Platte [kN]\n0;1;1\n0,002;1;1\n0,004;1;1\n")
    assert read_csv(
        tmp_path / "free.csv", load_mapping(tmp_path / "mapping.toml")
    ).sample_rate_hz == pytest.approx(500)


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
    assert (mapping.timing.column, mapping.timing.unit) == ("Zeit [ms]", "ms")
    assert {c.channel: (c.column, c.unit, c.scale) for c in mapping.channels}["fz_wfs_n"] == (
        "Fz [kN]",
        "kN",
        -1.0,
    )
    assert [(r.run_id, r.kind, r.tyre_pressure_bar, len(r.files)) for r in mapping.runs] == [
        ("lab_b_2019-r000-free_run", "free_run", None, 2),
        ("lab_b_2019-grid-2.5bar", "dwell_grid", 2.5, 2),
        ("lab_b_2019-r002-sweep", "sweep", 2.5, 1),
    ]
    assert mapping.runs[1].files[1].requested_amplitude_mm == 2
    assert mapping.runs[0].files[0].file == tmp_path / "free_10hz.csv"
