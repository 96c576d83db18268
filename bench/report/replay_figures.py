"""A road replay's figure: the WFS force raw, hub-acceleration compensated and model-compensated
against the post's contact force, in time (the forces and their errors over a stretch of the drive)
and as spectra (the forces' and their errors' power spectral densities), the model compensation's
valid band shaded."""

from __future__ import annotations

import textwrap

import numpy as np
from matplotlib.figure import Figure

from bench.analysis.road_replay import RoadReplayResult
from bench.analysis.road_validation import ERROR_BAND_HZ
from bench.report.axes import frequency_axes, new_figure

#: The forces drawn, with their labels, short labels and colours (the four-post figure's).
CURVES = (
    ("raw", "raw WFS", "raw", "tab:red"),
    ("hub_compensated", "hub-acceleration compensated", "hub", "tab:blue"),
    ("model_compensated", "model-compensated", "model", "tab:green"),
)
#: Lowest frequency drawn (Hz): the spectra's first bins of a short drive hold little excitation.
LOWEST_HZ = 0.5


def road_replay_figure(run_id: str, result: RoadReplayResult) -> Figure:
    """Four panels: the contact force and each WFS force over a stretch of the drive, their errors
    against the contact force there (each force's rms error in 0-30 Hz in the title), the forces'
    spectra and the errors' spectra (N^2/Hz) up to the error band's top."""
    fig, (forces, errors, spectra, error_spectra) = new_figure(4, sharex=False)
    fig.set_size_inches(9, 11)
    traces, f = result.traces, result.spectra["freq_hz"]
    t = traces["t_s"]
    shown = (f >= LOWEST_HZ) & (f <= ERROR_BAND_HZ[1])
    forces.plot(t, traces["contact"], color="black", lw=1.6, label="post's contact force")
    spectra.plot(f[shown], result.spectra["contact"][shown], color="black", lw=1.6)
    rms = []
    for key, label, short, colour in CURVES:
        if key not in result.errors:
            continue
        rms.append(f"{short} {result.errors[key].rms_n:.3g} N")
        forces.plot(t, traces[key], color=colour, lw=0.9, label=label)
        errors.plot(t, traces[key] - traces["contact"], color=colour, lw=0.9)
        spectra.plot(f[shown], result.spectra[key][shown], color=colour, lw=1.0)
        error_spectra.plot(f[shown], result.spectra[f"{key}_error"][shown], color=colour, lw=1.0)
    fig.suptitle(textwrap.fill(f"{run_id}: road replay of {result.source}", 100), fontsize=10)
    forces.legend(fontsize=8, loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=4, frameon=False)
    forces.set(ylabel="force (N)")
    errors.set(xlabel="time from the drive's start (s)", ylabel="error (N)")
    low, high = ERROR_BAND_HZ
    errors.set_title(
        f"error against the contact force; rms in {low:g}-{high:g} Hz: {', '.join(rms)}", fontsize=9
    )
    spectra.set(ylabel="PSD (N^2/Hz)", yscale="log")
    spectra.set_title("power spectral densities of the forces", fontsize=9)
    error_spectra.set(xlabel="frequency (Hz)", ylabel="error PSD (N^2/Hz)", yscale="log")
    title = "... of their errors"
    if result.valid_band_hz is not None:
        lo, hi = result.valid_band_hz
        for ax in (spectra, error_spectra):
            ax.axvspan(max(lo, LOWEST_HZ), hi, color="tab:green", alpha=0.08)
        title += f"; shaded: the model compensation's valid band {lo:.2g}-{hi:.3g} Hz"
    error_spectra.set_title(title, fontsize=9)
    for ax in (forces, errors):
        ax.grid(True, alpha=0.3)
        if np.ptp(t) > 0:
            ax.set_xlim(t[0], t[-1])
    frequency_axes(spectra, error_spectra)
    fig.subplots_adjust(top=0.92, bottom=0.05, hspace=0.45)
    return fig
