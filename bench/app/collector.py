"""The garbage collector kept off the WFS reader's path while a sequence runs.

A full collection walks every object the interpreter tracks, holding its lock all the while. In a
process that has loaded the analysis libraries and holds a campaign's analysis, one took 95 ms
(``benchmarks/reader_stall.py`` with a ``gc.callbacks`` probe), twice the 44 ms the port's receive
buffer lasts at 921600 baud: the WFS reader thread, waiting for the lock, lost frames. While a
sequence runs, the objects alive at its start (the modules, the configuration, the campaign's
knowledge so far) are frozen out of the collector's passes (``gc.freeze``), after one collection of
what is garbage already, taken before any stream runs; they are given back at its end
(``gc.unfreeze``), so that a process that runs many sequences (a terminal UI, a test run) goes on
collecting them.
"""

from __future__ import annotations

import contextlib
import gc
from collections.abc import Iterator


@contextlib.contextmanager
def collector_frozen() -> Iterator[None]:
    """Collect once, then leave every object alive now out of the collector's passes until the
    ``with`` block ends."""
    gc.collect()
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()
