"""A drive iteration's drives as drive files a road replay plays (docs/export.md, *Drive files*): per
run, ``<run_id>.drv`` (MTS RPC III, one channel ``drive`` in mm) and ``<run_id>.csv`` (``t [s]``,
``z [mm]``: docs/sequences.md's drive file conventions), the drive's samples as the controller
played them (its CRC-32 checked against the one the run recorded).

Without a run named, the final drive of each drive iteration in the file: its step's last run.
"""

from __future__ import annotations

import zlib
from pathlib import Path

import numpy as np

from bench.engine.run_ids import step_run_id
from bench.export.common import ExportError, output_folder
from bench.store import RunView
from bench.store.rpc3 import Rpc3Channel, time_history_bytes
from sequences.runs import RunKind

RPC3_SUFFIX = ".drv"
CSV_SUFFIX = ".csv"


def drive_samples(run: RunView) -> np.ndarray:
    """The drive ``run`` played (mm, float32 as the controller took it); ExportError when the run
    recorded none or its samples do not give its CRC-32."""
    samples = run.drive.get("samples_mm")
    if run.kind != RunKind.DRIVE_ITERATION or samples is None:
        raise ExportError(f"{run.path}: run {run.run_id}: no drive of a drive iteration recorded")
    values = np.asarray(samples, dtype="<f4")
    if f"{zlib.crc32(values.tobytes()):08x}" != run.drive.get("crc32"):
        raise ExportError(
            f"{run.path}: run {run.run_id}: its drive's samples do not give its recorded CRC-32"
        )
    return values


def final_runs(runs: tuple[RunView, ...]) -> tuple[RunView, ...]:
    """Of ``runs``, each drive iteration's last run with a drive (the final drive of its step)."""
    last: dict[str, RunView] = {}
    for run in runs:
        if run.kind == RunKind.DRIVE_ITERATION and int(run.drive.get("iteration", 0)) > 0:
            last[step_run_id(run.run_id)] = run
    return tuple(last.values())


def write_drive_files(runs: tuple[RunView, ...], out: Path) -> list[Path]:
    """Both drive files of each of ``runs`` in the new folder ``out`` (refused if it exists)."""
    drives = [(run, drive_samples(run)) for run in runs]
    written = []
    with output_folder(out) as folder:
        for run, values in drives:
            rate = float(run.drive["sample_rate_hz"])
            channel = Rpc3Channel("drive", "mm", values.astype(float))
            (folder / f"{run.run_id}{RPC3_SUFFIX}").write_bytes(
                time_history_bytes([channel], rate, operation="wfsbench export --format drive")
            )
            t = np.arange(values.size) / rate
            rows = "\n".join(f"{a!r},{float(b)!r}" for a, b in zip(t.tolist(), values.tolist(), strict=True))
            (folder / f"{run.run_id}{CSV_SUFFIX}").write_text(f"t [s],z [mm]\n{rows}\n")
            written += [out / f"{run.run_id}{RPC3_SUFFIX}", out / f"{run.run_id}{CSV_SUFFIX}"]
    return written
