"""The report's figures drawn where the post-run analysis runs, and kept beside its record.

Once the analysis is read from its records, drawing the figures is most of what ``wfsbench report``
costs (seconds of matplotlib for a whole campaign). The analysis process draws them instead, after
each run, while the bench waits on the next run in real time: :class:`FigureDrawer` draws every
figure whose values changed with the run, and the recorder keeps each beside the run
(``figures/<name>``, docs/hdf5.md) with the SHA-256 of what it shows (:func:`shows_sha256`: the
values drawn, and the drawing code and plotting library that drew them). The report takes a kept
figure only when the figure it would draw shows the same (:func:`kept_pngs`) and draws every other
one; ``--reanalyse`` draws them all.
"""

from __future__ import annotations

import functools
import hashlib
from collections.abc import Iterable
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

from bench.analysis.campaign import CampaignKnowledge
from bench.analysis.records import HammerRecord, SweepRecord
from bench.app.run_analysis import RunInputs
from bench.app.value_digest import value_sha256
from bench.report import figure_list
from bench.report.figure_list import FigureSpec, KeptFigure, figure_specs
from bench.store import open_campaign
from sequences.runs import RigKind, RunKind

#: The modules whose code decides how a figure looks: a change to any of them makes every kept
#: figure stale.
DRAWING_MODULES = ("axes.py", "figure_list.py", "figures.py", "iteration_figures.py", "replay_figures.py")
#: The first bytes of every PNG file.
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@functools.cache
def drawing_sha256() -> str:
    """The SHA-256 of the drawing code (:data:`DRAWING_MODULES`) and the plotting library's version."""
    digest = hashlib.sha256()
    folder = Path(figure_list.__file__).parent
    for name in DRAWING_MODULES:
        digest.update((folder / name).read_bytes())
    try:
        digest.update(version("matplotlib").encode())
    except PackageNotFoundError:  # an unreleased matplotlib: its figures are never taken as kept
        digest.update(b"matplotlib of no version")
    return digest.hexdigest()


def shows_sha256(spec: FigureSpec) -> str:
    """The SHA-256 of what the figure ``spec`` shows: the drawing code (:func:`drawing_sha256`), its
    name and kind and the values drawn, by value (:mod:`bench.app.value_digest`)."""
    return value_sha256((spec.name, str(spec.kind), spec.shows), drawing_sha256())


class FigureDrawer:
    """The analysis process's: after each run, the figures whose values changed, drawn. The figures
    ``knowledge`` supports when the process starts count as drawn: the runs that made it (an earlier
    sequence into the same file) had them drawn and kept."""

    def __init__(self, knowledge: CampaignKnowledge) -> None:
        self._hammer: HammerRecord | None = None
        self._sweep: SweepRecord | None = None
        #: figure name -> what it showed when last drawn
        self._drawn = {spec.name: shows_sha256(spec) for spec in figure_specs(knowledge, None, None)}

    def after(self, run: RunInputs, knowledge: CampaignKnowledge) -> tuple[KeptFigure, ...]:
        """The figures ``knowledge`` (after ``run``'s analysis) supports that show other values than
        when this drawer last drew them. The hammer figure is drawn from the first hammer run's blow
        and the four-post one from the last four-post sweep, as the report draws them."""
        if run.hammer is not None and self._hammer is None:
            self._hammer = run.hammer
        if (
            run.sweep is not None
            and run.kind == RunKind.SWEEP
            and run.conditions.get("bench") == RigKind.FOUR_POST
        ):
            self._sweep = run.sweep
        changed = [
            (spec, digest)
            for spec in figure_specs(knowledge, self._hammer, self._sweep)
            if self._drawn.get(spec.name) != (digest := shows_sha256(spec))
        ]
        if not changed:
            return ()
        from bench.report.figures import figure_png  # the plotting library, once there is a figure

        kept = []
        for spec, digest in changed:
            kept.append(KeptFigure(spec.name, digest, figure_png(spec)))
            self._drawn[spec.name] = digest
        return tuple(kept)


def kept_pngs(campaign_path: Path, specs: Iterable[FigureSpec]) -> dict[str, bytes]:
    """The PNG bytes kept in the campaign file for each figure of ``specs`` that shows what was drawn
    then (the latest run's copy first), by name; a copy whose bytes are damaged is not taken."""
    wanted = {spec.name: shows_sha256(spec) for spec in specs}
    found: dict[str, bytes] = {}
    with open_campaign(campaign_path) as campaign:
        for run in reversed(campaign.runs):
            for name, figure in run.figures().items():
                if name in found or wanted.get(name) != figure.shows_sha256:
                    continue
                png = figure.png
                if png.startswith(PNG_SIGNATURE) and hashlib.sha256(png).hexdigest() == figure.png_sha256:
                    found[name] = png
    return found
