"""CSV exports of another acquisition system brought into a campaign file (docs/import.md).

Every CSV file the mapping names is read once (:mod:`bench.store.csv_read`) and checked first, into
SI channels; only then is the campaign written, through :class:`bench.store.CampaignWriter`, to a
temporary file beside the output that is renamed into place once complete. So a bad CSV file (a
column the run needs missing, text in a number, a ragged row, an unknown unit, an empty file) is
refused with its file, line and column, and nothing half-written is left behind. The values the
mapping gives are then checked against the files and the bench (:func:`check_mapped_values`):
frequencies within the bench's range and below half the sample rate, a sweep's duration the length
of its file, points and holds inside their files, the points of one file apart, tyre pressures that
a pressure prompt accepts; every problem names the mapping file and the key.

Only the points are written: the part of its file each point names, so one continuous file per run
imports into a campaign file the size of one file per point.
"""

from __future__ import annotations

import contextlib
import itertools
import math
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench.store.csv_mapping import ImportMapping, PointPart, RunMapping, SweepFile, mapping_error
from bench.store.csv_read import CsvError, CsvTable, read_csv
from bench.store.reader import REQUIRED_CHANNELS
from bench.store.temporary import temporary_beside
from bench.store.writer import CampaignWriter
from sequences.channels import Channel, role_of_standard_name
from sequences.points import PointAttempt
from sequences.runs import EventKind, RunKind
from sequences.toml_text import load_toml


@dataclass(frozen=True)
class ImportedRun:
    """A run's CSV files read: each point's file as a table (several points may share one), the
    mapped ``channels`` its files have, and the mapped channels they all lack (``left_out``: its
    kind does not need them)."""

    mapping: RunMapping
    tables: tuple[CsvTable, ...]
    channels: tuple[str, ...]
    left_out: tuple[str, ...]

    @property
    def sample_rate_hz(self) -> float:
        return self.tables[0].sample_rate_hz


def read_run(run: RunMapping, mapping: ImportMapping, read: dict[tuple, CsvTable]) -> ImportedRun:
    """Every file of ``run``, read once and checked: one sample rate, and the same mapped columns
    in every file, a column lacking in all of them only where the run's kind does not need its
    channel. ``read``: the tables read so far (this run's are added), by file, timing and
    channels, so that a file is read once whatever number of points and runs name it."""
    tables = {}
    for file in run.files:
        key = (file, run.timing, run.channels)
        if key not in read:
            read[key] = read_csv(file, mapping.dialect, run.timing, run.channels)
        tables[file] = read[key]
    first = tables[run.points[0].file]
    for table in tables.values():
        if not math.isclose(table.sample_rate_hz, first.sample_rate_hz, rel_tol=1e-6):
            raise CsvError(
                table.path,
                None,
                None,
                f"sample rate {table.sample_rate_hz:g} Hz differs from the run's {first.sample_rate_hz:g} Hz",
            )
    needed = REQUIRED_CHANNELS[run.kind]
    channels, left_out = [], []
    for c in run.channels:
        having = [t for t in tables.values() if c.channel in t.columns]
        lacking = [t for t in tables.values() if c.channel not in t.columns]
        if not lacking:
            channels.append(c.channel)
        elif having:
            raise lacking[0].missing(c, f", though {having[0].path.name} of the same run has it")
        elif c.channel in needed:
            raise lacking[0].missing(c, f": a {run.kind} run needs {c.channel}")
        else:
            left_out.append(c.channel)
    return ImportedRun(run, tuple(tables[p.file] for p in run.points), tuple(channels), tuple(left_out))


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
    sweep's ``duration_s`` more than one sample from its file's length, a point or hold beyond its
    file, points of one file that overlap, a tyre pressure no pressure prompt accepts, a mapped
    column in none of the files."""
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
        for j, (f, table) in enumerate(zip(m.points, run.tables, strict=True)):
            if isinstance(f, SweepFile):
                problems += _sweep_problems(f"runs[{i}]", f, table, limits)
            else:
                problems += _point_problems(f"runs[{i}].points[{j}]", f, table, limits)
        problems += _overlaps(f"runs[{i}]", m)
    problems += _columns_in_no_file(runs)
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


def _point_problems(at: str, f: PointPart, table: CsvTable, limits: ImportLimits) -> list[tuple[str, str]]:
    """A dwell's frequency (a hammer blow has none); a part or hold beyond the file."""
    problems = []
    if f.freq_hz:
        problems.append(_frequency_problem(f"{at}.freq_hz", f.freq_hz, table, limits))
    length_s = table.length_s
    samples = f"the {length_s:g} s of samples of {table.path.name}"
    for key, value_s, allowed in (
        ("start_s", f.start_s, f"0 <= start_s < {length_s:g} s"),
        ("hold_start_s", f.hold_start_s, f"0 <= hold_start_s < {length_s:g} s"),
    ):
        if value_s is not None and value_s >= length_s:
            problems.append((f"{at}.{key}", f"{value_s:g} s is beyond {samples} (allowed {allowed})"))
    for key, value_s, allowed in (
        ("end_s", f.end_s, f"start_s < end_s <= {length_s:g} s"),
        ("hold_end_s", f.hold_end_s, f"hold_start_s < hold_end_s <= {length_s:g} s"),
    ):
        if value_s is not None and value_s > length_s:
            problems.append((f"{at}.{key}", f"{value_s:g} s is beyond {samples} (allowed {allowed})"))
    return [p for p in problems if p is not None]


