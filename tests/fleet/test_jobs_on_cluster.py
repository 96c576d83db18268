"""Both jobs over many files on a ``dask.distributed`` cluster whose scheduler and two workers are
processes of their own, started with Dask's own commands on 127.0.0.1 (:func:`tests.fleet.
conftest.scheduler`): ``wfsbench compensate`` over a folder of MDF4 and CSV measurements (one
damaged, one foreign) writes what the one-process run writes, sample for sample, and ``wfsbench
index`` the same index row for row; run again over the unchanged folders, neither reads a file nor
connects to the cluster."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import duckdb
import h5py
import numpy as np
import pytest
from asammdf import MDF
from dask.distributed import Client

from bench.archive.store import read_index
from bench.cli.main import main
from tests.archive.conftest import COPIES, SIMULATED
from tests.archive_files import copy_campaign, write_archive_campaign

#: Processes of their own, started with Dask's commands, and both jobs twice: the validation tier.
pytestmark = pytest.mark.validation

#: The summary's columns that do not depend on where and when a file was compensated.
SUMMARY = (
    "path, size_bytes, mtime_ns, status, error, identification, identified_as, out_hdf5, out_mdf4,"
    " n_samples, sample_rate_hz, start_s, fz_wfs_mean_n, fz_wfs_rms_n, fz_wfs_min_n, fz_wfs_max_n,"
    " f_contact_mean_n, f_contact_rms_n, f_contact_min_n, f_contact_max_n, u95_median_n, u95_max_n,"
    " valid_band_lo_hz, valid_band_hi_hz, assumptions"
)


def _summary(out: Path, columns: str = SUMMARY) -> list[tuple]:
    return duckdb.sql(f"SELECT {columns} FROM read_parquet('{out}/summary.parquet') ORDER BY path").fetchall()


def _clients_added(client: Client) -> int:
    return sum(event["action"] == "add-client" for _, event in client.get_events("all"))


def _series_hdf5(path: Path) -> dict[str, np.ndarray]:
    with h5py.File(path, "r") as f:
        return {name: f[name][:] for name in ("t_s", "f_contact_n", "u95_n")}


def _series_mdf4(path: Path) -> dict[str, np.ndarray]:
    with MDF(path) as mdf:
        force, band = mdf.get("f_contact_n"), mdf.get("u95_n")
        return {"t_s": force.timestamps, "f_contact_n": force.samples, "u95_n": band.samples}


def test_compensate_on_the_cluster_writes_what_one_process_writes_and_a_rerun_reads_nothing(
    campaign, roads, scheduler, tmp_path, capsys
):
    alone, on_dask = tmp_path / "alone", tmp_path / "on-dask"
    common = ["compensate", str(campaign), str(roads), "--pressure", "2.5"]
    assert main([*common, "--out", str(alone), "--workers", "0"]) == 0
    with Client(scheduler) as client:
        assert main([*common, "--out", str(on_dask), "--scheduler", scheduler]) == 0
        prefixes = client.run_on_scheduler(lambda dask_scheduler: sorted(dask_scheduler.task_prefixes))
        assert "compensate_files" in prefixes  # the files were read by tasks of the cluster
        printed = capsys.readouterr().out
        assert "compensate" in printed and "6 files found; 0 unchanged, not read;" in printed
        assert "read: 4 compensated, 2 unreadable" in printed
        rows = _summary(on_dask)
        assert rows == _summary(alone)
        statuses = {Path(row[0]).name: (row[3], row[4]) for row in rows}
        assert statuses["damaged.mf4"][0] == statuses["foreign.csv"][0] == "unreadable"
        assert "damaged.mf4" in statuses["damaged.mf4"][1] and "foreign.csv" in statuses["foreign.csv"][1]
        pids = {int(w.split(":")[1]) for (w,) in _summary(on_dask, "worker") if w is not None}
        assert pids and os.getpid() not in pids  # read in the workers' processes
        outputs = sorted(p.relative_to(alone) for p in alone.rglob("*.compensated.*"))
        assert len(outputs) == 8  # four measurements, HDF5 and MDF4 each
        assert outputs == sorted(p.relative_to(on_dask) for p in on_dask.rglob("*.compensated.*"))
        for output in outputs:
            read = _series_hdf5 if output.suffix == ".h5" else _series_mdf4
            one, other = read(alone / output), read(on_dask / output)
            for name in one:
                assert np.array_equal(one[name], other[name], equal_nan=True), (output, name)
        for h5 in (p for p in outputs if p.suffix == ".h5"):  # the MDF4 copy holds the HDF5's samples
            one, other = _series_hdf5(on_dask / h5), _series_mdf4(on_dask / h5.with_suffix(".mf4"))
            assert np.array_equal(one["f_contact_n"], other["f_contact_n"], equal_nan=True)
            assert np.allclose(one["t_s"], other["t_s"], rtol=0, atol=1e-9)

        # again over the unchanged folder: not one file read, no client of the cluster; a file given
        # other contents with its old size and time is not even opened (its outputs stay as they were)
        drive = roads / "drive-1.csv"
        stat, contents = drive.stat(), drive.read_bytes()
        written = {p: p.stat().st_mtime_ns for p in on_dask.rglob("*.compensated.*")}
        clients = _clients_added(client)
        try:
            drive.write_bytes(contents.replace(b"1", b"2"))
            os.utime(drive, ns=(stat.st_atime_ns, stat.st_mtime_ns))
            assert main([*common, "--out", str(on_dask), "--scheduler", scheduler]) == 0
        finally:
            drive.write_bytes(contents)
            os.utime(drive, ns=(stat.st_atime_ns, stat.st_mtime_ns))
        assert _clients_added(client) == clients  # the job never connected
        assert capsys.readouterr().out.startswith(
            f"compensate {on_dask}: 6 files found; 6 unchanged, not read; read: none;"
        )
        assert {p: p.stat().st_mtime_ns for p in on_dask.rglob("*.compensated.*")} == written
        assert _summary(on_dask) == rows


@pytest.fixture(scope="module")
def archive(tmp_path_factory) -> Path:
    """Three campaign files: one simulated, two copies under other metadata."""
    directory = tmp_path_factory.mktemp("archive")
    source = write_archive_campaign(directory / "campaign-a.h5", dataclasses.replace(SIMULATED))
    for name, copied in zip(("campaign-b.h5", "sub/campaign-c.h5"), COPIES, strict=True):
        copy_campaign(source, directory / name, copied)
    return directory


def test_index_on_the_cluster_equals_the_one_process_index_and_a_reindex_reads_nothing(
    archive, scheduler, tmp_path, capsys
):
    alone, on_dask = tmp_path / "alone", tmp_path / "on-dask"
    assert main(["index", str(archive), "--out", str(alone), "--workers", "0"]) == 0
    with Client(scheduler) as client:
        assert main(["index", str(archive), "--out", str(on_dask), "--scheduler", scheduler]) == 0
        prefixes = client.run_on_scheduler(lambda dask_scheduler: sorted(dask_scheduler.task_prefixes))
        assert "index_files" in prefixes
        assert read_index(on_dask).equals(read_index(alone))
        assert read_index(alone).num_rows > 3
        capsys.readouterr()
        clients = _clients_added(client)
        assert main(["index", str(archive), "--out", str(on_dask), "--scheduler", scheduler]) == 0
        assert _clients_added(client) == clients
        assert "3 files found; 3 unchanged, not read; read: none;" in capsys.readouterr().out
