"""A compensation job: which measurements to compensate, compensate them on an executor, keep the
summary (docs/compensate.md, *Many measurements*).

The client (the process that runs ``wfsbench compensate ... --out DIR``) walks the folders and
compares each measurement file (MDF4, CSV) with the summary held: a file of the same path, size and
modification time compensated with the same identification (:func:`identification`: the campaign
file's path, size and time, the options, the software) whose outcome was final is not read again.
The others go, as :class:`~bench.fleet.worker.MeasurementTask` values (paths and settings: plain
data), to :func:`~bench.fleet.worker.compensate_files`, one file a task (a measurement takes
seconds: a task's overhead is small beside it), on an executor of :mod:`bench.cluster`; a job with
nothing to do starts no cluster. The summary is replaced whole at the end, one run per output
folder at a time (its lock, :mod:`bench.locks`).
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Iterator, Sequence
from dataclasses import asdict, dataclass, field
from itertools import islice
from pathlib import Path
from typing import Protocol

from bench import locks
from bench.archive.files import FileStat, find_files, within
from bench.cluster import Executor
from bench.fleet.summary import TRIED_AGAIN, Row, Status, read_summary, write_summary
from bench.fleet.worker import WORKER_IMPORTS, MeasurementOutcome, MeasurementTask, Settings, compensate_files
from bench.store.channel_file import MDF_SUFFIXES

#: The measurement files a folder is searched for (any case).
MEASUREMENT_SUFFIXES = (*MDF_SUFFIXES, ".csv")
#: How the outputs are named: the measurement's path relative to its folder, and these.
HDF5_SUFFIX, MDF4_SUFFIX = ".compensated.h5", ".compensated.mf4"
#: Measurements a task compensates: one (each takes seconds).
FILES_PER_TASK = 1


def identification(settings: Settings) -> str:
    """The key of what a measurement is compensated with: the campaign file's path, size and time
    (not its bytes: nothing is read to know it is unchanged), the mapping's likewise, the options
    and the software's version; a SHA-256, hex."""
    from bench.app.version import software_version

    def stat(path: str | None) -> list[int] | None:
        return None if path is None else list(asdict(FileStat.of(path)).values())

    named = {
        **asdict(settings),
        "identification": None,
        "campaign_stat": stat(settings.campaign),
        "mapping_stat": stat(settings.mapping),
        "software": software_version(),
    }
    return hashlib.sha256(json.dumps(named, sort_keys=True).encode()).hexdigest()


class Progress(Protocol):
    """Told of each file as the job lists it and as it is done."""

    def listed(self, path: str, *, to_read: bool) -> None: ...

    def done(self, outcome: MeasurementOutcome) -> None: ...


@dataclass
class JobSummary:
    """What a job did: files found, files not read again (``unchanged``), files read by status
    (``statuses``), rows of files gone from the folders (``removed``), the summary's path, and
    every file not compensated with its status and error (``problems``)."""

    found: int = 0
    unchanged: int = 0
    statuses: dict[str, int] = field(default_factory=dict)
    removed: int = 0
    summary: Path | None = None
    problems: list[tuple[str, str, str]] = field(default_factory=list)


def compensate_many(
    roots: Sequence[Path],
    out_dir: Path,
    settings: Settings,
    executor: Executor,
    *,
    progress: Progress | None = None,
) -> JobSummary:
    """Compensate the measurements under ``roots`` (folders, searched recursively, or files) into
    ``out_dir`` with ``settings``; the summary ``out_dir/summary.parquet`` brought up to date."""
    out_dir = Path(out_dir)
    with locks.holding(locks.file_key(out_dir), f"the compensation output {out_dir}"):
        out_dir.mkdir(parents=True, exist_ok=True)
        held = read_summary(out_dir)
        return _Job(roots, out_dir, settings, held, progress).run(executor)


class _Job:
    """One run: the plan against the summary held, the outcomes taken, the summary replaced."""

    def __init__(
        self,
        roots: Sequence[Path],
        out_dir: Path,
        settings: Settings,
        held: dict[str, Row],
        progress: Progress | None,
    ) -> None:
        self.roots, self.out_dir, self.settings, self.held = roots, out_dir, settings, held
        self.progress = progress
        self.rows: dict[str, Row] = {}
        self.outputs: dict[str, str] = {}  # output (relative) -> the measurement it is of
        self.summary = JobSummary()

    def run(self, executor: Executor) -> JobSummary:
        tasks = self._tasks()
        batches = iter(lambda: list(islice(tasks, FILES_PER_TASK)), [])
        for outcomes in executor.run(compensate_files, batches, WORKER_IMPORTS):
            for outcome in outcomes:
                self._take(outcome)
        for path, row in self.held.items():
            if path in self.rows:
                continue
            if within(path, self.roots):
                self.summary.removed += 1  # gone from the folders: its row goes (its outputs stay)
            else:
                self.rows[path] = row  # a file of another job's folders
        self.summary.summary = write_summary(self.out_dir, list(self.rows.values()))
        return self.summary

    def _tasks(self) -> Iterator[MeasurementTask]:
        for root in self.roots:
            for path in find_files([root], MEASUREMENT_SUFFIXES):
                if path in self.rows:
                    continue  # under two of the folders given
                try:
                    stat = FileStat.of(path)
                except OSError:
                    continue  # gone between the folder's listing and its stat
                task = self._task(root, path, stat)
                if task is not None:
                    yield task

    def _task(self, root: Path, path: str, stat: FileStat) -> MeasurementTask | None:
        """The task of ``path``, or None when it is unchanged (its row kept) or its outputs would
        be another file's (refused)."""
        self.summary.found += 1
        held = self.held.get(path)
        unchanged = (
            held is not None
            and FileStat(held["size_bytes"], held["mtime_ns"]) == stat
            and held["identification"] == self.settings.identification
            and held["status"] not in TRIED_AGAIN
        )
        if self.progress is not None:
            self.progress.listed(path, to_read=not unchanged)
        top = os.path.abspath(root)
        relative = os.path.relpath(path, top) if os.path.isdir(top) else os.path.basename(path)
        other = self.outputs.setdefault(relative, path)
        if unchanged:
            assert held is not None
            self.rows[path] = held
            self.summary.unchanged += 1
            return None
        task = MeasurementTask(
            path,
            stat,
            str(self.out_dir / (relative + HDF5_SUFFIX)),
            str(self.out_dir / (relative + MDF4_SUFFIX)),
            relative + HDF5_SUFFIX,
            relative + MDF4_SUFFIX,
            self.settings,
        )
        if other != path:
            error = f"its outputs would be those of {other} (the same name under another folder): not written"
            self._take(
                MeasurementOutcome(
                    {
                        "path": path,
                        "size_bytes": stat.size_bytes,
                        "mtime_ns": stat.mtime_ns,
                        "status": Status.REFUSED,
                        "error": error,
                        "identification": self.settings.identification,
                        "campaign": self.settings.campaign,
                    }
                )
            )
            return None
        return task

    def _take(self, outcome: MeasurementOutcome) -> None:
        self.rows[outcome.path] = outcome.row
        self.summary.statuses[outcome.status] = self.summary.statuses.get(outcome.status, 0) + 1
        if outcome.error is not None:
            self.summary.problems.append((outcome.path, outcome.status, outcome.error))
        if self.progress is not None:
            self.progress.done(outcome)