def _overlaps(at: str, m: RunMapping) -> list[tuple[str, str]]:
    """Points of one file whose parts overlap: each would be stored with the other's samples
    (refused rather than stored twice; a point's part defaults to its whole file)."""
    problems = []
    parts = sorted(
        (p.file, p.start_s, math.inf if p.end_s is None else p.end_s, j)
        for j, p in enumerate(m.points)
        if isinstance(p, PointPart)
    )
    for (file, start_a, end_a, a), (other, start_b, _, b) in itertools.pairwise(parts):
        if file == other and start_b < end_a:
            end = "its end" if math.isinf(end_a) else f"{end_a:g} s"
            problems.append(
                (
                    f"{at}.points[{b}].start_s",
                    f"{start_b:g} s lies inside the part of {file.name} that {at}.points[{a}] holds"
                    f" ({start_a:g} s to {end}): the points of one file must not overlap (give each"
                    " point its start_s and end_s)",
                )
            )
    return problems


def _columns_in_no_file(runs: list[ImportedRun]) -> list[tuple[str, str]]:
    """Mapped columns that no file of any run mapping them has: a misspelt header, most likely."""
    found: dict[tuple[str, str], bool] = {}
    for run in runs:
        for c in run.mapping.channels:
            key = (f"{run.mapping.channels_key}.{c.channel}.column", c.column)
            found[key] = found.get(key, False) or c.channel in run.channels
    return [
        (key, f"{column!r} is a column of none of the CSV files that map it")
        for (key, column), seen in found.items()
        if not seen
    ]


def _sweep_problems(at: str, f: SweepFile, table: CsvTable, limits: ImportLimits) -> list[tuple[str, str]]:
    problems = [
        _frequency_problem(f"{at}.start_hz", f.start_hz, table, limits),
        _frequency_problem(f"{at}.end_hz", f.end_hz, table, limits),
    ]
    sample_s = 1 / table.sample_rate_hz
    length_s = table.length_s
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
    metadata: Mapping[str, str] | None = None,
) -> tuple[ImportedRun, ...]:
    """Read every CSV file of ``mapping`` and check the mapped values against them and ``limits``,
    then write the campaign file ``out_path`` (never over an existing file). ``config_toml``: the
    bench configuration recorded with the campaign; ``metadata``: its test metadata (field -> text,
    recorded on the campaign and every run). Returns the runs as read (what each holds)."""
    out_path = Path(out_path)
    if out_path.exists():
        raise FileExistsError(f"{out_path} exists already: import into a new file")
    read: dict[tuple, CsvTable] = {}
    runs = [read_run(run, mapping, read) for run in mapping.runs]
    check_mapped_values(mapping, runs, limits)
    tmp = temporary_beside(out_path)
    with _removed_on_failure(tmp):
        with CampaignWriter.create(
            tmp,
            software_version=software_version,
            config_toml=config_toml,
            sequence_toml=mapping.text,
            sequence_name=mapping.name,
            config_name=f"CSV import {mapping.path.name}",
            metadata=metadata,
        ) as campaign:
            campaign.add_event(
                EventKind.IMPORT, f"imported from CSV with {mapping.path.name}", mapping=str(mapping.path)
            )
            for run in runs:
                _write_run(campaign, run, mapping)
        if out_path.exists():
            raise FileExistsError(f"{out_path} appeared during the import: not replaced")
        os.replace(tmp, out_path)
    return tuple(runs)


