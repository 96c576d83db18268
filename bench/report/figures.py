"""The campaign's figures, drawn with matplotlib's Agg canvas (no display, no pyplot state): the
paper's Figs. 3, 6, 7/9 and 8 from the analysis results.

- ``hammer``: the blow's decay in time with the analysed free decay shaded, and its amplitude
  spectrum with the identified eigenfrequency marked (Fig. 3).
- ``shaker_<p>bar``: |F_WFS/F_contact| (log) and its phase over frequency at one tyre pressure, one
  column of panels per amplitude; measured dwells as dots with 95 % intervals (a magnitude's lower
  end no lower than the axis, a phase's wrapped into -180..180 deg), Models 1 / 2 / 3 as lines, the
  selected one thicker, the raw valid band as a strip along the frequency axis (Fig. 6).
- ``shaker_compensated_<p>bar``: the same ratio raw against model-compensated per amplitude, with
  the tolerance of the valid band and both valid bands as strips.
- ``four_post_ratios``: raw, hub-acceleration compensated and model-compensated ratios over the
  true contact force, each valid band shaded (Figs. 7 and 9).
- ``four_post_hub``: |F_WFS - F_contact| / |Z| against m_wheel |a_hub| / |Z| over frequency: the
  force difference the mass below the sensor makes (Fig. 8, in the frequency domain).
- ``road_replay_<run>`` and ``drive_iteration_<run>``: :mod:`~bench.report.replay_figures` and
  :mod:`~bench.report.iteration_figures`.

Which figures an analysis supports, and what each shows, is :mod:`bench.report.figure_list`'s;
:data:`DRAWERS` is the drawing function of each kind.
"""

from __future__ import annotations

import io
from collections.abc import Callable

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from bench.analysis.frf import Frf, ValidBand
from bench.analysis.hammer import HammerResult
from bench.analysis.records import HAMMER_FORCE, WFS_FORCE, HammerRecord, SweepRecord
from bench.analysis.runs import (
    ForceDifferenceTrace,
    FourPostResult,
    ShakerAmplitudeResult,
    ShakerCampaignResult,
    force_difference_trace,
)
from bench.analysis.shaker_models import shaker_response
from bench.models.parameters import WfsSensor
from bench.report.axes import DPI, frequency_axes, new_figure
from bench.report.figure_list import FigureKind, FigureSpec
from bench.report.iteration_figures import drive_iteration_figure
from bench.report.replay_figures import road_replay_figure

#: Points of a model curve over the measured band.
MODEL_GRID_POINTS = 300
#: Normal quantile of the drawn uncertainty bars (95 %).
Z95 = 1.96
#: Factor of room below the smallest and above the largest magnitude drawn on a log axis.
MAGNITUDE_MARGIN = 1.5
#: Room beyond +/-180 deg on a phase axis, so that points at the wrap stay visible.
PHASE_MARGIN_DEG = 10.0
_MODEL_STYLES = {1: ":", 2: "-", 3: "--"}


# ---------------------------------------------------------------------------------------- hammer


