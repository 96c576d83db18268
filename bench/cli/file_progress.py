"""The progress bar of a job over many files, on standard error."""

from __future__ import annotations

import sys
from typing import Protocol


class Done(Protocol):
    """A file done: its ``error`` (None when it was done fully)."""

    @property
    def error(self) -> str | None: ...


class FileBar:
    """A progress bar on standard error while a job over files runs (``wfsbench index``, ``wfsbench
    compensate`` over folders): files done of those to read so far (the folders are walked as the
    files are read, so the total grows until the walk ends), and how many were not done (``not_done``:
    the words for them)."""

    def __init__(self, label: str, not_done: str) -> None:
        from rich.progress import BarColumn, MofNCompleteColumn, TimeElapsedColumn

        from bench.app.live_display import progress_display

        self.progress = progress_display(
            sys.stderr,
            label,
            BarColumn(),
            MofNCompleteColumn(),
            TimeElapsedColumn(),
            text="{task.fields[problems]}",
        )
        self.task = self.progress.add_task(label, total=0, problems="")
        self.not_done = not_done
        self.to_read = self.problems = 0

    def listed(self, path: str, *, to_read: bool) -> None:
        if to_read:
            self.to_read += 1
            self.progress.update(self.task, total=self.to_read)

    def done(self, outcome: Done) -> None:
        if outcome.error is not None:
            self.problems += 1
        self.progress.update(
            self.task, advance=1, problems=f"{self.problems} {self.not_done}" if self.problems else ""
        )
