"""``wfsbench compensate CAMPAIGN MEASUREMENT...|DIR --out DIR``: many road measurements compensated
as one job (docs/compensate.md, *Many measurements*); the exit codes are in :mod:`bench.cli.compensate`."""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import replace
from pathlib import Path

from bench.cli.exit_codes import ExitCode
from bench.cli.file_progress import FileBar
from bench.cli.job_options import job_executor

#: Options of one measurement only, and why a job refuses them.
_ONE_MEASUREMENT_ONLY = {
    "run_id": "--run names a run of one campaign file",
    "json": "--json prints one measurement's compensation",
    "filters": "--filters exports one measurement's filters",
}


def summary_lines(summary, out: Path) -> list[str]:
    """What the job did, then each file not compensated with its status and error."""
    read = ", ".join(f"{n} {status}" for status, n in sorted(summary.statuses.items())) or "none"
    lines = [
        f"compensate {out}: {summary.found} files found; {summary.unchanged} unchanged, not read;"
        f" read: {read}; {summary.removed} gone from the summary; summary {summary.summary}"
    ]
    lines.extend(f"{status}: {path}: {error}" for path, status, error in summary.problems)
    return lines


def _check(args: argparse.Namespace) -> str | None:
    """Why the command line cannot run as a job (None: it can)."""
    for option, why in _ONE_MEASUREMENT_ONLY.items():
        if getattr(args, option):
            return f"error: {why}, not a job over many measurements"
    missing = [m for m in args.measurement if not Path(m).exists()]
    if missing:
        return f"error: no such file or directory: {', '.join(missing)}"
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        return f"error: --out {out}: exists and is not a folder (a job writes into a folder)"
    if args.mapping and not Path(args.mapping).is_file():
        return f"error: --mapping {args.mapping}: no such file"
    return None


def _campaign_error(campaign: Path) -> str | None:
    """Why ``campaign`` is no campaign file to compensate with (None: it opens as one)."""
    from bench.store import StoreError, open_campaign

    try:
        with open_campaign(campaign):
            return None
    except (StoreError, OSError) as exc:
        return f"error: {exc}"


def run_job(args: argparse.Namespace) -> int:
    from bench.fleet.job import compensate_many, identification
    from bench.fleet.summary import SummaryError
    from bench.fleet.worker import Settings
    from bench.locks import InUseError

    stop = _check(args) or _campaign_error(Path(args.campaign))
    if stop:
        print(stop, file=sys.stderr)
        return ExitCode.INVALID
    settings = Settings(
        campaign=os.path.abspath(args.campaign),
        identification="",
        reanalyse=args.reanalyse,
        pressure_bar=args.pressure,
        mapping=os.path.abspath(args.mapping) if args.mapping else None,
        hub_lag_ms=args.hub_lag_ms,
        bandwidth_hz=args.bandwidth_hz,
    )
    settings = replace(settings, identification=identification(settings))
    roots = [Path(m) for m in args.measurement]
    out = Path(args.out)
    bar = FileBar("compensating", "not compensated")
    executor = job_executor(args)
    try:
        with bar.progress:
            summary = compensate_many(roots, out, settings, executor, progress=bar)
    except SummaryError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return ExitCode.INVALID
    except (InUseError, OSError) as exc:  # another job; a scheduler that does not answer
        print(f"error: {exc}", file=sys.stderr)
        return ExitCode.UNAVAILABLE
    for line in summary_lines(summary, out):
        print(line)
    return ExitCode.OK
