"""The mapping file of a CSV import (docs/import.md): which CSV column is which channel in which
unit, the CSV dialect, the sample rate or time column, and what each CSV file is.

Loaded and checked whole before any CSV file is read: one error lists every problem of the file, in
the file's order, each naming the mapping file and the key
(``mapping.toml: runs[1].points[0].freq_hz: expected a number``).
"""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sequences.runs import RunKind
from sequences.toml_text import load_toml, toml_error_where

#: Units a column may be given in: unit -> (the SI unit of the schema's channel, factor to it).
UNITS: dict[str, tuple[str, float]] = {
    "N": ("N", 1.0),
    "kN": ("N", 1e3),
    "Nm": ("N m", 1.0),
    "kNm": ("N m", 1e3),
    "m": ("m", 1.0),
    "mm": ("m", 1e-3),
    "m/s2": ("m/s^2", 1.0),
    "m/s^2": ("m/s^2", 1.0),
    "g": ("m/s^2", 9.80665),
    "s": ("s", 1.0),
    "ms": ("s", 1e-3),
}
#: The SI unit a channel's name promises by its suffix (docs/hdf5.md: units in names).
CHANNEL_SUFFIX_UNITS = (("_m_s2", "m/s^2"), ("_nm", "N m"), ("_n", "N"), ("_m", "m"))
#: The channel that the CSV's time column is: seconds.
TIME_UNIT = "s"
#: The kinds of run a CSV export can hold (a hammer capture is not imported).
IMPORTED_KINDS = (RunKind.FREE_RUN, RunKind.DWELL_GRID, RunKind.SWEEP)
SWEEP_LAWS = ("linear", "log")

_TOP_KEYS = ("source", "csv", "time", "channels", "runs")


class MappingError(ValueError):
    """A mapping file that cannot be used: ``problems`` holds every ``(key, message)`` found, in the
    file's order; the message has one line per problem, each naming the file and the key, as a
    sequence file's error does (the first line, then ``and N more:``)."""

    def __init__(self, path: Path, problems: list[tuple[str, str]]) -> None:
        self.path, self.problems = path, tuple(problems)
        self.key = problems[0][0]
        lines = [f"{path}: {key}: {message}" if key else f"{path}: {message}" for key, message in problems]
        if len(lines) > 1:
            lines[1:] = [f"  and {len(lines) - 1} more:", *(f"  {line}" for line in lines[1:])]
        super().__init__("\n".join(lines))


def mapping_error(path: Path, data: dict, problems: list[tuple[str, str]]) -> MappingError:
    """One error for ``problems`` (at least one) of the mapping parsed as ``data``, in file order."""
    return MappingError(path, sorted(problems, key=lambda p: file_position(data, p[0])))


_KEY_PART = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def file_position(data: object, key: str) -> tuple[int, ...]:
    """Where ``key`` (``runs[1].points[0].freq_hz``) stands in the parsed file: at each level the
    index of its name among the table's keys (TOML keeps the file's order) or its array index; a key
    the file lacks sorts after the table's keys."""
    position = []
    for name, index in _KEY_PART.findall(key):
        if index:
            position.append(int(index))
            data = data[int(index)] if isinstance(data, list) and int(index) < len(data) else None
        elif isinstance(data, dict):
            names = list(data)
            position.append(names.index(name) if name in data else len(names))
            data = data.get(name)
        else:
            position.append(0)
    return tuple(position)


@dataclass(frozen=True)
class Dialect:
    """``delimiter`` between fields, ``decimal`` mark ("." or ","), ``skip_lines`` before the
    header line, ``encoding`` of the files."""

    delimiter: str = ","
    decimal: str = "."
    skip_lines: int = 0
    encoding: str = "utf-8"


@dataclass(frozen=True)
class ChannelColumn:
    """Channel ``channel`` (schema name, SI unit ``si_unit``) from CSV column ``column`` given in
    ``unit`` (None: the unit in brackets at the end of the column's header, e.g. ``Fz [kN]``),
    multiplied by ``scale`` after the unit's conversion."""

    channel: str
    si_unit: str
    column: str
    unit: str | None
    scale: float = 1.0


