"""The one way a sequence's estimate is printed: by ``wfsbench check``, the run log of ``wfsbench
run`` and the terminal UI, with the same words.

``Sequence.estimated_duration_s`` is bench time: every dwell and sweep with its tapers, hammer
captures, hydraulics ramps, tares and mean-position moves, with prompts at 0 s (docs/sequences.md,
"Estimated duration"); ``Sequence.estimated_duration_with_operator_s`` adds the operator's answers.
A duration is printed in seconds under a minute (a hammer sequence's 3 s would read ``0.0 min``),
in minutes above.
"""

from __future__ import annotations

from sequences import Sequence


def duration_text(seconds: float) -> str:
    """``3 s`` under a minute, ``8.6 min`` from a minute on."""
    if seconds < 59.5:
        return f"{seconds:.0f} s"
    return f"{seconds / 60:.1f} min"


def estimate_text(points: int, bench_s: float, with_operator_s: float | None = None) -> str:
    """``8 points; about 29 s of bench time, about 3.5 min with the operator's answers`` (the last
    part left out when the time with the operator is not known)."""
    text = f"{points} points; about {duration_text(bench_s)} of bench time"
    if with_operator_s is not None:
        text += f", about {duration_text(with_operator_s)} with the operator's answers"
    return text


def sequence_estimate_text(sequence: Sequence) -> str:
    """:func:`estimate_text` of ``sequence``."""
    return estimate_text(
        sequence.points(), sequence.estimated_duration_s, sequence.estimated_duration_with_operator_s
    )
