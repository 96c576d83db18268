"""A report's figures as PNG files: each as kept beside the analysis record, or drawn now."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path

from bench.report.figure_list import FigureFile, FigureSpec


def write_figures(
    specs: Iterable[FigureSpec], out_dir: Path, kept: Mapping[str, bytes] | None = None
) -> list[FigureFile]:
    """Each figure of ``specs`` into ``out_dir/<name>.png``: the PNG ``kept`` holds for its name
    (drawn before from the same values), else drawn now (the plotting library is loaded only then)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    kept = kept or {}
    written = []
    for spec in specs:
        path = out_dir / f"{spec.name}.png"
        png = kept.get(spec.name)
        if png is None:
            from bench.report.figures import figure_png

            png = figure_png(spec)
        path.write_bytes(png)
        written.append(FigureFile(spec.name, spec.title, spec.caption, path, kept=spec.name in kept))
    return written
