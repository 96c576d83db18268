"""Jobs over many files, in this process or on a ``dask.distributed`` cluster (``wfsbench index``,
``wfsbench compensate`` over folders).

A job cuts its files into batches of plain values (paths and what was seen of them: they pickle,
never an open file) and hands them with its work function to an executor, which yields each
batch's results as they are done (in any order):

- :class:`InProcess`: one batch after another in this process: no cluster to start;
- :class:`OnDask`: each batch a task on a cluster, the scheduler at an address or a local cluster
  of one-thread processes started for the job (batches are done in this process while it starts);
  at most :data:`TASKS_IN_FLIGHT_PER_WORKER` tasks per worker at once, each result released once
  taken, so the client holds the batches under way, not the job. The cluster is started (or the
  scheduler connected) only when the first batch exists: a job with nothing to do starts no worker.

A job names the modules its work imports at its first batch (``worker_imports``: the analysis, the
file readers, scipy's parts): a local cluster's workers are forked from one process that imported
them once, so no worker pays for them again (docs/index.md, *Where a local cluster's time went*).
"""

from __future__ import annotations

import contextlib
import itertools
import logging
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

if TYPE_CHECKING:
    from dask.distributed import Client, LocalCluster

#: Tasks in flight per worker: it always has the next one, and the client holds few results.
TASKS_IN_FLIGHT_PER_WORKER = 2

Item = TypeVar("Item")
Result = TypeVar("Result")


class Executor(Protocol):
    """Runs ``work`` on each batch of ``batches``, yielding each batch's results as it is done.
    ``worker_imports``: modules ``work`` imports at its first batch, beyond its own module."""

    def run(
        self,
        work: Callable[[list[Item]], list[Result]],
        batches: Iterator[list[Item]],
        worker_imports: Sequence[str] = (),
    ) -> Iterator[list[Result]]: ...


class InProcess:
    """Every batch in this process, one after another: no cluster to start (small jobs); the first
    batch imports what it needs."""

    def run(
        self,
        work: Callable[[list[Item]], list[Result]],
        batches: Iterator[list[Item]],
        worker_imports: Sequence[str] = (),
    ) -> Iterator[list[Result]]:
        for batch in batches:
            yield work(batch)


class OnDask:
    """Each batch a task (``client.submit``) on the cluster of ``scheduler`` (``tcp://host:8786``), or
    without one on a local cluster of ``workers`` processes started for the job; or on the cluster
    of an open ``client``. ``started``: whether a cluster was started or connected.

    A local cluster takes seconds to start (its processes import Python's numerical stack, then
    the job's modules): while it starts, the batches are done in this process, and the cluster
    takes the rest once its workers are up (a job done before that never waits for it).
    ``before_close``: called with the client once the last batch is done, before a cluster started
    here stops (a benchmark's look at its workers)."""

    def __init__(
        self,
        scheduler: str | None = None,
        workers: int = 1,
        client: Client | None = None,
        before_close: Callable[[Client], None] | None = None,
    ) -> None:
        self.scheduler, self.workers, self.client = scheduler, workers, client
        self.before_close = before_close
        self.started = False
        self.done_here = 0  # batches done in this process while the local cluster started

    def run(
        self,
        work: Callable[[list[Item]], list[Result]],
        batches: Iterator[list[Item]],
        worker_imports: Sequence[str] = (),
    ) -> Iterator[list[Result]]:
        first = next(batches, None)
        if first is None:
            return  # nothing to do: no cluster
        self.started = True
        if self.client is not None:
            yield from _on(self.client, work, first, batches)
        elif self.scheduler:
            with dask_client(self.scheduler, self.workers) as client:
                yield from _on(client, work, first, batches)
                self._before_close(client)
        else:
            yield from self._local(work, first, batches, (work.__module__, *worker_imports))

    def _local(
        self,
        work: Callable[[list[Item]], list[Result]],
        first: list[Item],
        rest: Iterator[list[Item]],
        preload: Sequence[str],
    ) -> Iterator[list[Result]]:
        """Batches done here while the local cluster starts, the rest on it. Both wait on threads
        of this process: the batch under way here goes on when the cluster is up, and the cluster
        takes the next batch at once (its workers never wait for this process's batch)."""
        from dask.distributed import Client

        with (
            contextlib.ExitStack() as stack,
            ThreadPoolExecutor(1, "cluster-start") as starter,
            ThreadPoolExecutor(1, "batch-here") as here,
        ):
            starting = starter.submit(lambda: stack.enter_context(local_cluster(self.workers, preload)))
            batch: list[Item] | None = first
            under_way = None
            while batch is not None:
                under_way = here.submit(work, batch)
                wait([under_way, starting], return_when=FIRST_COMPLETED)
                if not under_way.done():
                    break  # the cluster is up: the batch under way goes on here
                yield under_way.result()
                self.done_here += 1
                under_way, batch = None, next(rest, None)
                if starting.done():
                    break
            # the client in this thread (it is this thread's current client); a job done meanwhile
            # still closes what started
            client = stack.enter_context(Client(starting.result()))
            batch = next(rest, None) if under_way is not None else batch
            if batch is not None:
                yield from _on(client, work, batch, rest)
            if under_way is not None:
                yield under_way.result()
                self.done_here += 1
            self._before_close(client)

    def _before_close(self, client: Client) -> None:
        if self.before_close is not None:
            self.before_close(client)


