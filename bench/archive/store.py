"""The index on disk: a directory of Parquet parts, one table for every reader.

``RESULTS/part-<generation>-<n>.parquet``: each index run is a generation; it writes the rows it
made into new parts and rewrites only the parts that held rows it replaced (files read again,
removed, or found again under a new path with the same contents), then deletes those. Its parts
are written under hidden temporary names and published together at the run's end: renamed into
place, then the parts they replace deleted, in one go that takes milliseconds. A run killed before
it leaves the index as it was (the next run removes its temporaries), so a reader never sees half
a part nor a file twice; only a run stopped inside that last step leaves a file with rows in two
parts, and the next run keeps the newer part's (the higher generation) and drops the others. Read
the whole index with ``read_parquet('RESULTS/*.parquet')`` (DuckDB) or :func:`read_index`.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from bench.archive import columns as c
from bench.archive.files import FileStat

PART_NAME = re.compile(r"^part-(?P<generation>[0-9]{6})-(?P<n>[0-9]{5})\.parquet$")
_TEMPORARY = re.compile(r"^\.part-.*\.tmp$")
#: Rows a part's row group holds (fewer at a part's end): few enough that the rows held before they are
#: written stay a few MB (the client's memory must not grow with the archive), many enough for readers.
ROWS_PER_GROUP = 2048
#: Files whose rows one part holds at most: parts of a few MB, few enough files for a glob.
FILES_PER_PART = 1024
_FILE_VIEW = ("path", "size_bytes", "mtime_ns", "sha256", "file_status")


class IndexDirError(ValueError):
    """The index directory cannot be used as asked; the message names it and why."""


@dataclass(frozen=True)
class IndexedFile:
    """A file as the index holds it: its stat and hash when indexed, its status, and its part."""

    path: str
    stat: FileStat
    sha256: str | None
    status: str
    part: Path


def part_paths(directory: Path) -> list[Path]:
    """The index's parts, oldest generation first."""
    if not directory.is_dir():
        return []
    return sorted(directory / name for name in os.listdir(directory) if PART_NAME.match(name))


def check_part(path: Path) -> None:
    """Refuse a part of another schema or version (:class:`IndexDirError`)."""
    try:
        metadata = pq.read_schema(path).metadata or {}
    except (OSError, pa.ArrowInvalid) as err:
        raise IndexDirError(f"{path}: not a readable Parquet file ({err})") from err
    name, version = metadata.get(c.SCHEMA_KEY, b"").decode(), metadata.get(c.VERSION_KEY, b"").decode()
    if name != c.INDEX_SCHEMA or version != str(c.INDEX_VERSION):
        raise IndexDirError(
            f"{path}: a part of {name or 'no'} index schema version {version or '?'}; this software"
            f" writes {c.INDEX_SCHEMA} version {c.INDEX_VERSION}: index into a new directory"
        )


def open_index_dir(directory: Path) -> None:
    """Make ``directory`` ready for an index run: created if missing, every part checked, the
    temporary files of a run that stopped removed."""
    if directory.exists() and not directory.is_dir():
        raise IndexDirError(f"{directory}: exists and is not a directory")
    try:
        directory.mkdir(parents=True, exist_ok=True)
        for name in os.listdir(directory):
            if _TEMPORARY.match(name):
                (directory / name).unlink()
    except OSError as err:
        raise IndexDirError(f"{directory}: cannot be used ({err.strerror or err})") from err
    for part in part_paths(directory):
        check_part(part)


def indexed_files(directory: Path) -> tuple[dict[str, IndexedFile], dict[Path, set[str]]]:
    """Every file of the index (from its file rows, the newest part's where a file has rows in
    two), and per part the files whose rows there a newer part replaces (to drop)."""
    files: dict[str, IndexedFile] = {}
    superseded: dict[Path, set[str]] = {}
    for part in part_paths(directory):
        table = pq.read_table(part, columns=list(_FILE_VIEW), filters=[("entry", "=", c.FILE)])
        for row in table.to_pylist():
            path = row["path"]
            if path in files:
                superseded.setdefault(files[path].part, set()).add(path)
            stat = FileStat(row["size_bytes"], row["mtime_ns"])
            files[path] = IndexedFile(path, stat, row["sha256"], row["file_status"], part)
    return files, superseded


