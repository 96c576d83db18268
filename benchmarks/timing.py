"""Timing shared by the benchmarks: the best of several repeats is the least disturbed by a noisy
machine."""

from __future__ import annotations

import time
from collections.abc import Callable


def best_time_s(run: Callable[[], object], repeats: int = 5) -> float:
    """Shortest wall time of ``repeats`` calls of ``run``, in seconds."""
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - start)
    return best
