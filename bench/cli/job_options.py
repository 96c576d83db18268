"""The options every job over many files takes (``index``, ``compensate`` over folders): where it
runs (``--scheduler`` / ``--workers``), and the executor they name (:mod:`bench.cluster`)."""

from __future__ import annotations

import argparse
import os
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from bench.cluster import Executor


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
