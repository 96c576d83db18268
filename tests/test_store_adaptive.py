"""The points table's adaptive-dwell fields: written and read back, absent from older files (read
with their defaults), added to an older run's table when its writing resumes, and the measured part
of an adaptive dwell given to the analysis."""

from __future__ import annotations

import math
from dataclasses import astuple, replace
from pathlib import Path

import h5py
import numpy as np
import pytest

from bench.analysis.records import DEFAULT_SETTLE_S
from bench.store import CampaignWriter, StoreError, open_campaign
from bench.store.schema import OPTIONAL_POINT_FIELDS
from sequences.channels import Channel
from sequences.points import PointAttempt
from tests.test_store_errors import FS_HZ, write_by_hand

CHANNELS = [Channel(name, "SI") for name in ("z_base_m", "f_plate_n", "fz_wfs_n", "a_hub_m_s2")]


def _same(a: PointAttempt, b: PointAttempt) -> bool:
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


def test_a_version_1_file_is_read_as_version_2_and_never_appended_to(tmp_path: Path) -> None:
    """A file of the earlier schema (its points table with ``corrected_amplitude_mm``, NaN for an
    uncorrected command, and ``settled``; no adaptive fields) reads as the point attempts it recorded;
    the writer refuses to add runs to it, naming the version."""
    path = tmp_path / "campaign.h5"
    first = PointAttempt(0, 10.0, 1.0, 0, 150, 850, 1000, commanded_amplitude_mm=1.0, note="fixed")
    second = PointAttempt(1, 20.0, 1.0, 1000, 1150, 1850, 2000, commanded_amplitude_mm=1.1)
    with _writer(path) as writer:
        run = writer.begin_run(
            "grid", kind="dwell_grid", step={}, conditions={}, channels=CHANNELS, sample_rate_hz=FS_HZ
        )
        run.append({c.name: np.zeros(2000, "f4") for c in CHANNELS})
        run.add_point(first)
        run.add_point(second)
        run.finish("complete")
    with h5py.File(path, "r+") as f:  # the file as the version 1 writer made it
        table = f["runs/grid/points"][()]
        kept = [
            n for n in table.dtype.names if n not in OPTIONAL_POINT_FIELDS and n != "commanded_amplitude_mm"
        ]
        v1 = np.zeros(
            len(table),
            [*[(n, table.dtype[n]) for n in kept], ("corrected_amplitude_mm", "<f8"), ("settled", "u1")],
        )
        for name in kept:
            v1[name] = table[name]
        v1["corrected_amplitude_mm"] = [np.nan, 1.1]
        v1["settled"] = [1, 0]
        del f["runs/grid/points"]
        f["runs/grid"].create_dataset("points", data=v1, maxshape=(None,), chunks=(64,))
        f.attrs["schema_version"] = 1
    with open_campaign(path) as f:
        assert f.schema_version == 1
        read_first, read_second = f.runs[0].points
    assert _same(read_first, first)
    assert _same(read_second, replace(second, verdict="not settled"))
    assert not read_second.settled
    with pytest.raises(StoreError, match=r"/@schema_version: is 1: this software adds runs to version 2"):
        _writer(path, append=True)


def test_an_adaptive_dwell_round_trips_and_its_record_holds_its_measured_part(tmp_path: Path) -> None:
    path = tmp_path / "campaign.h5"
    n = 3000
    with _writer(path) as writer:
        run = writer.begin_run(
            "grid", kind="dwell_grid", step={}, conditions={}, channels=CHANNELS, sample_rate_hz=FS_HZ
        )
        t = np.arange(n) / FS_HZ
        run.append({c.name: np.sin(2 * np.pi * 10.0 * t).astype("f4") for c in CHANNELS})
        row = PointAttempt(
            index=9,
            freq_hz=10.0,
            amplitude_mm=1.0,
            requested_amplitude_mm=1.0,
            commanded_amplitude_mm=1.02,
            achieved_amplitude_mm=0.99,
            start_sample=0,
            hold_start_sample=150,
            hold_end_sample=2850,
            end_sample=n,
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
    # the fields it leaves NaN (no update, no notch) are read back as NaN, each a new NaN object
    assert all(
        x == y or (isinstance(x, float) and math.isnan(x) and math.isnan(y))
        for x, y in zip(astuple(read), astuple(row), strict=True)
    )
    # the analysis leaves its settling allowance before the measured part, not before the hold
    assert record.hold_s == ((550 - round(DEFAULT_SETTLE_S * FS_HZ)) / FS_HZ, 2850 / FS_HZ)
