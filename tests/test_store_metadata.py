"""The test metadata in the campaign file: written at create as UTF-8 strings of ``/`` (h5dump reads
them back), each run's bench, operator and notes, what a later session may and may not change,
files without them, and the time each result was stored."""

from __future__ import annotations

import hashlib
import re
import shutil
import subprocess
from datetime import datetime
from pathlib import Path

import h5py
import numpy as np
import pytest

from bench.cli.exit_codes import ExitCode
from bench.cli.main import main
from bench.store import CampaignWriter, StoreError, add_results, open_campaign
from bench.store.schema import METADATA_FIELDS, RUN_METADATA_FIELDS
from sequences import shipped_file
from sequences.channels import Channel, Role
from sequences.points import PointAttempt

H5DUMP = shutil.which("h5dump")

GIVEN = {
    "bench_id": "shaker-1",
    "sensor_serial": "WFS-0042",
    "sensor_calibration_date": "2026-03-01",
    "tyre_make": "Conti",
    "tyre_size": "205/55 R16",
    "tyre_id": "T-0815",
    "operator": "Jürgen Groß",
    "notes": 'run in 50 km\nsaid "fine"',
}
CHANNELS = (
    Channel("fz_wfs_n", "N", role=Role.WFS_FZ),
    Channel("z_base_m", "m", role=Role.BENCH_DISPLACEMENT),
)


def _create(path: Path, metadata: dict[str, str] | None) -> CampaignWriter:
    return CampaignWriter.create(
        path, software_version="t", config_toml="", sequence_toml="", sequence_name="s", metadata=metadata
    )


def _run(writer: CampaignWriter, run_id: str, *, finish: bool = True) -> None:
    run = writer.begin_run(
        run_id,
        kind="free_run",
        step={"type": "free_run"},
        conditions={},
        channels=CHANNELS,
        sample_rate_hz=1e3,
    )
    run.append({"fz_wfs_n": np.ones(1500), "z_base_m": np.zeros(1500)})
    run.add_point(PointAttempt(0, 5.0, 1.0, 0, 100, 1400, 1500))
    if finish:
        run.finish("complete")


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _h5dump_text(path: Path, attribute: str) -> tuple[str, str]:
    """The value and character set of one string attribute as h5dump shows it (``-e``: escaped)."""
    out = subprocess.run(
        [H5DUMP, "-e", "-a", attribute, str(path)], capture_output=True, text=True, timeout=60, check=True
    ).stdout
    value = re.search(r'\(0\): "((?:[^"\\]|\\.)*)"', out)
    charset = re.search(r"CSET (\w+);", out)
    assert value and charset, out
    return _unescape(value[1]), charset[1]


def _unescape(text: str) -> str:
    """h5dump's escaped string as the text it stands for: ``\\n``, ``\\"``, ``\\\\`` and octal bytes
    (h5dump 1.10 prints a byte above 127 sign-extended, ``\\37777777703`` for 0xc3), decoded UTF-8."""
    out = bytearray()
    simple = {"n": b"\n", "t": b"\t", "r": b"\r", '"': b'"', "\\": b"\\"}
    for match in re.finditer(r"\\([0-7]+)|\\(.)|([^\\]+)", text):
        octal, escaped, plain = match.groups()
        if octal:
            out.append(int(octal, 8) & 0xFF)
        elif escaped:
            out += simple[escaped]
        else:
            out += plain.encode("ascii")
    return out.decode("utf-8")


@pytest.mark.skipif(H5DUMP is None, reason="h5dump (Debian hdf5-tools) not installed")
def test_h5dump_reads_back_every_metadata_attribute_as_utf8_text(tmp_path: Path) -> None:
    path = tmp_path / "campaign.h5"
    with _create(path, GIVEN) as writer:
        _run(writer, "001")
    for name in METADATA_FIELDS:
        assert _h5dump_text(path, f"/{name}") == (GIVEN[name], "H5T_CSET_UTF8"), name
    for name in RUN_METADATA_FIELDS:
        assert _h5dump_text(path, f"/runs/001/{name}") == (GIVEN[name], "H5T_CSET_UTF8"), name
    with open_campaign(path) as campaign:
        assert campaign.metadata == GIVEN
        assert campaign.run("001").metadata == {name: GIVEN[name] for name in RUN_METADATA_FIELDS}


@pytest.mark.skipif(H5DUMP is None, reason="h5dump (Debian hdf5-tools) not installed")
def test_fields_not_given_are_empty_strings(tmp_path: Path) -> None:
    path = tmp_path / "campaign.h5"
    _create(path, {"tyre_id": "T-1"}).close()
    assert _h5dump_text(path, "/operator") == ("", "H5T_CSET_UTF8")
    with open_campaign(path) as campaign:
        assert campaign.metadata == {**dict.fromkeys(METADATA_FIELDS, ""), "tyre_id": "T-1"}


