"""One CSV file of another acquisition system's export read into SI channels (docs/import.md).

The layouts labs export are taken as they come: a units row under the header, a delimiter at the
end of the lines (data rows only, or every line), units spelt with non-ASCII characters (``m/s²``,
``µm``), a byte-order mark, blank lines at the end. A mapped column the file lacks is not an error
here: the run decides whether its kind needs that channel (:mod:`bench.store.csv_import`).

The data rows are read :data:`BLOCK_ROWS` at a time, each block's columns converted at once (numpy
parses a column's fields); only a column that fails is walked value by value, to name the first bad
field's line. Every error names the file, the line (counting from 1, lines skipped before the
header included) and the column.
"""

from __future__ import annotations

import codecs
import csv
import itertools
import math
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol, TextIO

import numpy as np

from bench.store.csv_mapping import ChannelColumn, Dialect, Timing
from bench.store.csv_units import TIME_UNIT, UNITS, known_units, unit_named

#: Largest deviation of one time step from the mean step, relative, before a time column is refused.
TIME_STEP_TOLERANCE = 0.01
_HEADER_UNIT = re.compile(r"\[([^\]]*)\]\s*$")
_BRACKETED = re.compile(r"^[\[(](.*)[\])]$")
#: The name of the time column among a table's columns while it is read.
_TIME = ""
#: Data rows read and converted at a time: a long continuous file never lies in memory whole as
#: text and Python strings, and a block's rows stay small (blocks of 65536 rows, tens of MB of
#: Python objects, made a continuous file 1.1-1.9x slower per MB than one file per dwell, with the
#: garbage collector on or off; 4096 rows: 0.6-1.0x, benchmarks/csv_import_speed.py).
BLOCK_ROWS = 4096
#: The largest magnitude a measured value may have in its SI unit (N, m, m/s^2, s): far beyond any
#: sensor's range, far below where float32 storage and the compensation's sums overflow. A value
#: beyond is a damaged cell or a wrong unit or scale, never a measurement.
LARGEST_SI_VALUE = 1e15
#: Time values checked at a time for an even step (a column kept on disk is read in such blocks).
TIME_BLOCK = 1 << 18


class CsvError(ValueError):
    """A CSV file that cannot be imported: the message names the file, the line and the column."""

    def __init__(self, path: Path, line: int | None, column: str | None, message: str) -> None:
        where = "".join(
            [f": line {line}" if line is not None else "", f", column {column!r}" if column else ""]
        )
        super().__init__(f"{path}{where}: {message}")
        self.path, self.line, self.column = path, line, column


@dataclass(frozen=True)
class CsvTable:
    """One CSV file read: its mapped ``columns`` that it has, by channel name, in SI units
    (float64 arrays, or what the reader's sink keeps: :class:`ColumnSink`), its ``header`` (the
    columns' names, on line ``header_line``), ``sample_rate_hz``,
    ``start_s``: the time of its first row (its time column's first value; 0 without one)."""

    path: Path
    header: tuple[str, ...]
    header_line: int
    columns: dict[str, Column]
    sample_rate_hz: float
    n_rows: int
    start_s: float = 0.0

    @property
    def length_s(self) -> float:
        return self.n_rows / self.sample_rate_hz

    def missing(self, channel: ChannelColumn, why: str = "") -> CsvError:
        """The error of this file lacking ``channel``'s column (``why``: what makes it an error)."""
        has = ", ".join(self.header)
        return CsvError(self.path, self.header_line, channel.column, f"missing{why} (the header has: {has})")


class Column(Protocol):
    """A column read: sliced like a 1-D array, with a ``size`` (an array, or one kept on disk)."""

    @property
    def size(self) -> int: ...

    def __getitem__(self, index: slice) -> np.ndarray: ...


class ColumnSink(Protocol):
    """Where the reader puts each column's converted blocks, in order, and what it makes of them."""

    def add(self, channel: str, values: np.ndarray) -> None: ...

    def column(self, channel: str) -> Column: ...


