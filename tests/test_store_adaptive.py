"""The points table's adaptive-dwell fields: written and read back, absent from older files (read
with their defaults), added to an older run's table when its writing resumes, and the measured part
of an adaptive dwell given to the analysis."""

from __future__ import annotations

import math
from dataclasses import astuple
from pathlib import Path

import h5py
import numpy as np

from bench.analysis.records import DEFAULT_SETTLE_S
from bench.store import CampaignWriter, PointRow, open_campaign
from bench.store.schema import OPTIONAL_POINT_FIELDS
from sequences.channels import Channel
from tests.test_store_errors import FS_HZ, write_by_hand

CHANNELS = [Channel(name, "SI") for name in ("z_base_m", "f_plate_n", "fz_wfs_n", "a_hub_m_s2")]


def _same(a: PointRow, b: PointRow) -> bool:
    """Equal rows, NaN equal to NaN."""
    return all(
        x == y or (isinstance(x, float) and math.isnan(x) and math.isnan(y))
        for x, y in zip(astuple(a), astuple(b), strict=True)
    )


def _writer(path: Path, *, append: bool = False) -> CampaignWriter:
    if append:
        return CampaignWriter.open_append(path)
    return CampaignWriter.create(
        path, software_version="test", config_toml="", sequence_toml="", sequence_name="t"
    )


def test_a_file_without_the_adaptive_fields_reads_with_their_defaults(tmp_path: Path) -> None:
    with open_campaign(write_by_hand(tmp_path / "old.h5")) as f:
        (run,) = f.runs
        for p in run.points:
            assert p.verdict == "" and p.added_reason == "" and p.measure_start_sample == -1
            assert math.isnan(p.settle_s) and math.isnan(p.magnitude_uncertainty_pct)
            assert math.isnan(p.phase_uncertainty_deg)
        assert [r.hold_s for r in run.dwell_records()] == [(0.2, 1.8), (0.2, 1.8)]


def test_resuming_an_older_run_adds_the_fields_and_keeps_its_rows(tmp_path: Path) -> None:
    """A run cut short by a writer of the earlier points table goes on in a table with the fields."""
    path = tmp_path / "campaign.h5"
    row = PointRow(
        0,
        10.0,
        1.0,
        0,
        150,
        850,
        1000,
        requested_amplitude_mm=1.0,
        corrected_amplitude_mm=1.0,
        achieved_amplitude_mm=1.0,
        note="fixed",
    )
    with _writer(path) as writer:
        run = writer.begin_run(
            "grid", kind="dwell_grid", step={}, conditions={}, channels=CHANNELS, sample_rate_hz=FS_HZ
        )
        run.append({c.name: np.zeros(1000, "f4") for c in CHANNELS})
        run.add_point(row)
        writer.flush()  # the writer stops here without finishing the run
    with h5py.File(path, "r+") as f:  # the table as the earlier writer made it
        table = f["runs/grid/points"]
        old = [name for name in table.dtype.names if name not in OPTIONAL_POINT_FIELDS]
        rows = table[()][old]
        del f["runs/grid/points"]
        f["runs/grid"].create_dataset("points", data=rows, maxshape=(None,), chunks=(64,))
    with _writer(path, append=True) as writer:
        writer.continue_run("grid").finish("complete")
    with h5py.File(path, "r") as f:
        assert set(OPTIONAL_POINT_FIELDS) <= set(f["runs/grid/points"].dtype.names)
    with open_campaign(path) as f:
        (read,) = f.runs[0].points
    assert _same(read, row)


def test_an_adaptive_dwell_round_trips_and_its_record_holds_its_measured_part(tmp_path: Path) -> None:
    path = tmp_path / "campaign.h5"
    n = 3000
    with _writer(path) as writer:
        run = writer.begin_run(
            "grid", kind="dwell_grid", step={}, conditions={}, channels=CHANNELS, sample_rate_hz=FS_HZ
        )
        t = np.arange(n) / FS_HZ
        run.append({c.name: np.sin(2 * np.pi * 10.0 * t).astype("f4") for c in CHANNELS})
        row = PointRow(
            index=9,
            freq_hz=10.0,
            amplitude_mm=1.0,
            requested_amplitude_mm=1.0,
            corrected_amplitude_mm=1.02,
            achieved_amplitude_mm=0.99,
            start_sample=0,
            hold_start_sample=150,
            hold_end_sample=2850,
            end_sample=n,
            settled=True,
            verdict="target",
            settle_s=1.5,
            measure_start_sample=150 + 400,
            magnitude_uncertainty_pct=0.31,
            phase_uncertainty_deg=0.18,
            added_reason="model peak: a single-mode fit puts the peak at 10.00 Hz",
        )
        run.add_point(row)
        run.finish("complete")
    with open_campaign(path) as f:
        (read,) = f.runs[0].points
        (record,) = f.runs[0].dwell_records()
    assert read == row
    # the analysis leaves its settling allowance before the measured part, not before the hold
    assert record.hold_s == ((550 - round(DEFAULT_SETTLE_S * FS_HZ)) / FS_HZ, 2850 / FS_HZ)
