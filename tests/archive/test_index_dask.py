"""The index built on a real ``dask.distributed`` cluster of local processes, by ``wfsbench index
--scheduler``, equals the one built in this process, row for row."""

from __future__ import annotations

import os

import pytest

from bench.archive.store import read_index
from bench.cli.main import main
from bench.cluster import dask_client

#: A cluster of processes of its own: with the fleet's jobs on a cluster, in the validation tier.
pytestmark = pytest.mark.validation


def test_index_on_a_local_cluster_of_processes_equals_the_one_process_index(
    archive, archive_index, tmp_path, capsys
):
    out = tmp_path / "results"
    with dask_client(None, workers=2) as client:  # LocalCluster(processes=True, n_workers=2)
        workers = client.scheduler_info(n_workers=-1)["workers"]
        assert len(workers) == 2
        assert os.getpid() not in client.run(os.getpid).values()  # the files are read elsewhere
        directory = next(iter(archive)).parent
        assert (
            main(["index", str(directory), "--out", str(out), "--scheduler", client.scheduler.address]) == 0
        )
        prefixes = client.run_on_scheduler(lambda dask_scheduler: sorted(dask_scheduler.task_prefixes))
    assert "index_files" in prefixes  # the files were read by tasks of the cluster's scheduler
    assert capsys.readouterr().out.startswith(
        f"index {out}: 3 files found; 0 unchanged, not read; read: 3 indexed;"
    )
    on_dask, in_process = read_index(out), read_index(archive_index)
    assert on_dask.num_rows == in_process.num_rows > 0
    assert on_dask.equals(in_process)
