"""The index built on a real ``dask.distributed`` cluster of local processes equals the one built
in this process, row for row."""

from __future__ import annotations

import os

from bench.archive.build import OnDask, build_index, dask_client
from bench.archive.store import read_index


def test_index_on_a_local_cluster_of_processes_equals_the_one_process_index(archive, archive_index, tmp_path):
    out = tmp_path / "results"
    with dask_client(None, workers=2) as client:  # LocalCluster(processes=True, n_workers=2)
        workers = client.scheduler_info(n_workers=-1)["workers"]
        assert len(workers) == 2
        assert os.getpid() not in client.run(os.getpid).values()  # the files are read elsewhere
        summary = build_index([next(iter(archive)).parent], out, OnDask(client), files_per_task=1)
    assert summary.statuses == {"indexed": len(archive)} and summary.problems == []
    on_dask, in_process = read_index(out), read_index(archive_index)
    assert on_dask.num_rows == in_process.num_rows > 0
    assert on_dask.equals(in_process)
