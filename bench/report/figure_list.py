"""Which figures a campaign's analysis supports and what each shows, without drawing any.

A :class:`FigureSpec` names a figure (its file stem), says its kind (:class:`FigureKind`: which
drawing function of :mod:`bench.report.figures` draws it), its title and caption for the page, and
``shows``: the values it is drawn from, exactly the drawing function's arguments. What a figure shows
is therefore known before matplotlib is loaded: the post-run analysis draws a figure when what it
shows has changed, and the report takes a figure kept beside the analysis record when it shows the
same values (:mod:`bench.app.kept_figures`); :func:`bench.report.figure_files.write_figures`
writes the kept ones as they are and draws the others.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from pathlib import Path

from bench.analysis.campaign import CampaignAnalysis, CampaignKnowledge
from bench.analysis.drive_iteration import by_step
from bench.analysis.records import HammerRecord, SweepRecord


class FigureKind(enum.StrEnum):
    """What a figure draws; the key of the drawing functions' table (``figures.DRAWERS``)."""

    HAMMER = "hammer"
    SHAKER = "shaker"
    SHAKER_COMPENSATED = "shaker_compensated"
    FOUR_POST_RATIOS = "four_post_ratios"
    FOUR_POST_HUB = "four_post_hub"
    ROAD_REPLAY = "road_replay"
    DRIVE_ITERATION = "drive_iteration"


#: Each kind's title (a format string of the figure's ``subject``: a tyre pressure in bar, a run id)
#: and caption on the report's page.
TITLES_AND_CAPTIONS: dict[FigureKind, tuple[str, str]] = {
    FigureKind.HAMMER: (
        "Hammer test (Fig. 3)",
        "Left to right in time: the blow and the sensor's free decay (shaded: the span the"
        " logarithmic decrement uses); below, its spectrum with the identified eigenfrequency.",
    ),
    FigureKind.SHAKER: (
        "Shaker at {subject:g} bar (Fig. 6)",
        "Measured F_WFS/F_contact per dwell with 95 % bars (hollow: not settled, unused) and"
        " the three tyre models fitted to them, one column per amplitude (the selected model"
        " thicker); the strip along the frequency axis is the raw valid band.",
    ),
    FigureKind.SHAKER_COMPENSATED: (
        "Shaker at {subject:g} bar: raw and compensated",
        "The raw ratio against the model-compensated one, one column per amplitude; within the"
        " dashed tolerances the WFS force is the contact force; the strips along the frequency"
        " axis are the valid bands, raw (red) and model-compensated (green).",
    ),
    FigureKind.FOUR_POST_RATIOS: (
        "Four-post: raw and compensated ratios (Figs. 7 and 9)",
        "Measured over true contact force, raw, with the hub-acceleration compensation and"
        " with the model compensator; each valid band shaded in its colour.",
    ),
    FigureKind.FOUR_POST_HUB: (
        "Four-post: force difference and hub acceleration (Fig. 8)",
        "Where the two curves agree, the difference between WFS and contact force is the"
        " inertia of the mass below the sensor.",
    ),
    FigureKind.ROAD_REPLAY: (
        "Road replay {subject}",
        "The WFS force raw, hub-acceleration compensated and model-compensated against the"
        " post's contact force (post force less m_comp z''), in time and as power spectral"
        " densities; the errors' panel gives each force's rms error in 0-30 Hz.",
    ),
    FigureKind.DRIVE_ITERATION: (
        "Drive iteration {subject}",
        "The rms error of the matched response against the target per iteration (and the share"
        " of samples inside the target's 95 % band), the damage ratio rig / road per iteration"
        " (the band 0.9-1.1 shaded), and the target and the last response overlaid.",
    ),
}


@dataclass(frozen=True)
class FigureSpec:
    """A figure the analysis supports: ``name`` (the PNG's file stem), ``kind``, ``title`` and
    ``caption`` for the page, and ``shows``: the drawing function's arguments."""

    name: str
    kind: FigureKind
    title: str
    caption: str
    shows: tuple[object, ...]


@dataclass(frozen=True)
class FigureFile:
    """A written figure: ``name`` (file stem), ``title`` and ``caption`` for the page, ``path``;
    ``kept``: taken as the post-run analysis drew it, not drawn again."""

    name: str
    title: str
    caption: str
    path: Path
    kept: bool = False


@dataclass(frozen=True)
class KeptFigure:
    """A figure the post-run analysis drew after a run, to be kept beside it: its ``name``, the
    SHA-256 of what it shows (``bench.app.kept_figures.shows_sha256``) and its ``png`` bytes."""

    name: str
    shows_sha256: str
    png: bytes


def pressure_tag(pressure_bar: float) -> str:
    """A tyre pressure as a file name's part: 2.5 bar -> ``2p5bar``."""
    return f"{pressure_bar:g}".replace(".", "p") + "bar"


def _spec(kind: FigureKind, shows: tuple[object, ...], subject: object = None, tag: str = "") -> FigureSpec:
    """The figure of ``kind`` named by its kind and ``tag`` (``shaker_2p5bar``), about ``subject``."""
    title, caption = TITLES_AND_CAPTIONS[kind]
    name = f"{kind}_{tag}" if tag else str(kind)
    return FigureSpec(name, kind, title.format(subject=subject), caption, shows)


def figure_specs(
    knowledge: CampaignKnowledge, hammer_record: HammerRecord | None, sweep_record: SweepRecord | None
) -> list[FigureSpec]:
    """Every figure ``knowledge`` supports, in the report's order. ``hammer_record``: the hammer
    blow's record (its figure needs it); ``sweep_record``: the four-post sweep's (None: its
    force-difference figure goes without the panel in time)."""
    k = knowledge
    out = []
    if k.hammer is not None and hammer_record is not None:
        out.append(_spec(FigureKind.HAMMER, (k.hammer, hammer_record)))
    for pressure, result in sorted((p, r) for p, r in k.shaker.items() if r.amplitudes):
        for kind in (FigureKind.SHAKER, FigureKind.SHAKER_COMPENSATED):
            out.append(_spec(kind, (pressure, result), pressure, pressure_tag(pressure)))
    if k.four_post is not None:
        out.append(_spec(FigureKind.FOUR_POST_RATIOS, (k.four_post,)))
        out.append(_spec(FigureKind.FOUR_POST_HUB, (k.four_post, sweep_record)))
    for run_id, replay in k.road_replays.items():
        out.append(_spec(FigureKind.ROAD_REPLAY, (run_id, replay), run_id, run_id))
    for step_run_id, runs in by_step(k.drive_iterations).items():
        results = [result for _, result in runs]
        out.append(_spec(FigureKind.DRIVE_ITERATION, (step_run_id, results), step_run_id, step_run_id))
    return out


def campaign_figure_specs(analysis: CampaignAnalysis) -> list[FigureSpec]:
    """:func:`figure_specs` of a campaign file's analysis."""
    return figure_specs(analysis.knowledge, analysis.hammer_record, analysis.sweep_record)

