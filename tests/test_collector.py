"""A sequence runs with the objects alive at its start frozen out of the garbage collector's passes
(bench/app/collector.py): a full collection then walks only what the sequence made, and holds the
interpreter's lock (which the WFS reader thread waits for) for a fraction of the time
(``benchmarks/reader_stall.py`` measures it)."""

from __future__ import annotations

import gc

from bench.app.collector import collector_frozen


def test_the_objects_alive_at_the_start_are_frozen_until_the_end_and_given_back():
    held = [[i] for i in range(200_000)]  # a heap of tracked objects, as a bench process holds
    assert gc.get_freeze_count() == 0
    with collector_frozen():
        assert gc.get_freeze_count() >= len(held)
        made = [[i] for i in range(10)]
        tracked = {id(obj) for obj in gc.get_objects()}
        assert id(made[0]) in tracked and id(held[0]) not in tracked
    assert gc.get_freeze_count() == 0
    assert id(held[0]) in {id(obj) for obj in gc.get_objects()}

