"""What a worker does with one measurement file of a compensation job: read it, compensate it with
the campaign's identification, write its outputs and its summary row; the only place the file is
read (docs/compensate.md, *Many measurements*).

A task is plain data (:class:`MeasurementTask`: paths, what was seen of the file, the job's
settings), never an open file, so that it pickles to any worker of a cluster. Each worker process
analyses the campaign once (:func:`_campaign`, kept while its file is unchanged) and compensates
every measurement it is given with it. Every failure is the file's status and error in its row,
never an exception: one damaged file does not stop the others.
"""

from __future__ import annotations

import functools
import math
import os
import socket
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from bench.analysis.blockwise import moments
from bench.analysis.records import WFS_FORCE
from bench.archive.files import FileStat
from bench.fleet.summary import Row, Status

#: What compensating a measurement imports on first use, beyond this module: the campaign's
#: analysis, the compensation, the MDF4 reader and writer, scipy's filters and pyarrow's pandas
#: layer; a local cluster's workers start with them imported (:mod:`bench.cluster`;
#: ``tests/fleet/test_worker_imports.py``, validation tier, keeps the list whole).
WORKER_IMPORTS = (
    "asammdf",
    "bench.app.analyze",
    "bench.app.compensate",
    "bench.app.run_analysis",
    "pyarrow.pandas_compat",
    "pyarrow.vendored.version",
    "scipy.optimize",
    "scipy.signal",
)

@dataclass(frozen=True)
class Settings:
    """What every measurement of a job is compensated with: the ``campaign`` file (its analysis
    read from its records, or fitted again: ``reanalyse``), the tyre pressure, the channel mapping
    file, the hub accelerometer's lag and the logger's bandwidth the command line states (None: not
    stated), and the ``identification`` key that names all of it with the campaign file's stat and
    the software (an unchanged file with an unchanged key is not compensated again)."""

    campaign: str
    identification: str
    reanalyse: bool = False
    pressure_bar: float | None = None
    mapping: str | None = None
    hub_lag_ms: float | str | None = None
    bandwidth_hz: float | None = None


@dataclass(frozen=True)
class MeasurementTask:
    """A measurement to compensate: its absolute ``path``, its stat when listed, its outputs'
    absolute paths (and as the summary names them, relative to the output folder), the settings."""

    path: str
    listed: FileStat
    out_hdf5: str
    out_mdf4: str
    relative_hdf5: str
    relative_mdf4: str
    settings: Settings


@dataclass(frozen=True)
class MeasurementOutcome:
    """What a worker made of a measurement: its summary ``row``; ``error`` and ``status`` as the row
    says (the progress display lists them)."""

    row: Row

    @property
    def path(self) -> str:
        return self.row["path"]

    @property
    def status(self) -> str:
        return self.row["status"]

    @property
    def error(self) -> str | None:
        return self.row["error"]


def compensate_files(tasks: Sequence[MeasurementTask]) -> list[MeasurementOutcome]:
    """Compensate each measurement of ``tasks`` (:func:`compensate_file`); what a Dask task runs."""
    return [compensate_file(task) for task in tasks]


def compensate_file(task: MeasurementTask) -> MeasurementOutcome:
    """Compensate one measurement into its outputs; every failure is its row's status and error."""
    start = time.process_time()
    row: Row = {
        "path": task.path,
        "size_bytes": task.listed.size_bytes,
        "mtime_ns": task.listed.mtime_ns,
        "identification": task.settings.identification,
        "campaign": task.settings.campaign,
        "worker": f"{socket.gethostname()}:{os.getpid()}",
    }
    try:
        row |= _compensated(task)
    except _NotCompensatedError as refusal:
        row |= {"status": refusal.status, "error": str(refusal)}
        for output in (task.out_hdf5, task.out_mdf4):  # an older output of a file now refused
            Path(output).unlink(missing_ok=True)
    except Exception as exc:  # a defect met in one file must not stop the others
        row |= {"status": Status.FAILED, "error": f"{type(exc).__name__}: {exc}"}
    if row["status"] == Status.COMPENSATED and FileStat.of(task.path) != task.listed:
        row |= {"status": Status.CHANGING, "error": "changed while it was read: being written or copied"}
    from bench.app.version import software_version

    row["compensated_by"] = software_version()
    row["processor_s"] = time.process_time() - start
    return MeasurementOutcome(row)


