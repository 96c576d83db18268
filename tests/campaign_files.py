"""Campaign files written straight from analysis records, as another writer of the schema would
write them: each run's dwells (or hammer blow) one after another with their points, no engine.
Tests of what the analysis of a file gives write the runs they need with :func:`write_campaign`."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench.analysis.records import FREE_RUN_CHANNELS, DwellRecord, HammerRecord, SweepRecord
from bench.config import BenchConfig, default_bench_config
from bench.models.setup import BenchKind, BenchSetup
from bench.store import CampaignWriter
from sequences.channels import Channel
from sequences.points import PointAttempt

#: The unit of each channel the records carry, by its name's suffix.
_UNITS = {"_m": "m", "_n": "N", "_m_s2": "m/s^2"}


def _unit(name: str) -> str:
    return next(
        unit for suffix, unit in sorted(_UNITS.items(), key=lambda s: -len(s[0])) if name.endswith(suffix)
    )


@dataclass(frozen=True)
class StoredRun:
    """One run to write: ``kind`` (``free_run``, ``dwell_grid``, ``hammer``, ``sweep``: one record,
    its step from the record), its records, its ``conditions`` and ``status``; ``channels``: the
    names written (default: every channel of the first record)."""

    run_id: str
    kind: str
    records: tuple[DwellRecord, ...] | tuple[HammerRecord, ...] | tuple[SweepRecord]
    conditions: dict[str, Any] = field(default_factory=dict)
    status: str = "complete"
    channels: tuple[str, ...] | None = None
    reason: str = ""  # why the run ended as it did (its ``status``)
    events: tuple[tuple[str, str], ...] = ()  # (kind, text) of events recorded after its records


def write_campaign(path: Path, runs: list[StoredRun], config: BenchConfig | None = None) -> Path:
    """Write ``runs`` into a new campaign file at ``path`` with ``config`` (default: the default
    shaker configuration) recorded as its bench configuration."""
    config = config or default_bench_config()
    with CampaignWriter.create(
        path,
        software_version="test",
        config_toml=config.to_toml(),
        sequence_toml="",
        sequence_name="written",
        config_name=config.source,
    ) as writer:
        for stored in runs:
            first = stored.records[0]
            names = stored.channels or tuple(first.channels)
            step: dict[str, Any] = {"type": stored.kind}
            if isinstance(first, SweepRecord):
                step.update(
                    start_hz=first.start_hz,
                    end_hz=first.end_hz,
                    duration_s=first.sweep_s,
                    amplitude_mm=1e3 * first.amplitude_m,
                )
            run = writer.begin_run(
                stored.run_id,
                kind=stored.kind,
                step=step,
                conditions=stored.conditions,
                channels=tuple(Channel(name, _unit(name)) for name in names),
                sample_rate_hz=first.sample_rate_hz,
            )
            for index, record in enumerate(stored.records):
                start = run.samples
                run.append({name: record.channels[name] for name in names})
                n = run.samples - start
                if isinstance(record, HammerRecord | SweepRecord):
                    run.add_point(PointAttempt(index, math.nan, math.nan, start, start, start + n, start + n))
                    continue
                hold = record.hold_s or (0.0, n / record.sample_rate_hz)
                hold_start, hold_end = (start + round(t * record.sample_rate_hz) for t in hold)
                nominal_mm = (
                    math.nan if record.nominal_amplitude_m is None else 1e3 * record.nominal_amplitude_m
                )
                run.add_point(
                    PointAttempt(
                        index,
                        record.freq_hz,
                        1e3 * record.amplitude_m,
                        start,
                        hold_start,
                        hold_end,
                        start + n,
                        requested_amplitude_mm=nominal_mm,
                    )
                )
            for kind, text in stored.events:
                run.add_event(kind, text)
            run.finish(stored.status, stored.reason)
    return path



def write_analysed_campaign(path: Path, runs: list[StoredRun], config: BenchConfig | None = None) -> Path:
    """:func:`write_campaign`, then the runs analysed and their analysis stored beside them, as
    ``wfsbench analyze`` stores it on a file without stored analyses: the commands that read the
    file (``compensate``, ``report``, ``export``) read the analysis instead of fitting it again."""
    from bench.app.analyze import analyze_campaign, store_reanalysis

    write_campaign(path, runs, config)
    store_reanalysis(analyze_campaign(path, keep_records=True))
    return path


def paper_corner_runs(car: BenchSetup, *, more_pressures_bar: tuple[float, ...] = ()) -> list[StoredRun]:
    """The paper's procedure for one corner at 2.5 bar: the shaker's free run, the 2.5 bar grids at
    1 / 2 / 5 mm, a 2 mm grid at each of ``more_pressures_bar``, the post's free run and the
    four-post sweep of ``car`` (its last two runs: leave them out for a shaker-only campaign)."""
    from bench.simulated_campaign import (
        FREE_RUN_GRID_HZ,
        PAPER_AMPLITUDES_M,
        PAPER_SWEEP,
        SHAKER_GRID_HZ,
        simulate_dwells,
        simulate_sweep,
    )

    free = simulate_dwells(BenchSetup.paper_free_run(), FREE_RUN_GRID_HZ, 2e-3, seed=100)
    runs = [StoredRun("free", "free_run", tuple(free), {"wheel_fitted": False}, channels=FREE_RUN_CHANNELS)]
    for i, amplitude in enumerate(PAPER_AMPLITUDES_M):
        grid = simulate_dwells(BenchSetup.paper_shaker(2.5), SHAKER_GRID_HZ, amplitude, seed=10 + i)
        runs.append(StoredRun(f"grid-{i}", "dwell_grid", tuple(grid), {"tyre_pressure_bar": 2.5}))
    for i, pressure in enumerate(more_pressures_bar):
        grid = simulate_dwells(BenchSetup.paper_shaker(pressure), SHAKER_GRID_HZ, 2e-3, seed=20 + i)
        runs.append(
            StoredRun(f"grid-{pressure:g}bar", "dwell_grid", tuple(grid), {"tyre_pressure_bar": pressure})
        )
    post = simulate_dwells(BenchSetup(BenchKind.FREE_RUN, rig=car.rig), FREE_RUN_GRID_HZ, 2e-3, seed=101)
    sweep = simulate_sweep(car, PAPER_SWEEP, seed=102)
    return [
        *runs,
        StoredRun("post-free", "free_run", tuple(post), {"bench": "four_post"}, channels=FREE_RUN_CHANNELS),
        StoredRun("sweep", "sweep", (sweep,), {"bench": "four_post", "tyre_pressure_bar": 2.5}),
    ]