@dataclass(frozen=True)
class Timing:
    """Either ``sample_rate_hz`` or a ``column`` of sample instants in ``unit`` (s or ms)."""

    sample_rate_hz: float | None = None
    column: str | None = None
    unit: str | None = None


@dataclass(frozen=True)
class DwellFile:
    """One CSV file holding one dwell: its frequency, amplitude (the grid's nominal amplitude too
    when a bench limit lowered it) and the constant-amplitude part, seconds from the file's start
    (``hold_end_s`` None: to the end)."""

    file: Path
    freq_hz: float
    amplitude_mm: float
    requested_amplitude_mm: float = math.nan
    hold_start_s: float = 0.0
    hold_end_s: float | None = None


@dataclass(frozen=True)
class SweepFile:
    file: Path
    start_hz: float
    end_hz: float
    duration_s: float
    amplitude_mm: float
    law: str = "linear"


@dataclass(frozen=True)
class RunMapping:
    """One run of the campaign: ``kind``, its id, tyre pressure (None: not known) and files."""

    run_id: str
    kind: str
    tyre_pressure_bar: float | None
    files: tuple[DwellFile, ...] | tuple[SweepFile]


@dataclass(frozen=True)
class ImportMapping:
    path: Path
    text: str
    name: str
    bench: str
    dialect: Dialect
    timing: Timing
    channels: tuple[ChannelColumn, ...]
    runs: tuple[RunMapping, ...]


def load_mapping(path: str | Path) -> ImportMapping:
    """Read and check the mapping at ``path``; CSV file names are relative to its folder.
    :class:`MappingError` lists every problem of the file."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise MappingError(path, [("", f"cannot be read: {exc.strerror or exc}")]) from None
    if not text.strip():
        raise MappingError(path, [("", "empty file")])
    try:
        data = load_toml(text)
    except tomllib.TOMLDecodeError as exc:
        raise MappingError(path, [toml_error_where(text, str(exc))]) from None
    r = _Reader(path)
    r.keys(data, "", _TOP_KEYS)
    source = r.table(data, "source")
    r.keys(source, "source", ("name", "bench"))
    name = r.string(source, "source.name", required=True)
    if name is not None and not re.fullmatch(r"[A-Za-z0-9_.-]+", name):
        r.add("source.name", f"{name!r}: use letters, digits, '_', '.' and '-' only")
    mapping = ImportMapping(
        path=path,
        text=text,
        name=name,
        bench=r.choice(source, "source.bench", ("shaker", "four_post"), "shaker"),
        dialect=r.dialect(r.table(data, "csv")),
        timing=r.timing(r.table(data, "time")),
        channels=r.channels(r.table(data, "channels")),
        runs=r.runs(data.get("runs"), name or "import"),
    )
    if r.problems:
        raise mapping_error(path, data, r.problems)
    return mapping


def channel_si_unit(name: str) -> str | None:
    """The SI unit promised by a channel name's suffix (``fz_wfs_n``: N), None when there is none."""
    for suffix, unit in CHANNEL_SUFFIX_UNITS:
        if name.endswith(suffix):
            return unit
    return None


def _allowed_above(lo: float, *, positive: bool) -> str:
    """The allowed range of a number bounded below: ``> 0`` for a positive one, else ``>= lo``."""
    if positive and lo <= 0:
        return "> 0"
    return f">= {lo:g}"


