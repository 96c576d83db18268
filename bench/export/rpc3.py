"""A run's measured channels as an MTS RPC III time-history file (the codec:
:mod:`bench.store.rpc3`, its layout in docs/export.md).

Only the run's physical channels (float32) are written; the integer link counters and status bits
(``seq``, ``sample``, ``status``) are not measured quantities and have no place in a time history.
"""

from __future__ import annotations

from datetime import datetime
from pathlib import Path

from bench.export.common import ExportError, output_folder
from bench.store import RunView
from bench.store.rpc3 import Rpc3Channel, Rpc3Error, time_history_bytes

#: The file name's suffix: a response time history.
SUFFIX = ".rsp"


def _date(started: str) -> str:
    """The run's start as the format's DATE (``22-Feb-2000 10:20:11``); empty if unknown."""
    try:
        return datetime.fromisoformat(started).strftime("%d-%b-%Y %H:%M:%S")
    except ValueError:
        return ""


def rpc3_bytes(run: RunView) -> bytes:
    """The whole RPC III file of ``run``'s physical channels."""
    specs = [spec for spec in run.channel_specs if spec.dtype == "f4"]
    if not specs:
        raise ExportError(f"{run.path}: run {run.run_id}: no physical (float) channel to write")
    if run.n_samples == 0:
        raise ExportError(f"{run.path}: run {run.run_id}: no samples")
    channels = [Rpc3Channel(spec.name, spec.unit, run.channels[spec.name]) for spec in specs]
    try:
        return time_history_bytes(
            channels, run.sample_rate_hz, date=_date(run.started), operation="wfsbench export"
        )
    except Rpc3Error as exc:
        raise ExportError(f"{run.path}: run {run.run_id}: {exc}") from None


def write_rpc3(runs: tuple[RunView, ...], out: Path) -> list[Path]:
    """One ``<run_id>.rsp`` per run in the new folder ``out`` (refused if it exists)."""
    written = []
    with output_folder(out) as folder:
        for run in runs:
            (folder / f"{run.run_id}{SUFFIX}").write_bytes(rpc3_bytes(run))
            written.append(out / f"{run.run_id}{SUFFIX}")
    return written