class _NotCompensatedError(Exception):
    """The file is not compensated, with its ``status``."""

    def __init__(self, status: Status, message: str) -> None:
        super().__init__(message)
        self.status = status


@functools.lru_cache(maxsize=2)
def _campaign(path: str, stat: FileStat, reanalyse: bool):
    """The campaign's analysis, made once per worker process while the file is unchanged."""
    from bench.app.analyze import analyze_campaign

    return analyze_campaign(Path(path), reanalyse=reanalyse)


def _compensated(task: MeasurementTask) -> Row:
    """Read, compensate and write one measurement; its row's figures. :class:`_NotCompensatedError` when the
    file cannot be used or the campaign does not cover it."""
    from bench.app.analyze import CampaignFileError
    from bench.app.compensate import prepare_compensation, with_stated_chain, write_output
    from bench.app.compensation_assumptions import CompensationRefusedError, MeasurementChainError
    from bench.store import StoreError
    from bench.store.csv_mapping import MappingError, load_channel_mapping
    from bench.store.measurement import (
        MeasurementError,
        MissingChannelError,
        NotOnTheTyreError,
        read_measurement,
    )

    settings = task.settings
    try:
        if FileStat.of(task.path) != task.listed:
            raise _NotCompensatedError(Status.CHANGING, "changed since it was listed: being written")
        mapping = load_channel_mapping(settings.mapping) if settings.mapping else None
        measurement = read_measurement(task.path, mapping=mapping)
        try:
            measurement = with_stated_chain(measurement, settings.hub_lag_ms, settings.bandwidth_hz)
        except ValueError as exc:  # the command line and the mapping state different values
            raise MeasurementChainError(str(exc)) from None
        analysis = _campaign(settings.campaign, FileStat.of(settings.campaign), settings.reanalyse)
        compensation = prepare_compensation(analysis, measurement, settings.pressure_bar)
    except (MissingChannelError, NotOnTheTyreError, CompensationRefusedError) as exc:
        raise _NotCompensatedError(Status.REFUSED, str(exc)) from None
    except (MappingError, MeasurementError, StoreError, MeasurementChainError) as exc:
        raise _NotCompensatedError(Status.UNREADABLE, str(exc)) from None
    except (CampaignFileError, OSError) as exc:
        raise _NotCompensatedError(Status.FAILED, str(exc)) from None
    Path(task.out_hdf5).parent.mkdir(parents=True, exist_ok=True)
    done = write_output(
        compensation,
        Path(task.out_hdf5),
        campaign=Path(settings.campaign),
        campaign_analysis=analysis.source,
        mdf4=Path(task.out_mdf4),
        replace=True,
    )
    fz = moments(measurement.channels[WFS_FORCE])
    basis = compensation.filters.basis
    n = measurement.n_samples
    return {
        "status": Status.COMPENSATED,
        "error": None,
        "identified_as": basis.label,
        "out_hdf5": task.relative_hdf5,
        "out_mdf4": task.relative_mdf4,
        "n_samples": n,
        "sample_rate_hz": measurement.sample_rate_hz,
        "start_s": measurement.start_s,
        "duration_s": n / measurement.sample_rate_hz,
        "tyre_pressure_bar": settings.pressure_bar,
        "fz_wfs_mean_n": fz.mean,
        "fz_wfs_rms_n": fz.std,
        "fz_wfs_min_n": fz.minimum,
        "fz_wfs_max_n": fz.maximum,
        "f_contact_mean_n": done.force.mean,
        "f_contact_rms_n": done.force.std,
        "f_contact_min_n": done.force.minimum,
        "f_contact_max_n": done.force.maximum,
        "u95_median_n": _finite(done.median_u95_n),
        "u95_max_n": _finite(done.max_u95_n),
        "valid_band_lo_hz": basis.valid_band_hz[0],
        "valid_band_hi_hz": basis.valid_band_hz[1],
        "assumptions": "\n".join(a.line for a in compensation.assumptions),
    }


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None
