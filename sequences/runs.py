"""What a run is, on which rig, how it ended and what its events record, declared once: the engine
records them, the campaign file stores them (a run's ``kind`` and ``status``, the ``bench`` of its
conditions, the ``kind`` of each event), the reader, the analysis and the front ends read them. All
are string enums, so a stored or printed value is the plain word (``dwell_grid``, ``complete``).
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


class RigKind(enum.StrEnum):
    """Which test rig the bench is: its configuration's ``kind``, and the ``bench`` each run's
    conditions record."""

    SHAKER = "shaker"
    FOUR_POST = "four_post"


class EventKind(enum.StrEnum):
    """What an event of a campaign file's ``events`` tables records (docs/hdf5.md, *Events*)."""

    PROMPT = "prompt"
    STATE = "state"
    REFINED = "refined"
    GAP = "gap"
    INTERLOCK = "interlock"
    HOST_STALL = "host stall"
    AMPLITUDE = "amplitude"
    LIMIT = "limit"
    TRACK = "track"
    RESUMED = "resumed"
    METADATA = "metadata"
    IMPORT = "import"
    SEQUENCE_FINISHED = "sequence finished"


#: Every kind, as plain words (``"sweep" in RUN_KINDS``).
RUN_KINDS = tuple(RunKind)
#: The statuses a run can end with.
FINISH_STATUSES = tuple(status for status in RunStatus if status is not RunStatus.INCOMPLETE)
