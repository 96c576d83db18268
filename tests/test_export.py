"""``wfsbench export`` of the smoke campaign (free run, 2 mm grid at 2.5 bar, a sweep on the shaker),
each format read back by a reader that is not its writer: MDF4 by mdfreader (asammdf writes it),
UFF 58 by pyuff and by the dataset's fixed-column record layout, CSV by the project's own
``import-csv``, RPC III by rpc3-file and by the format's byte layout. Bad requests are refused with
exit code 3, naming what is wrong, and leave nothing behind."""

from __future__ import annotations

import math
import shutil
import struct
from pathlib import Path

import h5py
import mdfreader
import numpy as np
import pytest
import pyuff
import rpc3

from bench.app.analyze import analyze_campaign
from bench.cli.exit_codes import ExitCode
from bench.cli.main import main
from bench.export.uff58 import CONTACT_NODE, PLUS_Z, WHEEL_NODE
from bench.store import open_campaign
from bench.store.rpc3 import BLOCK_BYTES, INT_FULL_SCALE, KEY_BYTES, PTS_PER_FRAME, RECORD_BYTES
from bench.store.schema import METADATA_FIELDS

#: What the other engineer's metadata writer puts at the campaign's root, for a file that has them.
METADATA = {
    "tyre_make": "Conti",
    "tyre_size": "205/55 R16",
    "sensor_serial": "WFS-0042",
    "operator": "A. Müller",
}


def export(*args: str) -> int:
    return main(["export", *map(str, args)])


@pytest.fixture(scope="module")
def with_metadata(smoke_campaign: Path, tmp_path_factory) -> Path:
    """A copy of the smoke campaign with some of the test's metadata attributes at its root."""
    path = Path(shutil.copyfile(smoke_campaign, tmp_path_factory.mktemp("meta") / "smoke.h5"))
    with h5py.File(path, "r+") as file:
        for name, value in METADATA.items():
            file.attrs[name] = value
    return path


# ---------------------------------------------------------------------------------------- MDF4


def _groups(mdf: mdfreader.Mdf) -> list[dict[str, str]]:
    """Each channel group as {name in the campaign file: name mdfreader gives it}; mdfreader makes
    a name that another group has too unique by appending its master's suffix."""
    out = []
    for master, names in mdf.masterChannelList.items():
        suffix = master[len("time") :]
        out.append({(n[: -len(suffix)] if suffix and n.endswith(suffix) else n): n for n in names})
    return out


def test_mdf4_holds_every_channel_with_units_roles_conditions_and_metadata(with_metadata, tmp_path):
    out = tmp_path / "smoke.mf4"
    assert export(with_metadata, "--format", "mdf4", "--out", out) == ExitCode.OK
    mdf = mdfreader.Mdf(str(out))
    info = mdfreader.MdfInfo(str(out))
    header = info["HD"]["Comment"]
    for name in METADATA_FIELDS:  # every field named, empty ones without a value
        assert name in header
        assert (header[name] or "") == METADATA.get(name, "")
    assert header["sequence_name"] == "smoke"
    comments = [cg["Comment"]["TX"] for cgs in info["CG"].values() for cg in cgs.values()]
    with open_campaign(with_metadata) as campaign:
        groups = _groups(mdf)
        assert len(groups) == len(campaign.runs) == len(comments)
        for run, group, comment in zip(campaign.runs, groups, comments, strict=True):
            assert f"run_id: {run.run_id}\nkind: {run.kind}\nstatus: complete\n" in comment
            if run.kind == "dwell_grid":
                assert "tyre_pressure_bar: 2.5\namplitudes_mm: 2\n" in comment
            assert set(group) == {"time", *(spec.name for spec in run.channel_specs)}
            time_s = mdf.get_channel_data(group["time"])
            assert np.array_equal(time_s, np.arange(run.n_samples) / run.sample_rate_hz)
            for spec in run.channel_specs:
                name = group[spec.name]
                data = mdf.get_channel_data(name)
                assert data.dtype == np.dtype(spec.dtype) and np.array_equal(data, run.channels[spec.name])
                assert mdf.get_channel_unit(name) == spec.unit
                role = f" (role: {spec.role.value})" if spec.role else ""
                assert mdf.get_channel_desc(name) == spec.description + role


