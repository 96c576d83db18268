"""A campaign's runs as CSV files with a header row and a units row, and the mapping file with
which ``wfsbench import-csv`` (docs/import.md) reads them back into a campaign file.

One file per run, ``<run_id>.csv``: a column ``time_s`` (seconds from the run's first sample),
then every channel the run recorded under its name in the campaign file; the line under the header
gives each column's unit. Values are written as recorded: a float32 as the shortest decimal that
reads back as the same float32, an integer counter as an integer. A sweep's file holds the
sweep (its done point) only, since the import takes a sweep's file as the sweep.

Beside them ``mapping.toml``, one ``[[runs]]`` table per run with done points: each point's part of
its file and its hold, frequency and amplitude, the run's tyre pressure, sample rate and channels.
The mapping maps the channels whose names promise an SI unit the import knows (``fz_wfs_n``,
``z_base_m``, ``a_hub_m_s2``, ...); the link counters, the status bits and channels of other units
(``speed_rad_s``, a spare input in volts) are in the files but not imported. The import takes one
bench kind per mapping: a campaign of shaker and four-post runs gets one mapping per bench,
``mapping_shaker.toml`` and ``mapping_four_post.toml``.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from bench.engine.run_ids import RUN_ID
from bench.export.common import done_points, output_folder
from bench.store import CampaignFile, RunView
from bench.store.csv_mapping import IMPORTED_KINDS
from bench.store.csv_units import channel_si_unit, unit_named
from sequences.runs import RigKind, RunKind

TIME_COLUMN = "time_s"
MAPPING = "mapping.toml"
DELIMITER = ","
#: Data rows formatted at a time (bounded memory on an hour-long run).
BLOCK_ROWS = 65536


def _string(text: str) -> str:
    """A TOML basic string (JSON's escapes are TOML's for these texts)."""
    return json.dumps(text)


def _number(value: float) -> str:
    return repr(float(value))


def importable(run: RunView) -> list[str]:
    """The run's channels the import maps: those whose name promises an SI unit the import knows
    and whose recorded unit is that unit."""
    return [
        spec.name
        for spec in run.channel_specs
        if (si := channel_si_unit(spec.name)) is not None
        and (known := unit_named(spec.unit)) is not None
        and unit_named(si) == known
    ]


def _span(run: RunView) -> tuple[int, int]:
    """The samples the run's file holds: the whole run, a sweep its sweep."""
    points = done_points(run)
    if run.kind == RunKind.SWEEP and len(points) == 1:
        return points[0].start_sample, points[0].end_sample
    return 0, run.n_samples


def write_run_csv(run: RunView, path: Path) -> None:
    """The run's channels (its span, :func:`_span`) as CSV with a header and a units row."""
    start, stop = _span(run)
    specs = run.channel_specs
    header = DELIMITER.join([TIME_COLUMN, *(spec.name for spec in specs)])
    units = DELIMITER.join(["s", *(spec.unit for spec in specs)])
    with path.open("w", encoding="utf-8", newline="\n") as out:
        out.write(f"{header}\n{units}\n")
        for first in range(start, stop, BLOCK_ROWS):
            last = min(first + BLOCK_ROWS, stop)
            time_s = np.arange(first, last) / run.sample_rate_hz
            # numpy's str of a float is the shortest decimal that reads back as the same value
            columns = [time_s, *(np.asarray(run.channels[spec.name][first:last]) for spec in specs)]
            texts = [column.astype(str).tolist() for column in columns]
            out.write("\n".join(map(DELIMITER.join, zip(*texts, strict=True))))
            out.write("\n")


def _run_table(run: RunView) -> Iterator[str]:
    """The ``[[runs]]`` table of ``run`` in the mapping (its file named ``<run_id>.csv``)."""
    start, _ = _span(run)
    rate = run.sample_rate_hz
    yield "[[runs]]"
    yield f"kind = {_string(run.kind)}"
    yield f"id = {_string(run.run_id)}"
    if (pressure := run.conditions.get("tyre_pressure_bar")) is not None:
        yield f"tyre_pressure_bar = {_number(pressure)}"
    yield f"file = {_string(f'{run.run_id}.csv')}"
    if run.kind == RunKind.SWEEP:
        step = run.step
        for key in ("start_hz", "end_hz", "duration_s", "amplitude_mm"):
            yield f"{key} = {_number(step[key])}"
        yield f"law = {_string(step.get('law', 'linear'))}"
    yield "[runs.time]"
    yield f"sample_rate_hz = {_number(rate)}"
    yield "[runs.channels]"
    for name in importable(run):
        yield f"{name} = {{ column = {_string(name)} }}"
    if run.kind == RunKind.SWEEP:
        return
    for point in done_points(run):
        yield "[[runs.points]]"
        parts = [("start_s", point.start_sample), ("end_s", point.end_sample)]
        if run.kind != RunKind.HAMMER:  # a hammer blow has no hold in the mapping: its part is its hold
            parts += [("hold_start_s", point.hold_start_sample), ("hold_end_s", point.hold_end_sample)]
        for key, sample in parts:
            yield f"{key} = {_number((sample - start) / rate)}"
        if run.kind != RunKind.HAMMER:
            yield f"freq_hz = {_number(point.freq_hz)}"
            yield f"amplitude_mm = {_number(point.amplitude_mm)}"
            if math.isfinite(point.requested_amplitude_mm):
                yield f"requested_amplitude_mm = {_number(point.requested_amplitude_mm)}"


def mapping_text(campaign: CampaignFile, runs: list[RunView], bench: str) -> str:
    """The mapping that imports ``runs`` (all on ``bench``) from their CSV files, named after the
    sequence that recorded the first of them (its run id's; the campaign's first sequence for a
    run id of another writer)."""
    recorded = RUN_ID.match(runs[0].run_id) if runs else None
    sequence = recorded.group("sequence") if recorded else campaign.sequence_name
    name = re.sub(r"[^A-Za-z0-9_.-]", "_", sequence) or "campaign"
    lines = [
        f"# wfsbench export of {campaign.path.name}: import with  wfsbench import-csv THIS_FILE --out FILE",
        "[source]",
        f"name = {_string(name)}",
        f"bench = {_string(bench)}",
        "[csv]",
        f"delimiter = {_string(DELIMITER)}",
        "units_row = true",
    ]
    for run in runs:
        lines += ["", *_run_table(run)]
    return "\n".join(lines) + "\n"


def write_csv(campaign: CampaignFile, runs: tuple[RunView, ...], out: Path) -> list[Path]:
    """One CSV file per run and the mapping(s) in the new folder ``out`` (refused if it exists);
    returns the mappings' paths."""
    by_bench: dict[str, list[RunView]] = {}
    for run in runs:
        # a run without a done point has nothing the import could take; a kind it does not import
        # (a tracked dwell, a road replay) has its file without a mapping
        if done_points(run) and run.kind in IMPORTED_KINDS:
            by_bench.setdefault(run.conditions.get("bench", RigKind.SHAKER), []).append(run)
    mappings = []
    with output_folder(out) as folder:
        for run in runs:
            write_run_csv(run, folder / f"{run.run_id}.csv")
        for bench, members in by_bench.items():
            name = MAPPING if len(by_bench) == 1 else f"mapping_{bench}.toml"
            (folder / name).write_text(mapping_text(campaign, members, bench), encoding="utf-8")
            mappings.append(out / name)
    return mappings
