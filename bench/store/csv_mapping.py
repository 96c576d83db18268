"""The mapping file of a CSV import (docs/import.md): which CSV column is which channel in which
unit, the CSV dialect, the sample rate or time column (for the whole campaign or per run), and
which part of which CSV file each point of each run is.

Loaded and checked whole before any CSV file is read: one error lists every problem of the file, in
the file's order, each naming the mapping file and the key
(``mapping.toml: runs[1].points[0].freq_hz: expected a number``).
"""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench.store import measurement_chain
from bench.store.csv_units import (
    CHANNEL_SUFFIX_UNITS,
    TIME_UNIT,
    UNITS,
    channel_si_unit,
    known_units,
    unit_named,
)
from sequences.runs import RUN_KINDS, RigKind, RunKind
from sequences.toml_text import load_toml, toml_error_where

#: The kinds of run a CSV export can hold: a tracked dwell's track is the engine's looks at its
#: resonance, which no acquisition system's CSV carries; a road replay's drive (its source and
#: checksum) neither, nor a drive iteration's drives and target.
_NOT_IMPORTED = (RunKind.TRACKED_DWELL, RunKind.ROAD_REPLAY, RunKind.DRIVE_ITERATION)
IMPORTED_KINDS = tuple(kind for kind in RUN_KINDS if kind not in _NOT_IMPORTED)

