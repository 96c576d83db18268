"""``wfsbench show FILE [--json]``: what a campaign file or a compensated force holds, read-only
(docs/cli.md).

Exit codes (:mod:`bench.cli.exit_codes`): OK shown; UNAVAILABLE a process is writing the file (its writer
lock or HDF5's lock held: refused, nothing read); INVALID the file is neither (missing, not HDF5,
another layout, truncated, damaged, a schema violation).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from bench.cli.exit_codes import ExitCode, unreadable_file_code


def _show(args: argparse.Namespace) -> int:
    from bench.app.show import campaign_summary, summary_lines
    from bench.store import StoreError
    from bench.store.compensated import CompensatedFileError, is_compensated

    path = Path(args.file)
    try:
        if is_compensated(path):
            from bench.app.show_compensated import compensated_lines, compensated_summary

            summary, summary_lines = compensated_summary(path), compensated_lines
        else:
            summary = campaign_summary(path)
    except (StoreError, CompensatedFileError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return unreadable_file_code(exc)
    if args.json:
        import json

        print(json.dumps(summary, indent=2, allow_nan=False, ensure_ascii=False))
    else:
        print("\n".join(summary_lines(summary)))
    return ExitCode.OK


def add_show_command(sub: argparse._SubParsersAction) -> None:
    """Add ``show`` to the ``wfsbench`` subcommands."""
    show = sub.add_parser(
        "show",
        help="what a campaign file holds (runs, points, conditions, metadata, analyses), or a"
        " compensated force (what made it, its band, its samples); read-only",
        description="Show what a campaign file holds: its runs in order with kind, status and reason,"
        " points done of planned, conditions (tyre pressure, wheel, amplitudes, frequency span), the"
        " specimen as configured, the test metadata and the analyses stored with when. Read-only: the"
        " file is never written. A file a process is writing is refused (exit 2); a file that is no"
        " campaign file exits 3 (docs/cli.md). A compensated force (wfsbench compensate's output) shows"
        " what it was made from, the assumptions, its valid band and its samples.",
    )
    show.add_argument(
        "file", help="campaign file (HDF5, docs/hdf5.md) or compensated force (docs/compensate.md)"
    )
    show.add_argument(
        "--json",
        action="store_true",
        help="JSON (schema wfs-bench-show, or wfs-bench-show-compensated; docs/cli.md) instead of text",
    )
    show.set_defaults(run=_show)