def _on(
    client: Client, work: Callable[[list[Item]], list[Result]], first: list[Item], rest: Iterator[list[Item]]
) -> Iterator[list[Result]]:
    from dask.distributed import as_completed

    workers = max(1, len(client.scheduler_info(n_workers=-1)["workers"]))
    limit = TASKS_IN_FLIGHT_PER_WORKER * workers
    running = as_completed()
    for batch in itertools.chain([first], rest):
        running.add(client.submit(work, batch, pure=False))
        while running.count() >= limit:
            yield _take(next(running))
    for future in running:
        yield _take(future)


def _take(future: Any) -> list[Any]:
    outcomes = future.result()
    future.release()
    return outcomes


#: What the local cluster changes of Dask's defaults (docs/index.md, *Where a local cluster's time
#: went*, measured by ``benchmarks/dask_overhead.py`` and ``benchmarks/fleet_jobs.py``):
#:
#: - no statistical profiler (a thread that walks the running task's stack every 10 ms, for a
#:   dashboard the local cluster does not serve);
#: - no ``MALLOC_TRIM_THRESHOLD_`` in the workers' environment (setting it also fixes glibc's mmap
#:   threshold, so that every large array is mapped, faulted in and unmapped anew);
#: - the system monitor (processor, memory, disk and network counters for the dashboard, in the
#:   scheduler, each nanny and each worker) every 5 s instead of 0.5 s, without the disks, and the
#:   event loops' responsiveness tick every 0.5 s instead of 20 ms: they ran in every process of
#:   the cluster for a dashboard and warnings the local cluster does not serve;
#: - the workers forked from one process that imported the job's modules (``forkserver``), not
#:   started as fresh interpreters that each import them again (``spawn``).
#:
#: Each worker's memory is still watched every 100 ms by its nanny, against the machine's share.
LOCAL_WORKER_SETTINGS = {
    "distributed.worker.profile.enabled": False,
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
    "distributed.admin.system-monitor.interval": "5s",
    "distributed.admin.system-monitor.disk": False,
    "distributed.admin.tick.interval": "500ms",
    "distributed.worker.multiprocessing-method": "forkserver",
}


@contextlib.contextmanager
def dask_client(scheduler: str | None, workers: int) -> Iterator[Client]:
    """A client of the ``dask.distributed`` scheduler at ``scheduler`` (``tcp://host:8786``), or,
    without one, of a local cluster of ``workers`` processes of one thread each on this machine
    (:func:`local_cluster`, started here, stopped on leaving)."""
    from dask.distributed import Client

    if scheduler:
        with Client(scheduler) as client:
            yield client
        return
    with local_cluster(workers) as cluster, Client(cluster) as client:
        yield client


@contextlib.contextmanager
def local_cluster(workers: int, preload: Sequence[str] = ()) -> Iterator[LocalCluster]:
    """A local cluster of ``workers`` processes of one thread each on this machine, with
    :data:`LOCAL_WORKER_SETTINGS` (started here, stopped on leaving); its workers are forked with
    the modules ``preload`` imported."""
    import dask
    from dask.distributed import LocalCluster

    with dask.config.set(LOCAL_WORKER_SETTINGS):
        _preload_forkserver(preload)
        with LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            silence_logs=logging.ERROR,
        ) as cluster:
            yield cluster


def _preload_forkserver(modules: Sequence[str]) -> None:
    """The process the workers are forked from imports Dask's worker and ``modules`` once, when it
    starts (this process's first local cluster; it serves every later one unchanged). Dask sets
    its own list (Dask and its optional packages) when it first asks for the context: this asks
    first, then replaces it."""
    from distributed.utils import get_mp_context

    get_mp_context().set_forkserver_preload(["distributed", *modules])
