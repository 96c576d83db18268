"""The exit codes of every ``wfsbench`` command: one table, one meaning per code (docs/cli.md).

A script that drives the bench branches on these; a command never gives a code another meaning.
"""

from __future__ import annotations

from enum import IntEnum

from bench.locks import InUseError


class ExitCode(IntEnum):
    """What a ``wfsbench`` command's exit status means, whatever the command."""

    #: Done, all of it: the sequence complete and every run's analysis complete, the file written,
    #: the report or the index made.
    OK = 0
    #: Stopped before the end: a run aborted (Ctrl-C, SIGTERM, SIGHUP), e-stopped, interlocked or
    #: failed (its file holds the data so far, marked); an interrupted command; a reset declined or
    #: one that left the controller interlocked.
    STOPPED = 1
    #: Something the command needs is unavailable: a device could not be reached or was found
    #: moving, or a device, a campaign file or an index is held by another process (a run writing
    #: the file), or the Dask scheduler could not be reached. Nothing was changed.
    UNAVAILABLE = 2
    #: Invalid input: the command line, a sequence, configuration, answers, mapping or CSV file, a
    #: file that is no campaign file, an output that exists or cannot be written. Nothing was
    #: opened, moved or written.
    INVALID = 3
    #: Refused: valid input asking for what the bench or the campaign cannot do: the dry run refused
    #: a point (or a step the bench cannot do); the campaign does not cover a measurement to
    #: compensate. Nothing was opened, moved or written.
    REFUSED = 4
    #: Done, but not all that was asked: a run's analysis failed or is partial (each named with
    #: why), or the file holds no complete run to analyse.
    INCOMPLETE = 5
    #: Analysed and printed, but the results could not be stored in the file (read-only).
    NOT_STORED = 6


def unreadable_file_code(exc: Exception) -> ExitCode:
    """The code for a file a command cannot read: UNAVAILABLE while another process holds it (a run
    writing a campaign file), else INVALID (missing, not HDF5, damaged, another layout)."""
    return ExitCode.UNAVAILABLE if isinstance(exc, InUseError) else ExitCode.INVALID
