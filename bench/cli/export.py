"""``wfsbench export``: a campaign file's runs or FRFs in a format other tools read (docs/export.md).

Exit codes (:mod:`bench.cli.exit_codes`): OK written; UNAVAILABLE a process is writing the
file; INVALID, nothing written: the file is no campaign file, the run is not
in it, the output exists (an export replaces nothing) or its folder does not, the format has
nothing to write for the runs asked (UFF 58 of a run without FRFs), or a value cannot be written
(a non-finite sample in RPC III).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from bench.cli.analysis import add_reanalyse_option
from bench.cli.exit_codes import ExitCode, unreadable_file_code

FORMATS = ("mdf4", "uff58", "csv", "rpc3", "drive")


def _export(args: argparse.Namespace) -> int:
    from bench.app.analyze import CampaignFileError
    from bench.export.common import ExportError
    from bench.store import StoreError
    from bench.store.compensated import CompensatedFileError

    try:
        lines = export(Path(args.file), args.format, Path(args.out), args.run_id, reanalyse=args.reanalyse)
        for line in lines:
            print(line)
    except (ExportError, StoreError, CampaignFileError, CompensatedFileError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return unreadable_file_code(exc)
    return ExitCode.OK


def export(path: Path, fmt: str, out: Path, run_id: str | None, *, reanalyse: bool = False) -> list[str]:
    """Export ``path`` (every run, or ``run_id``) as ``fmt`` to ``out``; the lines say what was
    written. UFF 58 writes the analysis's FRFs: as stored after each run, or fitted again
    (``reanalyse``, or none stored). Refusals raise :class:`~bench.export.common.ExportError` or
    :class:`~bench.store.StoreError`, before anything is written."""
    from bench.export.common import ExportError, check_output_free, selected_runs
    from bench.store import open_campaign
    from bench.store.compensated import is_compensated

    if fmt not in FORMATS:
        raise ExportError(f"unknown format {fmt!r} (formats: {', '.join(FORMATS)})")
    check_output_free(out)
    if is_compensated(path):
        return _export_compensated(path, fmt, out, run_id)
    with open_campaign(path) as campaign:
        runs = selected_runs(campaign, run_id)
        if fmt == "mdf4":
            from bench.export.mdf4 import write_mdf4

            write_mdf4(campaign, runs, out)
            return [f"mdf4 {out}: {len(runs)} run{'s' if len(runs) != 1 else ''}, one channel group each"]
        if fmt == "csv":
            from bench.export.csv_files import write_csv

            mappings = write_csv(campaign, runs, out)
            return [f"csv {out}/{run.run_id}.csv" for run in runs] + [f"mapping {m}" for m in mappings]
        if fmt == "rpc3":
            from bench.export.rpc3 import write_rpc3

            return [f"rpc3 {p}" for p in write_rpc3(runs, out)]
        if fmt == "drive":
            from bench.export.drive_files import final_runs, write_drive_files

            chosen = runs if run_id else final_runs(runs)
            if not chosen:
                raise ExportError(f"{path}: no drive iteration's drive to write")
            return [f"drive {p}" for p in write_drive_files(chosen, out)]
        ids, created = {run.run_id for run in runs}, campaign.created
    return _export_uff58(path, out, run_id, ids, created, reanalyse=reanalyse)


def _export_compensated(path: Path, fmt: str, out: Path, run_id: str | None) -> list[str]:
    """A compensated force (``wfsbench compensate``'s output) as CSV or MDF4, as a run is."""
    from bench.export.common import ExportError
    from bench.export.compensated import (
        COMPENSATED_FORMATS,
        write_compensated_csv,
        write_compensated_mdf4,
    )
    from bench.store.compensated import open_compensated

    if fmt not in COMPENSATED_FORMATS:
        raise ExportError(
            f"{path}: a compensated force exports as {' or '.join(COMPENSATED_FORMATS)}, not {fmt}"
        )
    if run_id is not None:
        raise ExportError(f"{path}: a compensated force has no runs: --run {run_id} names none")
    with open_compensated(path) as compensated:
        if fmt == "csv":
            return [f"csv {write_compensated_csv(compensated, out)}"]
        write_compensated_mdf4(compensated, out)
        return [f"mdf4 {out}: the compensated force, {compensated.n_samples} samples"]


def _export_uff58(
    path: Path, out: Path, run_id: str | None, ids: set[str], created: str, *, reanalyse: bool
) -> list[str]:
    from bench.app.analyze import analyze_campaign
    from bench.export.common import ExportError
    from bench.export.uff58 import campaign_functions, id_date, write_uff58

    analysis = analyze_campaign(path, reanalyse=reanalyse)
    functions = campaign_functions(analysis, ids)
    if not functions:
        which = f"run {run_id}" if run_id else "the campaign"
        raise ExportError(
            f"{path}: {which} has no FRF to write (UFF 58 holds the dwell grids' and the four-post"
            " sweep's FRFs; a free run, a hammer run and a sweep on the shaker have none)"
        )
    metadata = "; ".join(f"{k} {v}" for k, v in analysis.metadata.items() if v)
    with_file = f"{path.name}; {metadata}" if metadata else path.name
    write_uff58(functions, (with_file, id_date(created)), out)
    return [f"uff58 {out}: {len(functions)} FRFs, each with its uncertainty (sweeps: and coherence)"]


def add_export_command(sub: argparse._SubParsersAction) -> None:
    """Add ``export`` to the ``wfsbench`` subcommands."""
    parser = sub.add_parser(
        "export",
        help="write a campaign file's channels, FRFs or drives as MDF4, UFF 58, CSV or RPC III"
        " (docs/export.md)",
        description="Export a campaign file: mdf4 (every channel of the runs with units, roles,"
        " conditions and the campaign's metadata; one file), uff58 (the dwell and sweep FRFs of the"
        " analysis, raw and compensated, with uncertainty or coherence; one file), csv (one file per"
        " run with a units row and the mapping import-csv reads them with; a folder), rpc3 (one MTS"
        " RPC III time history per run; a folder), drive (a drive iteration's drive as drive files a"
        " road replay plays, RPC III .drv and CSV: of --run, else each iteration's final drive; a"
        " folder). A compensated force (wfsbench compensate's output) exports as csv or mdf4. An"
        " existing --out is never replaced.",
    )
    parser.add_argument(
        "file", help="campaign file (HDF5, docs/hdf5.md) or compensated force (docs/compensate.md)"
    )
    parser.add_argument("--format", required=True, choices=FORMATS, help="the format to write")
    parser.add_argument(
        "--run", dest="run_id", metavar="ID", help="only this run (default: every run of the file)"
    )
    parser.add_argument(
        "--out", required=True, metavar="PATH", help="new file (mdf4, uff58) or new folder (csv, rpc3)"
    )
    add_reanalyse_option(parser)
    parser.set_defaults(run=_export)
