"""CSV layouts labs export (docs/import.md, *Layouts*): a units row, delimiters ending the lines, units
spelt with non-ASCII characters, channels a run does not need, points as parts of one continuous
file, a run's own time and channels tables; and what stays refused among them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.cli.exit_codes import ExitCode
from bench.cli.main import main
from bench.store import csv_read, open_campaign
from bench.store.csv_mapping import MappingError, load_mapping
from bench.store.csv_units import UNITS, unit_named

HEAD = """\
[source]
name = "lab"
[csv]
delimiter = ";"
{csv}
[time]
sample_rate_hz = 1000
[channels]
z_base_m = {{ column = "Weg" }}
f_plate_n = {{ column = "F_Platte" }}
fz_wfs_n = {{ column = "Fz" }}
"""
FREE_RUN = """\
[[runs]]
kind = "free_run"
[[runs.points]]
file = "free.csv"
freq_hz = 10
amplitude_mm = 2
"""


def write(folder, mapping: str, **files: str):
    (folder / "mapping.toml").write_text(mapping)
    for name, text in files.items():
        (folder / f"{name}.csv").write_text(text)
    return folder / "mapping.toml"


def import_csv(mapping, capsys) -> tuple[int, str]:
    out = mapping.parent / "out.h5"
    code = main(["import-csv", str(mapping), "--out", str(out)])
    captured = capsys.readouterr()
    return code, captured.out + captured.err


@pytest.mark.parametrize(
    ("spellings", "unit"),
    [
        (("m/s²", "m/s2", "m/s^2", " m/s ^2 "), "m/s^2"),
        (("µm", "μm", "um"), "µm"),  # the micro sign, the Greek mu, plain u
        (("N·m", "N⋅m", "N m", "Nm"), "Nm"),
        (("kN·m", "kNm"), "kNm"),
        (("°", "deg"), "deg"),
        (("µs", "us"), "µs"),
    ],
)
def test_unit_spellings_of_exports_are_one_unit_of_the_table(spellings, unit):
    assert {unit_named(s) for s in spellings} == {unit}
    assert unit in UNITS


def test_unknown_spellings_are_no_unit():
    assert [unit_named(s) for s in ("kp", "mm/s", "G", "")] == [None] * 4
    assert UNITS["µm"] == ("m", 1e-6) and UNITS["deg"] == ("rad", math.pi / 180)


@pytest.mark.parametrize(
    "text",
    [
        "Weg;F_Platte;Fz\nmm;kN;N\n1;2;3;\n4;5;6;\n",  # a delimiter ending the data rows only
        "Weg;F_Platte;Fz;\nmm;kN;N;\n1;2;3;\n4;5;6;\n",  # ... every line
        "Weg;F_Platte;Fz\n[mm];(kN);N\n1;2;3\n4;5;6\n\n\n",  # bracketed units, blank lines at the end
    ],
    ids=["data rows", "every line", "bracketed units"],
)
def test_units_row_and_delimiters_ending_the_lines(tmp_path, capsys, text):
    mapping = write(tmp_path, HEAD.format(csv="units_row = true") + FREE_RUN, free=text)
    assert import_csv(mapping, capsys)[0] == ExitCode.OK
    with open_campaign(tmp_path / "out.h5") as campaign:
        channels = campaign.runs[0].channels
        np.testing.assert_allclose(channels["z_base_m"], [1e-3, 4e-3], rtol=1e-7)
        np.testing.assert_allclose(channels["f_plate_n"], [2e3, 5e3], rtol=1e-7)
        np.testing.assert_allclose(channels["fz_wfs_n"], [3, 6], rtol=1e-7)


@pytest.mark.parametrize(
    ("text", "error"),
    [
        ("Weg;F_Platte;Fz\nmm;kN;N\n1;2;3;\n4;5\n", "line 4: 2 fields where the header has 3"),
        ("Weg;F_Platte;Fz\nmm;kN;N\n1;2;3\n4;5;\n", "line 4, column 'Fz': '' is not a number"),
        ("Weg;F_Platte;Fz\nmm;kN\n1;2;3\n", "line 2: the units row has 2 fields where the header has 3"),
        (
            "Weg;F_Platte;Fz\nmm;kN;\n1;2;3\n",
            "line 2, column 'Fz': no unit in the mapping and none in the file",
        ),
        ("Weg;F_Platte;Fz\n", "line 2: no units row after the header (csv.units_row)"),
        ("Weg;F_Platte;Fz\nmm;kN;N\n", "line 3: no data rows after the header"),
        (
            "Weg;F_Platte;Fz\nmm;N/m;N\n1;2;3\n",
            "line 2, column 'F_Platte': unknown unit 'N/m' (known: N, kN,",
        ),
        (
            "Weg;F_Platte;Fz\nmm;kNm;N\n1;2;3\n",
            "line 2, column 'F_Platte': unit kNm is not a unit of N (f_plate_n)",
        ),
        # the first bad field in the file's order, whichever column it is in
        ("Weg;F_Platte;Fz\nmm;kN;N\n1;2;x\n4;y;6\n", "line 3, column 'Fz': 'x' is not a number"),
        ("Weg;F_Platte;Fz\nmm;kN;N\n1;nan;3\n", "line 3, column 'F_Platte': 'nan' is not a finite number"),
    ],
    ids=[
        "a field too few",
        "an empty last value",
        "a short units row",
        "a blank unit",
        "no units row",
        "no data",
        "unknown unit",
        "unit of another quantity",
        "first bad field",
        "not finite",
    ],
)
def test_what_stays_refused_with_a_units_row(tmp_path, capsys, text, error):
    mapping = write(tmp_path, HEAD.format(csv="units_row = true") + FREE_RUN, free=text)
    code, said = import_csv(mapping, capsys)
    assert code == ExitCode.INVALID
    assert said.startswith(f"error: {tmp_path}/free.csv: {error}")


@pytest.mark.parametrize(
    ("rows", "error"),
    [
        ("1;2;3\n2;2;3\n3;2;3\n4;2;3\n5;2;3\n\n \n\n", None),  # blank lines ending the file
        ("1;2;3\n2;2;3\n3;2;3\n4;x;3\n5;2;3\n", "line 6, column 'F_Platte': 'x' is not a number"),
        ("1;2;3\n2;2;3\n\n4;2;3\n", "line 5: a blank line amid the data rows"),  # blank ends a block
        ("1;2;3\n\n3;2;3\n", "line 4: a blank line amid the data rows"),  # blank inside a block
    ],
    ids=["blank end", "error in the second block", "blank line ending a block", "blank line in a block"],
)
def test_a_file_read_in_blocks_is_read_whole_and_its_errors_at_their_lines(
    tmp_path, capsys, monkeypatch, rows, error
):
    """Blocks of two rows, so that every row boundary case meets a block's end."""
    monkeypatch.setattr(csv_read, "BLOCK_ROWS", 2)
    mapping = write(
        tmp_path, HEAD.format(csv="units_row = true") + FREE_RUN, free="Weg;F_Platte;Fz\nmm;kN;N\n" + rows
    )
    code, said = import_csv(mapping, capsys)
    if error is not None:
        assert (code, said) == (ExitCode.INVALID, f"error: {tmp_path}/free.csv: {error}\n")
        return
    assert code == ExitCode.OK
    with open_campaign(tmp_path / "out.h5") as campaign:
        np.testing.assert_allclose(campaign.runs[0].channels["z_base_m"], np.arange(1, 6) * 1e-3, rtol=1e-7)


