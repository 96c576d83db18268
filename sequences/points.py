"""One attempt at one point of a run, declared once: the engine publishes it, the campaign file
stores it as a row of a run's ``points`` table (one column per field, same names), the reader and
the CSV import give it back. A new point field is added here, with its default, and nowhere else:
the table's dtype and the reader follow from these fields (``bench/store/schema.py``).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass


class PointStatus(enum.StrEnum):
    """How one attempt at a point ended."""

    DONE = "done"  # kept: its samples are the point's
    REPEATED = "repeated"  # the amplitude was off: tried again with a corrected command
    INTERRUPTED = "interrupted"  # a pause stopped it: repeated on resume
    ABORTED = "aborted"  # the run ended during it


class Verdict(enum.StrEnum):
    """How an adaptive dwell's hold ended (empty for fixed timing), or a tracked dwell's track."""

    NONE = ""  # a fixed-length hold: no online verdict
    TARGET = "target"  # settled and measured to the uncertainty targets
    MAX_LENGTH = "max length"  # settled, the targets not reached within the longest hold
    NOT_SETTLED = "not settled"
    TRACKED = "tracked"  # a track that ran its length
    STOPPED = "stopped"  # a track a stop rule ended (its note says why)


@dataclass(frozen=True, slots=True)
class PointAttempt:
    """One attempt at one point of a run (a dwell of a grid, the sweep, a hammer blow).

    ``index`` is the point's position in its step (the n-th dwell of a grid); a point repeated by the
    amplitude control or a pause has one attempt per ``attempt``, the last one ``done``.
    ``amplitude_mm`` is the step's amplitude (the sequence file's, after any bench-limit crossover),
    ``requested_amplitude_mm`` the grid's nominal amplitude when a bench limit lowered it (NaN:
    not lowered), ``commanded_amplitude_mm`` what this attempt sent to the controller (differs from
    ``amplitude_mm`` once the amplitude control corrected it), ``achieved_amplitude_mm`` what the
    displacement channel showed over the hold (NaN: not measured). Sample positions index the run's
    recorded samples: ``start_sample <= hold_start_sample <= hold_end_sample <= end_sample`` (end
    exclusive). An adaptive dwell adds its ``verdict``, ``settle_s`` (hold time when it settled),
    ``measure_start_sample`` (where its measured part begins, within the hold; -1 when none), the
    FRF point's standard uncertainties and, for a point the refinement added, ``added_reason``.
    A dwell whose amplitude was held within it (docs/engine.md) adds ``amplitude_updates``, the new
    amplitudes the controller took during the hold, and ``held_amplitude_mm``, the command in force
    over its hold after them (NaN: no update); its hold is the part after the last update's ramp.
    A point whose drive a response limit lowered (a notch) names it in ``notched_by``, with the span
    notched ``notch_start_hz``..``notch_end_hz`` (a dwell's: its frequency) and the amplitude
    commanded there, ``notch_amplitude_mm`` (NaN: not notched); a notched sweep's ``achieved_amplitude_mm`` is
    the displacement's amplitude reached within its notch. ``frames_missing``: frames lost on the
    WFS link within the attempt's hold (its samples are fitted on their true times, the frame
    counter's; docs/engine.md).
    """

    index: int
    freq_hz: float
    amplitude_mm: float
    start_sample: int
    hold_start_sample: int
    hold_end_sample: int
    end_sample: int
    status: str = PointStatus.DONE
    attempt: int = 1
    requested_amplitude_mm: float = math.nan
    commanded_amplitude_mm: float = math.nan
    achieved_amplitude_mm: float = math.nan
    note: str = ""
    verdict: str = Verdict.NONE
    settle_s: float = math.nan
    measure_start_sample: int = -1
    magnitude_uncertainty_pct: float = math.nan
    phase_uncertainty_deg: float = math.nan
    added_reason: str = ""
    amplitude_updates: int = 0
    held_amplitude_mm: float = math.nan
    notched_by: str = ""
    notch_start_hz: float = math.nan
    notch_end_hz: float = math.nan
    notch_amplitude_mm: float = math.nan
    frames_missing: int = 0

    @property
    def settled(self) -> bool:
        """Whether the dwell settled (a fixed-length hold is taken as settled; the analysis checks)."""
        return self.verdict != Verdict.NOT_SETTLED
