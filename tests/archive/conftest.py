"""A small archive for the index's tests: one campaign simulated by the bench, two copies given
other metadata (cheaper than simulating them), and its index built in this process, once."""

from __future__ import annotations

import dataclasses
from datetime import timedelta
from pathlib import Path

import pytest

from bench.archive.build import build_index
from bench.cluster import InProcess
from tests.archive_files import ArchiveCampaign, archive_campaign, copy_campaign, write_archive_campaign

#: The simulated campaign: sensor 0001, tyre T1 at 2 bar, on bench 2, with an interlocked grid.
SIMULATED = dataclasses.replace(archive_campaign(6), bench_id="2")
#: The copies: the same measurements under other metadata.
COPIES = (
    dataclasses.replace(
        SIMULATED,
        bench_id="1",
        tyre_id="T2",
        interlocked=False,
        created=SIMULATED.created + timedelta(days=40),
    ),
    dataclasses.replace(
        SIMULATED,
        bench_id="3",
        sensor_serial="0002",
        operator="B. Meyer",
        created=SIMULATED.created + timedelta(days=80),
    ),
)


@pytest.fixture(scope="session")
def archive(tmp_path_factory) -> dict[Path, ArchiveCampaign]:
    """The archive's files and what each stands for."""
    directory = tmp_path_factory.mktemp("archive")
    source = write_archive_campaign(directory / "campaign-a.h5", SIMULATED)
    files = {source: SIMULATED}
    for name, campaign in zip(("campaign-b.h5", "sub/campaign-c.h5"), COPIES, strict=True):
        files[copy_campaign(source, directory / name, campaign)] = campaign
    return files


@pytest.fixture(scope="session")
def archive_index(archive, tmp_path_factory) -> Path:
    """The archive's index, built in this process."""
    out = tmp_path_factory.mktemp("index") / "results"
    build_index([next(iter(archive)).parent], out, InProcess())
    return out
