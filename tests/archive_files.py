"""Small campaign files of a lab's archive, made by the simulated bench, for the archive index's
tests and benchmark (``benchmarks/archive_index.py``).

Each campaign is a hammer test of the sensor, the free run without the wheel and a dwell grid at
2 mm around the tyre's tread resonance at one tyre pressure, simulated on the plant with sensor
noise and the non-linear tyre (:mod:`bench.simulated_campaign`) and written with the campaign
writer (:mod:`tests.campaign_files`); then the test's metadata (bench, sensor serial and its
calibration date, tyre, operator) and the campaign's dates are set as a lab's writer sets them.
The ``i``-th campaign of an archive (:func:`archive_campaign`) varies its seed, bench, sensor,
tyre, pressure and date; every :data:`INTERLOCK_EVERY`-th has a second grid that an interlock
stopped. Sensor 0001's eigenfrequency drifts down after its calibration (:data:`DRIFT_HZ_PER_DAY`);
each tyre is the paper's tyre with its own stiffness factor.
"""

from __future__ import annotations

import dataclasses
import shutil
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path

import h5py
import numpy as np

from bench.models.benches import TyreModel
from bench.models.parameters import TyreNonlinearity, WfsSensor, tyre_at_pressure
from bench.models.setup import BenchKind, BenchSetup
from bench.simulated_campaign import simulate_dwells, simulate_hammer
from bench.store.schema import METADATA_FIELDS
from tests.campaign_files import StoredRun, write_campaign

BENCHES = ("1", "2", "3")
#: Sensor serial -> its eigenfrequency at calibration (Hz).
SENSORS = {"0001": 2200.0, "0002": 2150.0, "0003": 2250.0}
CALIBRATION = datetime(2026, 1, 5, tzinfo=UTC)
#: Sensor 0001's eigenfrequency change per day after its calibration (Hz): 18 Hz down in a year.
DRIFT_HZ_PER_DAY = {"0001": -0.05}
#: Tyre id -> (make, size, stiffness factor on the paper's tyre).
TYRES = {
    "T1": ("Continental", "205/55 R16", 1.0),
    "T2": ("Michelin", "225/45 R17", 1.15),
    "T3": ("Pirelli", "195/65 R15", 0.9),
}
PRESSURES_BAR = (1.5, 2.0, 2.5, 3.0, 3.5)
OPERATORS = ("A. Jones", "B. Meyer")
#: Dwell frequencies around the tread resonance (about 30-45 Hz at these pressures), and the free run's.
GRID_HZ = np.array([10.0, 20, 28, 32, 36, 40, 44, 50, 60])
FREE_RUN_HZ = np.array([10.0, 30, 60])
AMPLITUDE_M = 2e-3
INTERLOCK_EVERY = 7
FIRST_DAY = datetime(2026, 1, 12, 8, 0, tzinfo=UTC)


@dataclass(frozen=True)
class ArchiveCampaign:
    """What one campaign of the archive tests: its noise ``seed``, bench, sensor, tyre, pressure,
    date and operator, and whether a second grid ended on an interlock."""

    seed: int
    bench_id: str
    sensor_serial: str
    tyre_id: str
    pressure_bar: float
    created: datetime
    operator: str
    interlocked: bool = False

    @property
    def eigenfrequency_hz(self) -> float:
        days = (self.created - CALIBRATION).total_seconds() / 86400
        return SENSORS[self.sensor_serial] + DRIFT_HZ_PER_DAY.get(self.sensor_serial, 0.0) * days

    @property
    def tyre_stiffness_n_per_m(self) -> float:
        return TYRES[self.tyre_id][2] * tyre_at_pressure(self.pressure_bar).stiffness_n_per_m

    def metadata(self) -> dict[str, str]:
        make, size, _ = TYRES[self.tyre_id]
        values = {
            "bench_id": self.bench_id,
            "sensor_serial": self.sensor_serial,
            "sensor_calibration_date": CALIBRATION.date().isoformat(),
            "tyre_make": make,
            "tyre_size": size,
            "tyre_id": self.tyre_id,
            "operator": self.operator,
            "notes": f"archive campaign {self.seed}",
        }
        assert set(values) == set(METADATA_FIELDS)
        return values