@contextlib.contextmanager
def _removed_on_failure(path: Path) -> Iterator[None]:
    try:
        yield
    except BaseException:
        path.unlink(missing_ok=True)
        raise


def _write_run(campaign: CampaignWriter, run: ImportedRun, mapping: ImportMapping) -> None:
    """The run's points, each the part of its file it names, one after the other."""
    m = run.mapping
    rate = run.sample_rate_hz
    wheel_fitted = m.kind not in (RunKind.FREE_RUN, RunKind.HAMMER)
    conditions: dict[str, object] = {"bench": mapping.bench, "wheel_fitted": wheel_fitted}
    if m.tyre_pressure_bar is not None:
        conditions["tyre_pressure_bar"] = m.tyre_pressure_bar
    channels = [
        Channel(
            c.channel,
            c.si_unit,
            f"CSV column {c.column!r} x {c.scale:g}",
            role=role_of_standard_name(c.channel),
        )
        for c in m.channels
        if c.channel in run.channels
    ]
    writer = campaign.begin_run(
        m.run_id, kind=m.kind, step=_step(m), conditions=conditions, channels=channels, sample_rate_hz=rate
    )
    offset = 0
    for index, (f, table) in enumerate(zip(m.points, run.tables, strict=True)):
        start, hold_start, hold_end, end = _samples(f, table)
        writer.append({name: table.columns[name][start:end].astype(np.float32) for name in run.channels})
        writer.add_event(
            EventKind.IMPORT,
            f"point {index} from {f.file.name}, samples {start} to {end}",
            file=str(f.file),
            rows=end - start,
            first_row=start,
        )
        positions = (offset, offset + hold_start - start, offset + hold_end - start, offset + end - start)
        writer.add_point(_point(index, f, positions))
        offset += end - start
    writer.finish("complete")


def _samples(f: PointPart | SweepFile, table: CsvTable) -> tuple[int, int, int, int]:
    """Where the point ``f`` starts, holds and ends in its file's rows (a sweep: the whole file)."""
    if isinstance(f, SweepFile):
        return 0, 0, table.n_rows, table.n_rows
    rate = table.sample_rate_hz
    start = round(f.start_s * rate)
    end = table.n_rows if f.end_s is None else min(round(f.end_s * rate), table.n_rows)
    hold_start = start if f.hold_start_s is None else round(f.hold_start_s * rate)
    hold_end = end if f.hold_end_s is None else min(round(f.hold_end_s * rate), end)
    return start, hold_start, hold_end, end


def _point(index: int, f: PointPart | SweepFile, positions: tuple[int, int, int, int]) -> PointAttempt:
    """The point attempt of ``f`` at sample ``positions`` (start, hold start, hold end, end) of the run."""
    if isinstance(f, SweepFile):
        return PointAttempt(0, f.start_hz, f.amplitude_mm, *positions)
    return PointAttempt(
        index, f.freq_hz, f.amplitude_mm, *positions, requested_amplitude_mm=f.requested_amplitude_mm
    )


def _step(m: RunMapping) -> dict[str, object]:
    """The run's step as the schema records it (docs/hdf5.md): what the CSV files were."""
    if m.kind == RunKind.SWEEP:
        (f,) = m.points
        return {
            "kind": "sweep",
            "start_hz": f.start_hz,
            "end_hz": f.end_hz,
            "duration_s": f.duration_s,
            "amplitude_mm": f.amplitude_mm,
            "law": f.law,
            "source": "csv import",
        }
    parts = {
        "files": [f.file.name for f in m.points],
        "parts_s": [[f.start_s, f.end_s] for f in m.points],
        "source": "csv import",
    }
    if m.kind == RunKind.HAMMER:
        return {"kind": "hammer", "blows": len(m.points), **parts}
    return {
        "kind": m.kind,
        "freqs_hz": [f.freq_hz for f in m.points],
        "amplitudes_mm": sorted({f.amplitude_mm for f in m.points}),
        **parts,
    }


def import_summary(run: ImportedRun) -> str:
    """What a run became: ``lab-r000-free_run (free_run, 4 points from 1 file, without fz_wfs_n:
    not in its files, a free_run does not need it)``."""
    m = run.mapping
    points, files = len(m.points), len(m.files)
    text = f"{m.run_id} ({m.kind}, {points} point{'s' * (points != 1)} from {files} file{'s' * (files != 1)}"
    if run.left_out:
        them = "it" if len(run.left_out) == 1 else "them"
        text += f", without {', '.join(run.left_out)}: not in its files, a {m.kind} run does not need {them}"
    return text + ")"