def test_mdf4_of_a_file_without_metadata_names_the_fields_empty(smoke_campaign, tmp_path):
    out = tmp_path / "free.mf4"
    code = export(smoke_campaign, "--format", "mdf4", "--run", "smoke-s003-free_run", "--out", out)
    assert code == ExitCode.OK
    header = mdfreader.MdfInfo(str(out))["HD"]["Comment"]
    assert all(header[name] is None for name in METADATA_FIELDS)
    assert len(mdfreader.Mdf(str(out)).masterChannelList) == 1


# ---------------------------------------------------------------------------------------- UFF 58


def _records(text: str) -> list[list[str]]:
    """The lines of each dataset of a UFF file (between its ``-1`` delimiters), dataset number first."""
    blocks, lines = [], text.splitlines()
    i = 0
    while i < len(lines):
        assert lines[i] == "    -1", f"line {i + 1}: expected a dataset delimiter, found {lines[i]!r}"
        end = lines.index("    -1", i + 1)
        blocks.append(lines[i + 1 : end])
        i = end + 1
    return blocks


def _record_6(line: str) -> tuple:
    """Record 6, Format(2(I5,I10),2(1X,10A1,I10,I4)): the DOF identification by its columns."""
    return (
        int(line[0:5]),
        int(line[5:15]),
        int(line[15:20]),
        int(line[20:30]),
        line[31:41].strip(),
        int(line[41:51]),
        int(line[51:55]),
        line[56:66].strip(),
        int(line[66:76]),
        int(line[76:80]),
    )


def _characteristics(line: str) -> tuple:
    """Records 8-11, Format(I10,3I5,2(1X,20A1)): type, length/force/temperature exponents, labels."""
    return (
        int(line[0:10]),
        int(line[10:15]),
        int(line[15:20]),
        int(line[20:25]),
        line[26:46].strip(),
        line[47:67].strip(),
    )


