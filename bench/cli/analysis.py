"""``wfsbench analyze`` and ``wfsbench report``: a campaign file analysed, as text, JSON or a report.

Exit codes (:mod:`bench.cli.exit_codes`): OK; INVALID: the file is no campaign file (missing, not
HDF5, another layout, truncated, a schema violation or an invalid stored configuration), or
(``report``) the ``--out`` directory cannot be used (checked before the analysis): nothing was
written; UNAVAILABLE: a process is writing the file; for ``analyze`` also INCOMPLETE: a run's
analysis failed or is partial (each flagged with why), or the file holds no complete run; and
NOT_STORED: analysed and printed, the results not stored (a read-only file; never with
``--no-store``). ``report`` writes its page whatever the analyses' status.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from bench.cli.exit_codes import ExitCode, unreadable_file_code

if TYPE_CHECKING:
    from bench.analysis.campaign import CampaignAnalysis



def _status_line(analysis: CampaignAnalysis) -> str:
    """The analysis's status as the text output's last line: ``complete``, or ``partial`` with each
    run whose analysis failed or is partial, and why."""
    runs = analysis.not_complete
    if not analysis.runs:
        return "== analysis incomplete: the file holds no complete run to analyse"
    if not runs:
        n = len(analysis.runs)
        return f"== analysis complete: {n} run{'' if n == 1 else 's'} analysed"
    why = "; ".join(
        f"{run.run_id} {run.status}: {run.error or ', '.join(run.omitted)}" for run in runs
    )
    n = len(analysis.runs)
    return f"== analysis partial: {len(runs)} of {n} run{'' if n == 1 else 's'} not complete ({why})"


def _analyze(args: argparse.Namespace) -> int:
    from bench.app.analyze import CampaignFileError, analyze_campaign, store_reanalysis
    from bench.store import StoreError

    path = Path(args.file)
    try:
        analysis = analyze_campaign(path, reanalyse=args.reanalyse, keep_records=args.store)
    except (StoreError, CampaignFileError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return unreadable_file_code(exc)
    complete = analysis.runs and not analysis.not_complete
    code, names = ExitCode.OK if complete else ExitCode.INCOMPLETE, {}
    if args.store and not analysis.stored:  # an analysis read from the records is in the file already
        try:
            names = store_reanalysis(analysis)
        except StoreError as exc:
            print(f"error: results not stored: {exc}", file=sys.stderr)
            code = ExitCode.NOT_STORED
    if args.json:
        from bench.report.json_out import analysis_json_text

        print(analysis_json_text(analysis, names))
        return code
    from bench.report.metadata import metadata_lines

    print(f"== test metadata of {analysis.path}")
    for line in metadata_lines(analysis.metadata):
        print(line)
    print(f"== analysis {analysis.source}")
    for run in analysis.runs:
        stored = f"; stored as results/{names[run.run_id]}" if run.run_id in names else ""
        print(f"== {run.run_id} ({run.kind}: {run.name}{stored})")
        for line in run.lines:
            print(line)
    for run_id, status in analysis.skipped:
        print(f"== {run_id}: {status}, not analysed")
    print(_status_line(analysis))
    return code


def _report(args: argparse.Namespace) -> int:
    from bench.app.analyze import CampaignFileError
    from bench.app.report import REPORT_PAGE, ReportDirError, write_report
    from bench.store import StoreError

    if (Path(args.out) / REPORT_PAGE).is_file():  # said first: the earlier report is replaced
        print(f"replacing the report in {args.out} (its {REPORT_PAGE} and the figures of the same names)")
    try:
        written = write_report(Path(args.file), Path(args.out), reanalyse=args.reanalyse)
    except (StoreError, CampaignFileError, ReportDirError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return unreadable_file_code(exc)
    for figure in written.figures:
        print(f"figure {figure.path}")
    kept = len(written.figures) - len(written.drawn)
    print(f"{kept} figures as the post-run analysis drew them, {len(written.drawn)} drawn")
    print(f"report {written.page}")
    return ExitCode.OK


def add_reanalyse_option(parser: argparse.ArgumentParser) -> None:
    """``--reanalyse``: fit the campaign's runs again instead of reading the analysis stored after
    each run (docs/hdf5.md, *The analysis record*)."""
    parser.add_argument(
        "--reanalyse",
        action="store_true",
        help="fit every run again instead of reading the analysis stored after each run (a file"
        " without stored analyses is always fitted again, and says so)",
    )


def add_analysis_commands(sub: argparse._SubParsersAction) -> None:
    """Add ``analyze``, ``report`` and ``show`` (:mod:`bench.cli.show`) to the ``wfsbench``
    subcommands: the commands that read a campaign file."""
    from bench.cli.show import add_show_command

    analyze = sub.add_parser(
        "analyze",
        help="a campaign file's analysis: as stored after each run, or fitted again (--reanalyse, a"
        " file without stored analyses); the results of a new fit are stored in it under new names"
        " (--no-store: only printed)",
    )
    analyze.add_argument("file", help="campaign file (HDF5, docs/hdf5.md)")
    analyze.add_argument("--json", action="store_true", help="JSON (docs/analysis-json.md) instead of text")
    analyze.add_argument(
        "--no-store",
        dest="store",
        action="store_false",
        help="only print: store no results, open the file read-only (it is left byte for byte as it was)",
    )
    add_reanalyse_option(analyze)
    analyze.set_defaults(run=_analyze)
    report = sub.add_parser("report", help="figures and a self-contained HTML page of a campaign file")
    report.add_argument("file", help="campaign file (HDF5, docs/hdf5.md)")
    report.add_argument("--out", required=True, help="directory for the PNG figures and report.html")
    add_reanalyse_option(report)
    report.set_defaults(run=_report)
    add_show_command(sub)
