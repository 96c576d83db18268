"""``wfsbench index`` and ``wfsbench trends``: campaign archives indexed into Parquet on Dask, and
their trends drawn from the index (docs/index.md).

Exit codes (both commands, :mod:`bench.cli.exit_codes`):

- OK: done; for ``index``, every file found is in the index, those that could not be read listed
  with their status and error (on standard output, and in the index);
- UNAVAILABLE: the Dask scheduler could not be reached, or another index run holds the index directory;
- INVALID: invalid input: a path that does not exist, an index directory that cannot be used (a file,
  not writable, or an index of another version); for ``trends``, an index missing or empty, or an
  output directory that cannot be used: nothing was written.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from bench.cli.analysis import add_reanalyse_option
from bench.cli.exit_codes import ExitCode
from bench.cli.file_progress import FileBar
from bench.cli.job_options import add_job_options, job_executor

if TYPE_CHECKING:
    from bench.archive.build import IndexSummary



def summary_lines(summary: IndexSummary, out: Path) -> list[str]:
    """What the run did, then each file not (fully) indexed with its status and error."""
    read = ", ".join(f"{n} {status}" for status, n in sorted(summary.statuses.items())) or "none"
    lines = [
        f"index {out}: {summary.found} files found; {summary.unchanged} unchanged, not read; read: {read};"
        f" {summary.same_contents} with the contents of indexed files; {summary.removed} gone from the index;"
        f" {summary.rows_written} rows written"
    ]
    lines.extend(f"{status}: {path}: {error}" for path, status, error in summary.problems)
    return lines


def _index(args: argparse.Namespace) -> int:
    from bench.archive.build import build_index
    from bench.archive.store import IndexDirError
    from bench.locks import InUseError

    roots = [Path(p) for p in args.paths]
    missing = [str(p) for p in roots if not p.exists()]
    if missing:
        print(f"error: no such file or directory: {', '.join(missing)}", file=sys.stderr)
        return ExitCode.INVALID
    out = Path(args.out)
    bar = FileBar("indexing", "not indexed")
    try:
        options = {"verify": args.verify, "reanalyse": args.reanalyse, "progress": bar}
        with bar.progress:
            summary = build_index(roots, out, job_executor(args), **options)
    except IndexDirError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return ExitCode.INVALID
    except (InUseError, OSError) as exc:  # another index run; a scheduler that does not answer
        print(f"error: {exc}", file=sys.stderr)
        return ExitCode.UNAVAILABLE
    for line in summary_lines(summary, out):
        print(line)
    return ExitCode.OK


def _trends(args: argparse.Namespace) -> int:
    from bench.app.report import ReportDirError, check_report_dir
    from bench.archive.store import IndexDirError
    from bench.archive.trends import write_trends

    try:
        check_report_dir(Path(args.out))
        written = write_trends(Path(args.results), Path(args.out))
    except (IndexDirError, ReportDirError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return ExitCode.INVALID
    for figure in written.figures:
        print(f"figure {figure.path}")
    print(f"trends {written.page}")
    return ExitCode.OK


def add_archive_commands(sub: argparse._SubParsersAction) -> None:
    """Add ``index`` and ``trends`` to the ``wfsbench`` subcommands."""
    index = sub.add_parser(
        "index",
        help="index every campaign file under some directories into Parquet, on Dask",
        description="Index every campaign file (*.h5, *.hdf5) under the PATHs into the index directory"
        " RESULTS (Parquet parts, docs/index.md): metadata, runs, stored results and the identification"
        " of an analysis made in memory (the files are only read). Files indexed before and unchanged"
        " are not read again; files that are not campaigns, damaged, locked by a recording bench or being"
        " written are listed with their error. Runs on a local Dask cluster of processes, or on the"
        " cluster of --scheduler.",
    )
    index.add_argument(
        "paths", nargs="+", metavar="PATH", help="a directory (searched recursively) or a file"
    )
    index.add_argument(
        "--out", required=True, metavar="RESULTS", help="index directory (created, or brought up to date)"
    )
    add_job_options(
        index,
        scheduler_help="a dask.distributed scheduler (tcp://host:8786)",
        workers_help="processes of the local cluster (default: the machine's cores); 0: in this process,"
        " no cluster",
    )
    index.add_argument(
        "--verify", action="store_true", help="hash every file, not only those whose size or time changed"
    )
    add_reanalyse_option(index)
    index.set_defaults(run=_index)
    trends = sub.add_parser(
        "trends",
        help="figures of an index: tyres against pressure, sensors over time, interlocks per month",
        description="Draw from the index RESULTS each tyre's stiffness and damping against pressure, each"
        " sensor's eigenfrequency over time and the interlocks per bench and month, as PNG figures and"
        " one self-contained trends.html in DIR (docs/index.md).",
    )
    trends.add_argument("results", metavar="RESULTS", help="index directory written by wfsbench index")
    trends.add_argument(
        "--out", required=True, metavar="DIR", help="directory for the figures and trends.html"
    )
    trends.set_defaults(run=_trends)
