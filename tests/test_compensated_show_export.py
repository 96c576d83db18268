"""A compensated force (``wfsbench compensate``'s output) opens with ``wfsbench show`` and exports
as a run does: CSV read back by numpy, MDF4 read back by mdfreader (asammdf writes it), the values
those of the file's datasets; one too long for a block is read and written block by block. A file
that says it is one but is not whole, a format it has nothing for, ``--run``: refused, exit 3."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import mdfreader
import numpy as np
import pytest

from bench.cli.exit_codes import ExitCode
from bench.cli.main import main
from bench.simulated_campaign import BenchSetup, TyreModel
from bench.store import compensated as store
from tests.campaign_files import paper_corner_runs, write_analysed_campaign
from tests.made_once import made_once

CAR = BenchSetup.paper_quarter_car(2.5, model=TyreModel.WHEEL_TREAD)


@pytest.fixture(scope="module")
def compensated(shared_folder, tmp_path_factory) -> Path:
    """The paper's corner at 2.5 bar (the campaign tests/test_compensate.py compensates with, made
    once), its four-post sweep compensated."""
    campaign = made_once(
        shared_folder, "corner-2.5-bar.h5", lambda path: write_analysed_campaign(path, paper_corner_runs(CAR))
    )
    out = tmp_path_factory.mktemp("compensated") / "sweep.h5"
    assert main(["compensate", str(campaign), str(campaign), "--run", "sweep", "--out", str(out)]) == 0
    return out


def _datasets(path: Path) -> dict[str, np.ndarray]:
    with h5py.File(path, "r") as f:
        return {name: f[name][()] for name in ("t_s", "f_contact_n", "u95_n")}


def test_show_says_what_made_the_force_and_what_it_holds(compensated, capsys):
    assert main(["show", str(compensated), "--json"]) == ExitCode.OK
    summary = json.loads(capsys.readouterr().out)
    data = _datasets(compensated)
    defined = np.isfinite(data["f_contact_n"]) & np.isfinite(data["u95_n"])
    force = data["f_contact_n"][defined].astype(float)
    assert (summary["schema"], summary["version"], summary["schema_version"]) == (
        "wfs-bench-show-compensated",
        1,
        1,
    )
    assert summary["measurement"].endswith("corner-2.5-bar.h5 run sweep")
    assert summary["sources"]["hub_lag"] == "campaign" and summary["bandwidth_hz"] is None
    samples = summary["samples"]
    n_defined = int(defined.sum())
    assert (samples["n"], samples["sample_rate_hz"], samples["defined"]) == (60000, 1000.0, n_defined)
    assert (samples["first_s"], samples["last_s"]) == (0.0, pytest.approx(59.999))
    assert samples["f_contact_mean_n"] == pytest.approx(force.mean(), rel=1e-9)
    assert samples["f_contact_rms_n"] == pytest.approx(force.std(), rel=1e-9)
    assert (samples["f_contact_min_n"], samples["f_contact_max_n"]) == (force.min(), force.max())
    band = data["u95_n"][defined].astype(float)
    assert (samples["u95_mean_n"], samples["u95_max_n"]) == (pytest.approx(band.mean(), rel=1e-9), band.max())
    assert main(["show", str(compensated)]) == ExitCode.OK
    text = capsys.readouterr().out.splitlines()
    assert text[0].startswith(f"{compensated}: compensated force, schema version 1, written by wfs-bench ")
    assert "assumptions:" in text
    assert any(line.startswith("  campaign: hub accelerometer lag") for line in text)
    assert f"samples: 60000 at 1000 Hz, 0-59.999 s; {defined.sum()} defined" in text


def test_csv_export_holds_the_datasets_values_read_back_by_numpy(compensated, tmp_path, capsys):
    out = tmp_path / "csv"
    assert main(["export", str(compensated), "--format", "csv", "--out", str(out)]) == ExitCode.OK
    assert capsys.readouterr().out == f"csv {out / 'sweep.csv'}\n"
    lines = (out / "sweep.csv").read_text().splitlines()
    assert lines[:2] == ["time_s,f_contact_n,u95_n", "s,N,N"]
    table = np.loadtxt(out / "sweep.csv", delimiter=",", skiprows=2)
    data = _datasets(compensated)
    assert table.shape == (60000, 3)
    assert np.array_equal(table[:, 0], data["t_s"])
    for column, name in ((1, "f_contact_n"), (2, "u95_n")):
        assert np.array_equal(table[:, column].astype(np.float32), data[name], equal_nan=True), name


def test_mdf4_export_is_read_back_by_mdfreader_with_units_and_what_made_it(compensated, tmp_path):
    out = tmp_path / "sweep.mf4"
    assert main(["export", str(compensated), "--format", "mdf4", "--out", str(out)]) == ExitCode.OK
    mdf = mdfreader.Mdf(str(out))
    data = _datasets(compensated)
    ((master, names),) = mdf.masterChannelList.items()
    assert set(names) == {master, "f_contact_n", "u95_n"}
    assert np.array_equal(mdf.get_channel_data(master), data["t_s"])
    for name in ("f_contact_n", "u95_n"):
        assert np.array_equal(mdf.get_channel_data(name), data[name], equal_nan=True), name
        assert mdf.get_channel_unit(name) == "N"
    header = mdfreader.MdfInfo(str(out))["HD"]["Comment"]
    assert header["measurement"].endswith("corner-2.5-bar.h5 run sweep")
    assert header["identification"] == "tyre at 2.5 bar, 2 mm (Model 2)"


def test_a_record_longer_than_a_block_is_exported_block_by_block_as_it_is(compensated, tmp_path, monkeypatch):
    """Read 7,000 samples at a time (60,000 samples: 9 blocks, the last short): the same files."""
    whole_csv, whole_mdf = tmp_path / "whole", tmp_path / "whole.mf4"
    assert main(["export", str(compensated), "--format", "csv", "--out", str(whole_csv)]) == 0
    assert main(["export", str(compensated), "--format", "mdf4", "--out", str(whole_mdf)]) == 0
    monkeypatch.setattr(store, "READ_BLOCK_SAMPLES", 7000)
    blocks_csv, blocks_mdf = tmp_path / "blocks", tmp_path / "blocks.mf4"
    assert main(["export", str(compensated), "--format", "csv", "--out", str(blocks_csv)]) == 0
    assert main(["export", str(compensated), "--format", "mdf4", "--out", str(blocks_mdf)]) == 0
    assert (blocks_csv / "sweep.csv").read_bytes() == (whole_csv / "sweep.csv").read_bytes()
    whole, blocks = mdfreader.Mdf(str(whole_mdf)), mdfreader.Mdf(str(blocks_mdf))
    for name in ("f_contact_n", "u95_n"):
        assert np.array_equal(blocks.get_channel_data(name), whole.get_channel_data(name), equal_nan=True)


@pytest.mark.parametrize(
    ("args", "said"),
    [
        (["--format", "uff58"], "a compensated force exports as csv or mdf4, not uff58"),
        (["--format", "rpc3"], "a compensated force exports as csv or mdf4, not rpc3"),
        (["--format", "csv", "--run", "sweep"], "a compensated force has no runs: --run sweep names none"),
    ],
)
def test_an_export_it_has_nothing_for_is_refused_and_writes_nothing(
    compensated, tmp_path, capsys, args, said
):
    out = tmp_path / "out"
    assert main(["export", str(compensated), *args, "--out", str(out)]) == ExitCode.INVALID
    assert said in capsys.readouterr().err
    assert not out.exists()


def test_a_file_that_says_it_is_one_but_is_not_whole_is_refused_by_show_and_export(
    compensated, tmp_path, capsys
):
    newer, short = tmp_path / "newer.h5", tmp_path / "short.h5"
    for path in (newer, short):
        path.write_bytes(compensated.read_bytes())
    with h5py.File(newer, "r+") as f:
        f.attrs["schema_version"] = 2
    with h5py.File(short, "r+") as f:
        del f["u95_n"]
        f["u95_n"] = np.zeros(10, dtype="f4")
    for path, said in ((newer, "schema version 2: this version reads 1"), (short, "/u95_n has 10 samples")):
        assert main(["show", str(path)]) == ExitCode.INVALID
        assert said in capsys.readouterr().err
        out = tmp_path / f"{path.stem}.mf4"
        assert main(["export", str(path), "--format", "mdf4", "--out", str(out)]) == ExitCode.INVALID
        assert said in capsys.readouterr().err and not out.exists()
