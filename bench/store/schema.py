"""The campaign file's schema in one place: names, versions, table dtypes, and the errors.

One HDF5 file per campaign (layout in ``docs/hdf5.md``). Writer and reader both take every name,
dtype and version from here, so the two cannot drift apart. Bump :data:`SCHEMA_VERSION` whenever a
reader of the previous version would misread a new file.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import h5py
import numpy as np

SCHEMA_NAME = "wfs-bench campaign"
SCHEMA_VERSION = 1

#: Oldest and newest HDF5 file-format versions the writer may use. The low bound 1.8 keeps the
#: superblock at version 2, which has no "open for write" flag: a file whose writer was killed
#: opens without ``h5clear``. The high bound 1.10 keeps the files readable by HDF5 1.10 tools
#: (Debian's h5dump) and older h5py builds; HDF5 2.0 would otherwise write objects they refuse.
LIBVER = ("v108", "v110")

#: Writer cadence: the file is flushed once this much sample time has been appended since the last
#: flush, or this much wall time has passed since the last fsync (checked on every write), so at
#: most this much of the recording is ever at risk; the cadence fsyncs at most once per this much
#: wall time (explicit flushes, run ends and close fsync too). A chunk holds this much sample time.
FLUSH_INTERVAL_S = 1.0

#: File-space strategy: freed file space is never reused while the file is open, so a write
#: never lands where the last flushed state of the file still points.
FS_STRATEGY = "none"
#: Rows per chunk of the points and events tables (uncompressed: a table's last chunk is
#: rewritten as rows arrive, which only an unfiltered chunk survives a crash in the middle of).
TABLE_CHUNK_ROWS = 64
GZIP_LEVEL = 1

RUNS = "runs"
CHANNELS = "channels"
POINTS = "points"
EVENTS = "events"
LINK = "link"
RESULTS = "results"

RUN_KINDS = ("dwell_grid", "free_run", "sweep", "hammer")
FINISH_STATUSES = ("complete", "aborted", "interlocked", "e-stopped", "failed")
#: Status of a run that was begun and not finished: running now, or its writer died.
INCOMPLETE = "incomplete"
CHANNEL_DTYPES = ("f4", "u4", "u2")
POINT_STATUSES = ("done", "repeated", "interrupted", "aborted")

_STR = h5py.string_dtype("utf-8")

POINT_DTYPE = np.dtype(
    [
        ("index", "<i4"),
        ("freq_hz", "<f8"),
        ("amplitude_mm", "<f8"),
        ("requested_amplitude_mm", "<f8"),
        ("corrected_amplitude_mm", "<f8"),
        ("achieved_amplitude_mm", "<f8"),
        ("attempt", "<i4"),
        ("start_sample", "<i8"),
        ("hold_start_sample", "<i8"),
        ("hold_end_sample", "<i8"),
        ("end_sample", "<i8"),
        ("status", _STR),
        ("settled", "u1"),
        ("note", _STR),
        ("verdict", _STR),
        ("settle_s", "<f8"),
        ("measure_start_sample", "<i8"),
        ("magnitude_uncertainty_pct", "<f8"),
        ("phase_uncertainty_deg", "<f8"),
        ("added_reason", _STR),
    ]
)
#: Points-table fields of adaptive dwells, added after the first files were written: a reader takes
#: a table without them, with these values.
OPTIONAL_POINT_FIELDS: dict[str, object] = {
    "verdict": "",
    "settle_s": math.nan,
    "measure_start_sample": -1,
    "magnitude_uncertainty_pct": math.nan,
    "phase_uncertainty_deg": math.nan,
    "added_reason": "",
}

EVENT_DTYPE = np.dtype(
    [("time_unix_s", "<f8"), ("sample", "<i8"), ("kind", _STR), ("text", _STR), ("fields", _STR)]
)


class StoreError(ValueError):
    """A campaign file that cannot be written or read as asked; ``str`` names the file and the
    place inside it (``campaign.h5: /runs/003/points[2]: end_sample 5000 beyond ...``)."""

    def __init__(self, path: str | Path, where: str, message: str) -> None:
        self.path, self.where, self.message = str(path), where, message
        super().__init__(f"{self.path}: {where}: {message}" if where else f"{self.path}: {message}")


@dataclass(frozen=True, slots=True)
class PointRow:
    """One attempt at one point of a run (a dwell, a sweep, a hammer blow): a row of ``points``.

    ``index`` is the point's position in its step (the n-th dwell of a grid); a point repeated by
    the amplitude control or by a pause has one row per ``attempt``, the last one ``"done"``.
    ``amplitude_mm`` is the step's amplitude as the sequence commands it, ``requested_amplitude_mm``
    the grid's nominal amplitude when a bench limit lowered it, ``corrected_amplitude_mm`` what the
    amplitude control sent instead, ``achieved_amplitude_mm`` what the displacement channel showed
    (NaN when not applicable). Sample positions index this run's recorded arrays:
    ``start_sample <= hold_start_sample <= hold_end_sample <= end_sample`` (end exclusive).
    An adaptive dwell adds its ``verdict``, ``settle_s`` (hold time when it settled),
    ``measure_start_sample`` (where its measured part begins, within the hold; -1 when none), the FRF
    point's standard uncertainties and, for a point the refinement added, ``added_reason``.
    """

    index: int
    freq_hz: float
    amplitude_mm: float
    start_sample: int
    hold_start_sample: int
    hold_end_sample: int
    end_sample: int
    status: str = "done"
    attempt: int = 1
    requested_amplitude_mm: float = math.nan
    corrected_amplitude_mm: float = math.nan
    achieved_amplitude_mm: float = math.nan
    settled: bool = True
    note: str = ""
    verdict: str = ""
    settle_s: float = math.nan
    measure_start_sample: int = -1
    magnitude_uncertainty_pct: float = math.nan
    phase_uncertainty_deg: float = math.nan
    added_reason: str = ""


def to_json(value: Mapping[str, Any], *, path: str | Path, where: str) -> str:
    """``value`` as JSON text for an attribute; refuses what JSON cannot hold (NaN is written as
    ``NaN``, which Python's json reads back)."""
    try:
        return json.dumps(value, sort_keys=True, default=_json_default)
    except (TypeError, ValueError) as err:
        raise StoreError(path, where, f"cannot be stored as JSON: {err}") from err


def _json_default(value: object) -> object:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def from_json(text: str, *, path: str | Path, where: str) -> Any:
    try:
        return json.loads(text)
    except json.JSONDecodeError as err:
        raise StoreError(path, where, f"not valid JSON ({err})") from err
