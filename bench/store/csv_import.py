"""CSV exports of another acquisition system brought into a campaign file (docs/import.md).

Every CSV file the mapping names is read and checked first, into SI channels; only then is the
campaign written, through :class:`bench.store.CampaignWriter`, to a temporary file beside the
output that is renamed into place once complete. So a bad CSV file (a missing column, text in a
number, a ragged row, an unknown unit, an empty file) is refused with its file, line and column,
and nothing half-written is left behind. The values the mapping gives are then checked against the
files and the bench (:func:`check_mapped_values`): frequencies within the bench's range and below
half the sample rate, a sweep's duration the length of its file, holds inside their files, tyre
pressures that a pressure prompt accepts; every problem names the mapping file and the key.
"""

from __future__ import annotations

import codecs
import contextlib
import csv
import math
import os
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench.store.csv_mapping import (
    UNITS,
    ChannelColumn,
    Dialect,
    DwellFile,
    ImportMapping,
    RunMapping,
    SweepFile,
    mapping_error,
)
from bench.store.writer import CampaignWriter
from sequences.channels import Channel, role_of_standard_name
from sequences.points import PointAttempt
from sequences.toml_text import load_toml

#: Largest deviation of one time step from the mean step, relative, before a time column is refused.
TIME_STEP_TOLERANCE = 0.01
_HEADER_UNIT = re.compile(r"\[([^\]]*)\]\s*$")


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
    """One CSV file read into SI channels: ``columns`` by channel name, ``sample_rate_hz``."""

    path: Path
    columns: dict[str, np.ndarray]
    sample_rate_hz: float

    def __len__(self) -> int:
        return len(next(iter(self.columns.values())))


