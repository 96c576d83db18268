"""An index run: which files to read, read them on Dask, write their rows.

The client (the process that runs ``wfsbench index``) walks the directories and compares each
campaign file with what the index holds: a file of the same path, size and modification time whose
reading was final is not read again (``verify``: every file is hashed, and only one with the same
SHA-256 is kept); a file that was locked or changing is tried again. The others go, as
:class:`FileTask` values (a path and what was seen of it: plain data that pickles, never an open
h5py object), to :func:`index_files` in batches of ``files_per_task``, on an executor of
:mod:`bench.cluster` (a ``dask.distributed`` cluster, or this process); each batch's rows are
written as it comes back, so the client's memory holds the batches under way, not the archive.

:func:`index_file` is what a worker does with one file, and the only place the file is opened:
read only, never written. A file whose writer lock is held (a bench records into it,
:mod:`bench.locks`) or that changes while it is read is skipped at once and listed; a file that
is not a campaign or is damaged is listed with its error; nothing stops the run.
"""

from __future__ import annotations

import enum
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from itertools import islice
from pathlib import Path
from typing import Protocol

import h5py
import pyarrow as pa

from bench import locks
from bench.archive import columns as c
from bench.archive import store
from bench.archive.files import FileStat, find_files, sha256_of, within, writer_of
from bench.archive.rows import Row, campaign_columns, campaign_rows
from bench.cluster import Executor

#: Files a worker indexes per task: enough to make a task's overhead small against its files.
FILES_PER_TASK = 4
#: What indexing a file imports on first use, beyond this module: the analysis (scipy's fits and
#: filters), and pandas with pyarrow's layer over it (pyarrow imports them to build a table from
#: Python values); a local cluster's workers start with them imported
#: (:mod:`bench.cluster`; ``tests/fleet/test_worker_imports.py``, validation tier, keeps the list whole).
WORKER_IMPORTS = (
    "bench.app.analyze",
    "bench.app.run_analysis",
    "pandas",
    "pyarrow.pandas_compat",
    "pyarrow.vendored.version",
    "scipy.interpolate",
    "scipy.ndimage",
    "scipy.optimize",
    "scipy.signal",
    "scipy.stats",
)


class FileStatus(enum.StrEnum):
    """What became of a file (the ``file_status`` column)."""

    INDEXED = "indexed"  # read, its runs analysed (a run's own analysis may have failed: see its row)
    NOT_ANALYSED = "not_analysed"  # a campaign read, but the campaign analysis could not run: error
    NOT_CAMPAIGN = "not_campaign"  # not HDF5, or HDF5 of another layout
    DAMAGED = "damaged"  # HDF5 that cannot be read, or a campaign file that breaks the schema
    LOCKED = "locked"  # a bench is recording into it (its writer lock is held): skipped, tried again
    CHANGING = "changing"  # changed since it was listed or while it was read: skipped, tried again


#: Statuses whose file is read again by the next run even when unchanged.
TRIED_AGAIN = frozenset({FileStatus.LOCKED, FileStatus.CHANGING})


@dataclass(frozen=True)
class FileTask:
    """A file to index: its absolute ``path``, its stat when listed, and the SHA-256 of the indexed
    files of its size (``known_sha256``): a file with one of them is not read; ``reanalyse``: its runs
    fitted again, not read from the analysis it stores."""

    path: str
    listed: FileStat
    known_sha256: tuple[str, ...] = ()
    reanalyse: bool = False


@dataclass(frozen=True)
class FileOutcome:
    """What a worker made of a file: its ``status`` (a :class:`FileStatus` value), ``sha256``
    (None when it was not read), whether the campaign was ``opened``, and its ``rows`` (None when
    its contents are those of an indexed file: ``sha256`` names them)."""

    path: str
    status: str
    stat: FileStat | None
    sha256: str | None
    opened: bool
    rows: pa.Table | None
    error: str | None = None


def index_files(tasks: Sequence[FileTask]) -> list[FileOutcome]:
    """Index each file of ``tasks`` (:func:`index_file`); what a Dask task runs."""
    return [index_file(task) for task in tasks]


def index_file(task: FileTask) -> FileOutcome:
    """Index one file, read only; every failure is the file's status, never an exception."""
    seen = _seen(task)
    if isinstance(seen, FileOutcome):
        return seen
    stat, sha256 = seen
    if sha256 in task.known_sha256:
        return FileOutcome(task.path, FileStatus.INDEXED, stat, sha256, opened=False, rows=None)
    status, error, columns, rows = _read(task.path, reanalyse=task.reanalyse)
    if FileStat.of(task.path) != stat:
        return _skipped(task, FileStatus.CHANGING, "changed while it was read: being written", stat)
    file_row = {"entry": c.FILE, "file_status": status, "error": error}
    table = _table(task.path, stat, sha256, [{**columns, **row} for row in (file_row, *rows)])
    return FileOutcome(task.path, status, stat, sha256, opened=True, rows=table, error=error)


