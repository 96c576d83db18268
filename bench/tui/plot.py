"""A line plot in braille characters: each cell holds 2 x 4 dots, so a 60 x 8 cell widget draws
120 x 32 points. Dense data is decimated to the dot columns by min/max (a 50 Hz sine stays an
envelope, not an alias); sparse data (a few dwells) is joined by straight lines."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from rich.text import Text
from textual.widget import Widget

#: Braille dot bits by (row, column) inside a cell (Unicode braille patterns, U+2800 on).
_DOT_BITS = np.array([[0x01, 0x08], [0x02, 0x10], [0x04, 0x20], [0x40, 0x80]], dtype=np.int32)
#: Width (cells) of the y-axis labels left of the plot.
LABEL_CELLS = 9


@dataclass(frozen=True)
class Series:
    """One curve: ``x`` ascending, ``y`` the same length (NaN: no point), drawn in ``style``."""

    name: str
    x: np.ndarray
    y: np.ndarray
    style: str


def column_ranges(
    x: np.ndarray, y: np.ndarray, x_lim: tuple[float, float], width_dots: int
) -> tuple[np.ndarray, np.ndarray]:
    """The lowest and highest y in each dot column (NaN where the curve has no point).

    Columns between two samples further apart than a column get the line joining them."""
    lo = np.full(width_dots, np.nan)
    hi = np.full(width_dots, np.nan)
    keep = np.isfinite(x) & np.isfinite(y)
    x, y = np.asarray(x, float)[keep], np.asarray(y, float)[keep]
    if x.size == 0 or x_lim[1] <= x_lim[0]:
        return lo, hi
    scale = (width_dots - 1) / (x_lim[1] - x_lim[0])
    col = np.clip(np.rint((x - x_lim[0]) * scale).astype(int), 0, width_dots - 1)
    np.fmin.at(lo, col, y)
    np.fmax.at(hi, col, y)
    if x.size > 1:  # join sparse samples: interpolate the columns between them
        between = np.arange(col[0], col[-1] + 1)
        empty = between[np.isnan(lo[between])]
        joined = np.interp(empty, col, y)
        lo[empty] = hi[empty] = joined
        # each column reaches to its neighbour's value so that steep lines stay connected
        a, b = lo[col[0] : col[-1] + 1], hi[col[0] : col[-1] + 1]
        prev_lo, prev_hi = np.roll(a, 1), np.roll(b, 1)
        a[1:] = np.fmin(a[1:], prev_hi[1:])
        b[1:] = np.fmax(b[1:], prev_lo[1:])
    return lo, hi


def render_plot(series: list[Series], width: int, height: int, y_label: str = "") -> list[Text]:
    """The plot as ``height`` lines of ``width`` cells (labels included)."""
    plot_w = max(2, width - LABEL_CELLS)
    w_dots, h_dots = 2 * plot_w, 4 * height
    xs = [s.x[np.isfinite(s.x)] for s in series if np.size(s.x)]
    ys = [s.y[np.isfinite(s.y)] for s in series if np.size(s.y)]
    xs, ys = [a for a in xs if a.size], [a for a in ys if a.size]
    if not xs or not ys:
        return [Text(f"{y_label}: no data".ljust(width))] + [Text(" " * width) for _ in range(height - 1)]
    x_lim = (min(float(a.min()) for a in xs), max(float(a.max()) for a in xs))
    y_min, y_max = min(float(a.min()) for a in ys), max(float(a.max()) for a in ys)
    if y_max - y_min < 1e-12 * max(1.0, abs(y_max)):
        y_min, y_max = y_min - 1.0, y_max + 1.0
    owner = np.full((height, plot_w), -1)
    codes = np.zeros((height, plot_w), dtype=np.int32)
    for index, s in enumerate(series):
        lo, hi = column_ranges(s.x, s.y, x_lim, w_dots)
        grid = np.zeros((h_dots, w_dots), dtype=bool)
        rows = np.arange(h_dots)[:, None]
        top = np.rint((y_max - hi) / (y_max - y_min) * (h_dots - 1))
        bottom = np.rint((y_max - lo) / (y_max - y_min) * (h_dots - 1))
        with np.errstate(invalid="ignore"):
            grid[:] = (rows >= top[None, :]) & (rows <= bottom[None, :])
        cells = (grid.reshape(height, 4, plot_w, 2) * _DOT_BITS[None, :, None, :]).sum(axis=(1, 3))
        owner[cells > 0] = index
        codes |= cells
    lines = []
    for row in range(height):
        label = (
            f"{y_max:>8.4g} " if row == 0 else f"{y_min:>8.4g} " if row == height - 1 else " " * LABEL_CELLS
        )
        if row == height // 2 and y_label:
            label = f"{y_label[: LABEL_CELLS - 1]:>8} "
        line = Text(label[:LABEL_CELLS].ljust(LABEL_CELLS), style="dim")
        for col in range(plot_w):
            who = owner[row, col]
            line.append(chr(0x2800 + int(codes[row, col])), style=series[who].style if who >= 0 else "")
        lines.append(line)
    return lines


class BraillePlot(Widget):
    """A plot widget: set :attr:`series` (and the labels) with :meth:`plot`; a legend under it."""

    DEFAULT_CSS = """
    BraillePlot { height: 10; }
    """

    def __init__(self, title: str, y_label: str = "", **kwargs) -> None:
        super().__init__(**kwargs)
        self.title = title
        self.y_label = y_label
        self.x_note = ""
        self.series: list[Series] = []

    def plot(self, series: list[Series], x_note: str = "") -> None:
        self.series = series
        self.x_note = x_note
        self.refresh()

    def render(self) -> Text:
        width, height = self.size.width, self.size.height
        if width < LABEL_CELLS + 4 or height < 4:
            return Text(self.title)
        legend = "  ".join(f"[{s.style}]■ {s.name}[/]" for s in self.series)
        out = Text.from_markup(f"[bold]{self.title}[/]  {legend}")
        for line in render_plot(self.series, width, height - 2, self.y_label):
            out.append("\n")
            out.append_text(line)
        out.append("\n")
        out.append(" " * LABEL_CELLS + self.x_note, style="dim")
        return out
