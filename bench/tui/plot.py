"""A line plot in braille characters: each cell holds 2 x 4 dots, so a 60 x 8 cell widget draws
120 x 32 points. Dense data is decimated to the dot columns by min/max (a 50 Hz sine stays an
envelope, not an alias); sparse data (a few dwells) is joined by straight lines."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from rich.segment import Segment
from rich.style import Style
from textual.strip import Strip
from textual.widget import Widget

#: Braille dot bits by (row, column) inside a cell (Unicode braille patterns, U+2800 on).
_DOT_BITS = np.array([[0x01, 0x08], [0x02, 0x10], [0x04, 0x20], [0x40, 0x80]], dtype=np.int32)
#: Width (cells) of the y-axis labels left of the plot.
LABEL_CELLS = 9
_DIM = Style(dim=True)
_BOLD = Style(bold=True)


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


def tick_label(value: float, span: float, width: int = LABEL_CELLS - 1) -> str:
    """``value`` rounded to the resolution its axis can show: three significant digits of the
    axis' ``span`` without trailing zeros (a phase axis of 168 deg reads ``-168`` and ``0``, not
    ``0.0003842``), at most
    ``width`` characters (else in the ``g`` format)."""
    span = abs(span)
    if not math.isfinite(span) or span <= 0:
        return f"{value:.3g}"
    decimals = min(max(0, 2 - math.floor(math.log10(span))), 6)
    text = f"{round(value, decimals) + 0.0:.{decimals}f}"  # + 0.0: no "-0"
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    if text in ("", "-", "-0"):
        text = "0"
    return text if len(text) <= width else f"{value:.{max(1, width - 6)}g}"


def render_plot(series: list[Series], width: int, height: int, y_label: str = "") -> list[list[Segment]]:
    """The plot as ``height`` lines of ``width`` cells (labels included), each line a few segments:
    consecutive cells of one curve share one segment, which keeps redrawing cheap."""
    plot_w = max(2, width - LABEL_CELLS)
    w_dots, h_dots = 2 * plot_w, 4 * height
    xs = [a for a in (s.x[np.isfinite(s.x)] for s in series) if a.size]
    ys = [a for a in (s.y[np.isfinite(s.y)] for s in series) if a.size]
    if not xs or not ys:
        blank = [[Segment(" " * width)] for _ in range(height)]
        return [[Segment(f"{y_label}: no data".ljust(width), _DIM)], *blank[1:]]
    x_lim = (min(float(a.min()) for a in xs), max(float(a.max()) for a in xs))
    y_min, y_max = min(float(a.min()) for a in ys), max(float(a.max()) for a in ys)
    if y_max - y_min < 1e-12 * max(1.0, abs(y_max)):
        y_min, y_max = y_min - 1.0, y_max + 1.0
    owner = np.full((height, plot_w), -1)
    codes = np.zeros((height, plot_w), dtype=np.int32)
    rows = np.arange(h_dots)[:, None]
    for index, s in enumerate(series):
        lo, hi = column_ranges(s.x, s.y, x_lim, w_dots)
        top = np.rint((y_max - hi) / (y_max - y_min) * (h_dots - 1))
        bottom = np.rint((y_max - lo) / (y_max - y_min) * (h_dots - 1))
        with np.errstate(invalid="ignore"):
            grid = (rows >= top[None, :]) & (rows <= bottom[None, :])
        cells = (grid.reshape(height, 4, plot_w, 2) * _DOT_BITS[None, :, None, :]).sum(axis=(1, 3))
        owner[cells > 0] = index
        codes |= cells
    styles = [Style.parse(s.style) for s in series]
    lines = []
    for row in range(height):
        label = " " * LABEL_CELLS
        if row == 0:
            label = f"{tick_label(y_max, y_max - y_min):>8} "
        elif row == height - 1:
            label = f"{tick_label(y_min, y_max - y_min):>8} "
        elif row == height // 2 and y_label:
            label = f"{y_label[: LABEL_CELLS - 1]:>8} "
        segments = [Segment(label[:LABEL_CELLS].ljust(LABEL_CELLS), _DIM)]
        chars = "".join(chr(0x2800 + int(c)) for c in codes[row])
        who = owner[row]
        cuts = [0, *(np.flatnonzero(np.diff(who)) + 1).tolist(), plot_w]
        for a, b in itertools.pairwise(cuts):
            segments.append(Segment(chars[a:b], styles[who[a]] if who[a] >= 0 else None))
        lines.append(segments)
    return lines


class BraillePlot(Widget):
    """A plot widget: :meth:`plot` sets its curves; title and legend above, x note below."""

    DEFAULT_CSS = """
    BraillePlot { height: 10; }
    """

    def __init__(self, title: str, y_label: str = "", **kwargs) -> None:
        super().__init__(**kwargs)
        self.title = title
        self.y_label = y_label
        self.x_note = ""
        self.series: list[Series] = []
        self._lines: list[Strip] = []
        self._drawn_for: tuple[int, int] = (0, 0)

    def plot(self, series: list[Series], x_note: str = "") -> None:
        self.series = series
        self.x_note = x_note
        self._drawn_for = (0, 0)
        self.refresh()

    def _draw(self) -> None:
        width, height = self.size.width, self.size.height
        head = [Segment(self.title, _BOLD)]
        for s in self.series:
            head += [Segment("  ■ ", Style.parse(s.style)), Segment(s.name)]
        lines = [head]
        if width >= LABEL_CELLS + 4 and height >= 4:
            lines += render_plot(self.series, width, height - 2, self.y_label)
            lines.append([Segment(" " * LABEL_CELLS + self.x_note, _DIM)])
        self._lines = [Strip(line).crop_extend(0, width, None) for line in lines]
        self._drawn_for = (width, height)

    def render_line(self, y: int) -> Strip:
        if self._drawn_for != (self.size.width, self.size.height):
            self._draw()
        return self._lines[y] if y < len(self._lines) else Strip.blank(self.size.width)
