"""The road validation's figure, like the paper's Figure 1: the raw, hub-acceleration-compensated
and model-compensated WFS force over the true contact force on a simulated road, magnitude and
phase over frequency, a stretch of the forces in time, and the model-compensated force's error
there with its 95 % band (as it is, and limited to the valid band, where the band is claimed)."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from bench.analysis.road_validation import ERROR_BAND_HZ, RoadValidation, ratio_over_truth
from bench.report.axes import frequency_axes, new_figure

#: The forces drawn, with their labels and colours (the four-post figure's).
CURVES = (
    ("raw", "raw WFS", "tab:red"),
    ("hub_compensated", "hub-acceleration compensated", "tab:blue"),
    ("model_compensated", "model-compensated", "tab:green"),
)
#: The stretch of time drawn (s), from the middle of the record.
TRACE_S = 0.5
#: Lowest frequency drawn (Hz): below it a 20 s road has few Welch segments' worth of excitation.
LOWEST_HZ = 0.5


def road_compensation_figure(result: RoadValidation) -> Figure:
    """Magnitude and phase of ``F / F_contact`` (Welch H1 over the true force) for the three forces
    in 0.5-30 Hz, the valid band shaded; below, ``TRACE_S`` of the forces in time."""
    fig, (mag, phase, trace, error) = new_figure(4, sharex=False)
    fig.set_size_inches(9, 11)
    traces = result.traces
    fs = 1 / (traces["t_s"][1] - traces["t_s"][0])
    for key, label, colour in CURVES:
        f, ratio = ratio_over_truth(traces[key], traces["truth"], fs)
        shown = (f >= LOWEST_HZ) & (f <= ERROR_BAND_HZ[1])
        mag.plot(f[shown], np.abs(ratio[shown]), color=colour, lw=1.1, label=label)
        phase.plot(f[shown], np.degrees(np.angle(ratio[shown])), color=colour, lw=1.1)
    lo, hi = result.valid_band_hz
    for ax in (mag, phase):
        ax.axvspan(max(lo, LOWEST_HZ), hi, color="tab:green", alpha=0.08)
    mag.set(
        ylabel="|F / F_contact|",
        title=f"Road class {result.road_class} at {result.speed_km_h:g} km/h: measured over true contact"
        f" force; shaded: valid band {lo:.2g}-{hi:.3g} Hz",
    )
    phase.set(xlabel="frequency (Hz)", ylabel="phase (deg)")
    mag.legend(fontsize=8, loc="upper left")
    frequency_axes(mag, phase)
    middle = traces["t_s"].size // 2
    span = slice(middle, middle + round(TRACE_S * fs))
    t = traces["t_s"][span]
    trace.plot(t, traces["truth"][span], color="black", lw=1.6, label="true contact force")
    for key, label, colour in CURVES:
        trace.plot(t, traces[key][span], color=colour, lw=0.9, label=label)
    trace.set(ylabel="force (N)")
    trace.legend(fontsize=7, loc="upper right", ncol=2)
    u95 = traces["u95"][span]
    error.fill_between(t, -u95, u95, color="tab:green", alpha=0.25, lw=0, label="95 % band")
    unfiltered = traces["model_compensated"][span] - traces["truth"][span]
    error.plot(t, unfiltered, color="0.6", lw=0.7, label="model-compensated less true force")
    error.plot(
        t, traces["error_in_band"][span], color="tab:green", lw=1.1, label="the same within the valid band"
    )
    error.set(xlabel="time (s)", ylabel="error (N)")
    error.legend(fontsize=7, loc="upper right", ncol=2)
    for ax in (trace, error):
        ax.grid(True, alpha=0.3)
    fig.subplots_adjust(top=0.96, bottom=0.05, hspace=0.35)
    return fig