def _seen(task: FileTask) -> tuple[FileStat, str] | FileOutcome:
    """The file's stat and SHA-256 when it may be read: as listed and not locked; else the
    outcome that skips it."""
    try:
        stat = FileStat.of(task.path)
    except OSError as err:
        return _skipped(task, FileStatus.CHANGING, f"gone since it was listed ({err.strerror})")
    if stat != task.listed:
        return _skipped(task, FileStatus.CHANGING, "changed since it was listed: being written", stat)
    holder = writer_of(task.path)
    if holder is not None:
        return _skipped(task, FileStatus.LOCKED, f"being written by {holder}: skipped", stat)
    try:
        return stat, sha256_of(task.path)
    except OSError as err:
        return _skipped(task, FileStatus.DAMAGED, f"cannot be read ({err.strerror})", stat)


def _skipped(task: FileTask, status: FileStatus, error: str, stat: FileStat | None = None) -> FileOutcome:
    seen = stat or task.listed
    row = {"entry": c.FILE, "file_status": status, "error": error}
    table = _table(task.path, seen, None, [row])
    return FileOutcome(task.path, status, seen, None, opened=False, rows=table, error=error)


def _table(path: str, stat: FileStat, sha256: str | None, rows: list[Row]) -> pa.Table:
    """The file's rows with its path, stat, hash and the software that indexed it, numbered in
    order (the file row first)."""
    from bench.app.version import software_version

    base = {
        "path": path,
        "sha256": sha256,
        "size_bytes": stat.size_bytes,
        "mtime_ns": stat.mtime_ns,
        "indexed_by": software_version(),
    }
    numbered = [{**base, **row, "row": n} for n, row in enumerate(rows)]
    return pa.Table.from_pylist(numbered, schema=c.arrow_schema())


def _read(path: str, *, reanalyse: bool) -> tuple[FileStatus, str | None, Row, list[Row]]:
    """Open the campaign file (read only): its status and error, its file columns, and the rows
    of its runs, stored results and analysis."""
    from bench.app.analyze import CampaignFileError, analyze_campaign
    from bench.store import StoreError, open_campaign
    from bench.store.schema import CampaignInUseError

    try:
        campaign = open_campaign(path)
    except CampaignInUseError as err:  # open for writing elsewhere (HDF5's own file lock)
        return FileStatus.LOCKED, f"{err.message}: skipped", {}, []
    except StoreError as err:
        foreign = err.where == "/@schema" or not h5py.is_hdf5(path)
        return (FileStatus.NOT_CAMPAIGN if foreign else FileStatus.DAMAGED), _error(path, err), {}, []
    with campaign:
        try:
            columns = campaign_columns(campaign)
        except OSError as err:
            return FileStatus.DAMAGED, f"/: unreadable attributes ({err})", {}, []
        status, error, analysis = FileStatus.INDEXED, None, None
        try:
            analysis = analyze_campaign(path, reanalyse=reanalyse)
        except (StoreError, CampaignFileError) as err:
            status, error = FileStatus.NOT_ANALYSED, _error(path, err)
        except Exception as err:  # a defect met in one file of an archive must not stop the others
            status, error = FileStatus.NOT_ANALYSED, f"the analysis raised {type(err).__name__}: {err}"
        try:
            rows = campaign_rows(campaign, analysis)
        except StoreError as err:  # a stored result that cannot be read
            return FileStatus.DAMAGED, _error(path, err), {}, []
    return status, error, columns, rows


def _error(path: str, err: Exception) -> str:
    """An error's message without the file's path in front (the row names the file)."""
    text = str(err)
    return text.removeprefix(f"{path}: ")


class Progress(Protocol):
    """Told of each file as the index run lists it and as it is done."""

    def listed(self, path: str, *, to_read: bool) -> None: ...

    def done(self, outcome: FileOutcome) -> None: ...


@dataclass
class IndexSummary:
    """What an index run did: files found, files not read again (``unchanged``), files read by
    status (``statuses``), files whose contents were indexed already (``same_contents``), files
    gone from the directories (``removed``), rows written, and every file skipped or refused with
    its status and error (``problems``)."""

    found: int = 0
    unchanged: int = 0
    statuses: dict[str, int] = field(default_factory=dict)
    same_contents: int = 0
    removed: int = 0
    rows_written: int = 0
    problems: list[tuple[str, str, str]] = field(default_factory=list)