def test_uff58_holds_the_dwell_frfs_raw_and_compensated_with_their_uncertainty(with_metadata, tmp_path):
    out = tmp_path / "smoke.uff"
    assert export(with_metadata, "--format", "uff58", "--out", out) == ExitCode.OK
    amp = analyze_campaign(with_metadata).knowledge.shaker[2.5].amplitudes[2e-3]
    # (what, FRF, response DOF, reference DOF, ordinate and denominator record 9/10 types)
    expected = [
        ("F_WFS/Z", amp.frfs.wfs_per_z, ("WFS", WHEEL_NODE), ("BASE", CONTACT_NODE), 9, 8),
        ("F_contact/Z", amp.frfs.contact_per_z, ("CONTACT", CONTACT_NODE), ("BASE", CONTACT_NODE), 13, 8),
        (
            "F_WFS/F_contact raw",
            amp.frfs.wfs_per_contact,
            ("WFS", WHEEL_NODE),
            ("CONTACT", CONTACT_NODE),
            9,
            13,
        ),
        (
            "F_WFS model-compensated/F_contact",
            amp.compensated_per_contact,
            ("WFS+MODEL", WHEEL_NODE),
            ("CONTACT", CONTACT_NODE),
            9,
            13,
        ),
    ]
    # the independent reading: the record layout's fixed columns
    units, *blocks = _records(out.read_text())
    assert units[0].strip() == "164" and units[1].split()[:2] == ["1", "SI"]
    assert len(blocks) == 2 * len(expected)  # each FRF and its standard uncertainty
    for (what, frf, rsp, ref, num_type, den_type), value, sigma in zip(
        expected, blocks[::2], blocks[1::2], strict=True
    ):
        for block, func_type, title in ((value, 4, what), (sigma, 0, f"standard uncertainty of {what}")):
            assert block[0].strip() == "58"
            assert block[1].strip() == title
            assert block[2].strip() == "runs smoke-s009-dwell_grid"
            assert block[4].strip() == "shaker dwells, tyre 2.5 bar, 2 mm"
            assert "tyre_make Conti" in block[5] and "sensor_serial WFS-0042" in block[5]
            assert _record_6(block[6])[0] == func_type
            assert _record_6(block[6])[4:] == (*rsp, PLUS_Z, *ref, PLUS_Z)
            record_7 = block[7]
            assert int(record_7[0:10]) == (6 if func_type == 4 else 4)  # complex / real, double
            assert int(record_7[10:20]) == frf.freq_hz.size and int(record_7[20:30]) == 0  # uneven
            assert float(record_7[56:69]) == pytest.approx(2e-3)  # the z-axis value: the amplitude
            assert _characteristics(block[8]) == (18, 0, 0, 0, "frequency", "Hz")
            assert _characteristics(block[9])[0] == num_type and _characteristics(block[9])[5] == "N"
            assert _characteristics(block[10])[0] == den_type
            assert _characteristics(block[11]) == (8, 1, 0, 0, "amplitude", "m")
    # pyuff's reading of the same file
    sets = pyuff.UFF(str(out)).read_sets()
    assert [s["type"] for s in sets] == [164] + [58] * len(blocks)
    for (what, frf, *_), value, sigma in zip(expected, sets[1::2], sets[2::2], strict=True):
        assert value["id1"].strip() == what and value["func_type"] == 4
        np.testing.assert_allclose(value["x"], frf.freq_hz, rtol=1e-5)  # E13.5: 6 significant digits
        np.testing.assert_allclose(value["data"], frf.value, rtol=1e-11)  # E20.12: 13 digits
        np.testing.assert_allclose(sigma["data"], frf.sigma, rtol=1e-11)


# ---------------------------------------------------------------------------------------- CSV


def test_csv_reads_back_through_import_csv_as_the_recorded_points(smoke_campaign, tmp_path):
    out = tmp_path / "csv"
    assert export(smoke_campaign, "--format", "csv", "--out", out) == ExitCode.OK
    header, units = (out / "smoke-s009-dwell_grid.csv").read_text().splitlines()[:2]
    assert header.startswith("time_s,seq,sample,status,") and units.startswith("s,,,,")
    imported = tmp_path / "back.h5"
    assert main(["import-csv", str(out / "mapping.toml"), "--out", str(imported)]) == ExitCode.OK
    with open_campaign(smoke_campaign) as original, open_campaign(imported) as copy:
        assert [r.run_id for r in copy.runs] == [r.run_id for r in original.runs]
        for run, back in zip(original.runs, copy.runs, strict=True):
            assert (back.kind, back.conditions.get("tyre_pressure_bar")) == (
                run.kind,
                run.conditions.get("tyre_pressure_bar"),
            )
            done = sorted((p for p in run.points if p.status == "done"), key=lambda p: p.start_sample)
            assert len(back.points) == len(done)
            offset = 0
            for point, again in zip(done, back.points, strict=True):
                n = point.end_sample - point.start_sample
                assert (again.start_sample, again.end_sample) == (offset, offset + n)
                if run.kind == "sweep":  # the import takes a sweep's file as its hold (docs/import.md)
                    assert (again.hold_start_sample, again.hold_end_sample) == (0, n)
                else:
                    assert again.hold_start_sample - offset == point.hold_start_sample - point.start_sample
                    assert again.hold_end_sample - offset == point.hold_end_sample - point.start_sample
                assert (again.freq_hz, again.amplitude_mm) == (point.freq_hz, point.amplitude_mm)
                for name in back.channels:  # float32 written as its shortest decimal reads back bit-identical
                    kept = run.channels[name][point.start_sample : point.end_sample]
                    assert np.array_equal(back.channels[name][offset : offset + n], kept), name
                offset += n
            assert {spec.name for spec in back.channel_specs} == {
                spec.name for spec in run.channel_specs if spec.unit not in ("", "V", "rad/s")
            }