def read_csv(path: Path, mapping: ImportMapping) -> CsvTable:
    """The mapped columns of the CSV file at ``path`` in SI units (float64), with its sample rate."""
    d = mapping.dialect
    # a UTF-8 file may start with a byte-order mark (spreadsheet programs write one): not a header
    utf8 = codecs.lookup(d.encoding).name == "utf-8"
    try:
        with path.open(newline="", encoding="utf-8-sig" if utf8 else d.encoding) as f:
            lines = f.read().splitlines()
    except OSError as exc:
        raise CsvError(path, None, None, f"cannot be read: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise CsvError(path, None, None, f"not {d.encoding} text: {exc.reason}") from None
    header_line = d.skip_lines + 1
    rows = list(csv.reader(lines[d.skip_lines :], delimiter=d.delimiter))
    if not rows or not any(field.strip() for field in rows[0]):
        raise CsvError(path, header_line, None, "empty file: no header line")
    header = [name.strip() for name in rows[0]]
    wanted = [(c.channel, c.column, _factor(path, header_line, c)) for c in mapping.channels]
    if mapping.timing.column is not None:
        unit = mapping.timing.unit or _header_unit(path, header_line, mapping.timing.column)
        wanted.append(("", mapping.timing.column, UNITS[unit][1]))
    index = {}
    for channel, column, _ in wanted:
        if column not in header:
            raise CsvError(path, header_line, column, f"missing (the header has: {', '.join(header)})")
        index[channel] = header.index(column)
    data = rows[1:]
    if not data:
        raise CsvError(path, header_line + 1, None, "no data rows after the header")
    values = {channel: np.empty(len(data)) for channel in index}
    for n, row in enumerate(data):
        line = header_line + 1 + n
        if len(row) != len(header):
            raise CsvError(path, line, None, f"{len(row)} fields where the header has {len(header)}")
        for channel, i in index.items():
            values[channel][n] = _number(path, line, header[i], row[i], d)
    for channel, _, factor in wanted:
        values[channel] *= factor
    rate = mapping.timing.sample_rate_hz or _rate_from_time(path, header_line, mapping.timing.column, values)
    values.pop("", None)
    return CsvTable(path, values, rate)


def _number(path: Path, line: int, column: str, text: str, d: Dialect) -> float:
    field = text.strip()
    if d.decimal == ",":
        if "." in field:
            raise CsvError(path, line, column, f"{text!r}: a '.' where the decimal mark is ','")
        field = field.replace(",", ".")
    try:
        value = float(field)
    except ValueError:
        raise CsvError(path, line, column, f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise CsvError(path, line, column, f"{text!r} is not a finite number")
    return value


def _header_unit(path: Path, line: int, column: str) -> str:
    """The unit in brackets at the end of a column header (``Fz [kN]``), which must be known."""
    found = _HEADER_UNIT.search(column)
    if found is None:
        raise CsvError(path, line, column, "no unit in the mapping and none in brackets in the header")
    unit = found.group(1).strip()
    if unit not in UNITS:
        raise CsvError(path, line, column, f"unknown unit {unit!r} (known: {', '.join(UNITS)})")
    return unit


def _factor(path: Path, line: int, c: ChannelColumn) -> float:
    """The factor from the column's numbers to the channel's SI unit, times the mapping's scale."""
    unit = c.unit or _header_unit(path, line, c.column)
    si_unit, factor = UNITS[unit]
    if si_unit != c.si_unit:
        raise CsvError(path, line, c.column, f"unit {unit} is not a unit of {c.si_unit} ({c.channel})")
    return factor * c.scale


def _rate_from_time(path: Path, header_line: int, column: str | None, values: dict[str, np.ndarray]) -> float:
    """The sample rate of a time column (s), which must step evenly forward."""
    t = values[""]
    if len(t) < 2:
        raise CsvError(path, header_line + 1, column, "a time column needs at least two rows")
    step = (t[-1] - t[0]) / (len(t) - 1)
    off = np.flatnonzero(np.abs(np.diff(t) - step) > TIME_STEP_TOLERANCE * abs(step))
    if step <= 0 or len(off):
        n = int(off[0]) + 1 if len(off) else 1
        raise CsvError(
            path,
            header_line + 1 + n,
            column,
            f"time steps unevenly (mean step {step:g} s): not one sample rate",
        )
    return 1.0 / step


@dataclass(frozen=True)
class ImportedRun:
    """A run's CSV files read, one table per point."""

    mapping: RunMapping
    tables: tuple[CsvTable, ...]

    @property
    def sample_rate_hz(self) -> float:
        return self.tables[0].sample_rate_hz


def read_run(run: RunMapping, mapping: ImportMapping) -> ImportedRun:
    """Every file of ``run``, read and checked: one sample rate."""
    tables = tuple(read_csv(f.file, mapping) for f in run.files)
    rate = tables[0].sample_rate_hz
    for f, table in zip(run.files, tables, strict=True):
        if not math.isclose(table.sample_rate_hz, rate, rel_tol=1e-6):
            raise CsvError(
                f.file,
                None,
                None,
                f"sample rate {table.sample_rate_hz:g} Hz differs from the run's {rate:g} Hz",
            )
    return ImportedRun(run, tables)


@dataclass(frozen=True)
class ImportLimits:
    """What the mapped values must lie within: the bench's excitation frequency range (its
    configuration's limits) and the tyre pressures a ``set_tyre_pressure`` prompt accepts (bar)."""

    min_freq_hz: float
    max_freq_hz: float
    min_tyre_pressure_bar: float
    max_tyre_pressure_bar: float


def check_mapped_values(mapping: ImportMapping, runs: list[ImportedRun], limits: ImportLimits) -> None:
    """Refuse, with a :class:`~bench.store.csv_mapping.MappingError` listing every problem in the
    mapping's order, what the files and the bench make impossible: a frequency outside the bench's
    range or not below half its file's sample rate (a time column in the wrong unit shows here), a
    sweep's ``duration_s`` more than one sample from its file's length, a hold beyond its file, a
    tyre pressure no pressure prompt accepts."""
    problems: list[tuple[str, str]] = []
    lo_bar, hi_bar = limits.min_tyre_pressure_bar, limits.max_tyre_pressure_bar
    for i, run in enumerate(runs):
        m = run.mapping
        pressure = m.tyre_pressure_bar
        if pressure is not None and not lo_bar <= pressure <= hi_bar:
            problems.append(
                (
                    f"runs[{i}].tyre_pressure_bar",
                    f"{pressure:g} bar is outside what a set_tyre_pressure prompt accepts"
                    f" (allowed {lo_bar:g} <= tyre_pressure_bar <= {hi_bar:g} bar)",
                )
            )
        for j, (f, table) in enumerate(zip(m.files, run.tables, strict=True)):
            if isinstance(f, SweepFile):
                problems += _sweep_problems(f"runs[{i}]", f, table, limits)
            else:
                problems += _dwell_problems(f"runs[{i}].points[{j}]", f, table, limits)
    if problems:
        raise mapping_error(mapping.path, load_toml(mapping.text), problems)


def _frequency_problem(
    key: str, freq_hz: float, table: CsvTable, limits: ImportLimits
) -> tuple[str, str] | None:
    """A frequency outside the bench's range, or not below half the file's sample rate."""
    name = key.rsplit(".", 1)[-1]
    nyquist_hz = table.sample_rate_hz / 2
    below_nyquist = nyquist_hz <= limits.max_freq_hz
    upper = f"< {nyquist_hz:g}" if below_nyquist else f"<= {limits.max_freq_hz:g}"
    allowed = f"(allowed {limits.min_freq_hz:g} <= {name} {upper} Hz)"
    if freq_hz < limits.min_freq_hz:
        return key, f"{freq_hz:g} Hz is below the bench's minimum {allowed}"
    if freq_hz > limits.max_freq_hz:
        return key, f"{freq_hz:g} Hz is above the bench's maximum {allowed}"
    if freq_hz >= nyquist_hz:
        rate = f"{table.path.name} ({table.sample_rate_hz:g} Hz)"
        return key, f"{freq_hz:g} Hz is not below half the sample rate of {rate} {allowed}"
    return None


def _dwell_problems(at: str, f: DwellFile, table: CsvTable, limits: ImportLimits) -> list[tuple[str, str]]:
    problems = [_frequency_problem(f"{at}.freq_hz", f.freq_hz, table, limits)]
    length_s = len(table) / table.sample_rate_hz
    samples = f"the {length_s:g} s of samples of {table.path.name}"
    if f.hold_start_s >= length_s:
        problems.append(
            (
                f"{at}.hold_start_s",
                f"{f.hold_start_s:g} s is beyond {samples} (allowed 0 <= hold_start_s < {length_s:g} s)",
            )
        )
    elif f.hold_end_s is not None and f.hold_end_s > length_s:
        problems.append(
            (
                f"{at}.hold_end_s",
                f"{f.hold_end_s:g} s is beyond {samples}"
                f" (allowed hold_start_s < hold_end_s <= {length_s:g} s)",
            )
        )
    return [p for p in problems if p is not None]


def _sweep_problems(at: str, f: SweepFile, table: CsvTable, limits: ImportLimits) -> list[tuple[str, str]]:
    problems = [
        _frequency_problem(f"{at}.start_hz", f.start_hz, table, limits),
        _frequency_problem(f"{at}.end_hz", f.end_hz, table, limits),
    ]
    sample_s = 1 / table.sample_rate_hz
    length_s = len(table) * sample_s
    if abs(f.duration_s - length_s) > sample_s * (1 + 1e-9):
        problems.append(
            (
                f"{at}.duration_s",
                f"{f.duration_s:g} s does not match the {length_s:g} s of samples of {table.path.name}"
                f" (allowed {length_s:g} s, within one sample: {sample_s:g} s)",
            )
        )
    return [p for p in problems if p is not None]


def import_campaign(
    mapping: ImportMapping,
    out_path: Path,
    *,
    limits: ImportLimits,
    config_toml: str,
    software_version: str,
) -> None:
    """Read every CSV file of ``mapping`` and check the mapped values against them and ``limits``,
    then write the campaign file ``out_path`` (never over an existing file). ``config_toml``: the
    bench configuration recorded with the campaign."""
    out_path = Path(out_path)
    if out_path.exists():
        raise FileExistsError(f"{out_path} exists already: import into a new file")
    runs = [read_run(run, mapping) for run in mapping.runs]
    check_mapped_values(mapping, runs, limits)
    tmp = out_path.with_name(f".{out_path.name}.importing-{os.getpid()}")
    with _removed_on_failure(tmp):
        with CampaignWriter.create(
            tmp,
            software_version=software_version,
            config_toml=config_toml,
            sequence_toml=mapping.text,
            sequence_name=mapping.name,
            config_name=f"CSV import {mapping.path.name}",
        ) as campaign:
            campaign.add_event(
                "import", f"imported from CSV with {mapping.path.name}", mapping=str(mapping.path)
            )
            for run in runs:
                _write_run(campaign, run, mapping)
        if out_path.exists():
            raise FileExistsError(f"{out_path} appeared during the import: not replaced")
        os.replace(tmp, out_path)


@contextlib.contextmanager
def _removed_on_failure(path: Path) -> Iterator[None]:
    try:
        yield
    except BaseException:
        path.unlink(missing_ok=True)
        raise


def _write_run(campaign: CampaignWriter, run: ImportedRun, mapping: ImportMapping) -> None:
    m = run.mapping
    rate = run.sample_rate_hz
    conditions: dict[str, object] = {"bench": mapping.bench, "wheel_fitted": m.kind != "free_run"}
    if m.tyre_pressure_bar is not None:
        conditions["tyre_pressure_bar"] = m.tyre_pressure_bar
    channels = [
        Channel(
            c.channel,
            c.si_unit,
            f"CSV column {c.column!r} x {c.scale:g}",
            role=role_of_standard_name(c.channel),
        )
        for c in mapping.channels
    ]
    writer = campaign.begin_run(
        m.run_id, kind=m.kind, step=_step(m), conditions=conditions, channels=channels, sample_rate_hz=rate
    )
    start = 0
    for index, (f, table) in enumerate(zip(m.files, run.tables, strict=True)):
        writer.append({name: values.astype(np.float32) for name, values in table.columns.items()})
        writer.add_event("import", f"point {index} from {f.file.name}", file=str(f.file), rows=len(table))
        writer.add_point(_point(index, f, start, len(table), rate))
        start += len(table)
    writer.finish("complete")


def _point(index: int, f: DwellFile | SweepFile, start: int, n: int, rate_hz: float) -> PointAttempt:
    if isinstance(f, SweepFile):
        return PointAttempt(0, f.start_hz, f.amplitude_mm, start, start, start + n, start + n)
    hold_start = start + round(f.hold_start_s * rate_hz)
    hold_end = start + (n if f.hold_end_s is None else round(f.hold_end_s * rate_hz))
    return PointAttempt(
        index,
        f.freq_hz,
        f.amplitude_mm,
        start,
        hold_start,
        hold_end,
        start + n,
        requested_amplitude_mm=f.requested_amplitude_mm,
    )


def _step(m: RunMapping) -> dict[str, object]:
    """The run's step as the schema records it (docs/hdf5.md): what the CSV files were."""
    if m.kind == "sweep":
        (f,) = m.files
        return {
            "kind": "sweep",
            "start_hz": f.start_hz,
            "end_hz": f.end_hz,
            "duration_s": f.duration_s,
            "amplitude_mm": f.amplitude_mm,
            "law": f.law,
            "source": "csv import",
        }
    return {
        "kind": m.kind,
        "freqs_hz": [f.freq_hz for f in m.files],
        "amplitudes_mm": sorted({f.amplitude_mm for f in m.files}),
        "files": [f.file.name for f in m.files],
        "source": "csv import",
    }
