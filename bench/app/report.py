"""``wfsbench report``: a campaign file's figures and its self-contained HTML page in a directory.

The file is analysed in memory (:func:`~bench.app.analyze.analyze_campaign`; nothing is written
into it), the figures are drawn to ``DIR/<name>.png`` and the page to ``DIR/report.html``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from bench.app.analyze import CampaignAnalysis, analyze_campaign
from bench.report.figures import FigureFile, write_figures
from bench.report.html import report_html

REPORT_PAGE = "report.html"


@dataclass(frozen=True)
class WrittenReport:
    """Where the report went: the ``page`` and the ``figures``, with the ``analysis`` they show."""

    page: Path
    figures: tuple[FigureFile, ...]
    analysis: CampaignAnalysis


def write_report(campaign_path: str | Path, out_dir: str | Path) -> WrittenReport:
    """Analyse the campaign file and write its figures and ``report.html`` into ``out_dir``
    (created if needed; earlier figures of the same names are replaced)."""
    out_dir = Path(out_dir)
    analysis = analyze_campaign(campaign_path)
    figures = tuple(write_figures(analysis, out_dir))
    page = out_dir / REPORT_PAGE
    page.write_text(report_html(analysis, figures), encoding="utf-8")
    return WrittenReport(page, figures, analysis)