def test_a_column_a_run_does_not_need_is_left_out_and_said(tmp_path, capsys):
    """Units in the headers' brackets, ``m/s²`` among them; the free run has no WFS nor hub column."""
    grid = '[[runs]]\nkind = "dwell_grid"\ntyre_pressure_bar = 2.5\n[[runs.points]]\nfile = "grid.csv"\n'
    grid += "freq_hz = 10\namplitude_mm = 2\n"
    head = HEAD.format(csv="").replace('"Weg"', '"Weg [mm]"').replace('"F_Platte"', '"F_Platte [kN]"')
    head = head.replace('"Fz"', '"Fz [N]"') + 'a_hub_m_s2 = { column = "a_Nabe [m/s²]" }\n'
    mapping = write(
        tmp_path,
        head + FREE_RUN + grid,
        free="Weg [mm];F_Platte [kN]\n1;2\n",
        grid="Weg [mm];F_Platte [kN];Fz [N];a_Nabe [m/s²]\n1;2;3;4\n",
    )
    code, said = import_csv(mapping, capsys)
    assert code == ExitCode.OK, said
    assert (
        "lab-r000-free_run (free_run, 1 point from 1 file, without fz_wfs_n, a_hub_m_s2: not in its files,"
        in said
    )
    with open_campaign(tmp_path / "out.h5") as campaign:
        free, grid_run = campaign.runs
        assert sorted(free.channels) == ["f_plate_n", "z_base_m"]
        assert float(grid_run.channels["a_hub_m_s2"][0]) == 4.0
        assert free.conditions == {"bench": "shaker", "wheel_fitted": False}


def test_a_column_in_some_files_of_a_run_only_is_refused(tmp_path, capsys):
    two = FREE_RUN + '[[runs.points]]\nfile = "other.csv"\nfreq_hz = 20\namplitude_mm = 2\n'
    mapping = write(
        tmp_path,
        HEAD.format(csv="units_row = true") + two,
        free="Weg;F_Platte;Fz\nmm;kN;N\n1;2;3\n",
        other="Weg;F_Platte\nmm;kN\n1;2\n",
    )
    code, said = import_csv(mapping, capsys)
    assert code == ExitCode.INVALID
    assert said == (
        f"error: {tmp_path}/other.csv: line 1, column 'Fz': missing, though free.csv of the same run has it"
        " (the header has: Weg, F_Platte)\n"
    )


