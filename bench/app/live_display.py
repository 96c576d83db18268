"""The command line's one live progress display (rich), shared by ``wfsbench run`` and
``wfsbench index``: one line per task below what the command prints, cut at the terminal's width
(never wrapped onto a second line, which a redraw in place could not take back) and gone at its end.
"""

from __future__ import annotations

import os
from typing import Any, TextIO

from rich.console import Console
from rich.progress import Progress, ProgressColumn, TextColumn
from rich.table import Column

#: ``TERM`` of a terminal that cannot erase a line (an editor's shell buffer), as rich reads it.
DUMB_TERMINALS = ("dumb", "unknown")


def redraws_in_place(stream: TextIO) -> bool:
    """Whether ``stream`` is a terminal that can redraw a line in place: a terminal, and not a dumb
    one (a pipe, a log file and a dumb terminal take plain lines instead)."""
    return stream.isatty() and os.environ.get("TERM", "").lower() not in DUMB_TERMINALS


def progress_display(
    stream: TextIO,
    *columns: str | ProgressColumn,
    text: str,
    interactive: bool | None = None,
    **options: Any,
) -> Progress:
    """A transient rich progress display on ``stream``: ``columns``, then ``text`` (a task's format,
    as rich's :class:`~rich.progress.TextColumn` takes it, without markup), which takes the rest of
    the line and is cut at its end with an ellipsis.

    ``interactive``: redraw in place whatever rich makes of ``stream`` (the caller has decided that
    it is a terminal; a test's stream); None: as rich detects it. ``options``: rich's
    :class:`~rich.progress.Progress` options (``auto_refresh``, ``redirect_stdout``, ``get_time``)."""
    console = Console(file=stream, force_terminal=interactive, force_interactive=interactive)
    rest = Column(ratio=1, no_wrap=True, overflow="ellipsis")
    last = TextColumn(text, markup=False, table_column=rest)
    return Progress(*columns, last, console=console, transient=True, expand=True, **options)