def archive_campaign(i: int) -> ArchiveCampaign:
    """The ``i``-th campaign of the archive: benches, sensors, tyres and pressures in turn (with
    coprime periods, so that they combine), one every 1.7 days from :data:`FIRST_DAY`."""
    return ArchiveCampaign(
        seed=1000 + 10 * i,
        bench_id=BENCHES[i % len(BENCHES)],
        sensor_serial=tuple(SENSORS)[i % 2 if i % 5 else 2],
        tyre_id=tuple(TYRES)[(i // 2) % len(TYRES)],
        pressure_bar=PRESSURES_BAR[i % len(PRESSURES_BAR)],
        created=FIRST_DAY + timedelta(days=1.7 * i),
        operator=OPERATORS[i % len(OPERATORS)],
        interlocked=i % INTERLOCK_EVERY == INTERLOCK_EVERY - 1,
    )


def write_archive_campaign(path: Path, campaign: ArchiveCampaign) -> Path:
    """Simulate ``campaign`` and write it to a new campaign file at ``path``."""
    tyre = dataclasses.replace(
        tyre_at_pressure(campaign.pressure_bar), stiffness_n_per_m=campaign.tyre_stiffness_n_per_m
    )
    shaker = BenchSetup(BenchKind.SHAKER, TyreModel.WHEEL_TREAD, tyre, nonlinearity=TyreNonlinearity())
    sensor = BenchSetup(BenchKind.HAMMER, sensor=WfsSensor(eigenfrequency_hz=campaign.eigenfrequency_hz))
    seed, at = campaign.seed, {"tyre_pressure_bar": campaign.pressure_bar}
    runs = [
        StoredRun("archive-s001-hammer", "hammer", (simulate_hammer(sensor, seed=seed),)),
        StoredRun(
            "archive-s002-free_run",
            "free_run",
            tuple(simulate_dwells(BenchSetup.paper_free_run(), FREE_RUN_HZ, AMPLITUDE_M, seed=seed + 1)),
        ),
        StoredRun(
            "archive-s003-dwell_grid",
            "dwell_grid",
            tuple(simulate_dwells(shaker, GRID_HZ, AMPLITUDE_M, seed=seed + 2)),
            at,
        ),
    ]
    if campaign.interlocked:
        stopped = simulate_dwells(shaker, GRID_HZ[:2], 2 * AMPLITUDE_M, seed=seed + 3)
        why = "displacement limit: 6.2 mm beyond the bench's 6 mm"
        runs.append(
            StoredRun(
                "archive-s004-dwell_grid",
                "dwell_grid",
                tuple(stopped),
                at,
                "interlocked",
                reason=why,
                events=(("interlock", why),),
            )
        )
    write_campaign(path, runs)
    set_campaign(path, campaign)
    return path


def set_campaign(path: Path, campaign: ArchiveCampaign) -> None:
    """Give the file at ``path`` the metadata and dates of ``campaign``: created then, each run an
    hour after the one before, each lasting ten minutes."""
    with h5py.File(path, "r+") as file:
        file.attrs.update(campaign.metadata())
        file.attrs["created"] = campaign.created.isoformat(timespec="milliseconds")
        for n, run in enumerate(file["runs"].values()):
            started = campaign.created + timedelta(hours=n)
            run.attrs["started"] = started.isoformat(timespec="milliseconds")
            run.attrs["finished"] = (started + timedelta(minutes=10)).isoformat(timespec="milliseconds")


def copy_campaign(source: Path, path: Path, campaign: ArchiveCampaign) -> Path:
    """A copy of the campaign file ``source`` given the metadata and dates of ``campaign`` (its
    measurements stay those of ``source``): another file of the archive at the cost of a copy."""
    path.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(source, path)
    set_campaign(path, campaign)
    return path


def write_archive(directory: Path, n: int, start: int = 0) -> list[Path]:
    """Campaigns ``start`` to ``start + n - 1`` of the archive in ``directory``, one file each
    (``campaign-<i>.h5``); a file that exists is kept (a benchmark's archive is made once)."""
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    for i in range(start, start + n):
        path = directory / f"campaign-{i:04d}.h5"
        if not path.exists():
            partial = path.with_name(path.name + ".partial")
            partial.unlink(missing_ok=True)
            write_archive_campaign(partial, archive_campaign(i)).rename(path)
        paths.append(path)
    return paths
