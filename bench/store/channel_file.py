"""One channel of a time-history file read into samples at one rate, in an SI unit: what a road
replay plays (a displacement, :mod:`bench.store.drive_files`) and what a drive iteration aims at (a
force or an acceleration, :mod:`bench.store.iteration_target`) are read alike.

- **CSV** (``.csv``), the import's conventions (docs/import.md) in its default dialect: UTF-8,
  ``,`` between fields, ``.`` as the decimal mark, a header line naming the columns; each column's
  unit in brackets at the end of its name (``t [s]``, ``z [mm]``) or in a units row under the
  header (as ``wfsbench export --format csv`` writes it: the line under the header is a units row
  when none of its fields is a number). The time column (by default the first) must
  step evenly forward in a unit of time; the channel's column (by default the only other one) must
  be in a unit of the channel's quantity. A cell that is no number, a time that goes back or steps
  unevenly, a unit of another quantity: refused naming the file, the line and the column.
- **RPC III** (``.rsp``, ``.drv``, ``.tim``, ``.rpc``; :mod:`bench.store.rpc3`): the channel named
  (its ``DESC.CHAN_n``; by default the only channel) in its ``UNITS.CHAN_n``, at the file's
  ``DELTA_T``. An RPC III file fills its last frame up: a drive exported by this project carries up
  to one frame less a point of its last value at the end.
- **MDF4** (``.mf4``, ``.mdf``), where the reader takes it: the channel named (by default the only
  one besides a time channel) in its unit, its time stamps stepping evenly.

A unit given by the step replaces the file's. The step's keys are named where it must say more
(which channel, which unit): :class:`ChannelFileError` names the file and what is wrong.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench.store.csv_mapping import ChannelColumn, Dialect, Timing
from bench.store.csv_read import TIME_STEP_TOLERANCE, CsvError, read_csv
from bench.store.csv_units import UNITS, known_units, unit_named
from bench.store.rpc3 import Rpc3Error, read_rpc3

CSV_SUFFIXES = (".csv",)
RPC3_SUFFIXES = (".rsp", ".drv", ".tim", ".rpc")
MDF_SUFFIXES = (".mf4", ".mdf", ".mdf4")
#: The quantity an SI unit measures, as an error names it.
QUANTITY_OF = {"m": "length", "N": "force", "m/s^2": "acceleration"}


class ChannelFileError(ValueError):
    """A channel that cannot be read: the message names the file and where in it."""


@dataclass(frozen=True)
class ChannelKeys:
    """What the channel is to the step that reads it, and the step's keys that choose it: ``what``
    (``displacement``, ``target``), the key naming its column or channel, the key giving its unit
    (empty: the step cannot give one, the file's unit is the channel's), and whether MDF4 files
    are read."""

    what: str
    channel_key: str
    unit_key: str = ""
    mdf: bool = False


@dataclass(frozen=True)
class ChannelSamples:
    """A channel as read: ``values`` in its SI unit at ``sample_rate_hz``, from ``source`` (the file
    and its column or channel)."""

    values: np.ndarray
    sample_rate_hz: float
    source: str


@dataclass(frozen=True)
class _Asked:
    """One reading: the file, what the channel is to its step, its SI unit, and what the step
    gives (empty: the defaults)."""

    path: Path
    keys: ChannelKeys
    si_unit: str
    channel: str
    unit: str
    time_column: str

    def the_only(self, names: list[str], where: str, what: str) -> str:
        """The channel when the step names none: the only one there is."""
        if len(names) != 1:
            raise ChannelFileError(
                f"{where}: which is the {self.keys.what}? {len(names)} {what}: name one as the step's"
                f" {self.keys.channel_key} ({', '.join(names)})"
            )
        return names[0]

    @property
    def quantity(self) -> str:
        return f"{QUANTITY_OF.get(self.si_unit, self.si_unit)} ({self.si_unit})"

    def unit_given(self) -> str:
        """The unit the step gives (its ``unit_key``): a known unit of the SI unit."""
        known = unit_named(self.unit.strip("[]() "))
        if known is None:
            raise ChannelFileError(
                f"{self.path}: {self.keys.unit_key} {self.unit!r} is not one of {known_units()}"
            )
        if UNITS[known][0] != self.si_unit:
            raise ChannelFileError(
                f"{self.path}: {self.keys.unit_key} {self.unit} is not a unit of {self.quantity}"
            )
        return known

    def factor(self, channel: str, stated: str, where: str) -> float:
        """The factor to the SI unit from the step's unit, else the file's ``stated`` (at ``where``
        in the file)."""
        if self.unit:
            return UNITS[self.unit_given()][1]
        known = unit_named(stated.strip("[]() ")) if stated.strip() else None
        if known is None or UNITS[known][0] != self.si_unit:
            hint = f"; give its unit as the step's {self.keys.unit_key}" if self.keys.unit_key else ""
            raise ChannelFileError(
                f"{self.path}: {where} of {channel!r} is {stated!r}, not a unit of {self.quantity}"
                f" (known: {known_units()}){hint}"
            )
        return UNITS[known][1]


def read_channel(
    path: Path, keys: ChannelKeys, *, si_unit: str, channel: str = "", unit: str = "", time_column: str = ""
) -> ChannelSamples:
    """The channel ``channel`` of the file at ``path`` (by its suffix: see the module docstring) in
    ``si_unit``; ``unit`` (the step's) replaces the file's, ``time_column`` names a CSV file's time
    column (empty: the defaults)."""
    asked = _Asked(path, keys, si_unit, channel, unit, time_column)
    suffix = path.suffix.lower()
    suffixes = (*CSV_SUFFIXES, *RPC3_SUFFIXES, *(MDF_SUFFIXES if keys.mdf else ()))
    if suffix not in suffixes:
        known = ", ".join(suffixes)
        raise ChannelFileError(f"{path}: unknown {keys.what} file format {suffix!r} (known: {known})")
    if suffix in CSV_SUFFIXES:
        return _csv(asked)
    if time_column:
        raise ChannelFileError(f"{path}: time_column names a CSV file's time column; this file has none")
    return _rpc3(asked) if suffix in RPC3_SUFFIXES else _mdf(asked)


def _csv(asked: _Asked) -> ChannelSamples:
    path = asked.path
    header, units_row = csv_header(path)
    time_column = asked.time_column or header[0]
    if time_column not in header:
        raise ChannelFileError(
            f"{path}: line 1: no time column {time_column!r} (the header has: {', '.join(header)})"
        )
    others = [name for name in header if name != time_column]
    channel = asked.channel or asked.the_only(
        others, f"{path}: line 1", f"columns besides the time column {time_column!r}"
    )
    read = asked.keys.what  # the channel's name while it is read, as an error names it
    column = ChannelColumn(read, asked.si_unit, channel, asked.unit_given() if asked.unit else None)
    try:
        table = read_csv(path, Dialect(units_row=units_row), Timing(column=time_column), (column,))
    except CsvError as exc:
        raise ChannelFileError(str(exc)) from None
    if read not in table.columns:
        raise ChannelFileError(str(table.missing(column)))
    return ChannelSamples(table.columns[read], table.sample_rate_hz, f"{path} column {channel!r}")


def _rpc3(asked: _Asked) -> ChannelSamples:
    path = asked.path
    try:
        rpc = read_rpc3(path)
    except Rpc3Error as exc:
        raise ChannelFileError(str(exc)) from None
    names = [c.name for c in rpc.channels]
    channel = asked.channel or asked.the_only(names, str(path), "channels")
    if channel not in names:
        raise ChannelFileError(f"{path}: no channel {channel!r} (DESC.CHAN_n: {', '.join(names)})")
    k = names.index(channel)
    found = rpc.channels[k]
    factor = asked.factor(channel, found.unit, f"UNITS.CHAN_{k + 1}")
    return ChannelSamples(found.values * factor, rpc.sample_rate_hz, f"{path} channel {channel!r}")


def _mdf(asked: _Asked) -> ChannelSamples:
    from asammdf import MDF  # only here: it takes a second to import

    path = asked.path
    try:
        mdf = MDF(path)
    except Exception as exc:  # asammdf raises many kinds for a file it cannot read
        raise ChannelFileError(f"{path}: not a readable MDF file: {exc}") from None
    with mdf:
        names = sorted(name for name in mdf.channels_db if not name.startswith("$"))
        channel = asked.channel or asked.the_only(
            [n for n in names if n.lower() not in ("t", "time")], str(path), "channels"
        )
        if channel not in mdf.channels_db:
            raise ChannelFileError(f"{path}: no channel {channel!r} (the file has {', '.join(names)})")
        signal = mdf.get(channel)
    t = np.asarray(signal.timestamps, dtype=float)
    where = f"{path}: channel {channel!r}"
    if t.size < 2 or not np.all(np.diff(t) > 0):
        raise ChannelFileError(f"{where}: its time stamps do not step forward")
    step = (t[-1] - t[0]) / (t.size - 1)
    if np.any(np.abs(np.diff(t) - step) > TIME_STEP_TOLERANCE * step):
        raise ChannelFileError(f"{where}: the time stamps step unevenly: not one sample rate")
    values = np.asarray(signal.samples, dtype=float) * asked.factor(channel, str(signal.unit), "its unit")
    return ChannelSamples(values, 1.0 / step, f"{path} channel {channel!r}")


def csv_header(path: Path) -> tuple[list[str], bool]:
    """The CSV file's column names and whether the line under them is a units row: none of its
    fields a number, one at least not blank (the units of columns not read need not be known ones:
    an export's ``rad/s`` and ``V``)."""
    try:
        with path.open(newline="", encoding="utf-8-sig") as f:
            reader = csv.reader(f)
            header = [name.strip() for name in next(reader, [])]
            second = next(reader, [])
    except OSError as exc:
        raise ChannelFileError(f"{path}: cannot be read: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise ChannelFileError(f"{path}: not UTF-8 text: {exc.reason}") from None
    if len(header) > 1 and not header[-1]:
        header.pop()  # a delimiter at the end of the line
    if not any(header):
        raise ChannelFileError(f"{path}: line 1: empty file: no header line")
    fields = [field.strip() for field in second]
    return header, any(fields) and not any(map(_is_number, fields))


def _is_number(field: str) -> bool:
    try:
        float(field)
    except ValueError:
        return False
    return True
