"""``wfsbench report``: a campaign file's figures and its self-contained HTML page in a directory.

The file's analysis is read from its records, or fitted again in memory
(:func:`~bench.app.analyze.analyze_campaign`; nothing is written into the file); the figures go to
``DIR/<name>.png``, each as the post-run analysis drew and kept it when it shows the same values
(:mod:`bench.app.kept_figures`), else drawn here, and the page to ``DIR/report.html``. A ``DIR``
that cannot hold them (a file, under a file, not writable) is refused before the analysis.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from bench.app.analyze import analyze_campaign
from bench.app.kept_figures import kept_pngs
from bench.report.figure_files import write_figures
from bench.report.figure_list import campaign_figure_specs

if TYPE_CHECKING:
    from bench.analysis.campaign import CampaignAnalysis, CampaignKnowledge
    from bench.report.figure_list import FigureFile

REPORT_PAGE = "report.html"


class ReportDirError(Exception):
    """The report directory cannot be used; the message starts with its path."""


@dataclass(frozen=True)
class WrittenReport:
    """Where the report went: the ``page`` and the ``figures``, with the ``analysis`` they show."""

    page: Path
    figures: tuple[FigureFile, ...]
    analysis: CampaignAnalysis

    @property
    def drawn(self) -> tuple[str, ...]:
        """The figures drawn for this report (the others were kept by the post-run analysis)."""
        return tuple(figure.name for figure in self.figures if not figure.kept)


def check_report_dir(out_dir: Path) -> None:
    """Raise :class:`ReportDirError` unless ``out_dir`` is a writable directory or can be created
    as one (its nearest existing ancestor is a writable directory). Nothing is created here."""
    if out_dir.exists():
        if not out_dir.is_dir():
            raise ReportDirError(f"{out_dir}: exists and is not a directory")
        if not os.access(out_dir, os.W_OK | os.X_OK):
            raise ReportDirError(f"{out_dir}: directory is not writable")
        return
    ancestor = out_dir.absolute().parent
    while not ancestor.exists():
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise ReportDirError(f"{out_dir}: cannot be created: {ancestor} is not a directory")
    if not os.access(ancestor, os.W_OK | os.X_OK):
        raise ReportDirError(f"{out_dir}: cannot be created: {ancestor} is not writable")


def write_report(
    campaign_path: str | Path,
    out_dir: str | Path,
    knowledge: CampaignKnowledge | None = None,
    *,
    reanalyse: bool = False,
) -> WrittenReport:
    """Analyse the campaign file and write its figures and ``report.html`` into ``out_dir``
    (created if needed; earlier figures of the same names are replaced). ``out_dir`` is checked
    first (:func:`check_report_dir`), so an unusable one costs no analysis; a write that fails
    anyway raises :class:`ReportDirError` too. ``knowledge``: the post-run analysis of the campaign
    that wrote the file, whose runs are then not analysed again; else the analysis stored after each
    run, or (``reanalyse``, or none stored) a new fit (:func:`analyze_campaign`). A figure the
    post-run analysis kept is taken when it shows the same values, except with ``reanalyse``, which
    draws every figure again."""
    out_dir = Path(out_dir)
    check_report_dir(out_dir)
    analysis = analyze_campaign(campaign_path, knowledge=knowledge, reanalyse=reanalyse)
    specs = campaign_figure_specs(analysis)
    kept = {} if reanalyse else kept_pngs(Path(campaign_path), specs)
    from bench.report.html import report_html

    try:
        figures = tuple(write_figures(specs, out_dir, kept))
        page = out_dir / REPORT_PAGE
        page.write_text(report_html(analysis, figures), encoding="utf-8")
    except OSError as exc:
        raise ReportDirError(f"{out_dir}: {exc.strerror or exc}") from exc
    return WrittenReport(page, figures, analysis)
