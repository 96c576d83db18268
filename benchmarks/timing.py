"""Timing shared by the benchmarks: the best of several repeats is the least disturbed by a noisy
machine."""

from __future__ import annotations

import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from bench.app.library_log import library_log


def best_time_s(run: Callable[[], object], repeats: int = 5) -> float:
    """Shortest wall time of ``repeats`` calls of ``run``, in seconds."""
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - start)
    return best


def run_benchmark(main: Callable[[], object]) -> None:
    """Run a benchmark's ``main`` with the links' and libraries' warnings (pymodbus's retries and
    raw frames on a busy machine) in a log file, not among the figures it prints; say where, if any."""
    with library_log(Path(tempfile.gettempdir()) / "wfsbench-benchmarks.log") as log:
        main()
    if log.written:
        print(f"warnings of the links and libraries: {log.path}", file=sys.stderr)