def hammer_figure(result: HammerResult, record: HammerRecord) -> Figure:
    """Decay in time (analysed span shaded) and amplitude spectrum with the eigenfrequency marked."""
    fs = record.sample_rate_hz
    force = np.asarray(record.channels[WFS_FORCE], dtype=float)
    t_ms = 1e3 * np.arange(force.size) / fs
    fig, (decay, spectrum) = new_figure(2, sharex=False)
    decay.plot(t_ms, force, lw=0.8, color="tab:blue", label="F_WFS")
    if HAMMER_FORCE in record.channels:
        decay.plot(t_ms, record.channels[HAMMER_FORCE], lw=0.8, color="tab:gray", label="hammer")
    decay.axvspan(
        1e3 * result.decay_start_s,
        1e3 * result.decay_stop_s,
        color="tab:green",
        alpha=0.15,
        label=f"free decay analysed ({result.n_peaks} peaks)",
    )
    decay.set(xlabel="time (ms)", ylabel="force (N)", title="Hammer blow on the bare sensor")
    decay.legend(loc="upper right")
    start, stop = int(result.decay_start_s * fs), int(result.decay_stop_s * fs) + 1
    span_ms = 1e3 * (result.decay_stop_s - result.decay_start_s)
    decay.set_xlim(1e3 * result.decay_start_s - 0.5 * span_ms, 1e3 * result.decay_stop_s + span_ms)
    tail = force[start:stop] - np.mean(force[stop:]) if stop < force.size else force[start:stop]
    n_fft = 1 << int(np.ceil(np.log2(max(16 * tail.size, 4096))))
    amplitude = np.abs(np.fft.rfft(tail, n_fft))  # the decay windows itself: no taper
    freq = np.fft.rfftfreq(n_fft, 1 / fs)
    spectrum.semilogy(freq, amplitude / amplitude.max(), lw=0.8, color="tab:blue")
    spectrum.axvline(
        result.eigenfrequency_hz,
        color="tab:red",
        ls="--",
        label=f"eigenfrequency {result.eigenfrequency_hz:.1f} Hz"
        f" (damping ratio {result.damping_ratio_log_decrement:.4f})",
    )
    spectrum.set(
        xlabel="frequency (Hz)",
        ylabel="amplitude (normalised)",
        xlim=(0, fs / 2),
        title="Spectrum of the free decay",
    )
    spectrum.legend(loc="upper right")
    return fig


# ---------------------------------------------------------------------------------------- shaker


def _model_ratio(
    result: ShakerAmplitudeResult, model: int, sensor: WfsSensor, f_hz: np.ndarray
) -> np.ndarray:
    fit = result.identification.fits[model]
    wfs, contact = shaker_response(fit.model, fit.tyre, sensor, f_hz, fit.rubber)
    return wfs / contact


def magnitude_limits(magnitudes: list[np.ndarray]) -> tuple[float, float]:
    """Log-axis limits that show every drawn magnitude (dots and model lines, not the bars) with a
    margin of ``MAGNITUDE_MARGIN``: an interval reaching beyond them runs off the axes instead of
    stretching them over decades of nothing."""
    values = np.concatenate([np.ravel(m) for m in magnitudes])
    values = values[np.isfinite(values) & (values > 0)]
    if values.size == 0:
        return 0.1, 10.0
    return float(values.min()) / MAGNITUDE_MARGIN, float(values.max()) * MAGNITUDE_MARGIN


def magnitude_bar(magnitude: np.ndarray, sigma: np.ndarray, floor: float) -> np.ndarray:
    """Lower and upper extent (2 x n, for ``errorbar``'s ``yerr``) of the 95 % interval of a
    magnitude: ``|H| -/+ 1.96 sigma``, the lower end no lower than ``floor`` (> 0, the axis' bottom):
    a magnitude is not negative, and an interval that reaches zero runs to the bottom of the axes."""
    lower = np.minimum(Z95 * sigma, np.maximum(magnitude - floor, 0.0))
    return np.vstack([lower, Z95 * sigma])