# ---------------------------------------------------------------------------------------- RPC III


def _rpc_header(data: bytes) -> dict[str, str]:
    """The header records by the format's rules, checked on the way: 128-byte records of a 32-byte
    key and a 96-byte value, each NUL-terminated ASCII; FORMAT, NUM_HEADER_BLOCKS and NUM_PARAMS
    first; NUM_PARAMS records, the rest of the last 512-byte block NUL."""
    records = [data[i : i + RECORD_BYTES] for i in range(0, BLOCK_BYTES, RECORD_BYTES)]
    first = [
        (r[:KEY_BYTES].rstrip(b"\0").decode(), r[KEY_BYTES:].rstrip(b"\0").decode()) for r in records[:3]
    ]
    assert [k for k, _ in first] == ["FORMAT", "NUM_HEADER_BLOCKS", "NUM_PARAMS"]
    assert first[0][1] == "BINARY_IEEE_LITTLE_END"
    n_blocks, n_params = int(first[1][1]), int(first[2][1])
    assert math.ceil(n_params / 4) == n_blocks
    params = {}
    for i in range(n_blocks * BLOCK_BYTES // RECORD_BYTES):
        record = data[i * RECORD_BYTES : (i + 1) * RECORD_BYTES]
        if i >= n_params:
            assert record == bytes(RECORD_BYTES), f"record {i} beyond NUM_PARAMS is not empty"
            continue
        key, value = record[:KEY_BYTES], record[KEY_BYTES:]
        assert b"\0" in key and b"\0" in value  # NUL-terminated within their fields
        key_text, value_text = key.split(b"\0")[0].decode("ascii"), value.split(b"\0")[0].decode("ascii")
        assert key.rstrip(b"\0") == key.split(b"\0")[0] and value.rstrip(b"\0") == value.split(b"\0")[0]
        params[key_text] = value_text
    return params


def test_rpc3_is_laid_out_as_the_format_describes_and_reads_back_within_its_resolution(
    smoke_campaign, tmp_path
):
    out = tmp_path / "rpc"
    code = export(smoke_campaign, "--format", "rpc3", "--run", "smoke-s010-sweep", "--out", out)
    assert code == ExitCode.OK
    path = out / "smoke-s010-sweep.rsp"
    data = path.read_bytes()
    params = _rpc_header(data)
    with open_campaign(smoke_campaign) as campaign:
        run = campaign.run("smoke-s010-sweep")
        specs = [spec for spec in run.channel_specs if spec.dtype == "f4"]
        n, channels = run.n_samples, len(specs)
        frames = math.ceil(n / PTS_PER_FRAME)
        assert {k: params[k] for k in ("FILE_TYPE", "DATA_TYPE", "CHANNELS", "FRAMES", "INT_FULL_SCALE")} == {
            "FILE_TYPE": "TIME_HISTORY",
            "DATA_TYPE": "SHORT_INTEGER",
            "CHANNELS": str(channels),
            "FRAMES": str(frames),
            "INT_FULL_SCALE": str(INT_FULL_SCALE),
        }
        assert int(params["PTS_PER_FRAME"]) == int(params["PTS_PER_GROUP"]) == PTS_PER_FRAME
        assert float(params["DELTA_T"]) == pytest.approx(1 / run.sample_rate_hz, rel=1e-12)
        start = int(params["NUM_HEADER_BLOCKS"]) * BLOCK_BYTES
        assert len(data) == start + frames * channels * PTS_PER_FRAME * 2  # whole groups of int16
        values = np.frombuffer(data[start:], dtype="<i2").reshape(frames, channels, PTS_PER_FRAME)
        for c, spec in enumerate(specs, start=1):
            assert (params[f"DESC.CHAN_{c}"], params[f"UNITS.CHAN_{c}"]) == (spec.name, spec.unit)
            scale = float(params[f"SCALE.CHAN_{c}"])
            counts = values[:, c - 1, :].reshape(-1)  # demultiplexed: the channel's run in each group
            recorded = np.asarray(run.channels[spec.name], dtype=float)
            # the largest magnitude takes the full scale; each value within half a count of its scale
            if np.any(recorded):
                assert np.max(np.abs(counts)) == INT_FULL_SCALE
            assert np.max(np.abs(counts[:n] * scale - recorded)) <= scale / 2 * (1 + 1e-6)
            assert np.all(counts[n:] == counts[n - 1])  # the last frame filled with the last value
        # rpc3-file's reading of the same file
        read, _ = rpc3.read(str(path), strip=False)
        assert [ch.name for ch in read] == [spec.name for spec in specs]
        for ch, spec in zip(read, specs, strict=True):
            scale = float(params[f"SCALE.CHAN_{[s.name for s in specs].index(spec.name) + 1}"])
            assert ch.unit == spec.unit and ch.dt == pytest.approx(1 / run.sample_rate_hz)
            recorded = np.asarray(run.channels[spec.name], dtype=float)
            assert np.max(np.abs(ch.data[:n] - recorded)) <= scale / 2 * (1 + 1e-4) + 1e-7 * np.max(
                np.abs(recorded)
            )


def test_rpc3_header_field_sizes_follow_the_record(smoke_campaign, tmp_path):
    """Every key fits 31 characters and every value 95 (a NUL ends each field): checked on the
    struct layout the format gives a record, ``32s96s``."""
    out = tmp_path / "rpc"
    code = export(smoke_campaign, "--format", "rpc3", "--run", "smoke-s003-free_run", "--out", out)
    assert code == ExitCode.OK
    data = (out / "smoke-s003-free_run.rsp").read_bytes()
    n_params = int(_rpc_header(data)["NUM_PARAMS"])
    for i in range(n_params):
        key, value = struct.unpack_from("<32s96s", data, i * RECORD_BYTES)
        assert key[-1] == 0 and value[-1] == 0


# ---------------------------------------------------------------------------------------- refusals


def test_an_unknown_run_an_existing_output_and_a_run_without_frfs_are_refused(
    smoke_campaign, tmp_path, capsys
):
    out = tmp_path / "x.mf4"
    code = export(smoke_campaign, "--format", "mdf4", "--run", "no-such-run", "--out", out)
    assert code == ExitCode.INVALID
    error = capsys.readouterr().err
    assert (
        "no run 'no-such-run'" in error and "smoke-s009-dwell_grid" in error and str(smoke_campaign) in error
    )
    assert not out.exists()

    out.write_bytes(b"keep me")
    assert export(smoke_campaign, "--format", "mdf4", "--out", out) == ExitCode.INVALID
    assert f"{out}: exists" in capsys.readouterr().err and out.read_bytes() == b"keep me"

    uff = tmp_path / "free.uff"
    assert (
        export(smoke_campaign, "--format", "uff58", "--run", "smoke-s003-free_run", "--out", uff)
        == ExitCode.INVALID
    )
    assert "run smoke-s003-free_run has no FRF" in capsys.readouterr().err and not uff.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.mf4"]  # no temporary left behind


def test_an_unknown_format_is_refused_with_the_formats(smoke_campaign, tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        export(smoke_campaign, "--format", "xlsx", "--out", tmp_path / "x")
    assert stop.value.code == ExitCode.INVALID
    assert "invalid choice: 'xlsx'" in capsys.readouterr().err
