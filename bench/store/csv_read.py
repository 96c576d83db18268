"""One CSV file of another acquisition system's export read into SI channels (docs/import.md).

The layouts labs export are taken as they come: a units row under the header, a delimiter at the
end of the lines (data rows only, or every line), units spelt with non-ASCII characters (``m/s²``,
``µm``), a byte-order mark, blank lines at the end. A mapped column the file lacks is not an error
here: the run decides whether its kind needs that channel (:mod:`bench.store.csv_import`).

A column's numbers are converted at once (numpy parses the whole column); only a column that fails
is walked value by value, to name the first bad field's line. Every error names the file, the line
(counting from 1, lines skipped before the header included) and the column.
"""

from __future__ import annotations

import codecs
import csv
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench.store.csv_mapping import ChannelColumn, Dialect, Timing
from bench.store.csv_units import UNITS, known_units, unit_named

#: Largest deviation of one time step from the mean step, relative, before a time column is refused.
TIME_STEP_TOLERANCE = 0.01
_HEADER_UNIT = re.compile(r"\[([^\]]*)\]\s*$")
_BRACKETED = re.compile(r"^[\[(](.*)[\])]$")
#: The name of the time column among a table's columns while it is read.
_TIME = ""


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
    (float64), its ``header`` (the columns' names, on line ``header_line``), ``sample_rate_hz``."""

    path: Path
    header: tuple[str, ...]
    header_line: int
    columns: dict[str, np.ndarray]
    sample_rate_hz: float
    n_rows: int

    @property
    def length_s(self) -> float:
        return self.n_rows / self.sample_rate_hz

    def missing(self, channel: ChannelColumn, why: str = "") -> CsvError:
        """The error of this file lacking ``channel``'s column (``why``: what makes it an error)."""
        has = ", ".join(self.header)
        return CsvError(self.path, self.header_line, channel.column, f"missing{why} (the header has: {has})")


def read_csv(path: Path, dialect: Dialect, timing: Timing, channels: tuple[ChannelColumn, ...]) -> CsvTable:
    """The columns of ``channels`` that the CSV file at ``path`` has, in SI units, with its sample
    rate (``timing``: a rate, or a time column the file must have)."""
    lines = _lines(path, dialect)
    header_line = dialect.skip_lines + 1
    if len(lines) < header_line or not lines[header_line - 1].strip():
        raise CsvError(path, header_line, None, "empty file: no header line")
    header = [name.strip() for name in _fields(lines[header_line - 1], dialect.delimiter)]
    units = [None] * len(header)
    data_line = header_line + 1
    if dialect.units_row:
        units = _units_row(path, lines, header_line, len(header), dialect.delimiter)
        data_line += 1
    wanted = {c.channel: (c.column, c.unit, c.si_unit, c.scale) for c in channels if c.column in header}
    if timing.column is not None:
        if timing.column not in header:
            raise CsvError(path, header_line, timing.column, f"missing (the header has: {', '.join(header)})")
        wanted[_TIME] = (timing.column, timing.unit, "s", 1.0)
    factors = {}
    units_line = header_line + 1 if dialect.units_row else None
    for channel, (column, unit, si_unit, scale) in wanted.items():
        i = header.index(column)
        found, line = _unit(path, column, unit, units[i], header_line=header_line, units_line=units_line)
        if UNITS[found][0] != si_unit:
            raise CsvError(path, line, column, f"unit {found} is not a unit of {si_unit} ({channel})")
        factors[channel] = UNITS[found][1] * scale
    rows = _rows(path, lines[data_line - 1 :], data_line, len(header), dialect.delimiter)
    values, problems = {}, []
    for channel, (column, *_) in wanted.items():
        i = header.index(column)
        column_values = _column(path, [row[i] for row in rows], data_line, column, dialect.decimal)
        if isinstance(column_values, CsvError):
            problems.append(column_values)
        else:
            values[channel] = column_values * factors[channel]
    if problems:
        raise min(problems, key=lambda e: e.line)
    if timing.column is None:
        rate = timing.sample_rate_hz
    else:
        rate = _rate_from_time(path, data_line, timing.column, values.pop(_TIME))
    return CsvTable(path, tuple(header), header_line, values, rate, len(rows))


def _lines(path: Path, d: Dialect) -> list[str]:
    """The file's lines without the blank lines at its end; a UTF-8 byte-order mark (spreadsheet
    programs write one) is not part of the first line."""
    utf8 = codecs.lookup(d.encoding).name == "utf-8"
    try:
        with path.open(newline="", encoding="utf-8-sig" if utf8 else d.encoding) as f:
            lines = f.read().splitlines()
    except OSError as exc:
        raise CsvError(path, None, None, f"cannot be read: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise CsvError(path, None, None, f"not {d.encoding} text: {exc.reason}") from None
    while lines and not lines[-1].strip():
        lines.pop()
    return lines


def _fields(line: str, delimiter: str) -> list[str]:
    """The fields of one line; a delimiter at its end (spaces aside) ends the line, no field after it."""
    fields = next(csv.reader([line], delimiter=delimiter), [])
    if len(fields) > 1 and not fields[-1].strip():
        fields.pop()
    return fields


def _units_row(path: Path, lines: list[str], header_line: int, n: int, delimiter: str) -> list[str | None]:
    """The units row under the header: one field per column (None where it is blank)."""
    if len(lines) <= header_line:
        raise CsvError(path, header_line + 1, None, "no units row after the header (csv.units_row)")
    fields = next(csv.reader([lines[header_line]], delimiter=delimiter), [])
    if len(fields) == n + 1 and not fields[-1].strip():
        fields.pop()  # a delimiter ending the line (a blank last field is the last column's)
    if len(fields) != n:
        raise CsvError(
            path, header_line + 1, None, f"the units row has {len(fields)} fields where the header has {n}"
        )
    return [field.strip() or None for field in fields]


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
    line = units_line if stated is not None or units_line is not None else header_line
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


def _rows(path: Path, lines: list[str], first_line: int, n: int, delimiter: str) -> list[list[str]]:
    """The data rows, each of ``n`` fields (one more, blank, where the line ends with a delimiter)."""
    if not lines:
        raise CsvError(path, first_line, None, "no data rows after the header")
    rows = list(csv.reader(lines, delimiter=delimiter))
    if list(map(len, rows)).count(n) != len(rows):
        for k, row in enumerate(rows):
            if len(row) == n + 1 and not row[-1].strip():
                row.pop()
            elif len(row) != n:
                fields = f"{len(row)} field{'s' * (len(row) != 1)}"
                raise CsvError(path, first_line + k, None, f"{fields} where the header has {n}")
    return rows


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


def _rate_from_time(path: Path, first_line: int, column: str, t: np.ndarray) -> float:
    """The sample rate of a time column (s), which must step evenly forward."""
    if len(t) < 2:
        raise CsvError(path, first_line, column, "a time column needs at least two rows")
    step = (t[-1] - t[0]) / (len(t) - 1)
    off = np.flatnonzero(np.abs(np.diff(t) - step) > TIME_STEP_TOLERANCE * abs(step))
    if step <= 0 or len(off):
        n = int(off[0]) + 1 if len(off) else 1
        raise CsvError(
            path, first_line + n, column, f"time steps unevenly (mean step {step:g} s): not one sample rate"
        )
    return 1.0 / step
