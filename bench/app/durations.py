"""The one way a duration estimate is printed, by ``wfsbench check`` and by the run log.

``Sequence.estimated_duration_s`` is bench time: every dwell and sweep with its tapers, hammer
captures, hydraulics ramps, tares and mean-position moves, with prompts at 0 s (docs/sequences.md,
"Estimated duration"). It is printed in seconds under a minute (a hammer sequence's 3 s would read
``0.0 min``), in minutes above.
"""

from __future__ import annotations


def duration_text(seconds: float) -> str:
    """``3 s`` under a minute, ``8.6 min`` from a minute on."""
    if seconds < 59.5:
        return f"{seconds:.0f} s"
    return f"{seconds / 60:.1f} min"


def bench_time_text(seconds: float) -> str:
    """``about 29 s of bench time``: the label of ``Sequence.estimated_duration_s`` everywhere."""
    return f"about {duration_text(seconds)} of bench time"
