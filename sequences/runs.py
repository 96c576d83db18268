"""What a run is and how it ended, declared once: the engine records them, the campaign file stores
them as run attributes (``kind``, ``status``), the reader, the analysis and the front ends read them.
Both are string enums, so a stored or printed value is the plain word (``dwell_grid``, ``complete``).
"""

from __future__ import annotations

import enum


class RunKind(enum.StrEnum):
    """The measurement a run records (a single sine dwell is recorded as a grid of one point)."""

    DWELL_GRID = "dwell_grid"
    FREE_RUN = "free_run"
    SWEEP = "sweep"
    TRACKED_DWELL = "tracked_dwell"
    ROAD_REPLAY = "road_replay"
    DRIVE_ITERATION = "drive_iteration"
    HAMMER = "hammer"


class RunStatus(enum.StrEnum):
    """How a run ended, or ``incomplete`` while it runs (or when its writer died)."""

    COMPLETE = "complete"
    ABORTED = "aborted"
    INTERLOCKED = "interlocked"
    ESTOPPED = "e-stopped"
    FAILED = "failed"
    INCOMPLETE = "incomplete"


#: Every kind, as plain words (``"sweep" in RUN_KINDS``).
RUN_KINDS = tuple(RunKind)
#: The statuses a run can end with.
FINISH_STATUSES = tuple(status for status in RunStatus if status is not RunStatus.INCOMPLETE)
