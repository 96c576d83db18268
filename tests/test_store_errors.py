"""The reader takes any file laid out as docs/hdf5.md says, whatever wrote it, and refuses bad files
with the file and the place inside it.

The files here are written with plain h5py from the documented layout, not with the store's writer,
then broken one way at a time.
"""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest

from bench.store import StoreError, open_campaign

FS_HZ = 500.0
STR = h5py.string_dtype()
POINTS = np.dtype(
    [
        ("index", "<i4"),
        ("freq_hz", "<f8"),
        ("amplitude_mm", "<f8"),
        ("requested_amplitude_mm", "<f8"),
        ("corrected_amplitude_mm", "<f8"),
        ("achieved_amplitude_mm", "<f8"),
        ("attempt", "<i4"),
        ("start_sample", "<i8"),
        ("hold_start_sample", "<i8"),
        ("hold_end_sample", "<i8"),
        ("end_sample", "<i8"),
        ("status", STR),
        ("settled", "u1"),
        ("note", STR),
    ]
)
EVENTS = np.dtype([("time_unix_s", "<f8"), ("sample", "<i8"), ("kind", STR), ("text", STR), ("fields", STR)])
N = 2000


def write_by_hand(
    path: Path, *, channels=("z_base_m", "f_plate_n", "fz_wfs_n", "a_hub_m_s2"), **changes
) -> Path:
    """A one-run campaign file (a dwell grid of two points) from the documented layout;
    ``changes`` override root attributes (``schema``, ``schema_version``), run attributes
    (``step``, ``status``) or the second point's ``end_sample``."""
    with h5py.File(path, "w") as f:
        root = {
            "schema": "wfs-bench campaign",
            "schema_version": 1,
            "software_version": "other writer 2.0",
            "created": "2026-11-01T10:00:00+00:00",
            "config_name": "lab.toml",
            "config_toml": "",
            "sequence_name": "grid.toml",
            "sequence_toml": "",
        }
        for key, value in root.items():
            if changes.get(key, value) is not None:
                f.attrs[key] = changes.get(key, value)
        f.create_dataset("events", shape=(0,), maxshape=(None,), dtype=EVENTS)
        run = f.create_group("runs/a")
        attrs = {
            "kind": "dwell_grid",
            "status": "complete",
            "reason": "",
            "started": "",
            "finished": "",
            "step": json.dumps({"type": "dwell_grid"}),
            "conditions": json.dumps({"tyre_pressure_bar": 2.5}),
            "resumes": "",
            "resumed_by": "",
            "sample_rate_hz": FS_HZ,
        }
        run.attrs.update({k: changes.get(k, v) for k, v in attrs.items()})
        t = np.arange(N) / FS_HZ
        for k, name in enumerate(channels):
            ds = run.create_dataset(f"channels/{name}", data=np.sin(2 * np.pi * 4.0 * t + k).astype("f4"))
            ds.attrs.update({"unit": "SI", "description": "", "sample_rate_hz": FS_HZ})
        rows = [
            (0, 4.0, 1.0, np.nan, np.nan, 1.0, 1, 0, 100, 900, 1000, "done", 1, ""),
            (
                1,
                8.0,
                1.0,
                np.nan,
                np.nan,
                1.0,
                1,
                1000,
                1100,
                1900,
                changes.get("end_sample", 2000),
                "done",
                1,
                "",
            ),
        ]
        run.create_dataset("points", data=np.array(rows, dtype=POINTS))
        run.create_dataset(
            "events", data=np.array([(0.0, 5, "gap", "2 frames", '{"missing": 2}')], dtype=EVENTS)
        )
        run.create_group("link").attrs["gaps"] = 1
        run.create_group("results")
    return path


def test_a_file_written_by_another_writer_gives_its_records(tmp_path):
    with open_campaign(write_by_hand(tmp_path / "other.h5")) as f:
        assert f.software_version == "other writer 2.0"
        (run,) = f.runs
        assert run.events[0].fields == {"missing": 2}
        assert run.link_counters == {"gaps": 1}
        records = run.dwell_records()
    assert [(r.freq_hz, r.amplitude_m, r.hold_s) for r in records] == [
        (4.0, 1e-3, (0.2, 1.8)),
        (8.0, 1e-3, (0.2, 1.8)),
    ]
    assert records[1].channels["z_base_m"][0] == np.float32(np.sin(2 * np.pi * 4.0 * 1000 / FS_HZ))


