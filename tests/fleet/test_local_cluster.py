"""A job on a local cluster (:class:`bench.cluster.OnDask` without a scheduler): its first batches
are done in the command's own process while the cluster starts, and once the cluster is up it takes
the next batch at once, while the batch under way in the command's process goes on."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

from bench.cluster import OnDask

#: A cluster of processes of its own: with the fleet's jobs on a cluster, in the validation tier.
pytestmark = pytest.mark.validation

#: How long the batch under way in the command's process waits for the cluster's first task.
WAIT_S = 120.0


def done_where(batch: list[tuple[int, str, int]]) -> list[tuple[int, int, bool]]:
    """Each item ``(pid of the command, marker file, number)``: done in the command's process, it
    waits until a task of the cluster has left the marker (bounded); done on the cluster, it leaves
    the marker. ``(number, pid where done, whether the marker was there when it ended)``."""
    done = []
    for command_pid, marker, number in batch:
        if os.getpid() == command_pid:
            deadline = time.monotonic() + WAIT_S
            while not Path(marker).exists() and time.monotonic() < deadline:
                time.sleep(0.05)
        else:
            Path(marker).touch()
        done.append((number, os.getpid(), Path(marker).exists()))
    return done


def test_the_cluster_takes_the_next_batch_while_the_one_under_way_here_goes_on(tmp_path):
    marker = str(tmp_path / "a cluster task ran")
    batches = iter([[(os.getpid(), marker, number)] for number in range(6)])
    executor = OnDask(None, workers=2)
    results = [item for outcome in executor.run(done_where, batches) for item in outcome]

    assert sorted(number for number, _, _ in results) == list(range(6))  # each batch once
    here = [(number, seen) for number, pid, seen in results if pid == os.getpid()]
    assert [number for number, _ in here] == [0]  # the first batch here; the cluster took the rest
    assert here[0][1]  # and it ended only after a task of the cluster had run: none waited for it
    assert executor.done_here == 1
    assert {pid for _, pid, _ in results} - {os.getpid()}  # done in the cluster's processes