def test_a_column_in_none_of_the_files_is_refused_naming_its_key(tmp_path, capsys):
    mapping = write(
        tmp_path, HEAD.format(csv="units_row = true") + FREE_RUN, free="Weg;F_Platte\nmm;kN\n1;2\n"
    )
    code, said = import_csv(mapping, capsys)
    assert (code, said) == (
        ExitCode.INVALID,
        f"error: {mapping}: channels.fz_wfs_n.column: 'Fz' is a column of none of the CSV files"
        " that map it\n",
    )


CONTINUOUS = """\
[[runs]]
kind = "free_run"
file = "run.csv"
[[runs.points]]
freq_hz = 10
amplitude_mm = 2
start_s = 0.002
end_s = 0.005
hold_start_s = 0.003
[[runs.points]]
freq_hz = 20
amplitude_mm = 2
start_s = 0.006
"""


def test_points_of_one_continuous_file_are_its_parts_only(tmp_path, capsys):
    rows = "".join(f"{i};{10 * i};0\n" for i in range(9))
    mapping = write(
        tmp_path, HEAD.format(csv="units_row = true") + CONTINUOUS, run="Weg;F_Platte;Fz\nmm;N;N\n" + rows
    )
    assert import_csv(mapping, capsys)[0] == ExitCode.OK
    with open_campaign(tmp_path / "out.h5") as campaign:
        (run,) = campaign.runs
        np.testing.assert_allclose(run.channels["z_base_m"], np.array([2, 3, 4, 6, 7, 8]) * 1e-3, rtol=1e-7)
        assert [
            (p.start_sample, p.hold_start_sample, p.hold_end_sample, p.end_sample) for p in run.points
        ] == [
            (0, 1, 3, 3),
            (3, 3, 6, 6),
        ]
        assert run.step["parts_s"] == [[0.002, 0.005], [0.006, None]]


@pytest.mark.parametrize(
    ("change", "error"),
    [
        (
            ("end_s = 0.005", "end_s = 0.007"),
            "runs[0].points[1].start_s: 0.006 s lies inside the part of run.csv",
        ),
        (
            ("start_s = 0.006", "end_s = 0.02"),
            "runs[0].points[1].end_s: 0.02 s is beyond the 0.009 s of samples",
        ),
        (("start_s = 0.006", "start_s = 0.009"), "runs[0].points[1].start_s: 0.009 s is beyond the 0.009 s"),
        (
            ("start_s = 0.006", "start_s = 0.006\nhold_end_s = 0.004"),
            "runs[0].points[1].hold_end_s: must come after",
        ),
        (
            ("hold_start_s = 0.003", "hold_start_s = 0.001"),
            "runs[0].points[0].hold_start_s: must not come before",
        ),
        (
            ("hold_start_s = 0.003", "hold_end_s = 0.006"),
            "runs[0].points[0].hold_end_s: must not come after end_s",
        ),
        (("end_s = 0.005", "end_s = 0.001"), "runs[0].points[0].end_s: must come after start_s"),
        (
            ("hold_start_s = 0.003", "hold_start_s = 0.005"),
            "runs[0].points[0].hold_start_s: must come before end_s",
        ),
    ],
    ids=[
        "overlap",
        "end beyond",
        "start beyond",
        "hold end before start",
        "hold before part",
        "hold after part",
        "end before start",
        "hold from the end",
    ],
)
def test_parts_that_cannot_be_are_refused_naming_the_key(tmp_path, capsys, change, error):
    rows = "".join(f"{i};{10 * i};0\n" for i in range(9))
    text = HEAD.format(csv="units_row = true") + CONTINUOUS.replace(*change)
    mapping = write(tmp_path, text, run="Weg;F_Platte;Fz\nmm;N;N\n" + rows)
    code, said = import_csv(mapping, capsys)
    assert code == ExitCode.INVALID
    assert f"{mapping}: {error}" in said


def test_points_sharing_a_file_without_parts_are_refused(tmp_path, capsys):
    """Two dwells naming one whole file: each would be stored with the other's samples."""
    text = (
        HEAD.format(csv="units_row = true") + FREE_RUN + '[[runs.points]]\nfile = "free.csv"\nfreq_hz = 20\n'
    )
    mapping = write(tmp_path, text + "amplitude_mm = 2\n", free="Weg;F_Platte;Fz\nmm;N;N\n1;2;3\n4;5;6\n")
    code, said = import_csv(mapping, capsys)
    assert code == ExitCode.INVALID
    assert said.startswith(
        f"error: {mapping}: runs[0].points[1].start_s: 0 s lies inside the part of free.csv that"
        " runs[0].points[0] holds (0 s to its end): the points of one file must not overlap"
    )


