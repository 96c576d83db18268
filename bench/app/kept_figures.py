"""The report's figures drawn where the post-run analysis runs, and kept beside its record.

Once the analysis is read from its records, drawing the figures is most of what ``wfsbench report``
costs (seconds of matplotlib for a whole campaign). The analysis process draws them instead, after
each run, while the bench waits on the next run in real time: :class:`FigureDrawer` draws every
figure whose values changed with the run, and the recorder keeps each beside the run
(``figures/<name>``, docs/hdf5.md) with the SHA-256 of what it shows (:func:`shows_sha256`: the
values drawn, and the code and libraries that draw them). The report takes a kept
figure only when the figure it would draw shows the same (:func:`kept_pngs`) and draws every other
one; ``--reanalyse`` draws them all.
"""

from __future__ import annotations

import functools
import hashlib
from collections.abc import Iterable
from dataclasses import dataclass
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

#: The packages of ``bench`` whose code decides how a figure looks: the figures' own, and what they
#: compute as they draw (model curves, the force-difference trace, spectra). A change to any of their
#: modules makes every kept figure stale.
DRAWING_PACKAGES = ("report", "analysis", "models", "numerics")
#: The libraries that draw and compute a figure: another version of any makes every kept figure stale.
DRAWING_LIBRARIES = ("matplotlib", "numpy", "scipy")
#: The first bytes of every PNG file.
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@functools.cache
def drawing_sha256() -> str:
    """The SHA-256 of the code that draws a figure: every module of :data:`DRAWING_PACKAGES` (by
    path and bytes) and the versions of :data:`DRAWING_LIBRARIES`."""
    digest = hashlib.sha256()
    root = Path(figure_list.__file__).parents[1]
    for package in DRAWING_PACKAGES:
        for module in sorted((root / package).rglob("*.py")):
            digest.update(module.relative_to(root).as_posix().encode())
            digest.update(module.read_bytes())
    for library in DRAWING_LIBRARIES:
        try:
            digest.update(f"{library} {version(library)}".encode())
        except PackageNotFoundError:  # a library of no release: its figures are never taken as kept
            digest.update(f"{library} of no version".encode())
    return digest.hexdigest()


def shows_sha256(spec: FigureSpec) -> str:
    """The SHA-256 of what the figure ``spec`` shows: the drawing code (:func:`drawing_sha256`), its
    name and kind and the values drawn, by value (:mod:`bench.app.value_digest`)."""
    return value_sha256((spec.name, str(spec.kind), spec.shows), drawing_sha256())


@dataclass(frozen=True)
class DrawnFigures:
    """What the drawer gave after a run: the ``kept`` figures, and for each figure it could not
    draw, why (``failed``: the report draws it, and says why it cannot, itself)."""

    kept: tuple[KeptFigure, ...] = ()
    failed: tuple[str, ...] = ()


class FigureDrawer:
    """The analysis process's: after each run, the figures whose values changed, drawn. The figures
    ``knowledge`` supports when the process starts count as drawn: the runs that made it (an earlier
    sequence into the same file) had them drawn and kept."""

    def __init__(self, knowledge: CampaignKnowledge) -> None:
        self._hammer: HammerRecord | None = None
        self._sweep: SweepRecord | None = None
        #: figure name -> what it showed when last drawn (or tried)
        self._drawn = {spec.name: shows_sha256(spec) for spec in figure_specs(knowledge, None, None)}

    def after(self, run: RunInputs, knowledge: CampaignKnowledge, *, draw: bool = True) -> DrawnFigures:
        """The figures ``knowledge`` (after ``run``'s analysis) supports that show other values than
        when this drawer last drew them, each drawn once: a figure that fails is said in
        ``failed`` and tried again only when its values change. Not ``draw``: a run analysed again
        whose figures its campaign kept already; they count as drawn. The hammer figure is drawn
        from the first hammer blow this process analysed and the four-post ones from the last
        four-post sweep; where the report reads another (a file with two hammer runs), its digest
        differs and the report draws it."""
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
        for spec, digest in changed:
            self._drawn[spec.name] = digest
        if not (changed and draw):
            return DrawnFigures()
        from bench.report.figures import figure_png  # the plotting library, once there is a figure

        kept, failed = [], []
        for spec, digest in changed:
            try:
                kept.append(KeptFigure(spec.name, digest, figure_png(spec)))
            except Exception as exc:  # any failure of the plotting library: this figure only
                failed.append(f"figure {spec.name} not drawn: {type(exc).__name__}: {exc}")
        return DrawnFigures(tuple(kept), tuple(failed))


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
