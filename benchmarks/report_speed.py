"""Wall time and size of the report of the paper's whole campaign (``wfsbench report``).

The campaign file is the demo's (hammer test, shaker free run and 9 dwell grids, four-post free run
and sweep: 839 s of samples); it is made first with ``wfsbench demo`` unless ``--campaign`` names
one (not timed). Timed, each the best of ``--repeats``: the whole report (``write_report``: the
analysis read from its records, the 9 figures as the post-run analysis kept them, the page written),
the analysis alone, and the 9 figures drawn (what the report costs for figures not kept, and what
``--reanalyse`` draws). Baseline in the same run: reading every channel of every run of the file (the data
volume the report starts from). Sizes: the campaign file, the page (figures embedded) and the PNGs.

Run: ``OMP_NUM_THREADS=1 PYTHONPATH=. .venv/bin/python benchmarks/report_speed.py [--campaign FILE]``
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from bench.app.analyze import analyze_campaign
from bench.app.report import write_report
from bench.demo import run_demo
from bench.report.figure_files import write_figures
from bench.report.figure_list import campaign_figure_specs
from bench.store import open_campaign
from benchmarks.timing import best_time_s


def read_every_channel(path: Path) -> int:
    """The baseline: every sample of every run read from the file; returns the sample count."""
    n = 0
    with open_campaign(path) as campaign:
        for run in campaign.runs:
            for values in run.channels.values():
                n += values.size
    return n


def campaign_or_demo(campaign: Path | None, work: Path) -> Path:
    """``campaign``, or the campaign file the demo makes in ``work`` (not timed) when it is None."""
    if campaign is not None:
        return campaign
    print("making the campaign file with the demo (not timed) ...", flush=True)
    run_demo(work / "demo")
    return work / "demo" / "campaign.h5"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--campaign", type=Path, help="campaign file (default: made with the demo)")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        campaign = campaign_or_demo(args.campaign, work)
        samples = read_every_channel(campaign)
        t_base = best_time_s(lambda: read_every_channel(campaign), args.repeats)
        t_report = best_time_s(lambda: write_report(campaign, work / "report"), args.repeats)
        t_analysis = best_time_s(lambda: analyze_campaign(campaign), args.repeats)
        analysis = analyze_campaign(campaign)
        specs = campaign_figure_specs(analysis)
        t_figures = best_time_s(lambda: write_figures(specs, work / "figures"), args.repeats)
        page = work / "report" / "report.html"
        pngs = sorted((work / "report").glob("*.png"))
        mb = 1e6
        print(f"campaign file: {campaign.stat().st_size / mb:.1f} MB, {samples / 1e6:.2f} M samples")
        print(f"baseline, read every channel: {t_base:.2f} s")
        ratio = t_report / t_base
        print(f"report, figures kept: {t_report:.2f} s wall ({ratio:.1f}x the baseline; target < 10 s)")
        print(f"  analysis of the whole file: {t_analysis:.2f} s ({t_analysis / t_base:.1f}x the baseline)")
        print(f"  {len(pngs)} figures drawn: {t_figures:.2f} s ({t_figures / t_base:.1f}x the baseline)")
        print(
            f"report.html: {page.stat().st_size / mb:.2f} MB (figures embedded);"
            f" PNGs {sum(p.stat().st_size for p in pngs) / mb:.2f} MB in all"
        )


if __name__ == "__main__":
    start = time.perf_counter()
    main()
    print(f"(benchmark wall time {time.perf_counter() - start:.0f} s)")
