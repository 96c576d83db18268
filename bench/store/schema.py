"""The campaign file's schema in one place: names, versions, table dtypes, and the errors.

One HDF5 file per campaign (layout in ``docs/hdf5.md``). Writer and reader both take every name,
dtype and version from here, so the two cannot drift apart. Bump :data:`SCHEMA_VERSION` whenever a
reader of the previous version would misread a new file.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import fields
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from bench.locks import Holder, InUseError, file_key
from sequences import metadata
from sequences.points import PointAttempt, PointStatus

SCHEMA_NAME = "wfs-bench campaign"
SCHEMA_VERSION = 2
#: Versions the reader reads: 1 differs in two points-table columns (:data:`VERSION_1_POINT_FIELDS`).
READABLE_VERSIONS = (1, 2)

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

#: The test's metadata: attributes of the campaign (``/``), UTF-8 strings, empty when not given.
#: They name what was tested and by whom, so that a campaign can be found among many. Defined with
#: the bench's vocabulary (:mod:`sequences.metadata`), where the configuration and the sequence
#: files check them too; a run records its own ``RUN_METADATA_FIELDS`` (who ran it, where, notes).
METADATA_FIELDS = metadata.METADATA_FIELDS
RUN_METADATA_FIELDS = metadata.RUN_FIELDS
#: Attribute of ``results/<name>``: when the result was stored (ISO 8601 UTC); a result's own
#: top-level key may not take this name.
RESULT_STORED = "stored"

RUNS = "runs"
CHANNELS = "channels"
POINTS = "points"
EVENTS = "events"
LINK = "link"
RESULTS = "results"
#: A run's analysis record: one JSON text (bench/app/analysis_record.py), written once.
ANALYSIS = "analysis"
#: A run's figures as the post-run analysis drew them after the run (bench/app/kept_figures.py): per
#: figure a 1-D uint8 dataset of PNG bytes named as the figure, with the attributes below.
FIGURES = "figures"
#: Attribute of a kept figure: the SHA-256 of what it shows (the values drawn and the software).
FIGURE_SHOWS = "shows_sha256"
#: Attribute of a kept figure: the SHA-256 of its PNG bytes, so that a damaged copy is not taken.
FIGURE_PNG = "png_sha256"

CHANNEL_DTYPES = ("f4", "u4", "u2")
POINT_STATUSES = tuple(PointStatus)

#: A UTF-8 variable-length string.
STR = h5py.string_dtype("utf-8")

#: numpy type of a points-table column, by the type of the :class:`PointAttempt` field it holds.
_COLUMN_TYPES = {"int": "<i8", "float": "<f8", "str": STR}
#: The points table: one column per field of :class:`~sequences.points.PointAttempt`, same names.
POINT_DTYPE = np.dtype([(f.name, _COLUMN_TYPES[f.type]) for f in fields(PointAttempt)])
#: Points-table fields added to version-2 files after the first were written (the amplitude held
#: within the dwell, the notch of a response limit, the frames lost in a hold): a reader takes a
#: table without them, with these values.
VERSION_2_ADDED_POINT_FIELDS: dict[str, object] = {
    "amplitude_updates": 0,
    "held_amplitude_mm": math.nan,
    "notched_by": "",
    "notch_start_hz": math.nan,
    "notch_end_hz": math.nan,
    "notch_amplitude_mm": math.nan,
    "frames_missing": 0,
}
#: Points-table fields of adaptive dwells, added to version-1 files after the first were written,
#: and the fields added to version 2 since: a reader takes a version-1 table without them, with
#: these values.
OPTIONAL_POINT_FIELDS: dict[str, object] = {
    "verdict": "",
    "settle_s": math.nan,
    "measure_start_sample": -1,
    "magnitude_uncertainty_pct": math.nan,
    "phase_uncertainty_deg": math.nan,
    "added_reason": "",
    **VERSION_2_ADDED_POINT_FIELDS,
}
#: Version 1 stored ``corrected_amplitude_mm`` (NaN when the command was the step's amplitude) and
#: ``settled`` where version 2 stores ``commanded_amplitude_mm`` and the verdict alone.
VERSION_1_POINT_FIELDS = ("corrected_amplitude_mm", "settled")


def required_point_fields(version: int) -> tuple[str, ...]:
    """The columns a points table of schema ``version`` must have."""
    if version >= 2:
        return tuple(n for n in POINT_DTYPE.names if n not in VERSION_2_ADDED_POINT_FIELDS)
    kept = (n for n in POINT_DTYPE.names if n not in OPTIONAL_POINT_FIELDS and n != "commanded_amplitude_mm")
    return (*kept, *VERSION_1_POINT_FIELDS)


EVENT_DTYPE = np.dtype(
    [("time_unix_s", "<f8"), ("sample", "<i8"), ("kind", STR), ("text", STR), ("fields", STR)]
)


class StoreError(ValueError):
    """A campaign file that cannot be written or read as asked; ``str`` names the file and the
    place inside it (``campaign.h5: /runs/003/points[2]: end_sample 5000 beyond ...``)."""

    def __init__(self, path: str | Path, where: str, message: str) -> None:
        self.path, self.where, self.message = str(path), where, message
        super().__init__(f"{self.path}: {where}: {message}" if where else f"{self.path}: {message}")


class CampaignInUseError(StoreError, InUseError):
    """The campaign file is being written by another process (``holder``: who, where known; see
    :mod:`bench.locks`)."""

    def __init__(self, path: str | Path, holder: Holder | None, advice: str) -> None:
        self.what, self.holder = f"the campaign file {path}", holder
        by = holder or "another process"
        StoreError.__init__(self, path, "", f"in use: being written by {by}; {advice}")


def campaign_key(path: str | Path) -> str:
    """The key of a campaign file's writer lock (:mod:`bench.locks`)."""
    return file_key(path)


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
