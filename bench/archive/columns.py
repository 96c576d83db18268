"""The index's columns, declared once: name, Arrow type and meaning (docs/index.md lists them).

The index is a table of flat rows; every row repeats its file's columns (path, hash, metadata), so
that a query needs no join. ``entry`` says what a row is:

- ``file``: one per file found, read or not (``file_status``, ``error``);
- ``run``: one per run of a campaign file (its kind, status, interlocks, how its analysis went);
- ``value``: one identified number (``parameter``, ``value``, ``ci95``) of a run's analysis made by
  the index (``source`` ``analysis``) or stored in the file (``source`` ``stored``);
- ``flag``: one flag of a run's analysis (``text``).

The schema is named and versioned in each Parquet part's key-value metadata
(:data:`INDEX_SCHEMA`, :data:`INDEX_VERSION`). Version 1 only gains columns (at the end) and
parameters; renaming or removing a column, or changing its unit or meaning, makes version 2.
"""

from __future__ import annotations

import pyarrow as pa

from bench.store.schema import METADATA_FIELDS

INDEX_SCHEMA = "wfs-bench-index"
INDEX_VERSION = 1
#: Keys of a part's Parquet key-value metadata that name and version its schema.
SCHEMA_KEY, VERSION_KEY = b"wfs_bench_index_schema", b"wfs_bench_index_version"

#: What a row is (the ``entry`` column).
FILE, RUN, VALUE, FLAG = "file", "run", "value", "flag"

_TIME = pa.timestamp("ms", tz="UTC")

#: (name, type, meaning) of every column, in order.
COLUMNS: tuple[tuple[str, pa.DataType, str], ...] = (
    ("entry", pa.string(), "what the row is: file, run, value or flag"),
    ("path", pa.string(), "absolute path of the file"),
    ("sha256", pa.string(), "SHA-256 of the file's bytes, hex; null when the file was skipped unread"),
    ("size_bytes", pa.int64(), "the file's size when indexed"),
    ("mtime_ns", pa.int64(), "the file's modification time when indexed, ns since 1970 (UTC)"),
    ("file_status", pa.string(), "indexed, not_analysed, not_campaign, damaged, locked or changing"),
    ("error", pa.string(), "why the file is not fully indexed; null when it is"),
    ("row", pa.int32(), "the row's number within its file (0: the file row): the rows' stable order"),
    ("indexed_by", pa.string(), "the wfs-bench version whose analysis made the row"),
    ("schema_version", pa.int32(), "the campaign file's schema version (/@schema_version)"),
    ("software_version", pa.string(), "the software that wrote the file (/@software_version)"),
    ("created", _TIME, "when the campaign file was created (/@created)"),
    ("config_name", pa.string(), "the bench configuration's name (/@config_name)"),
    ("sequence_name", pa.string(), "the sequence that created the file (/@sequence_name)"),
    *(
        (name, pa.string(), f"the test's metadata /@{name} (empty when not given)")
        for name in METADATA_FIELDS
    ),
    ("run_id", pa.string(), "the run's group name under /runs"),
    ("run_kind", pa.string(), "hammer, free_run, dwell_grid or sweep"),
    ("run_status", pa.string(), "complete, aborted, interlocked, e-stopped, failed or incomplete"),
    ("run_reason", pa.string(), "why the run ended as it did (empty when complete)"),
    ("run_started", _TIME, "when the run began"),
    ("run_finished", _TIME, "when the run ended; null when it did not"),
    ("run_interlocks", pa.int32(), "interlock events recorded in the run"),
    ("tyre_pressure_bar", pa.float64(), "the tyre pressure the run was recorded at (bar)"),
    ("analysis", pa.string(), "what the run's analysis is: hammer, plate_mass, shaker, four_post, sweep"),
    ("analysis_status", pa.string(), "complete, partial or failed; null for a run not analysed"),
    ("analysis_error", pa.string(), "why the run's analysis failed, or what it omitted"),
    ("source", pa.string(), "analysis (made by the index) or stored (read from the file)"),
    ("result_name", pa.string(), "the stored result's name in the run's results group"),
    ("amplitude_m", pa.float64(), "the excitation amplitude the value belongs to (m)"),
    ("model", pa.int8(), "the tyre model (1, 2, 3) the value belongs to"),
    ("selected", pa.bool_(), "the model is the one selected (lowest BIC with every parameter determined)"),
    ("determined", pa.bool_(), "the data determines the value (false: do not use it)"),
    ("parameter", pa.string(), "the value's name, its unit in the name (docs/index.md); a flag's code"),
    ("value", pa.float64(), "the value, SI; null when the data does not give it"),
    ("ci95", pa.float64(), "half-width of the value's 95 % interval; null when none"),
    ("freq_hz", pa.float64(), "the frequency a repeatability value belongs to (Hz)"),
    ("text", pa.string(), "a flag's text"),
)

NAMES = tuple(name for name, _, _ in COLUMNS)
#: The columns every row of a file repeats (the file row holds only these).
FILE_COLUMNS = NAMES[: NAMES.index("run_id")]


def arrow_schema() -> pa.Schema:
    """The index's Arrow schema, with its name and version in the key-value metadata."""
    fields = [pa.field(name, kind) for name, kind, _ in COLUMNS]
    return pa.schema(
        fields, metadata={SCHEMA_KEY: INDEX_SCHEMA.encode(), VERSION_KEY: str(INDEX_VERSION).encode()}
    )
