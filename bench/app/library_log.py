"""The log records of the drivers and libraries (the links' warnings, pymodbus's retries with its
raw frames in hex) go to a file beside the output, never to the terminal, where they would cut into
the status line and read as garbage to the person at it.

Without a handler of its own a Python program prints every warning to standard error (logging's
"last resort"); a command that drives devices installs this one instead, for as long as it runs, and
says afterwards whether anything was written (the file is created only when there is).
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

#: How each record reads in the file.
LOG_FORMAT = "%(asctime)s %(name)s %(levelname)s: %(message)s"


def log_beside(out: Path) -> Path:
    """The log file of a command that writes ``out``: ``out`` with ``.log`` added."""
    return out.with_name(out.name + ".log")


@dataclass
class LibraryLog:
    """The log file of a command's run: ``path``, and once the run ended, ``written``: whether it
    holds records of this run."""

    path: Path
    written: bool = False


@contextmanager
def library_log(path: Path, level: int = logging.WARNING) -> Iterator[LibraryLog]:
    """Records of ``level`` and above go to ``path`` (appended; created at the first record) while
    the block runs; the handler is removed and the file closed at its end, whatever the end."""
    size_before = path.stat().st_size if path.exists() else 0
    handler = logging.FileHandler(path, delay=True)
    handler.setFormatter(logging.Formatter(LOG_FORMAT))
    handler.setLevel(level)
    root = logging.getLogger()
    level_before = root.level
    root.addHandler(handler)
    root.setLevel(min(level, level_before))
    log = LibraryLog(path)
    try:
        yield log
    finally:
        root.removeHandler(handler)
        root.setLevel(level_before)
        handler.close()
        log.written = path.exists() and path.stat().st_size > size_before