def phase_half_width_deg(magnitude: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Half-width of the 95 % phase interval of a complex point: the phases of the circle of radius
    ``1.96 sigma`` around it, ``arcsin(1.96 sigma / |H|)``; 180 deg (any phase) when the circle
    holds zero."""
    ratio = np.divide(Z95 * sigma, magnitude, out=np.full(magnitude.shape, np.inf), where=magnitude > 0)
    return np.where(ratio < 1, np.degrees(np.arcsin(np.minimum(ratio, 1.0))), 180.0)


def _phase_bars(phase: Axes, f: np.ndarray, phase_deg: np.ndarray, half_deg: np.ndarray, style: dict) -> None:
    """Phase intervals on the (-180, 180] axis: the part beyond +/-180 deg continues from the other
    edge (the phase wraps), an interval of 360 deg or more spans the whole axis."""
    lo, hi = phase_deg - half_deg, phase_deg + half_deg
    full = half_deg >= 180.0
    lo, hi = np.where(full, -180.0, np.maximum(lo, -180.0)), np.where(full, 180.0, np.minimum(hi, 180.0))
    pieces = [(f, lo, hi)]
    over = ~full & (phase_deg + half_deg > 180.0)
    under = ~full & (phase_deg - half_deg < -180.0)
    pieces.append((f[over], np.full(over.sum(), -180.0), phase_deg[over] + half_deg[over] - 360.0))
    pieces.append((f[under], phase_deg[under] - half_deg[under] + 360.0, np.full(under.sum(), 180.0)))
    for x, y0, y1 in pieces:
        if x.size:
            phase.vlines(x, y0, y1, color=style["ecolor"], lw=style["elinewidth"])


def _phase_axis(phase: Axes) -> None:
    """Phase from -180 to 180 deg (the range of a wrapped phase), ticks every 90 deg."""
    phase.set_ylim(-180.0 - PHASE_MARGIN_DEG, 180.0 + PHASE_MARGIN_DEG)
    phase.set_yticks([-180, -90, 0, 90, 180])


def _dots(
    mag: Axes, phase: Axes, frf: Frf, colour: str, label: str, *, floor: float, marker: str = "o"
) -> None:
    """Measured points with 95 % intervals (magnitude: lower ends no lower than ``floor``; phase:
    wrapped); unreliable points hollow."""
    for keep, face in ((frf.reliable, colour), (~frf.reliable, "none")):
        if not np.any(keep):
            continue
        f, h, sigma = frf.freq_hz[keep], frf.value[keep], frf.sigma[keep]
        dots = {
            "fmt": marker,
            "ms": 4,
            "mfc": face,
            "mec": colour,
            "ecolor": colour,
            "elinewidth": 0.8,
            "capsize": 2,
            "ls": "none",
        }
        magnitude = np.abs(h)
        bar = magnitude_bar(magnitude, sigma, floor)
        mag.errorbar(f, magnitude, yerr=bar, label=label if face != "none" else None, **dots)
        phase.plot(f, np.degrees(np.angle(h)), marker, ms=4, mfc=face, mec=colour, ls="none")
        _phase_bars(phase, f, np.degrees(np.angle(h)), phase_half_width_deg(magnitude, sigma), dots)


#: Colours of the models' lines and of the measured points in the shaker panels.
_MODEL_COLOURS = {1: "tab:gray", 2: "tab:blue", 3: "tab:orange"}
_MEASURED, _COMPENSATED = "black", "tab:green"
#: Colours of the valid-band strips: raw and model-compensated ratio.
_BAND_COLOURS = {"raw": "tab:red", "model-compensated": "tab:green"}
#: Height of a valid-band strip, as a fraction of the magnitude axes' height.
BAND_STRIP = 0.045


def _amplitude_panels(n: int) -> tuple[Figure, list[Axes], list[Axes]]:
    """One column per amplitude, magnitude above phase, the axes of a row sharing their scale; room
    at the top for the title and one legend for all panels."""
    fig = Figure(figsize=(9 if n == 1 else 12, 7), dpi=DPI)
    FigureCanvasAgg(fig)
    fig.subplots_adjust(
        left=0.08 if n == 1 else 0.06, right=0.98, top=0.83, bottom=0.08, hspace=0.1, wspace=0.05
    )
    axes = fig.subplots(2, n, sharex=True, sharey="row", squeeze=False)
    return fig, list(axes[0]), list(axes[1])


def _band_strips(mag: Axes, bands: list[tuple[str, ValidBand]]) -> None:
    """Each valid band as a strip along the frequency axis at the bottom of ``mag``, one above the
    other, in its colour (:data:`_BAND_COLOURS`); a band not determined draws nothing."""
    for i, (name, band) in enumerate(bands):
        if band.determined:
            mag.axvspan(
                band.lowest_hz,
                band.upper_hz,
                ymin=i * BAND_STRIP,
                ymax=(i + 1) * BAND_STRIP,
                color=_BAND_COLOURS[name],
                alpha=0.55,
                lw=0,
            )


def _band_legend(names: tuple[str, ...]) -> list[Patch]:
    return [Patch(color=_BAND_COLOURS[n], alpha=0.55, label=f"valid band, {n} (strip)") for n in names]


def _panel_title(ax: Axes, amp: ShakerAmplitudeResult, bands: list[tuple[str, ValidBand]]) -> None:
    def text(band: ValidBand) -> str:
        return f"{band.lowest_hz:.3g}-{band.upper_hz:.3g} Hz" if band.determined else "none"

    valid = ", ".join(f"{name} {text(band)}" for name, band in bands)
    ax.set_title(f"{amp.label}: Model {int(amp.identification.best)} selected\nvalid: {valid}", fontsize=9)


def _finish_panel(
    mag: Axes, phase: Axes, amp: ShakerAmplitudeResult, bands: list[tuple[str, ValidBand]]
) -> None:
    """An amplitude's panels: its valid bands as strips, its title, the phase axis."""
    _band_strips(mag, bands)
    _panel_title(mag, amp, bands)
    phase.set_xlabel("frequency (Hz)")
    _phase_axis(phase)


def _finish_panels(
    fig: Figure,
    mags: list[Axes],
    phases: list[Axes],
    *,
    limits: tuple[float, float],
    ylabel: str,
    title: str,
    handles: list,
) -> None:
    """The shared magnitude scale and labels, the title and one legend above every panel."""
    mags[0].set(yscale="log", ylim=limits, ylabel=ylabel)
    phases[0].set_ylabel("phase (deg)")
    fig.suptitle(title, y=0.985)
    fig.legend(
        handles=handles, loc="upper center", bbox_to_anchor=(0.5, 0.955), ncol=3, fontsize=8, frameon=False
    )
    frequency_axes(*mags, *phases)


def shaker_figure(pressure_bar: float, result: ShakerCampaignResult) -> Figure:
    """|F_WFS/F_contact| (log) and phase, one column per amplitude: the measured dwells with 95 %
    bars, Models 1-3 as lines (the selected one thicker), the raw valid band as a strip."""
    amplitudes = list(result.amplitudes.values())
    fig, mags, phases = _amplitude_panels(len(amplitudes))
    models = {}
    drawn = []
    for amp in amplitudes:
        ratio = amp.frfs.wfs_per_contact
        grid = np.geomspace(ratio.freq_hz[0], ratio.freq_hz[-1], MODEL_GRID_POINTS)
        drawn.append(ratio.magnitude)
        models[amp.amplitude_m] = {
            int(m): _model_ratio(amp, int(m), result.sensor, grid) for m in amp.identification.fits
        }
        drawn += [np.abs(h) for h in models[amp.amplitude_m].values()]
    limits = magnitude_limits(drawn)
    for mag, phase, amp in zip(mags, phases, amplitudes, strict=True):
        ratio = amp.frfs.wfs_per_contact
        grid = np.geomspace(ratio.freq_hz[0], ratio.freq_hz[-1], MODEL_GRID_POINTS)
        for model, h in models[amp.amplitude_m].items():
            width = 2.2 if model == int(amp.identification.best) else 1.0
            style = {"ls": _MODEL_STYLES[model], "color": _MODEL_COLOURS[model], "lw": width}
            mag.plot(grid, np.abs(h), **style)
            phase.plot(grid, np.degrees(np.angle(h)), **style)
        _dots(mag, phase, ratio, _MEASURED, "measured", floor=limits[0])
        _finish_panel(mag, phase, amp, [("raw", amp.valid_band_raw)])
    handles = [
        Line2D(
            [],
            [],
            color=_MEASURED,
            marker="o",
            ls="none",
            ms=4,
            label="measured, 95 % bars (hollow: unsettled)",
        ),
        *(
            Line2D([], [], color=_MODEL_COLOURS[m], ls=_MODEL_STYLES[m], label=f"Model {m}")
            for m in (1, 2, 3)
        ),
        Line2D([], [], color="black", lw=2.2, label="thick: the selected model"),
        *_band_legend(("raw",)),
    ]
    title = f"Shaker, tyre at {pressure_bar:g} bar: F_WFS / F_contact measured and Models 1-3"
    _finish_panels(
        fig, mags, phases, limits=limits, ylabel="|F_WFS / F_contact|", title=title, handles=handles
    )
    return fig


def _tolerance(mag: Axes, phase: Axes, band: ValidBand) -> None:
    for sign in (-1, 1):
        mag.axhline(1 + sign * band.amplitude_tolerance, color="gray", lw=0.8, ls="--")
        phase.axhline(sign * band.phase_tolerance_deg, color="gray", lw=0.8, ls="--")


def shaker_compensated_figure(pressure_bar: float, result: ShakerCampaignResult) -> Figure:
    """Raw against model-compensated ratio, one column per amplitude, with the valid band's
    tolerances and both valid bands as strips."""
    amplitudes = list(result.amplitudes.values())
    fig, mags, phases = _amplitude_panels(len(amplitudes))
    limits = magnitude_limits(
        [
            frf.magnitude
            for amp in amplitudes
            for frf in (amp.frfs.wfs_per_contact, amp.compensated_per_contact)
        ]
    )
    for mag, phase, amp in zip(mags, phases, amplitudes, strict=True):
        compensated = amp.compensated_per_contact
        _dots(mag, phase, amp.frfs.wfs_per_contact, _BAND_COLOURS["raw"], "raw", floor=limits[0], marker="o")
        _dots(mag, phase, compensated, _COMPENSATED, "model-compensated", floor=limits[0], marker="s")
        mag.plot(compensated.freq_hz, compensated.magnitude, color=_COMPENSATED, lw=0.8)
        phase.plot(compensated.freq_hz, compensated.phase_deg, color=_COMPENSATED, lw=0.8)
        _tolerance(mag, phase, amp.valid_band_raw)
        bands = [("raw", amp.valid_band_raw), ("model-compensated", amp.valid_band_compensated)]
        _finish_panel(mag, phase, amp, bands)
    handles = [
        Line2D(
            [], [], color=_BAND_COLOURS["raw"], marker="o", ls="none", ms=4, label="raw F_WFS (95 % bars)"
        ),
        Line2D([], [], color=_COMPENSATED, marker="s", ms=4, lw=0.8, label="model-compensated (95 % bars)"),
        Line2D([], [], color="gray", ls="--", lw=0.8, label="tolerance of the valid band"),
        *_band_legend(("raw", "model-compensated")),
    ]
    title = f"Shaker, tyre at {pressure_bar:g} bar: raw and model-compensated force over the contact force"
    _finish_panels(fig, mags, phases, limits=limits, ylabel="|F / F_contact|", title=title, handles=handles)
    return fig


# ---------------------------------------------------------------------------------------- four-post


def four_post_ratios_figure(result: FourPostResult) -> Figure:
    """Raw, hub-acceleration and model-compensated ratios with each valid band shaded."""
    fig, (mag, phase) = new_figure(2)
    curves = (
        ("raw", result.wfs_per_contact, result.valid_band_raw, "tab:red"),
        (
            "hub-acceleration compensated",
            result.hub_compensated_per_contact,
            result.valid_band_hub_compensated,
            "tab:blue",
        ),
        (
            "model-compensated",
            result.model_compensated_per_contact,
            result.valid_band_model_compensated,
            "tab:green",
        ),
    )
    for i, (name, frf, band, colour) in enumerate(curves):
        f = frf.freq_hz
        usable = np.where(frf.reliable, 1.0, np.nan)
        mag.plot(f, frf.magnitude * usable, color=colour, lw=1.1, label=name)
        phase.plot(f, frf.phase_deg * usable, color=colour, lw=1.1)
        if band.determined:
            y0, y1 = i / len(curves), (i + 1) / len(curves)
            for ax in (mag, phase):
                ax.axvspan(band.lowest_hz, band.upper_hz, ymin=y0, ymax=y1, color=colour, alpha=0.12)
            mag.annotate(
                f"{name} valid {band.lowest_hz:.3g}-{band.upper_hz:.3g} Hz",
                xy=(0.01, y0 + 0.02),
                xycoords="axes fraction",
                fontsize=7,
                color=colour,
            )
    _tolerance(mag, phase, result.valid_band_raw)
    mag.set(
        ylabel="|F / F_contact|",
        title="Four-post: measured over true contact force; shaded: valid bands; dashed: tolerance",
    )
    phase.set(xlabel="frequency (Hz)", ylabel="phase (deg)")
    mag.legend(fontsize=8, loc="upper left")
    frequency_axes(mag, phase)
    return fig


def four_post_hub_figure(result: FourPostResult, trace: ForceDifferenceTrace | None = None) -> Figure:
    """F_contact - F_WFS against m_wheel a_hub, both over Z (reliable bins): the hub-acceleration
    compensation ``F_contact = F_WFS + m_wheel a_hub`` holds where they agree. The hub acceleration
    is advanced by the accelerometer's lag, as the compensation advances it. With ``trace`` (the
    sweep's record at hand) a third panel shows both in time, as the paper's Fig. 8 does."""
    frfs, m = result.frfs, result.wheel_mass
    keep = frfs.wfs_per_z.reliable & frfs.contact_per_z.reliable & frfs.accel_per_z.reliable
    f = frfs.wfs_per_z.freq_hz[keep]
    difference = (frfs.contact_per_z.value - frfs.wfs_per_z.value)[keep]
    advance = np.exp(2j * np.pi * f * m.accelerometer_delay_s)
    inertial = m.mass_kg * frfs.accel_per_z.value[keep] * advance
    if trace is None:
        fig, (mag, phase) = new_figure(2)
    else:
        fig = Figure(figsize=(9, 9), dpi=DPI)
        FigureCanvasAgg(fig)
        fig.subplots_adjust(left=0.09, right=0.98, top=0.96, bottom=0.06, hspace=0.35)
        grid = fig.add_gridspec(3, 1)
        mag = fig.add_subplot(grid[0])
        phase = fig.add_subplot(grid[1], sharex=mag)
        _time_panel(fig.add_subplot(grid[2]), trace)
    mag.plot(f, np.abs(difference), color="tab:red", lw=1.1, label="F_contact - F_WFS")
    mag.plot(
        f,
        np.abs(inertial),
        color="tab:blue",
        lw=1.1,
        ls="--",
        label=f"m_wheel a_hub (m_wheel {m.mass_kg:.2f} kg from the run;"
        f" a_hub advanced by its {1e3 * m.accelerometer_delay_s:.3f} ms lag)",
    )
    phase.plot(f, np.degrees(np.angle(difference)), color="tab:red", lw=1.1)
    phase.plot(f, np.degrees(np.angle(inertial)), color="tab:blue", lw=1.1, ls="--")
    mag.set(
        yscale="log",
        ylabel="magnitude over Z (N/m)",
        title="Four-post: force difference against the mass below the sensor times the hub acceleration",
    )
    phase.set(xlabel="frequency (Hz)", ylabel="phase (deg)")
    mag.legend(fontsize=8)
    frequency_axes(mag, phase)
    return fig


def _time_panel(ax: Axes, trace: ForceDifferenceTrace) -> None:
    ax.plot(trace.t_s, trace.difference_n, color="tab:red", lw=1.1, label="F_contact - F_WFS")
    ax.plot(trace.t_s, trace.inertial_n, color="tab:blue", lw=1.1, ls="--", label="m_wheel a_hub")
    ax.set(
        xlabel="time in the sweep (s)",
        ylabel="force (N), less its mean",
        title=f"in time, as the sweep passes {trace.freq_hz:.1f} Hz (Fig. 8 of the paper)",
    )
    ax.legend(fontsize=8, loc="upper right")
    ax.grid(alpha=0.3)


# ---------------------------------------------------------------------------------------- all


def _four_post_hub(result: FourPostResult, sweep: SweepRecord | None) -> Figure:
    """The force-difference figure, with its panel in time when the sweep's record is at hand."""
    return four_post_hub_figure(result, None if sweep is None else force_difference_trace(sweep, result))


#: The function that draws each kind of figure from its spec's ``shows``.
DRAWERS: dict[FigureKind, Callable[..., Figure]] = {
    FigureKind.HAMMER: hammer_figure,
    FigureKind.SHAKER: shaker_figure,
    FigureKind.SHAKER_COMPENSATED: shaker_compensated_figure,
    FigureKind.FOUR_POST_RATIOS: four_post_ratios_figure,
    FigureKind.FOUR_POST_HUB: _four_post_hub,
    FigureKind.ROAD_REPLAY: road_replay_figure,
    FigureKind.DRIVE_ITERATION: drive_iteration_figure,
}


def figure_png(spec: FigureSpec) -> bytes:
    """The figure ``spec`` names, drawn, as PNG bytes."""
    buffer = io.BytesIO()
    DRAWERS[spec.kind](*spec.shows).savefig(buffer, format="png", dpi=DPI)
    return buffer.getvalue()
