"""What every export shares: its error, the runs it takes, a run's conditions and the campaign's
metadata as text, and an output that appears whole or not at all.

An export never writes over anything: an existing output is refused before the campaign file is
read, and the output is written beside its place under a temporary name and renamed into place
once complete, so a failed export leaves nothing behind.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from bench.store import CampaignFile, RunView
from bench.store.temporary import temporary_beside
from sequences.points import PointAttempt, PointStatus


class ExportError(ValueError):
    """An export that cannot be made as asked; the message names the file, run or format and why."""


def check_output_free(out: Path) -> None:
    """Refuse an output path that exists (a file or a directory: an export replaces nothing) or
    whose folder does not exist."""
    if out.exists() or out.is_symlink():
        raise ExportError(f"{out}: exists; an export replaces nothing (choose another --out or remove it)")
    if not out.parent.is_dir():
        raise ExportError(f"{out}: the folder {out.parent} does not exist")


@contextmanager
def output_file(out: Path, suffix: str = "") -> Iterator[Path]:
    """A temporary file beside ``out`` to write the export into, ending in ``suffix`` (for a writer
    that insists on its own); renamed to ``out`` when the block ends without an error, removed
    otherwise."""
    check_output_free(out)
    temporary = temporary_beside(out, suffix)  # the writer creates it
    try:
        yield temporary
        temporary.rename(out)
    finally:
        temporary.unlink(missing_ok=True)


@contextmanager
def output_folder(out: Path) -> Iterator[Path]:
    """A temporary folder beside ``out`` to write the export's files into; renamed to ``out`` when
    the block ends without an error, removed otherwise."""
    check_output_free(out)
    temporary = temporary_beside(out)
    temporary.mkdir()
    try:
        yield temporary
        temporary.rename(out)
    finally:
        if temporary.exists():
            shutil.rmtree(temporary)


def selected_runs(campaign: CampaignFile, run_id: str | None) -> tuple[RunView, ...]:
    """Every run of the campaign in order, or the one named ``run_id`` (an unknown id is refused
    naming the file and the runs it holds)."""
    if run_id is None:
        return campaign.runs
    if run_id not in {run.run_id for run in campaign.runs}:
        known = ", ".join(run.run_id for run in campaign.runs) or "none"
        raise ExportError(f"{campaign.path}: no run {run_id!r} (runs: {known})")
    return (campaign.run(run_id),)


def done_points(run: RunView) -> list[PointAttempt]:
    """The run's done points (each point's kept attempt), in the order they were recorded."""
    return sorted((p for p in run.points if p.status == PointStatus.DONE), key=lambda p: p.start_sample)


def amplitudes_mm(run: RunView) -> tuple[float, ...]:
    """The amplitudes (mm) the run's done points were commanded at, ascending (none for a hammer
    blow, whose amplitude is 0)."""
    return tuple(sorted({p.amplitude_mm for p in done_points(run) if p.amplitude_mm > 0}))


def run_description(run: RunView) -> dict[str, str]:
    """What the run was, as text by name: its kind, status (and why), start and end, the tyre
    pressure and amplitudes, the conditions and the step (JSON), and who ran it (the run's own
    metadata: bench, operator, notes)."""
    pressure = run.conditions.get("tyre_pressure_bar")
    return {
        "run_id": run.run_id,
        "kind": run.kind,
        "status": run.status,
        "reason": run.reason,
        "started": run.started,
        "finished": run.finished,
        "sample_rate_hz": f"{run.sample_rate_hz:g}",
        "tyre_pressure_bar": "" if pressure is None else f"{pressure:g}",
        "amplitudes_mm": ", ".join(f"{a:g}" for a in amplitudes_mm(run)),
        "conditions": json.dumps(run.conditions, sort_keys=True),
        "step": json.dumps(run.step, sort_keys=True),
        **run.metadata,
    }