class _Reader:
    """Typed access to the parsed TOML that collects every problem, each naming its key. A value in
    error reads as its default (None when it has none), so the rest of the file is still checked."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.problems: list[tuple[str, str]] = []

    def add(self, key: str, message: str) -> None:
        self.problems.append((key, message))

    def keys(self, table: dict, where: str, allowed: tuple[str, ...]) -> None:
        for key in table:
            if key not in allowed:
                at = f"{where}.{key}" if where else key
                self.add(at, f"unknown key (allowed: {', '.join(allowed)})")

    def table(self, data: dict, key: str) -> dict:
        value = data.get(key, {})
        if not isinstance(value, dict):
            self.add(key, f"expected a table, got {value!r}")
            return {}
        return value

    def string(self, table: dict, key: str, default: str | None = None, *, required: bool = False) -> Any:
        name = key.rsplit(".", 1)[-1]
        if name not in table:
            if required:
                self.add(key, "missing")
            return default
        value = table[name]
        if not isinstance(value, str) or not value:
            self.add(key, f"expected a non-empty string, got {value!r}")
            return default
        return value

    def choice(self, table: dict, key: str, allowed: tuple[str, ...], default: str | None) -> Any:
        value = self.string(table, key, default, required=default is None)
        if value is not None and value not in allowed:
            self.add(key, f"{value!r} is not one of {', '.join(allowed)}")
            return default
        return value

    def number(
        self, table: dict, key: str, default: float | None = None, *, lo: float = -math.inf, positive=False
    ) -> Any:
        name = key.rsplit(".", 1)[-1]
        if name not in table:
            if default is None:
                self.add(key, "missing")
            return default
        value = table[name]
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            self.add(key, f"expected a number, got {value!r}")
            return default
        if value < lo or (positive and value <= 0):
            self.add(key, f"{value:g} is out of range (allowed {_allowed_above(lo, positive=positive)})")
            return default
        return float(value)

    def dialect(self, t: dict) -> Dialect:
        self.keys(t, "csv", ("delimiter", "decimal", "skip_lines", "encoding"))
        d = Dialect()
        delimiter = self.string(t, "csv.delimiter", d.delimiter)
        if len(delimiter) != 1 and delimiter != "\\t":
            self.add("csv.delimiter", f"{delimiter!r} is not one character")
        delimiter = "\t" if delimiter == "\\t" else delimiter
        decimal = self.choice(t, "csv.decimal", (".", ","), d.decimal)
        if decimal == delimiter:
            self.add("csv.decimal", f"{decimal!r} is the delimiter too")
        skip = self.number(t, "csv.skip_lines", 0, lo=0)
        if skip != int(skip):
            self.add("csv.skip_lines", f"{skip:g} is not a whole number")
        encoding = self.string(t, "csv.encoding", d.encoding)
        try:
            "".encode(encoding)
        except LookupError:
            self.add("csv.encoding", f"unknown encoding {encoding!r}")
        return Dialect(delimiter, decimal, int(skip), encoding)

    def timing(self, t: dict) -> Timing:
        self.keys(t, "time", ("sample_rate_hz", "column", "unit"))
        if ("sample_rate_hz" in t) == ("column" in t):
            self.add("time", "give either sample_rate_hz or a time column (column and unit)")
            return Timing()
        if "sample_rate_hz" in t:
            return Timing(sample_rate_hz=self.number(t, "time.sample_rate_hz", positive=True))
        unit = self.unit(t, "time.unit", TIME_UNIT, required=False)
        return Timing(column=self.string(t, "time.column", required=True), unit=unit)

    def unit(self, t: dict, key: str, si_unit: str, *, required: bool) -> str | None:
        unit = self.string(t, key, required=required)
        if unit is None:
            return None
        if unit not in UNITS:
            self.add(key, f"unknown unit {unit!r} (known: {', '.join(UNITS)})")
        elif UNITS[unit][0] != si_unit:
            self.add(key, f"{unit} is not a unit of {si_unit}")
        return unit

    def channels(self, t: dict) -> tuple[ChannelColumn, ...]:
        if not t:
            self.add("channels", "no channel mapped")
        out = []
        for channel, spec in t.items():
            where = f"channels.{channel}"
            si_unit = channel_si_unit(channel)
            if si_unit is None:
                suffixes = ", ".join(s for s, _ in CHANNEL_SUFFIX_UNITS)
                self.add(where, f"a channel name ends with its unit ({suffixes})")
            if not isinstance(spec, dict):
                self.add(where, f"expected a table (column, unit, scale), got {spec!r}")
                continue
            self.keys(spec, where, ("column", "unit", "scale"))
            out.append(
                ChannelColumn(
                    channel,
                    si_unit,
                    self.string(spec, f"{where}.column", required=True),
                    None if si_unit is None else self.unit(spec, f"{where}.unit", si_unit, required=False),
                    self.number(spec, f"{where}.scale", 1.0),
                )
            )
        return tuple(out)

    def runs(self, runs: object, name: str) -> tuple[RunMapping, ...]:
        if not isinstance(runs, list) or not runs:
            self.add("runs", "expected at least one [[runs]] table")
            return ()
        out = []
        for i, run in enumerate(runs):
            where = f"runs[{i}]"
            if not isinstance(run, dict):
                self.add(where, "expected a table")
                continue
            kind = self.choice(run, f"{where}.kind", IMPORTED_KINDS, None)
            run_id = self.string(run, f"{where}.id", f"{name}-r{i:03d}-{kind}")
            pressure = run.get("tyre_pressure_bar")
            if pressure is not None:
                pressure = self.number(run, f"{where}.tyre_pressure_bar", positive=True)
            # a kind in error: the files are checked as the run's keys suggest
            if kind == "sweep" or (kind is None and "points" not in run):
                self.keys(run, where, ("kind", "id", "tyre_pressure_bar", *SweepFile.__dataclass_fields__))
                files: tuple = (self.sweep(run, where),)
            else:
                self.keys(run, where, ("kind", "id", "tyre_pressure_bar", "points"))
                files = self.dwells(run.get("points"), where)
            out.append(RunMapping(run_id, kind, pressure, files))
        ids = [r.run_id for r in out]
        for i, run_id in enumerate(ids):
            if run_id in ids[:i]:
                self.add(f"runs[{i}].id", f"{run_id!r} is the id of an earlier run too")
        return tuple(out)

    def file(self, t: dict, key: str) -> Path | None:
        name = self.string(t, key, required=True)
        return None if name is None else self.path.parent / name

    def dwells(self, points: object, where: str) -> tuple[DwellFile, ...]:
        if not isinstance(points, list) or not points:
            self.add(f"{where}.points", "expected at least one [[runs.points]] table (a file each)")
            return ()
        out = []
        for j, p in enumerate(points):
            at = f"{where}.points[{j}]"
            if not isinstance(p, dict):
                self.add(at, "expected a table")
                continue
            self.keys(p, at, tuple(DwellFile.__dataclass_fields__))
            hold_end = p.get("hold_end_s")
            out.append(
                DwellFile(
                    self.file(p, f"{at}.file"),
                    self.number(p, f"{at}.freq_hz", positive=True),
                    self.number(p, f"{at}.amplitude_mm", positive=True),
                    self.number(p, f"{at}.requested_amplitude_mm", math.nan, positive=True),
                    self.number(p, f"{at}.hold_start_s", 0.0, lo=0),
                    None if hold_end is None else self.number(p, f"{at}.hold_end_s", positive=True),
                )
            )
            if out[-1].hold_end_s is not None and out[-1].hold_end_s <= out[-1].hold_start_s:
                self.add(f"{at}.hold_end_s", "must come after hold_start_s")
        return tuple(out)

    def sweep(self, t: dict, where: str) -> SweepFile:
        return SweepFile(
            self.file(t, f"{where}.file"),
            self.number(t, f"{where}.start_hz", positive=True),
            self.number(t, f"{where}.end_hz", positive=True),
            self.number(t, f"{where}.duration_s", positive=True),
            self.number(t, f"{where}.amplitude_mm", positive=True),
            self.choice(t, f"{where}.law", SWEEP_LAWS, "linear"),
        )
