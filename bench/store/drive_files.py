"""A road replay's drive file read into displacement samples at one rate (docs/sequences.md,
*Road replay*): a CSV file or an MTS RPC III time history.

- **CSV** (``.csv``), the import's conventions (docs/import.md) in its default dialect: UTF-8,
  ``,`` between fields, ``.`` as the decimal mark, a header line naming the columns; each column's
  unit in brackets at the end of its name (``t [s]``, ``z [mm]``) or in a units row under the
  header (as ``wfsbench export --format csv`` writes it: the line under the header is a units row
  when every field of it is a known unit or blank). The time column (by default the first) must
  step evenly forward in a unit of time; the displacement column (by default the only other one)
  must be in a unit of length. A cell that is no number, a time that goes back or steps unevenly,
  a unit of another quantity: refused naming the file, the line and the column.
- **RPC III** (``.rsp``, ``.drv``, ``.tim``, ``.rpc``; :mod:`bench.store.rpc3`): the channel
  named (its ``DESC.CHAN_n``; by default the only channel), its ``UNITS.CHAN_n`` a unit of length,
  at the file's ``DELTA_T``. An RPC III file fills its last frame up: a drive exported by this
  project carries up to one frame less a point of its last value at the end.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench.store.csv_mapping import ChannelColumn, Dialect, Timing
from bench.store.csv_read import CsvError, read_csv
from bench.store.csv_units import UNITS, known_units, unit_named
from bench.store.rpc3 import Rpc3Error, read_rpc3

CSV_SUFFIXES = (".csv",)
RPC3_SUFFIXES = (".rsp", ".drv", ".tim", ".rpc")
#: The displacement's name while it is read (its SI unit: m).
_DISPLACEMENT = "z_drive_m"


class DriveFileError(ValueError):
    """A drive file that cannot be played: the message names the file and where in it."""


@dataclass(frozen=True)
class DriveSamples:
    """A drive as read: ``displacement_m`` at ``sample_rate_hz``, from ``source`` (the file and the
    column or channel)."""

    displacement_m: np.ndarray
    sample_rate_hz: float
    source: str


def read_drive_file(path: str | Path, *, channel: str = "", time_column: str = "") -> DriveSamples:
    """The drive in ``path`` (by its suffix: see the module docstring); ``channel`` names its
    displacement column or channel and ``time_column`` a CSV file's time column (empty: the
    defaults). :class:`DriveFileError` naming the file and where."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix in CSV_SUFFIXES:
        return _csv(path, channel, time_column)
    if time_column:
        raise DriveFileError(f"{path}: time_column names a CSV file's time column; an RPC III file has none")
    if suffix in RPC3_SUFFIXES:
        return _rpc3(path, channel)
    known = ", ".join((*CSV_SUFFIXES, *RPC3_SUFFIXES))
    raise DriveFileError(f"{path}: unknown drive file format {suffix!r}: CSV or RPC III ({known})")


def _csv(path: Path, channel: str, time_column: str) -> DriveSamples:
    header, units_row = csv_header(path)
    time_column = time_column or header[0]
    if time_column not in header:
        raise DriveFileError(
            f"{path}: line 1: no time column {time_column!r} (the header has: {', '.join(header)})"
        )
    others = [name for name in header if name != time_column]
    channel = channel or _the_only(
        others, f"{path}: line 1", f"columns besides the time column {time_column!r}"
    )
    column = ChannelColumn(_DISPLACEMENT, "m", channel, None)
    try:
        table = read_csv(path, Dialect(units_row=units_row), Timing(column=time_column), (column,))
    except CsvError as exc:
        raise DriveFileError(str(exc)) from None
    if _DISPLACEMENT not in table.columns:
        raise DriveFileError(str(table.missing(column)))
    return DriveSamples(table.columns[_DISPLACEMENT], table.sample_rate_hz, f"{path} column {channel!r}")


def _the_only(names: list[str], where: str, what: str) -> str:
    """The displacement's column or channel when the step names none: the only one there is."""
    if len(names) != 1:
        raise DriveFileError(
            f"{where}: which is the displacement? {len(names)} {what}: name one as the step's channel"
            f" ({', '.join(names)})"
        )
    return names[0]


def csv_header(path: Path) -> tuple[list[str], bool]:
    """The CSV file's column names and whether the line under them is a units row."""
    try:
        with path.open(newline="", encoding="utf-8-sig") as f:
            reader = csv.reader(f)
            header = [name.strip() for name in next(reader, [])]
            second = next(reader, [])
    except OSError as exc:
        raise DriveFileError(f"{path}: cannot be read: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise DriveFileError(f"{path}: not UTF-8 text: {exc.reason}") from None
    if len(header) > 1 and not header[-1]:
        header.pop()  # a delimiter at the end of the line
    if not any(header):
        raise DriveFileError(f"{path}: line 1: empty file: no header line")
    fields = [field.strip() for field in second]
    units_row = bool(fields) and all(not f or unit_named(f.strip("[]()")) for f in fields) and any(fields)
    return header, units_row


def _rpc3(path: Path, channel: str) -> DriveSamples:
    try:
        rpc = read_rpc3(path)
    except Rpc3Error as exc:
        raise DriveFileError(str(exc)) from None
    names = [c.name for c in rpc.channels]
    channel = channel or _the_only(names, str(path), "channels")
    if channel not in names:
        raise DriveFileError(f"{path}: no channel {channel!r} (DESC.CHAN_n: {', '.join(names)})")
    k = names.index(channel)
    found = rpc.channels[k]
    unit = unit_named(found.unit) if found.unit.strip() else None
    if unit is None or UNITS[unit][0] != "m":
        raise DriveFileError(
            f"{path}: UNITS.CHAN_{k + 1} of {channel!r} is {found.unit!r}, not a unit of length"
            f" (known: {known_units()})"
        )
    return DriveSamples(found.values * UNITS[unit][1], rpc.sample_rate_hz, f"{path} channel {channel!r}")
