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
"""

from __future__ import annotations

import contextlib
import itertools
import logging
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

if TYPE_CHECKING:
    from dask.distributed import Client, LocalCluster

#: Tasks in flight per worker: it always has the next one, and the client holds few results.
TASKS_IN_FLIGHT_PER_WORKER = 2

Item = TypeVar("Item")
Result = TypeVar("Result")


class Executor(Protocol):
    """Runs ``work`` on each batch of ``batches``, yielding each batch's results as it is done."""

    def run(
        self, work: Callable[[list[Item]], list[Result]], batches: Iterator[list[Item]]
    ) -> Iterator[list[Result]]: ...


class InProcess:
    """Every batch in this process, one after another: no cluster to start (small jobs)."""

    def run(
        self, work: Callable[[list[Item]], list[Result]], batches: Iterator[list[Item]]
    ) -> Iterator[list[Result]]:
        for batch in batches:
            yield work(batch)


class OnDask:
    """Each batch a ``dask.delayed`` task on the cluster of ``scheduler`` (``tcp://host:8786``), or
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
        self, work: Callable[[list[Item]], list[Result]], batches: Iterator[list[Item]]
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
            yield from self._local(work, first, batches)

    def _local(
        self, work: Callable[[list[Item]], list[Result]], first: list[Item], rest: Iterator[list[Item]]
    ) -> Iterator[list[Result]]:
        """Batches done here while the local cluster starts on a thread, the rest on it."""
        from dask.distributed import Client

        with contextlib.ExitStack() as stack, ThreadPoolExecutor(1) as starter:
            starting = starter.submit(lambda: stack.enter_context(local_cluster(self.workers)))
            batch: list[Item] | None = first
            while batch is not None and not starting.done():
                yield work(batch)
                self.done_here += 1
                batch = next(rest, None)
            # the client in this thread (it is this thread's current client); a job done meanwhile
            # still closes what started
            client = stack.enter_context(Client(starting.result()))
            if batch is not None:
                yield from _on(client, work, batch, rest)
            self._before_close(client)

    def _before_close(self, client: Client) -> None:
        if self.before_close is not None:
            self.before_close(client)


def _on(
    client: Client, work: Callable[[list[Item]], list[Result]], first: list[Item], rest: Iterator[list[Item]]
) -> Iterator[list[Result]]:
    from dask import delayed
    from dask.distributed import as_completed

    workers = max(1, len(client.scheduler_info(n_workers=-1)["workers"]))
    limit = TASKS_IN_FLIGHT_PER_WORKER * workers
    running = as_completed()
    for batch in itertools.chain([first], rest):
        running.add(client.compute(delayed(work, pure=False)(batch)))
        while running.count() >= limit:
            yield _take(next(running))
    for future in running:
        yield _take(future)


def _take(future: Any) -> list[Any]:
    outcomes = future.result()
    future.release()
    return outcomes


#: What the local cluster changes of Dask's defaults for its workers (docs/index.md, *Why two workers
#: gave 0.98x*, measured by ``benchmarks/dask_overhead.py``): no statistical profiler (a thread that
#: walks the running task's stack every 10 ms, for a dashboard the local cluster does not serve), and
#: no ``MALLOC_TRIM_THRESHOLD_`` in the workers' environment (setting it also fixes glibc's mmap
#: threshold, so that every large array is mapped, faulted in and unmapped anew).
LOCAL_WORKER_SETTINGS = {
    "distributed.worker.profile.enabled": False,
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
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
def local_cluster(workers: int) -> Iterator[LocalCluster]:
    """A local cluster of ``workers`` processes of one thread each on this machine, with
    :data:`LOCAL_WORKER_SETTINGS` (started here, stopped on leaving)."""
    import dask
    from dask.distributed import LocalCluster

    with (
        dask.config.set(LOCAL_WORKER_SETTINGS),
        LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            silence_logs=logging.ERROR,
        ) as cluster,
    ):
        yield cluster