def test_a_later_session_records_its_own_bench_operator_and_notes_and_fills_in_what_was_empty(
    tmp_path: Path,
) -> None:
    path = tmp_path / "campaign.h5"
    first = {"bench_id": "shaker-1", "operator": "Ann", "tyre_id": "T-1"}
    with _create(path, first) as writer:
        _run(writer, "001")
    later = {
        "bench_id": "four-post-2",
        "operator": "Bob",
        "notes": "after lunch",
        "tyre_make": "Conti",
        "tyre_id": "T-1",
    }
    with CampaignWriter.open_append(path, metadata=later) as writer:
        _run(writer, "002")
    with open_campaign(path) as campaign:
        assert campaign.run("001").metadata == {"bench_id": "shaker-1", "operator": "Ann", "notes": ""}
        assert campaign.run("002").metadata == {
            "bench_id": "four-post-2",
            "operator": "Bob",
            "notes": "after lunch",
        }
        # the campaign keeps its own; what it had left empty is filled in, and an event says so
        assert campaign.metadata == {
            **dict.fromkeys(METADATA_FIELDS, ""),
            **first,
            "notes": "after lunch",
            "tyre_make": "Conti",
        }
        (event,) = [e for e in campaign.events if e.kind == "metadata"]
        assert event.fields == {"notes": "after lunch", "tyre_make": "Conti"}


def test_another_sensor_or_tyre_is_refused_before_anything_is_written(tmp_path: Path, capsys) -> None:
    path = tmp_path / "campaign.h5"
    with _create(path, {"tyre_id": "T-1", "sensor_serial": "S-1"}) as writer:
        _run(writer, "001")
    before = _sha256(path)
    with pytest.raises(StoreError) as info:
        CampaignWriter.open_append(
            path, metadata={"tyre_id": "T-2", "sensor_serial": "S-9", "operator": "Bob"}
        )
    assert str(info.value) == (
        f"{path}: /@sensor_serial: 'S-9' now, 'S-1' in the file (and tyre_id): one campaign file holds"
        " one sensor and one tyre; record another specimen into another file"
    )
    assert _sha256(path) == before
    # wfsbench run refuses it before the bench is opened: exit 3, the file as it was
    code = main(["run", str(shipped_file("smoke.toml")), "--out", str(path), "--meta", "tyre_id=T-2"])
    assert code == ExitCode.INVALID
    assert "/@tyre_id: 'T-2' now, 'T-1' in the file" in capsys.readouterr().err
    assert _sha256(path) == before and not path.with_name(path.name + ".log").exists()


def test_a_resumed_run_keeps_its_operator_and_its_resumed_event_names_the_new_one(tmp_path: Path) -> None:
    path = tmp_path / "campaign.h5"
    with _create(path, {"operator": "Ann"}) as writer:
        _run(writer, "001", finish=False)  # closed unfinished: incomplete
    with CampaignWriter.open_append(path, metadata={"operator": "Cy", "notes": "went on"}) as writer:
        writer.continue_run("001").finish("complete")
    with open_campaign(path) as campaign:
        run = campaign.run("001")
        assert run.metadata["operator"] == "Ann"
        (resumed,) = [e for e in run.events if e.kind == "resumed"]
        assert resumed.fields["operator"] == "Cy" and resumed.fields["notes"] == "went on"


@pytest.mark.parametrize(
    ("metadata", "where", "reason"),
    [
        ({"tyre_idd": "x"}, "/@tyre_idd", "unknown key"),
        (
            {"sensor_calibration_date": "1.3.2026"},
            "/@sensor_calibration_date",
            "not a date written YYYY-MM-DD",
        ),
        ({"notes": 5}, "/@notes", "expected text"),
    ],
)
def test_the_writer_refuses_garbage_metadata_and_leaves_no_file(
    tmp_path: Path, metadata, where, reason
) -> None:
    path = tmp_path / "campaign.h5"
    with pytest.raises(StoreError, match=re.escape(where)) as info:
        _create(path, metadata)
    assert reason in str(info.value) and not path.exists()


def test_a_file_without_metadata_reads_empty_and_a_non_text_one_is_refused(tmp_path: Path) -> None:
    """A file written before the metadata was recorded (here: the attributes removed) reads as
    empty, its results as stored at an unknown time; an attribute that is not text is refused."""
    path = tmp_path / "campaign.h5"
    with _create(path, GIVEN) as writer:
        _run(writer, "001")
    with h5py.File(path, "r+") as file:
        for name in METADATA_FIELDS:
            del file.attrs[name]
        for name in RUN_METADATA_FIELDS:
            del file["runs/001"].attrs[name]
    with open_campaign(path) as campaign:
        assert campaign.metadata == dict.fromkeys(METADATA_FIELDS, "")
        assert campaign.run("001").metadata == dict.fromkeys(RUN_METADATA_FIELDS, "")
    with h5py.File(path, "r+") as file:
        file.attrs["tyre_id"] = 42
    with pytest.raises(StoreError, match=re.escape(f"{path}: /@tyre_id: must be text, found")):
        open_campaign(path)


def test_each_result_records_when_it_was_stored(tmp_path: Path) -> None:
    path = tmp_path / "campaign.h5"
    with _create(path, None) as writer:
        _run(writer, "001")
    add_results(path, {("001", "plate_mass"): {"m_comp_kg": 12.0}})
    before = _sha256(path)
    with pytest.raises(StoreError, match="other/stored: is the attribute saying when it was stored"):
        add_results(path, {("001", "fine"): {"x": 1.0}, ("001", "other"): {"stored": "yesterday"}})
    assert _sha256(path) == before  # refused as a whole: nothing written
    with open_campaign(path) as campaign:
        view = campaign.run("001")
        assert view.results("plate_mass") == {"m_comp_kg": 12.0}  # the time is not part of the result
        stored = datetime.fromisoformat(view.result_stored("plate_mass"))
        assert stored.tzinfo is not None and view.result_names == ("plate_mass",)
    with h5py.File(path, "r+") as file:
        del file["runs/001/results/plate_mass"].attrs["stored"]
    with open_campaign(path) as campaign:
        assert campaign.run("001").result_stored("plate_mass") == ""