@pytest.mark.parametrize(
    ("changes", "where", "message"),
    [
        ({"schema": "nexus"}, "/@schema", "is 'nexus', not a 'wfs-bench campaign' file"),
        ({"schema": None}, "/@schema", "is None"),
        ({"schema_version": 3}, "/@schema_version", "is 3; this software reads versions 1 and 2"),
        ({"schema_version": "1"}, "/@schema_version", "must be a number"),
        ({"sequence_name": None}, "/@sequence_name", "missing attribute"),
        ({"step": "{type: grid"}, "/runs/a@step", "not valid JSON"),
        ({"status": "done"}, "/runs/a@status", "'done' is not a run status"),
        ({"kind": "dwell"}, "/runs/a@kind", "'dwell' is not one of"),
        (
            {"end_sample": 2001},
            "/runs/a/points[1]",
            "point 1: end_sample 2001 beyond the 2000 recorded samples",
        ),
    ],
)
def test_bad_files_are_refused_naming_the_place(tmp_path, changes, where, message):
    path = write_by_hand(tmp_path / "bad.h5", **changes)
    with pytest.raises(StoreError) as err:
        open_campaign(path)
    assert (err.value.path, err.value.where) == (str(path), where)
    assert message in err.value.message
    assert str(err.value).startswith(f"{path}: {where}: ")


def test_a_missing_channel_is_named_when_records_are_asked_for(tmp_path):
    path = write_by_hand(tmp_path / "no_wfs.h5", channels=("z_base_m", "f_plate_n", "a_hub_m_s2"))
    with (
        open_campaign(path) as f,
        pytest.raises(StoreError, match=r"no_wfs.h5: /runs/a/channels/fz_wfs_n: missing"),
    ):
        f.runs[0].dwell_records()


def test_a_dwell_grid_without_hub_acceleration_gives_its_records(tmp_path):
    """The shaker clamps the hub: a lab without a hub accelerometer records none."""
    path = write_by_hand(tmp_path / "no_hub.h5", channels=("z_base_m", "f_plate_n", "fz_wfs_n"))
    with open_campaign(path) as f:
        records = f.runs[0].dwell_records()
    assert [sorted(r.channels) for r in records] == [["f_plate_n", "fz_wfs_n", "z_base_m"]] * 2


def test_channels_of_a_finished_run_must_have_one_length(tmp_path):
    path = write_by_hand(tmp_path / "ragged.h5")
    with h5py.File(path, "a") as f:
        del f["runs/a/channels/fz_wfs_n"]
        ds = f.create_dataset("runs/a/channels/fz_wfs_n", data=np.zeros(N - 1, "f4"))
        ds.attrs.update({"unit": "N", "description": "", "sample_rate_hz": FS_HZ})
    with pytest.raises(StoreError, match=r"/runs/a/channels: channels of a finished run differ in length"):
        open_campaign(path)


def test_a_channel_of_an_undocumented_dtype_is_refused(tmp_path):
    path = write_by_hand(tmp_path / "f8.h5")
    with h5py.File(path, "a") as f:
        del f["runs/a/channels/z_base_m"]
        ds = f.create_dataset("runs/a/channels/z_base_m", data=np.zeros(N))
        ds.attrs.update({"unit": "m", "description": "", "sample_rate_hz": FS_HZ})
    with pytest.raises(StoreError, match=r"/runs/a/channels/z_base_m: dtype float64 is not one of"):
        open_campaign(path)


@pytest.mark.parametrize("content", [b"", b"time,fz\n0,1\n", b"\x89HDF\r\n\x1a\n" + bytes(100)])
def test_files_that_are_not_hdf5_are_refused(tmp_path, content):
    path = tmp_path / "garbage.h5"
    path.write_bytes(content)
    with pytest.raises(StoreError, match=r"garbage.h5: not a readable HDF5 file"):
        open_campaign(path)


def test_a_missing_file_is_named(tmp_path):
    with pytest.raises(StoreError, match=r"nothing.h5: no such file"):
        open_campaign(tmp_path / "nothing.h5")


def test_a_truncated_file_is_refused(tmp_path):
    path = write_by_hand(tmp_path / "cut.h5")
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(StoreError, match=r"cut.h5: not a readable HDF5 file \(.*truncated file"):
        open_campaign(path)
