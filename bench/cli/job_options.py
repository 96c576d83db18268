"""The options every job over many files takes (``index``, ``compensate`` over folders): where it
runs (``--scheduler`` / ``--workers``), and the executor they name (:mod:`bench.cluster`); and the
numerical libraries' threads a job's own process runs with (:func:`one_numerical_thread`)."""

from __future__ import annotations

import argparse
import os
import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from bench.cluster import Executor


#: The numerical libraries' thread counts a job's process sets, as a local cluster's nannies set
#: them in its workers: one thread each.
ONE_THREAD_ENVIRONMENT = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def one_numerical_thread() -> None:
    """Run this process's linear algebra on one thread, unless the environment says otherwise.

    A job's work is many small problems (fits of a few parameters, filters), which a thread pool of
    the linear-algebra library does not speed up: indexing 200 campaign files in one process took
    29.4-33.8 s with one thread and 31.5-35.2 s with OpenBLAS's default of one per core, which spent
    50.7-55.3 s of processor on it (``benchmarks/fleet_jobs.py --jobs index``, with and without
    ``OPENBLAS_NUM_THREADS=1``): a core another program, or a bench, needs. The library reads the
    setting when numpy is first imported, so this acts only before that (the command's first act);
    a value the environment already holds is kept."""
    if "numpy" in sys.modules:
        return
    for name, value in ONE_THREAD_ENVIRONMENT.items():
        os.environ.setdefault(name, value)


def _workers(text: str) -> int:
    """A local cluster's processes: a whole number, 0 or more."""
    try:
        workers = int(text)
    except ValueError:
        workers = -1
    if workers < 0:
        raise argparse.ArgumentTypeError(f"a whole number of processes, 0 or more, not {text!r}")
    return workers


def add_job_options(parser: argparse.ArgumentParser, *, scheduler_help: str, workers_help: str) -> None:
    """Add ``--scheduler ADDRESS`` and ``--workers N`` to a job's ``parser``."""
    parser.add_argument("--scheduler", metavar="ADDRESS", help=scheduler_help)
    parser.add_argument("--workers", type=_workers, default=None, metavar="N", help=workers_help)


def job_executor(args: argparse.Namespace) -> Executor:
    """Where the job runs: in this process with ``--workers 0`` and no scheduler; else on the cluster
    of ``--scheduler``, or on a local cluster of ``--workers`` processes (default: the machine's
    cores), started only once the job has a batch to give it."""
    from bench.cluster import InProcess, OnDask

    if args.workers == 0 and not args.scheduler:
        return InProcess()
    return OnDask(args.scheduler, args.workers or os.cpu_count() or 1)