class PartWriter:
    """Writes the rows given to new parts of ``generation``, under hidden temporary names: row groups
    of :data:`ROWS_PER_GROUP` rows, at most :data:`FILES_PER_PART` files per part. :meth:`publish`
    completes the last part and puts them all in place."""

    def __init__(self, directory: Path, generation: int) -> None:
        self.directory, self.generation = directory, generation
        self.written: list[Path] = []  # the parts' names once published
        self._completed: list[Path] = []  # the temporaries of the parts complete
        self.rows = 0
        self._pending: list[pa.Table] = []
        self._pending_rows = 0
        self._writer: pq.ParquetWriter | None = None
        self._temporary: Path | None = None
        self._files_in_part = 0

    def add(self, table: pa.Table) -> None:
        """Add the rows of whole files (each file's rows in one call or consecutive calls)."""
        files = pc.sum(pc.equal(table["entry"], c.FILE)).as_py() or 0
        if self._files_in_part + files > FILES_PER_PART and self._files_in_part:
            self._finish_part()
        self._files_in_part += files
        self._pending.append(table)
        self._pending_rows += table.num_rows
        self.rows += table.num_rows
        if self._pending_rows >= ROWS_PER_GROUP:
            self._write_pending()

    def _write_pending(self) -> None:
        if not self._pending_rows:
            return
        if self._writer is None:
            name = f"part-{self.generation:06d}-{len(self.written):05d}.parquet"
            self._temporary = self.directory / f".{name}.tmp"
            self._writer = pq.ParquetWriter(self._temporary, c.arrow_schema(), compression="zstd")
            self.written.append(self.directory / name)
        self._writer.write_table(pa.concat_tables(self._pending), row_group_size=ROWS_PER_GROUP)
        self._pending, self._pending_rows = [], 0

    def _finish_part(self) -> None:
        self._write_pending()
        if self._writer is not None:
            assert self._temporary is not None
            self._writer.close()
            self._completed.append(self._temporary)
            self._writer = self._temporary = None
        self._files_in_part = 0

    def publish(self, replaced: Iterable[Path]) -> None:
        """Complete the last part, rename every part into place, then delete the ``replaced``
        parts: a reader of ``*.parquet`` sees the index before or after, a file once."""
        self._finish_part()
        for temporary, part in zip(self._completed, self.written, strict=True):
            os.replace(temporary, part)
        for part in replaced:
            part.unlink()


def next_generation(directory: Path) -> int:
    generations = [int(PART_NAME.match(part.name)["generation"]) for part in part_paths(directory)]
    return max(generations, default=0) + 1


def carry_over(
    part: Path,
    drop: set[str],
    moved: Iterable[tuple[str, str, FileStat]],
    writer: PartWriter,
) -> None:
    """Copy the rows of ``part`` into ``writer`` but those of the files in ``drop``, and add the
    rows of each file in ``moved`` (old path, new path, new stat: the same contents found again)
    under its new path and stat."""
    table = pq.read_table(part, schema=c.arrow_schema())
    keep = pc.invert(pc.is_in(table["path"], value_set=pa.array(sorted(drop), pa.string())))
    writer.add(table.filter(keep))
    for old_path, new_path, stat in moved:
        rows = table.filter(pc.equal(table["path"], old_path))
        for name, value in (("path", new_path), ("size_bytes", stat.size_bytes), ("mtime_ns", stat.mtime_ns)):
            column = pa.array([value] * rows.num_rows, rows.schema.field(name).type)
            rows = rows.set_column(rows.schema.get_field_index(name), name, column)
        writer.add(rows)


def read_index(directory: str | Path, columns: list[str] | None = None) -> pa.Table:
    """The whole index (or ``columns`` of it) in its stable order: by path, then row."""
    directory = Path(directory)
    parts = part_paths(directory)
    if not directory.is_dir():
        raise IndexDirError(f"{directory}: no such index directory")
    for part in parts:
        check_part(part)
    schema = c.arrow_schema()
    tables = [pq.read_table(part, schema=schema) for part in parts] or [schema.empty_table()]
    table = pa.concat_tables(tables).sort_by([("path", "ascending"), ("row", "ascending")])
    return table.select(columns) if columns is not None else table