SWEEP_LAWS = ("linear", "log")
#: A run's own keys, by kind: the point-wise kinds list their points, a sweep is one file.
_RUN_KEYS = {
    RunKind.FREE_RUN: ("kind", "id", "tyre_pressure_bar", "time", "channels", "file", "points"),
    RunKind.DWELL_GRID: ("kind", "id", "tyre_pressure_bar", "time", "channels", "file", "points"),
    RunKind.HAMMER: ("kind", "id", "time", "channels", "file", "points"),
}
_SWEEP_KEYS = ("file", "start_hz", "end_hz", "duration_s", "amplitude_mm", "law")
#: A point's keys: a hammer blow is a part of a file, a dwell says what it excited too.
_HAMMER_POINT_KEYS = ("file", "start_s", "end_s")
_DWELL_POINT_KEYS = (
    *_HAMMER_POINT_KEYS,
    "freq_hz",
    "amplitude_mm",
    "requested_amplitude_mm",
    "hold_start_s",
    "hold_end_s",
)

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
    header line, ``units_row``: the line under the header gives each column's unit, ``encoding``
    of the files."""

    delimiter: str = ","
    decimal: str = "."
    skip_lines: int = 0
    units_row: bool = False
    encoding: str = "utf-8"


@dataclass(frozen=True)
class ChannelColumn:
    """Channel ``channel`` (schema name, SI unit ``si_unit``) from CSV column ``column`` given in
    ``unit`` (a key of :data:`~bench.store.csv_units.UNITS`; None: the unit the file gives, in its
    units row or in brackets at the end of the column's header, e.g. ``Fz [kN]``), multiplied by
    ``scale`` after the unit's conversion."""

    channel: str
    si_unit: str
    column: str
    unit: str | None
    scale: float = 1.0


@dataclass(frozen=True)
class Timing:
    """Either ``sample_rate_hz`` or a ``column`` of sample instants in ``unit`` (a unit of
    seconds; None: the unit the file gives)."""

    sample_rate_hz: float | None = None
    column: str | None = None
    unit: str | None = None


@dataclass(frozen=True)
class PointPart:
    """One point of a free run, dwell grid or hammer run: the part of ``file`` that holds it,
    ``start_s`` to ``end_s`` (None: the file's end), seconds from the file's first sample, and for
    a dwell its frequency, amplitude (and the grid's nominal amplitude when a bench limit lowered
    it) and constant-amplitude hold, also from the file's first sample (None: the part's start,
    its end). A hammer blow has no frequency nor amplitude (0). Only the part is imported: the
    points of a continuous file are imported without what lies between them."""

    file: Path
    freq_hz: float = 0.0
    amplitude_mm: float = 0.0
    requested_amplitude_mm: float = math.nan
    start_s: float = 0.0
    end_s: float | None = None
    hold_start_s: float | None = None
    hold_end_s: float | None = None


@dataclass(frozen=True)
class SweepFile:
    """A sweep's one file and its step: ``start_hz`` to ``end_hz`` over ``duration_s`` (the file's
    length) at ``amplitude_mm``, ``law`` linear or log."""

    file: Path
    start_hz: float
    end_hz: float
    duration_s: float
    amplitude_mm: float
    law: str = "linear"


@dataclass(frozen=True)
class RunMapping:
    """One run of the campaign: ``kind``, its id, tyre pressure (None: not given), how its files'
    samples are timed and which columns are its channels (the run's own tables, else the
    mapping's: ``channels_key`` names the table), and its points (a sweep: its one file)."""

    run_id: str
    kind: str
    tyre_pressure_bar: float | None
    timing: Timing
    channels: tuple[ChannelColumn, ...]
    points: tuple[PointPart, ...] | tuple[SweepFile]
    channels_key: str = "channels"

    @property
    def files(self) -> tuple[Path, ...]:
        """The run's CSV files, each once, in the order its points name them."""
        return tuple(dict.fromkeys(p.file for p in self.points))


@dataclass(frozen=True)
class ImportMapping:
    path: Path
    text: str
    name: str
    bench: str
    dialect: Dialect
    runs: tuple[RunMapping, ...]


def load_mapping(path: str | Path) -> ImportMapping:
    """Read and check the mapping at ``path``; CSV file names are relative to its folder.
    :class:`MappingError` lists every problem of the file."""
    path = Path(path)
    text, data = _parsed(path)
    r = _Reader(path)
    r.keys(data, "", _TOP_KEYS)
    source = r.table(data, "source")
    r.keys(source, "source", ("name", "bench"))
    name = r.string(source, "source.name", required=True)
    if name is not None and not re.fullmatch(r"[A-Za-z0-9_.-]+", name):
        r.add("source.name", f"{name!r}: use letters, digits, '_', '.' and '-' only")
    bench = r.choice(source, "source.bench", tuple(RigKind), RigKind.SHAKER)
    defaults = _RunDefaults(
        timing=r.timing(r.table(data, "time"), "time") if "time" in data else None,
        channels=r.channels(r.table(data, "channels"), "channels") if "channels" in data else None,
        bench=bench,
    )
    mapping = ImportMapping(
        path=path,
        text=text,
        name=name,
        bench=bench,
        dialect=r.dialect(r.table(data, "csv")),
        runs=r.runs(data.get("runs"), name or "import", defaults),
    )
    if r.problems:
        raise mapping_error(path, data, r.problems)
    return mapping


def _parsed(path: Path) -> tuple[str, dict]:
    """The text of the mapping file at ``path`` and its TOML parsed (MappingError: unreadable,
    empty, or not TOML, naming the line)."""
    try:
        text = path.read_text()
    except OSError as exc:
        raise MappingError(path, [("", f"cannot be read: {exc.strerror or exc}")]) from None
    if not text.strip():
        raise MappingError(path, [("", "empty file")])
    try:
        return text, load_toml(text)
    except tomllib.TOMLDecodeError as exc:
        raise MappingError(path, [toml_error_where(text, str(exc))]) from None


@dataclass(frozen=True)
class ChannelMapping:
    """How one measurement file's channels are read (``wfsbench compensate --mapping``,
    docs/compensate.md): the import's ``csv`` dialect, ``time`` table and ``channels`` table, with
    the same keys; ``timing`` None when the mapping has no ``time`` table (an MDF4 file keeps its
    own time stamps); ``chain``: what its ``measurement`` table states of the measurement's own
    hub accelerometer and logger (:mod:`bench.store.measurement_chain`)."""

    path: Path
    dialect: Dialect
    timing: Timing | None
    channels: tuple[ChannelColumn, ...]
    chain: measurement_chain.MeasurementChain = field(default_factory=measurement_chain.MeasurementChain)


def load_channel_mapping(path: str | Path) -> ChannelMapping:
    """Read and check a measurement's mapping at ``path`` (tables ``csv``, ``time``,
    ``channels``, ``measurement``); :class:`MappingError` lists every problem of the file."""
    path = Path(path)
    _, data = _parsed(path)
    r = _Reader(path)
    r.keys(data, "", ("csv", "time", "channels", measurement_chain.MAPPING_TABLE))
    mapping = ChannelMapping(
        path=path,
        dialect=r.dialect(r.table(data, "csv")),
        timing=r.timing(r.table(data, "time"), "time") if "time" in data else None,
        channels=r.channels(r.table(data, "channels"), "channels"),
        chain=r.chain(r.table(data, measurement_chain.MAPPING_TABLE)),
    )
    if r.problems:
        raise mapping_error(path, data, r.problems)
    return mapping


@dataclass(frozen=True)
class _RunDefaults:
    """What a run takes from the mapping's top level unless it has its own: the ``[time]`` and
    ``[channels]`` tables (None: not given), and the bench (for what its analysis needs)."""

    timing: Timing | None
    channels: tuple[ChannelColumn, ...] | None
    bench: str


def pressure_needed(kind: str, bench: str) -> str | None:
    """Why a run of ``kind`` on ``bench`` needs its tyre pressure, None when it does not: its
    analysis takes the grids (or the shaker identification) of that pressure."""
    if kind == RunKind.DWELL_GRID:
        return "a dwell grid is analysed with the other grids of its tyre pressure"
    if kind == RunKind.SWEEP and bench == RigKind.FOUR_POST:
        return "a four-post sweep is analysed with the shaker identification at its tyre pressure"
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

    def table(self, data: dict, key: str, where: str = "") -> dict:
        """The table ``key`` of ``data`` (at ``where``), empty when missing or not a table."""
        value = data.get(key, {})
        if not isinstance(value, dict):
            self.add(f"{where}.{key}" if where else key, f"expected a table, got {value!r}")
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

    def bool(self, table: dict, key: str, default: bool) -> bool:
        name = key.rsplit(".", 1)[-1]
        value = table.get(name, default)
        if not isinstance(value, bool):
            self.add(key, f"expected true or false, got {value!r}")
            return default
        return value

    def dialect(self, t: dict) -> Dialect:
        self.keys(t, "csv", tuple(Dialect.__dataclass_fields__))
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
        units_row = self.bool(t, "csv.units_row", d.units_row)
        encoding = self.string(t, "csv.encoding", d.encoding)
        try:
            "".encode(encoding)
        except LookupError:
            self.add("csv.encoding", f"unknown encoding {encoding!r}")
        return Dialect(delimiter, decimal, int(skip), units_row, encoding)

    def chain(self, t: dict) -> measurement_chain.MeasurementChain:
        """The ``measurement`` table: the measurement's hub accelerometer lag and logger bandwidth,
        each checked as the command line's options are (:mod:`bench.store.measurement_chain`)."""
        where = measurement_chain.MAPPING_TABLE
        keys = {
            measurement_chain.HUB_LAG_KEY: measurement_chain.hub_lag_ms,
            measurement_chain.BANDWIDTH_KEY: measurement_chain.bandwidth_hz,
        }
        self.keys(t, where, tuple(keys))
        stated = {}
        for key, check in keys.items():
            if key not in t:
                continue
            try:
                stated[key] = measurement_chain.Stated(check(t[key]), f"{self.path}: {where}.{key}")
            except ValueError as exc:
                self.add(f"{where}.{key}", str(exc))
        return measurement_chain.MeasurementChain(**stated)

    def timing(self, t: dict, where: str) -> Timing:
        """The ``time`` table at ``where`` (``time`` or ``runs[i].time``)."""
        self.keys(t, where, ("sample_rate_hz", "column", "unit"))
        if ("sample_rate_hz" in t) == ("column" in t):
            self.add(where, "give either sample_rate_hz or a time column (column and unit)")
            return Timing()
        if "sample_rate_hz" in t:
            return Timing(sample_rate_hz=self.number(t, f"{where}.sample_rate_hz", positive=True))
        unit = self.unit(t, f"{where}.unit", TIME_UNIT, required=False)
        return Timing(column=self.string(t, f"{where}.column", required=True), unit=unit)

    def unit(self, t: dict, key: str, si_unit: str, *, required: bool) -> str | None:
        """The unit at ``key``, as its key in :data:`UNITS` (``m/s²`` is ``m/s^2``)."""
        spelling = self.string(t, key, required=required)
        if spelling is None:
            return None
        unit = unit_named(spelling)
        if unit is None:
            self.add(key, f"unknown unit {spelling!r} (known: {known_units()})")
        elif UNITS[unit][0] != si_unit:
            self.add(key, f"{spelling} is not a unit of {si_unit}")
        return unit

    def channels(self, t: dict, where: str) -> tuple[ChannelColumn, ...]:
        """The ``channels`` table at ``where`` (``channels`` or ``runs[i].channels``)."""
        if not t:
            self.add(where, "no channel mapped")
        out = []
        for channel, spec in t.items():
            at = f"{where}.{channel}"
            si_unit = channel_si_unit(channel)
            if si_unit is None:
                suffixes = ", ".join(s for s, _ in CHANNEL_SUFFIX_UNITS)
                self.add(at, f"a channel name ends with its unit ({suffixes})")
            if not isinstance(spec, dict):
                self.add(at, f"expected a table (column, unit, scale), got {spec!r}")
                continue
            self.keys(spec, at, ("column", "unit", "scale"))
            out.append(
                ChannelColumn(
                    channel,
                    si_unit,
                    self.string(spec, f"{at}.column", required=True),
                    None if si_unit is None else self.unit(spec, f"{at}.unit", si_unit, required=False),
                    self.number(spec, f"{at}.scale", 1.0),
                )
            )
        return tuple(out)

    def runs(self, runs: object, name: str, defaults: _RunDefaults) -> tuple[RunMapping, ...]:
        if not isinstance(runs, list) or not runs:
            self.add("runs", "expected at least one [[runs]] table")
            return ()
        out = []
        for i, run in enumerate(runs):
            if not isinstance(run, dict):
                self.add(f"runs[{i}]", "expected a table")
                continue
            out.append(self.run(run, i, name, defaults))
        ids = [r.run_id for r in out]
        for i, run_id in enumerate(ids):
            if run_id in ids[:i]:
                self.add(f"runs[{i}].id", f"{run_id!r} is the id of an earlier run too")
        return tuple(out)

    def run(self, run: dict, i: int, name: str, defaults: _RunDefaults) -> RunMapping:
        where = f"runs[{i}]"
        kind = self.choice(run, f"{where}.kind", IMPORTED_KINDS, None)
        run_id = self.string(run, f"{where}.id", f"{name}-r{i:03d}-{kind}")
        pressure = run.get("tyre_pressure_bar")
        if pressure is not None:
            pressure = self.number(run, f"{where}.tyre_pressure_bar", positive=True)
        elif (why := pressure_needed(kind, defaults.bench)) is not None:
            self.add(f"{where}.tyre_pressure_bar", f"missing: {why} (give it in bar)")
        # a kind in error: the points are checked as the run's keys suggest
        if kind == RunKind.SWEEP or (kind is None and "points" not in run):
            self.keys(run, where, ("kind", "id", "tyre_pressure_bar", "time", "channels", *_SWEEP_KEYS))
            points: tuple = (self.sweep(run, where),)
        else:
            self.keys(run, where, _RUN_KEYS.get(kind, _RUN_KEYS[RunKind.DWELL_GRID]))
            points = self.points(run, where, kind)
        timing, channels, channels_key = defaults.timing, defaults.channels, "channels"
        if "time" in run:
            timing = self.timing(self.table(run, "time", where), f"{where}.time")
        elif timing is None:
            self.add(f"{where}.time", "missing: give a [time] table, or the run's own")
        if "channels" in run:
            channels_key = f"{where}.channels"
            channels = self.channels(self.table(run, "channels", where), channels_key)
        elif channels is None:
            self.add(f"{where}.channels", "missing: give a [channels] table, or the run's own")
        return RunMapping(run_id, kind, pressure, timing or Timing(), channels or (), points, channels_key)

    def file(self, t: dict, key: str) -> Path | None:
        name = self.string(t, key, required=True)
        return None if name is None else self.path.parent / name

    def point_file(self, p: dict, at: str, run_file: Path | None) -> Path | None:
        """A point's file: its own, else its run's."""
        if "file" in p:
            return self.file(p, f"{at}.file")
        if run_file is None:
            self.add(f"{at}.file", "missing: give the point's file, or the run's")
        return run_file

    def points(self, run: dict, where: str, kind: str | None) -> tuple[PointPart, ...]:
        """A point-wise run's points; each names its file or takes the run's ``file`` (a hammer
        run without points: one blow, the whole of the run's file)."""
        run_file = self.file(run, f"{where}.file") if "file" in run else None
        points = run.get("points")
        if points is None and kind == RunKind.HAMMER and run_file is not None:
            return (PointPart(run_file),)
        if not isinstance(points, list) or not points:
            self.add(f"{where}.points", "expected at least one [[runs.points]] table (a part of a file each)")
            return ()
        out = []
        for j, p in enumerate(points):
            at = f"{where}.points[{j}]"
            if not isinstance(p, dict):
                self.add(at, "expected a table")
                continue
            read = self.hammer_blow if kind == RunKind.HAMMER else self.dwell
            out.append(read(p, at, run_file))
        return tuple(out)

    def span(self, p: dict, at: str) -> tuple[float, float | None]:
        """A point's ``start_s`` and ``end_s`` (None: the file's end), the end after the start."""
        start = self.number(p, f"{at}.start_s", 0.0, lo=0)
        end = None if "end_s" not in p else self.number(p, f"{at}.end_s", positive=True)
        if end is not None and start is not None and end <= start:
            self.add(f"{at}.end_s", "must come after start_s")
        return start, end

    def hammer_blow(self, p: dict, at: str, run_file: Path | None) -> PointPart:
        self.keys(p, at, _HAMMER_POINT_KEYS)
        start, end = self.span(p, at)
        return PointPart(self.point_file(p, at, run_file), start_s=start, end_s=end)

    def dwell(self, p: dict, at: str, run_file: Path | None) -> PointPart:
        self.keys(p, at, _DWELL_POINT_KEYS)
        start, end = self.span(p, at)
        hold_start = None if "hold_start_s" not in p else self.number(p, f"{at}.hold_start_s", lo=0)
        hold_end = None if "hold_end_s" not in p else self.number(p, f"{at}.hold_end_s", positive=True)
        if hold_start is not None and start is not None and hold_start < start:
            self.add(f"{at}.hold_start_s", "must not come before start_s (both from the file's start)")
        elif hold_start is not None and end is not None and hold_start >= end:
            self.add(f"{at}.hold_start_s", "must come before end_s (both from the file's start)")
        if hold_end is not None and (hold_end <= (start if hold_start is None else hold_start)):
            self.add(f"{at}.hold_end_s", "must come after hold_start_s")
        elif hold_end is not None and end is not None and hold_end > end:
            self.add(f"{at}.hold_end_s", "must not come after end_s (both from the file's start)")
        return PointPart(
            self.point_file(p, at, run_file),
            self.number(p, f"{at}.freq_hz", positive=True),
            self.number(p, f"{at}.amplitude_mm", positive=True),
            self.number(p, f"{at}.requested_amplitude_mm", math.nan, positive=True),
            start,
            end,
            hold_start,
            hold_end,
        )

    def sweep(self, t: dict, where: str) -> SweepFile:
        return SweepFile(
            self.file(t, f"{where}.file"),
            self.number(t, f"{where}.start_hz", positive=True),
            self.number(t, f"{where}.end_hz", positive=True),
            self.number(t, f"{where}.duration_s", positive=True),
            self.number(t, f"{where}.amplitude_mm", positive=True),
            self.choice(t, f"{where}.law", SWEEP_LAWS, "linear"),
        )
