"""The summary of a compensation job: one row per measurement file, as one Parquet file
``OUT/summary.parquet`` (docs/compensate.md, *The summary*).

Each row says what became of the file (``status``, ``error``), what it was compensated with (the
identification's key and label, the assumptions), where its outputs are, and its figures: the
input's Fz and the compensated contact force (mean, rms about the mean, peaks), the 95 % band's
median and largest half-width, the valid band. The job reads the rows back to know which files are
unchanged since (:func:`read_summary`); the file is replaced whole at the run's end, never half
written (a temporary renamed into place).

The schema is named and versioned in the file's key-value metadata (:data:`SUMMARY_SCHEMA`,
:data:`SUMMARY_VERSION`); version 1 only gains columns at the end.
"""

from __future__ import annotations

import enum
import os
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from bench.store.temporary import temporary_beside

SUMMARY_SCHEMA = "wfs-bench-compensation-summary"
SUMMARY_VERSION = 1
SCHEMA_KEY, VERSION_KEY = b"wfs_bench_summary_schema", b"wfs_bench_summary_version"
SUMMARY_NAME = "summary.parquet"


class Status(enum.StrEnum):
    """What became of a measurement file (the ``status`` column)."""

    COMPENSATED = "compensated"  # its outputs written
    REFUSED = "refused"  # the campaign does not cover it (its pressure, rate, a channel): error says what
    UNREADABLE = "unreadable"  # damaged, foreign, or its samples cannot be used: error says where
    CHANGING = "changing"  # its size or time changed while it was read: tried again by the next run
    FAILED = "failed"  # the software met an error on it: tried again by the next run


#: Statuses whose file is compensated again by the next run even when unchanged.
TRIED_AGAIN = frozenset({Status.CHANGING, Status.FAILED})

#: (name, type, meaning) of every column, in order.
COLUMNS: tuple[tuple[str, pa.DataType, str], ...] = (
    ("path", pa.string(), "absolute path of the measurement file"),
    ("size_bytes", pa.int64(), "its size when compensated"),
    ("mtime_ns", pa.int64(), "its modification time when compensated, ns since 1970"),
    ("status", pa.string(), "compensated, refused, unreadable, changing or failed"),
    ("error", pa.string(), "why it is not compensated; null when it is"),
    ("identification", pa.string(), "key of what it was compensated with (campaign, options, software)"),
    ("campaign", pa.string(), "the campaign file whose identification compensated it"),
    ("identified_as", pa.string(), "the identification used: tyre, pressure, amplitude, model"),
    ("out_hdf5", pa.string(), "the output (HDF5), relative to the output folder"),
    ("out_mdf4", pa.string(), "the output (MDF4), relative to the output folder"),
    ("n_samples", pa.int64(), "samples of the measurement"),
    ("sample_rate_hz", pa.float64(), "its sample rate"),
    ("start_s", pa.float64(), "time of its first sample in its own time"),
    ("duration_s", pa.float64(), "its length"),
    ("tyre_pressure_bar", pa.float64(), "the tyre pressure it was compensated at"),
    ("fz_wfs_mean_n", pa.float64(), "mean of the WFS Fz"),
    ("fz_wfs_rms_n", pa.float64(), "rms of the WFS Fz about its mean"),
    ("fz_wfs_min_n", pa.float64(), "smallest WFS Fz"),
    ("fz_wfs_max_n", pa.float64(), "largest WFS Fz"),
    ("f_contact_mean_n", pa.float64(), "mean of the compensated contact force"),
    ("f_contact_rms_n", pa.float64(), "rms of the contact force about its mean"),
    ("f_contact_min_n", pa.float64(), "smallest contact force (the lowest peak)"),
    ("f_contact_max_n", pa.float64(), "largest contact force (the highest peak)"),
    ("u95_median_n", pa.float64(), "median half-width of the 95 % band"),
    ("u95_max_n", pa.float64(), "largest half-width of the 95 % band"),
    ("valid_band_lo_hz", pa.float64(), "where the valid band starts"),
    ("valid_band_hi_hz", pa.float64(), "where the valid band ends"),
    ("assumptions", pa.string(), "what the compensation assumed, one line each (source: text)"),
    ("compensated_by", pa.string(), "the wfs-bench version that compensated it"),
    ("worker", pa.string(), "the process that read it (host:pid)"),
    ("processor_s", pa.float64(), "processor time spent on it"),
)

Row = dict[str, Any]


def arrow_schema() -> pa.Schema:
    """The summary's Arrow schema with its name and version as key-value metadata."""
    metadata = {SCHEMA_KEY: SUMMARY_SCHEMA.encode(), VERSION_KEY: str(SUMMARY_VERSION).encode()}
    return pa.schema([pa.field(name, kind) for name, kind, _ in COLUMNS], metadata=metadata)


class SummaryError(ValueError):
    """The summary file cannot be used: the message names it and why."""


def read_summary(out_dir: Path) -> dict[str, Row]:
    """The rows of the summary in ``out_dir`` by path ({} without one); one of another schema or
    version is refused (:class:`SummaryError`)."""
    path = out_dir / SUMMARY_NAME
    if not path.exists():
        return {}
    try:
        table = pq.read_table(path)
    except (OSError, pa.ArrowInvalid) as err:
        raise SummaryError(f"{path}: not a readable Parquet file ({err})") from err
    metadata = table.schema.metadata or {}
    name, version = metadata.get(SCHEMA_KEY, b"").decode(), metadata.get(VERSION_KEY, b"").decode()
    if name != SUMMARY_SCHEMA or version != str(SUMMARY_VERSION):
        raise SummaryError(
            f"{path}: a summary of {name or 'no'} schema version {version or '?'}; this software writes"
            f" {SUMMARY_SCHEMA} version {SUMMARY_VERSION}: give another --out"
        )
    return {row["path"]: row for row in table.to_pylist()}


def write_summary(out_dir: Path, rows: list[Row]) -> Path:
    """Replace the summary in ``out_dir`` by ``rows`` (sorted by path), whole."""
    path = out_dir / SUMMARY_NAME
    table = pa.Table.from_pylist(sorted(rows, key=lambda row: row["path"]), schema=arrow_schema())
    temporary = temporary_beside(path)
    try:
        pq.write_table(table, temporary, compression="zstd")
        os.replace(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)
    return path
