"""The figures' common frame: a figure on an Agg canvas (no display, no pyplot state) and log
frequency axes labelled so that a person can read them. Every renderer of the report draws on it."""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, Locator, MaxNLocator, NullFormatter

#: Pixels per inch of the PNGs (a 9 x 6.5 in figure is 900 x 650 px).
DPI = 100
#: Labelled frequencies per decade, coarse to fine; a log axis takes the first giving enough labels.
FREQUENCY_TICK_SUBS = ((1.0, 2.0, 5.0), (1.0, 2.0, 3.0, 5.0, 7.0), tuple(float(k) for k in range(1, 10)))
#: Labelled frequencies a log axis shows at least (when the finest subdivision gives them).
MIN_FREQUENCY_LABELS = 5


def new_figure(rows: int, *, sharex: bool = True) -> tuple[Figure, list[Axes]]:
    """A 9 x 6.5 in figure on an Agg canvas with ``rows`` axes above each other."""
    fig = Figure(figsize=(9, 6.5), dpi=DPI)  # fixed margins: a layout engine doubles the drawing time
    FigureCanvasAgg(fig)
    fig.subplots_adjust(left=0.09, right=0.98, top=0.95, bottom=0.08, hspace=0.12 if sharex else 0.3)
    axes = fig.subplots(rows, 1, sharex=sharex, squeeze=False)[:, 0]
    return fig, list(axes)


class FrequencyLocator(Locator):
    """Major ticks of a log frequency axis: 1-2-5 per decade (0.5, 1, 2, 5, 10 Hz) where that
    labels at least :data:`MIN_FREQUENCY_LABELS` frequencies in view, else the finer 1-2-3-5-7 or
    every integer multiple (a band of about one decade, 2.3-28 Hz, gets 3, 5, 7, 10, 20 Hz, not
    only 5, 10, 20 Hz); a band narrower still (12-38 Hz) gets evenly spaced round numbers."""

    def __call__(self) -> list[float]:
        low, high = self.axis.get_view_interval()
        return self.tick_values(low, high)

    def tick_values(self, vmin: float, vmax: float) -> list[float]:
        low, high = sorted((vmin, vmax))
        if not (np.isfinite(low) and np.isfinite(high)) or low <= 0:
            return []
        decades = np.arange(np.floor(np.log10(low)), np.ceil(np.log10(high)) + 1)
        for subs in FREQUENCY_TICK_SUBS:
            candidates = sorted(float(f"{sub * 10.0**d:.6g}") for d in decades for sub in subs)
            ticks = [t for t in candidates if low <= t <= high]
            if len(ticks) >= MIN_FREQUENCY_LABELS:
                return ticks
        even = MaxNLocator(nbins=8, steps=[1, 2, 2.5, 5, 10], min_n_ticks=MIN_FREQUENCY_LABELS)
        even = even.tick_values(low, high)
        return [float(t) for t in even if low <= t <= high]


def frequency_axes(*axes: Axes) -> None:
    """Log frequency axes labelled with plain numbers, enough of them to read (:class:`FrequencyLocator`),
    a light grid."""
    for ax in axes:
        ax.set_xscale("log")
        ax.xaxis.set_major_locator(FrequencyLocator())
        ax.xaxis.set_major_formatter(FuncFormatter(lambda x, _: f"{x:g}"))
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.grid(True, which="both", alpha=0.3)