HAMMER = """\
[source]
name = "lab"
[[runs]]
kind = "hammer"
file = "hammer.csv"
[runs.time]
column = "t [ms]"
[runs.channels]
fz_wfs_n = { column = "Fz [kN]" }
"""


def test_a_hammer_capture_at_its_own_rate_with_its_own_columns(tmp_path, capsys):
    rows = "".join(f"{0.05 * i:.2f},{0.001 * i:g}\n" for i in range(6))
    mapping = write(tmp_path, HAMMER, hammer="t [ms],Fz [kN]\n" + rows)
    assert import_csv(mapping, capsys)[0] == ExitCode.OK
    with open_campaign(tmp_path / "out.h5") as campaign:
        (run,) = campaign.runs
        assert (run.kind, run.sample_rate_hz, run.step["blows"]) == ("hammer", pytest.approx(20e3), 1)
        np.testing.assert_allclose(run.hammer_record().channels["fz_wfs_n"], np.arange(6), rtol=1e-6)
        assert run.conditions == {"bench": "shaker", "wheel_fitted": False}


def test_two_blows_of_one_capture_file_are_two_points(tmp_path, capsys):
    rows = "".join(f"{0.05 * i:.2f},{i:g}\n" for i in range(10))
    blows = "[[runs.points]]\nend_s = 0.0002\n[[runs.points]]\nstart_s = 0.0003\n"
    mapping = write(tmp_path, HAMMER + blows, hammer="t [ms],Fz [kN]\n" + rows)
    assert import_csv(mapping, capsys)[0] == ExitCode.OK
    with open_campaign(tmp_path / "out.h5") as campaign:
        (run,) = campaign.runs
        assert run.step["blows"] == 2
        first, second = (run.hammer_record(blow).channels["fz_wfs_n"] for blow in (0, 1))
        np.testing.assert_allclose(first, [0, 1e3, 2e3, 3e3], rtol=1e-6)
        np.testing.assert_allclose(second, np.arange(6, 10) * 1e3, rtol=1e-6)


@pytest.mark.parametrize(
    ("change", "error"),
    [
        (('file = "hammer.csv"\n', ""), "runs[0].points: expected at least one [[runs.points]] table"),
        (
            ("[runs.time]\ncolumn", "[runs.tyme]\ncolumn"),
            "runs[0].time: missing: give a [time] table, or the run's own",
        ),
        (
            ('kind = "hammer"\n', 'kind = "hammer"\ntyre_pressure_bar = 2.5\n'),
            "runs[0].tyre_pressure_bar: unknown key",
        ),
        (
            ('file = "hammer.csv"\n', 'file = "hammer.csv"\n[[runs.points]]\nfreq_hz = 10\n'),
            "runs[0].points[0].freq_hz: unknown key (allowed: file, start_s, end_s)",
        ),
    ],
    ids=["no file nor points", "no time", "a pressure", "a frequency"],
)
def test_a_hammer_run_mapped_wrong_is_refused_naming_the_key(tmp_path, change, error):
    (tmp_path / "mapping.toml").write_text(HAMMER.replace(*change))
    with pytest.raises(MappingError) as refused:
        load_mapping(tmp_path / "mapping.toml")
    assert error in str(refused.value)


@pytest.mark.parametrize(
    ("bench", "kind", "refused"),
    [
        ("shaker", "dwell_grid", True),
        ("four_post", "sweep", True),
        ("shaker", "sweep", False),
        ("shaker", "free_run", False),
    ],
)
def test_the_runs_whose_analysis_needs_the_tyre_pressure_are_refused_without_it(
    tmp_path, bench, kind, refused
):
    points = '[[runs.points]]\nfile = "a.csv"\nfreq_hz = 10\namplitude_mm = 2\n'
    sweep = 'file = "a.csv"\nstart_hz = 1\nend_hz = 20\nduration_s = 10\namplitude_mm = 1\n'
    text = HEAD.format(csv="").replace('name = "lab"', f'name = "lab"\nbench = "{bench}"')
    text += f'[[runs]]\nkind = "{kind}"\n' + (sweep if kind == "sweep" else points)
    (tmp_path / "mapping.toml").write_text(text)
    if not refused:
        assert load_mapping(tmp_path / "mapping.toml").runs[0].tyre_pressure_bar is None
        return
    with pytest.raises(MappingError) as error:
        load_mapping(tmp_path / "mapping.toml")
    assert str(error.value).startswith(f"{tmp_path}/mapping.toml: runs[0].tyre_pressure_bar: missing: a ")