class InMemory:
    """Each column's blocks joined into one array (a file that fits in memory: the import)."""

    def __init__(self) -> None:
        self._parts: dict[str, list[np.ndarray]] = {}

    def add(self, channel: str, values: np.ndarray) -> None:
        self._parts.setdefault(channel, []).append(values)

    def column(self, channel: str) -> np.ndarray:
        return np.concatenate(self._parts.get(channel, [np.empty(0)]))


def read_csv(
    path: Path,
    dialect: Dialect,
    timing: Timing,
    channels: tuple[ChannelColumn, ...],
    sink: Callable[[], ColumnSink] = InMemory,
) -> CsvTable:
    """The columns of ``channels`` that the CSV file at ``path`` has, in SI units, with its sample
    rate (``timing``: a rate, or a time column the file must have); each column's blocks go to a
    new ``sink`` (default: joined in memory)."""
    # a UTF-8 file may start with a byte-order mark (spreadsheet programs write one): not a header
    utf8 = codecs.lookup(dialect.encoding).name == "utf-8"
    try:
        with path.open(newline="", encoding="utf-8-sig" if utf8 else dialect.encoding) as f:
            return _read(path, f, dialect, timing, channels, sink=sink())
    except OSError as exc:
        raise CsvError(path, None, None, f"cannot be read: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise CsvError(path, None, None, f"not {dialect.encoding} text: {exc.reason}") from None


@dataclass(frozen=True)
class _Wanted:
    """A column to read: field ``index`` of each row, named ``column``, into ``channel`` (the time
    column: ""), times ``factor`` to its SI unit."""

    channel: str
    column: str
    index: int
    factor: float


def _read(
    path: Path,
    f: TextIO,
    dialect: Dialect,
    timing: Timing,
    channels: tuple[ChannelColumn, ...],
    *,
    sink: ColumnSink,
) -> CsvTable:
    """:func:`read_csv` on the open file ``f``, its data rows read and converted a block at a time."""
    for _ in range(dialect.skip_lines):
        f.readline()
    reader = csv.reader(f, delimiter=dialect.delimiter)
    header_line = dialect.skip_lines + 1
    header = [name.strip() for name in _without_end_delimiter(next(reader, []), None)]
    if not any(header):
        raise CsvError(path, header_line, None, "empty file: no header line")
    units: list[str | None] = [None] * len(header)
    units_line = None
    if dialect.units_row:
        units_line = header_line + 1
        units = _units_row(path, next(reader, None), units_line, len(header))
    wanted = _wanted(
        path, header, units, header_line=header_line, units_line=units_line, timing=timing, channels=channels
    )
    data_line = header_line + 1 + dialect.units_row
    n_rows, blank_line = 0, None
    while rows := list(itertools.islice(reader, BLOCK_ROWS)):
        first_line = data_line + n_rows
        if blank_line is not None and any("".join(row).strip() for row in rows):
            raise CsvError(path, blank_line, None, "a blank line amid the data rows")  # not the file's end
        rows, blank = _rows(path, rows, first_line, len(header))
        blank_line = blank_line or blank
        converted_columns = _converted(path, rows, first_line, wanted, dialect.decimal)
        for channel, converted in converted_columns.items():
            sink.add(channel, converted)
        n_rows += len(rows)
    if not n_rows:
        raise CsvError(path, data_line, None, "no data rows after the header")
    values = {w.channel: sink.column(w.channel) for w in wanted}
    if timing.column is None:
        rate, start_s = timing.sample_rate_hz, 0.0
    else:
        time_s = values.pop(_TIME)
        rate, start_s = _rate_from_time(path, data_line, timing.column, time_s), float(time_s[0:1][0])
    return CsvTable(path, tuple(header), header_line, values, rate, n_rows, start_s)


def _converted(
    path: Path, rows: list[list[str]], first_line: int, wanted: list[_Wanted], decimal: str
) -> dict[str, np.ndarray]:
    """A block's wanted columns in SI units, or the error of its first bad field (by line)."""
    problems = []
    converted_columns: dict[str, np.ndarray] = {}
    for w in wanted:
        values = _column(path, [row[w.index] for row in rows], first_line, w.column, decimal)
        if isinstance(values, CsvError):
            problems.append(values)
            continue
        converted = values * w.factor
        beyond = np.flatnonzero(~(np.abs(converted) <= LARGEST_SI_VALUE))
        if beyond.size:
            k = beyond[0]
            problems.append(
                CsvError(
                    path,
                    first_line + k,
                    w.column,
                    f"{rows[k][w.index].strip()!r} is {converted[k]:.3g} in SI units (its unit and scale"
                    f" applied): beyond +/-{LARGEST_SI_VALUE:g}, no measured value (a damaged cell, or"
                    " a wrong unit or scale in the mapping)",
                )
            )
            continue
        converted_columns[w.channel] = converted
    if problems:
        raise min(problems, key=lambda e: e.line)
    return converted_columns


def _without_end_delimiter(fields: list[str], n: int | None) -> list[str]:
    """``fields`` without the blank one after a delimiter that ends the line (spaces aside): of a
    header (``n`` None: its columns unknown), or of a line under a header of ``n`` columns when
    it has one field more."""
    if len(fields) > 1 and not fields[-1].strip() and (n is None or len(fields) == n + 1):
        fields.pop()
    return fields


def _units_row(path: Path, fields: list[str] | None, line: int, n: int) -> list[str | None]:
    """The units row's fields, one per column (None where it is blank)."""
    if fields is None:
        raise CsvError(path, line, None, "no units row after the header (csv.units_row)")
    fields = _without_end_delimiter(fields, n)
    if len(fields) != n:
        raise CsvError(path, line, None, f"the units row has {len(fields)} fields where the header has {n}")
    return [field.strip() or None for field in fields]


def _wanted(
    path: Path,
    header: list[str],
    units: list[str | None],
    *,
    header_line: int,
    units_line: int | None,
    timing: Timing,
    channels: tuple[ChannelColumn, ...],
) -> list[_Wanted]:
    """The mapped columns the header has, with their units checked (and the time column, which
    it must have)."""
    specs = [(c.channel, c.column, c.unit, c.si_unit, c.scale) for c in channels if c.column in header]
    if timing.column is not None:
        if timing.column not in header:
            raise CsvError(path, header_line, timing.column, f"missing (the header has: {', '.join(header)})")
        specs.append((_TIME, timing.column, timing.unit, TIME_UNIT, 1.0))
    wanted = []
    for channel, column, mapped, si_unit, scale in specs:
        i = header.index(column)
        unit, line = _unit(path, column, mapped, units[i], header_line=header_line, units_line=units_line)
        if UNITS[unit][0] != si_unit:
            raise CsvError(
                path, line, column, f"unit {unit} is not a unit of {si_unit} ({channel or 'time'})"
            )
        wanted.append(_Wanted(channel, column, i, UNITS[unit][1] * scale))
    return wanted


def _unit(
    path: Path,
    column: str,
    mapped: str | None,
    stated: str | None,
    *,
    header_line: int,
    units_line: int | None,
) -> tuple[str, int]:
    """A column's unit (a key of :data:`UNITS`) and the line that gives it: the mapping's, else the
    file's: its units row's field (``mm``, ``[mm]``, ``(mm)``; ``units_line`` None: no units row) or
    the brackets at the end of its header (``Weg [mm]``). A known unit the file states must be the
    mapping's."""
    line = units_line or header_line
    if stated is None and (found := _HEADER_UNIT.search(column)) is not None:
        stated, line = found.group(1), header_line
    if stated is not None:
        bracketed = _BRACKETED.match(stated.strip())
        stated = (bracketed.group(1) if bracketed else stated).strip()
    known = None if stated is None else unit_named(stated)
    if mapped is None:
        if stated is None:
            raise CsvError(
                path, line, column, "no unit in the mapping and none in the file (units row, [unit])"
            )
        if known is None:
            raise CsvError(path, line, column, f"unknown unit {stated!r} (known: {known_units()})")
        return known, line
    if known is not None and known != mapped:
        raise CsvError(path, line, column, f"the file gives the unit {stated}, the mapping {mapped}")
    return mapped, line


def _rows(path: Path, rows: list[list[str]], first_line: int, n: int) -> tuple[list[list[str]], int | None]:
    """A block of data rows, each of ``n`` fields (one more, blank, where the line ends with a
    delimiter), without the blank lines at its end; and the line of the first of those (None: none),
    which must be the file's end."""
    if list(map(len, rows)).count(n) == len(rows):
        return rows, None
    end = len(rows)
    while end and not "".join(rows[end - 1]).strip():
        end -= 1
    for k, row in enumerate(rows[:end]):
        if len(_without_end_delimiter(row, n)) == n:
            continue
        if not "".join(row).strip():
            raise CsvError(path, first_line + k, None, "a blank line amid the data rows")
        fields = f"{len(row)} field{'s' * (len(row) != 1)}"
        raise CsvError(path, first_line + k, None, f"{fields} where the header has {n}")
    return rows[:end], (first_line + end if end < len(rows) else None)


def _column(
    path: Path, texts: list[str], first_line: int, column: str, decimal: str
) -> np.ndarray | CsvError:
    """A column's fields ``texts`` (the first on line ``first_line``) as numbers, or the error of
    its first bad field (numpy converts the column at once; a column it refuses is read field by
    field to find that field)."""
    numbers = texts
    if decimal == ",":
        joined = "\n".join(texts)
        if "." in joined:
            k = next(k for k, text in enumerate(texts) if "." in text)
            return CsvError(
                path, first_line + k, column, f"{texts[k]!r}: a '.' where the decimal mark is ','"
            )
        numbers = joined.replace(",", ".").split("\n")
    try:
        values = np.array(numbers, dtype=np.float64)
    except ValueError:
        values = None
    if values is not None and np.isfinite(values).all():
        return values
    parsed = []
    for k, (text, number) in enumerate(zip(texts, numbers, strict=True)):
        try:
            parsed.append(float(number))
        except ValueError:
            return CsvError(path, first_line + k, column, f"{text!r} is not a number")
        if not math.isfinite(parsed[-1]):
            return CsvError(path, first_line + k, column, f"{text!r} is not a finite number")
    return np.array(parsed)


def _rate_from_time(path: Path, first_line: int, column: str, t: Column) -> float:
    """The sample rate of a time column (s), which must step evenly forward: a time that does not
    come after the one before it, or a step off the mean step, is refused naming its line. The
    column is read :data:`TIME_BLOCK` values at a time (with the value before each block)."""
    n = t.size
    if n < 2:
        raise CsvError(path, first_line, column, "a time column needs at least two rows")
    step = (float(t[n - 1 : n][0]) - float(t[0:1][0])) / (n - 1)
    for start, steps in _steps(t):
        back = np.flatnonzero(steps <= 0)
        if len(back):  # a time that stands or goes back: the line where it does
            k = int(back[0])
            before, after = t[start + k : start + k + 2]
            raise CsvError(
                path, first_line + start + k + 1, column, f"time {after:g} s does not come after {before:g} s"
            )
    for start, steps in _steps(t):
        off = np.flatnonzero(np.abs(steps - step) > TIME_STEP_TOLERANCE * abs(step))
        if len(off):
            k = start + int(off[0]) + 1
            why = f"time steps unevenly (mean step {step:g} s): not one sample rate"
            raise CsvError(path, first_line + k, column, why)
    return 1.0 / step


def _steps(t: Column) -> Iterator[tuple[int, np.ndarray]]:
    """The steps of the time column ``t`` from each block's ``start``: ``t[start + k + 1] -
    t[start + k]``, :data:`TIME_BLOCK` at a time."""
    for start in range(0, t.size - 1, TIME_BLOCK):
        yield start, np.diff(np.asarray(t[start : start + TIME_BLOCK + 1], dtype=float))