def build_index(
    roots: Sequence[Path],
    out_dir: Path,
    executor: Executor,
    *,
    verify: bool = False,
    reanalyse: bool = False,
    files_per_task: int = FILES_PER_TASK,
    progress: Progress | None = None,
) -> IndexSummary:
    """Index the campaign files under ``roots`` into the index directory ``out_dir`` (created, or
    brought up to date); one index run at a time per directory (its lock, :mod:`bench.locks`).
    ``reanalyse``: the files read are fitted again instead of read from the analysis they store."""
    out_dir = Path(out_dir)
    with locks.holding(locks.file_key(out_dir), f"the index {out_dir}"):
        store.open_index_dir(out_dir)
        return _Run(roots, out_dir, verify, progress, reanalyse=reanalyse).run(executor, files_per_task)


class _Run:
    """One index run: the plan against the index held, the outcomes written, the parts replaced."""

    def __init__(
        self,
        roots: Sequence[Path],
        out_dir: Path,
        verify: bool,
        progress: Progress | None,
        *,
        reanalyse: bool,
    ) -> None:
        self.roots, self.out_dir, self.verify, self.progress = roots, out_dir, verify, progress
        self.reanalyse = reanalyse
        self.held, superseded = store.indexed_files(out_dir)
        self.drop: dict[Path, set[str]] = {part: set(paths) for part, paths in superseded.items()}
        self.by_contents: dict[int, dict[str, str]] = {}  # size -> sha256 -> a path indexed with it
        for held in self.held.values():
            if held.sha256 is not None and held.status not in TRIED_AGAIN:
                self.by_contents.setdefault(held.stat.size_bytes, {})[held.sha256] = held.path
        self.moved: dict[Path, list[tuple[str, str, FileStat]]] = {}
        self.listed: set[str] = set()
        self.summary = IndexSummary()

    def run(self, executor: Executor, files_per_task: int) -> IndexSummary:
        writer = store.PartWriter(self.out_dir, store.next_generation(self.out_dir))
        tasks = self._tasks()
        batches = iter(lambda: list(islice(tasks, files_per_task)), [])
        for outcomes in executor.run(index_files, batches, WORKER_IMPORTS):
            for outcome in outcomes:
                self._take(outcome, writer)
        for path, held in self.held.items():
            if path not in self.listed and within(path, self.roots):
                self._replace(held)
                self.summary.removed += 1
        for part in sorted(set(self.drop) | set(self.moved)):
            store.carry_over(part, self.drop.get(part, set()), self.moved.get(part, ()), writer)
        writer.publish(sorted(set(self.drop) | set(self.moved)))
        self.summary.rows_written = writer.rows
        return self.summary

    def _tasks(self) -> Iterator[FileTask]:
        for path in find_files(self.roots):
            try:
                stat = FileStat.of(path)
            except OSError:
                continue  # gone between the directory listing and its stat
            self.listed.add(path)
            self.summary.found += 1
            held = self.held.get(path)
            unchanged = held is not None and held.stat == stat and held.status not in TRIED_AGAIN
            if self.progress is not None:
                self.progress.listed(path, to_read=not unchanged or self.verify)
            if unchanged and not self.verify:
                self.summary.unchanged += 1
                continue
            yield FileTask(path, stat, tuple(self.by_contents.get(stat.size_bytes, {})), self.reanalyse)

    def _replace(self, held: store.IndexedFile) -> None:
        """The rows of ``held`` in its part are replaced (or dropped)."""
        self.drop.setdefault(held.part, set()).add(held.path)

    def _take(self, outcome: FileOutcome, writer: store.PartWriter) -> None:
        held = self.held.get(outcome.path)
        if outcome.rows is None:  # contents indexed already: their rows, under this path and stat
            assert outcome.sha256 is not None and outcome.stat is not None
            same = held is not None and held.sha256 == outcome.sha256
            source = held if same else self.held[self.by_contents[outcome.stat.size_bytes][outcome.sha256]]
            if source.path == outcome.path and source.stat == outcome.stat:
                self.summary.unchanged += 1  # verified: nothing to rewrite
            else:
                if held is not None:
                    self._replace(held)
                self.moved.setdefault(source.part, []).append((source.path, outcome.path, outcome.stat))
                self.summary.same_contents += 1
        else:
            if held is not None:
                self._replace(held)
            writer.add(outcome.rows)
            self.summary.statuses[outcome.status] = self.summary.statuses.get(outcome.status, 0) + 1
            if outcome.error is not None:
                self.summary.problems.append((outcome.path, outcome.status, outcome.error))
        if self.progress is not None:
            self.progress.done(outcome)
