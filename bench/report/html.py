"""The campaign report as one self-contained HTML page: the figures embedded as base64 PNG data
URIs, the style inline, no script, no link, no external reference of any kind, so the page reads
the same offline, mailed or archived.

Laid out to be read top-down: the heading (the campaign file), a summary (per tyre pressure and
amplitude the selected model's parameters in kN/m, kg and Ns/m with their 95 % intervals and the
valid bands; the sensor; the four-post result), the flags, the figures; then an appendix with the
full tables: the campaign and its givens, the sensor, m_comp, every model's parameters and what is
not determined, the amplitude dependence, m_wheel, the quarter car and its modes, every valid band
with the reason it ends, and each run's text summary under a heading that names its tyre pressure.
Text wraps to the page's width (no sideways scrolling).
"""

from __future__ import annotations

import base64
import math
from collections.abc import Iterable, Sequence
from html import escape

from bench.analysis.campaign import CampaignAnalysis, RunAnalysis
from bench.analysis.frf import ValidBand
from bench.analysis.lsq import Z95
from bench.analysis.road_replay import FORCES
from bench.analysis.road_validation import ERROR_BAND_HZ, OCTAVE_CENTRES_HZ
from bench.report.figure_list import FigureFile
from bench.report.metadata import metadata_html
from sequences.runs import RunKind

PAGE_STYLE = """
body { font-family: sans-serif; max-width: 72em; margin: 1em auto; padding: 0 1em; color: #222;
  overflow-wrap: break-word; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; border-bottom: 1px solid #ccc; margin-top: 2em; }
h1.part { font-size: 1.35em; margin-top: 3em; border-top: 3px double #999; padding-top: 0.5em; }
table { border-collapse: collapse; margin: 0.5em 0 1em; font-size: 0.9em; }
div.wide { overflow-x: auto; } /* a table wider than a narrow window scrolls in its box, not the page */
th, td { border: 1px solid #ccc; padding: 0.2em 0.5em; text-align: left; vertical-align: top; }
th { background: #f0f0f0; } td.num { text-align: right; font-variant-numeric: tabular-nums; }
@media (min-width: 60em) { table.summary td { white-space: nowrap; } }
table.summary td:last-child { white-space: normal; } h3 { font-size: 1em; margin-top: 1.5em; }
figure { margin: 1em 0; } figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.9em; color: #444; } .flag { color: #a00; } .note { color: #555; }
pre { background: #f7f7f7; padding: 0.5em; white-space: pre-wrap; font-size: 0.8em; }
"""


def table_html(header: Sequence[str], rows: Iterable[Sequence[object]]) -> str:
    """A table (in a box that scrolls by itself where a narrow window cannot hold it); floats and
    ints are right-aligned."""

    def cell(value: object) -> str:
        numeric = isinstance(value, int | float) and not isinstance(value, bool)
        return f'<td class="num">{escape(str(value))}</td>' if numeric else f"<td>{escape(str(value))}</td>"

    head = "".join(f"<th>{escape(h)}</th>" for h in header)
    body = "".join(f"<tr>{''.join(cell(v) for v in row)}</tr>" for row in rows)
    return f'<div class="wide"><table><tr>{head}</tr>{body}</table></div>'


def _g(value: float, digits: int = 4) -> str:
    return f"{value:.{digits}g}"


def _band_row(what: str, band: ValidBand) -> tuple[str, ...]:
    lowest = _g(band.lowest_hz) if band.n_points else "-"
    upper = _g(band.upper_hz) if band.determined else "not determined"
    skipped = ", ".join(_g(f, 3) for f in band.skipped_hz) or "-"
    return what, lowest, upper, band.starts_at, band.limited_by, skipped


def figure_html(fig: FigureFile) -> str:
    data = base64.b64encode(fig.path.read_bytes()).decode("ascii")
    return (
        f'<figure id="{escape(fig.name)}"><img alt="{escape(fig.title)}" src="data:image/png;base64,{data}">'
        f"<figcaption><b>{escape(fig.title)}.</b> {escape(fig.caption)}</figcaption></figure>"
    )


def _sequences_run(analysis: CampaignAnalysis) -> str:
    """``hammer (1 run), shaker (10 runs)``: every sequence the file holds, in the order they ran."""
    runs = (f"{name} ({n} run{'' if n == 1 else 's'})" for name, n in analysis.sequences)
    return ", ".join(runs) or "none"


def _campaign(analysis: CampaignAnalysis) -> str:
    return table_html(
        ("item", "value"),
        (
            ("file", analysis.path),
            ("written by", analysis.software_version),
            ("sequence that created the file", analysis.sequence_name),
            ("sequences run", _sequences_run(analysis)),
            ("configuration", analysis.config_source),
            ("sensor mass (given)", f"{analysis.sensor_mass_kg:g} kg"),
            ("wheel mass below the sensor (weighed)", f"{analysis.wheel_mass_kg:g} kg"),
            ("runs analysed", len(analysis.runs)),
            (
                "runs not analysed (incomplete)",
                ", ".join(f"{r} ({s})" for r, s in analysis.skipped) or "none",
            ),
        ),
    )


def _sensor(analysis: CampaignAnalysis) -> str:
    h = analysis.knowledge.hammer
    if h is None:
        k = analysis.knowledge
        return (
            f"<p>No hammer test: the sensor is taken as {k.sensor.eigenfrequency_hz:g} Hz, damping ratio"
            f" {k.sensor.damping_ratio:.3g} ({escape(k.sensor_source.text)}).</p>"
        )
    return table_html(
        ("quantity", "value", "unit"),
        (
            ("eigenfrequency (undamped)", _g(h.eigenfrequency_hz, 5), "Hz"),
            ("damped frequency", _g(h.damped_frequency_hz, 5), "Hz"),
            ("damping ratio, logarithmic decrement", _g(h.damping_ratio_log_decrement), "-"),
            ("damping ratio, half-power", _g(h.damping_ratio_half_power), "-"),
            ("stiffness (from the sensor mass)", _g(h.stiffness_n_per_m), "N/m"),
            ("damping (from the sensor mass)", _g(h.damping_ns_per_m), "Ns/m"),
            ("peaks in the free decay", h.n_peaks, "-"),
        ),
    )


def _plate_masses(analysis: CampaignAnalysis) -> str:
    """Every free run analysed, whether or not a later run of the file used its m_comp (a file
    whose shaker grids were interrupted still weighed its plate)."""
    rows = [
        (
            run.plate,
            run.run_id,
            _g(run.result.plate.mass_kg, 6),
            _g(Z95 * run.result.plate.sigma_kg, 2),
            f"{run.result.plate.n_points} of {len(run.result.fits)}",
        )
        for run in analysis.knowledge.plate_masses
    ]
    header = ("plate", "free run", "m_comp (kg)", "+/- 95 % (kg)", "dwells used")
    return table_html(header, rows) if rows else "<p>none</p>"


def _parameters(analysis: CampaignAnalysis) -> str:
    rows = []
    for pressure, result in sorted(analysis.knowledge.shaker.items()):
        for amp in result.amplitudes.values():
            ident = amp.identification
            for model, fit in ident.fits.items():
                chosen = "selected" if model == ident.best else ""
                for name, value in fit.values.items():
                    determined = "NOT DETERMINED" if name in fit.undetermined else ""
                    rows.append(
                        (
                            f"{pressure:g} bar",
                            amp.label,
                            f"Model {int(model)} {chosen}".strip(),
                            name,
                            _g(value, 6),
                            _g(fit.ci95[name], 2),
                            determined,
                            f"{fit.bic:.1f}",
                        )
                    )
    if not rows:
        return "<p>No shaker identification in this file.</p>"
    return table_html(("pressure", "amplitude", "model", "parameter", "value", "+/- 95 %", "", "BIC"), rows)


def _dependence(analysis: CampaignAnalysis) -> str:
    rows = []
    for pressure, result in sorted(analysis.knowledge.shaker.items()):
        dep = result.amplitude_dependence
        if dep is None:
            rows.append((f"{pressure:g} bar", "one amplitude only: not determined", "", "", "", ""))
            continue
        for a, k, ci, dk, d, dd in dep.rows():
            rows.append(
                (
                    f"{pressure:g} bar",
                    f"{1e3 * a:g} mm",
                    f"{k / 1e3:.2f} +/- {ci / 1e3:.2f}",
                    f"{100 * dk:+.2f} %",
                    f"{d:.1f}",
                    f"{100 * dd:+.1f} %",
                )
            )
    if not rows:
        return "<p>none</p>"
    return table_html(("pressure", "amplitude", "k (kN/m, 95 %)", "change", "d (Ns/m)", "change"), rows)


def _four_post(analysis: CampaignAnalysis) -> str:
    r = analysis.knowledge.four_post
    if r is None:
        return "<p>No four-post sweep in this file.</p>"
    m, car = r.wheel_mass, r.quarter_car
    mass = table_html(
        ("quantity", "value"),
        (
            ("run", r.label),
            ("tyre below the sensor", f"Model {int(r.tyre_model)} from {r.tyre_source}"),
            (
                "m_wheel from the run",
                f"{m.mass_kg:.3f} +/- {Z95 * m.sigma_kg:.2g} kg (95 %;"
                f" {m.band_hz[0]:.3g}-{m.band_hz[1]:.3g} Hz)",
            ),
            (
                "m_wheel weighed",
                f"{r.wheel_mass_given_kg:g} kg ({100 * (m.mass_kg / r.wheel_mass_given_kg - 1):+.1f} %)",
            ),
            ("accelerometer lag", f"{1e3 * m.accelerometer_delay_s:.3f} ms"),
            ("unreliable bins", f"{r.unreliable_bins} of {r.frfs.wfs_per_z.freq_hz.size}"),
        ),
    )
    params = table_html(
        ("quarter-car parameter", "value", "+/- 95 %", ""),
        (
            (n, _g(v, 6), _g(car.ci95[n], 2), "NOT DETERMINED" if n in car.undetermined else "")
            for n, v in car.values.items()
        ),
    )
    modes = table_html(
        ("mode", "frequency (Hz)", "+/- 95 % (Hz)", "damping ratio"),
        (
            (
                "body",
                _g(car.body_frequency_hz),
                _g(car.body_frequency_ci95_hz, 2),
                _g(car.body_damping_ratio, 3),
            ),
            (
                "wheel",
                _g(car.wheel_frequency_hz),
                _g(car.wheel_frequency_ci95_hz, 2),
                _g(car.wheel_damping_ratio, 3),
            ),
        ),
    )
    given = "; ".join(car.taken_as_given) or "nothing"
    notes = (
        f"<p>Reduced chi^2 {car.reduced_chi2:.1f} over {car.band_hz[0]:.4g}-{car.band_hz[1]:.4g} Hz;"
        f" unsprung mass above the sensor {car.suspension.unsprung_mass_above_kg:.2f} kg;"
        f" taken as given: {escape(given)}.</p>"
    )
    return mass + params + modes + notes


def _road_replays(analysis: CampaignAnalysis) -> str:
    """Each road replay's rms errors against the post's contact force, in 0-30 Hz and per octave."""
    replays = analysis.knowledge.road_replays
    if not replays:
        return "<p>No road replay in this file.</p>"
    octaves = [f"{c:g} Hz" for c in OCTAVE_CENTRES_HZ]
    rows = []
    for run_id, r in replays.items():
        rows.append((run_id, "contact force (rms)", _g(r.contact_rms_n), *([""] * len(octaves))))
        for name, label in FORCES:
            if name in r.errors:
                e = r.errors[name]
                rows.append((run_id, label, _g(e.rms_n), *(_g(x, 3) for x in e.octave_rms_n)))
            else:
                rows.append((run_id, label, f"none: {r.model_omitted}", *([""] * len(octaves))))
    header = ("run", "force", f"rms error {ERROR_BAND_HZ[0]:g}-{ERROR_BAND_HZ[1]:g} Hz (N)", *octaves)
    drives = "".join(f"<li>{escape(run_id)}: {escape(r.source)}</li>" for run_id, r in replays.items())
    return table_html(header, rows) + f"<p>Drives:</p><ul>{drives}</ul>"


def _bands(analysis: CampaignAnalysis) -> str:
    rows = []
    for pressure, result in sorted(analysis.knowledge.shaker.items()):
        for amp in result.amplitudes.values():
            rows.append(_band_row(f"shaker {pressure:g} bar {amp.label} raw", amp.valid_band_raw))
            rows.append(
                _band_row(
                    f"shaker {pressure:g} bar {amp.label} model-compensated", amp.valid_band_compensated
                )
            )
    r = analysis.knowledge.four_post
    if r is not None:
        rows += [
            _band_row("four-post raw", r.valid_band_raw),
            _band_row("four-post hub-acceleration compensated", r.valid_band_hub_compensated),
            _band_row("four-post model-compensated", r.valid_band_model_compensated),
        ]
    if not rows:
        return "<p>none</p>"
    any_band = (
        r.valid_band_raw
        if r is not None
        else next(a for s in analysis.knowledge.shaker.values() for a in s.amplitudes.values()).valid_band_raw
    )
    tolerance = (
        f"<p>Tolerance: | |H| - 1 | &lt;= {100 * any_band.amplitude_tolerance:g} % and |phase| &lt;="
        f" {any_band.phase_tolerance_deg:g} deg, every point from the lowest reliable one on.</p>"
    )
    return tolerance + table_html(
        ("ratio", "from (Hz)", "up to (Hz)", "starts", "ends because", "skips (Hz)"), rows
    )


#: A parameter's unit in the summary by its name's suffix: (factor from SI, unit).
_UNITS = (
    ("_n_per_m", 1e-3, "kN/m"),
    ("_ns_per_m", 1.0, "Ns/m"),
    ("_kg", 1.0, "kg"),
    ("_per_decade", 100.0, "%/decade"),
)
#: The summary's own columns (every other parameter of the selected model goes under "more").
_SUMMARY_PARAMETERS = (("stiffness_n_per_m", "k"), ("damping_ns_per_m", "d"), ("tread_mass_kg", "m_T"))


def _unit(name: str) -> tuple[float, str]:
    """A parameter's summary unit and the factor to it from SI, by its name's suffix."""
    return next(((f, u) for suffix, f, u in _UNITS if name.endswith(suffix)), (1.0, ""))


def _with_interval(name: str, value: float, ci: float, undetermined: bool, *, unit: bool = True) -> str:
    """``390.014 ± 0.028 kN/m``: the parameter in its summary unit, to the digit its 95 % half-width
    (two significant digits) reaches, with the unit unless ``unit`` is false; ``not determined``
    where the data do not determine it."""
    factor, symbol = _unit(name)
    symbol = f" {symbol}" if unit and symbol else ""
    value, ci = factor * value, factor * ci
    if undetermined or not (math.isfinite(ci) and ci > 0):
        return f"not determined ({_g(value, 4)}{symbol})"
    decimals = max(0, 1 - math.floor(math.log10(ci)))
    return f"{value:.{decimals}f} ± {ci:.{decimals}f}{symbol}"


def _parameter_label(name: str) -> str:
    """``stiffness_rise_per_decade``: ``stiffness rise``: the name without its unit, in words."""
    suffix = next((suffix for suffix, _, _ in _UNITS if name.endswith(suffix)), "")
    return name.removesuffix(suffix).replace("_", " ")


def _band_cell(band: ValidBand) -> str:
    if not band.determined:
        return "not determined"
    return f"{_g(band.lowest_hz, 3)}-{_g(band.upper_hz, 3)} Hz ({band.limited_by})"


def _summary(analysis: CampaignAnalysis) -> str:
    """Per tyre pressure and amplitude: the selected model, its k, d and m_T with 95 % intervals and
    its other parameters, the raw and model-compensated valid bands; then the sensor and the four-post."""
    rows = []
    for pressure, result in sorted(analysis.knowledge.shaker.items()):
        for amp in result.amplitudes.values():
            fit = amp.identification.best_fit
            cells = [
                _with_interval(name, fit.values[name], fit.ci95[name], name in fit.undetermined, unit=False)
                if name in fit.values
                else "-"
                for name, _ in _SUMMARY_PARAMETERS
            ]
            undetermined = set(fit.undetermined)
            more = "; ".join(
                f"{_parameter_label(name)} {_with_interval(name, v, fit.ci95[name], name in undetermined)}"
                for name, v in fit.values.items()
                if name not in dict(_SUMMARY_PARAMETERS)
            )
            rows.append(
                (
                    f"{pressure:g} bar",
                    amp.label,
                    f"Model {int(fit.model)}",
                    *cells,
                    _band_cell(amp.valid_band_raw),
                    "; ".join((_band_cell(amp.valid_band_compensated), *amp.band_conditions)),
                    more,
                )
            )
        for ratios in result.ratios_only.values():
            rows.append((f"{pressure:g} bar", ratios.label, f"no fit: {ratios.why}", "", "", "", "", "", ""))
    if rows:
        header = (
            "tyre",
            "amplitude",
            "selected",
            *(f"{label} ({_unit(name)[1]}, ± 95 %)" for name, label in _SUMMARY_PARAMETERS),
            "valid band raw",
            "valid band compensated",
            "more parameters (95 %)",
        )
        tyre = table_html(header, rows).replace("<table>", '<table class="summary">', 1)
    else:
        tyre = "<p>No shaker identification in this file.</p>"
    k = analysis.knowledge
    sensor = (
        f"Sensor: {k.sensor.eigenfrequency_hz:.5g} Hz, damping ratio {k.sensor.damping_ratio:.3g}"
        f" ({escape(k.sensor_source.text)})."
    )
    lines = [sensor]
    r = k.four_post
    if r is not None:
        m = r.wheel_mass
        lines.append(
            f"Four-post ({escape(r.label)}): m_wheel {m.mass_kg:.3f} ± {Z95 * m.sigma_kg:.2g} kg;"
            f" valid bands raw {_band_cell(r.valid_band_raw)}, hub-acceleration compensated"
            f" {_band_cell(r.valid_band_hub_compensated)}, model-compensated"
            f" {_band_cell(r.valid_band_model_compensated)}."
        )
    note = (
        '<p class="note">Parameters of the model the data select (lowest BIC among the determined'
        " fits) with 95 % half-widths; a valid band runs from the lowest reliable point to where the"
        " ratio leaves its tolerance (the reason in brackets). Every model: appendix.</p>"
    )
    return tyre + note + "".join(f"<p>{line}</p>" for line in lines)


def run_heading(run: RunAnalysis, pressure_bar: float | None) -> str:
    """A run's heading in the run summaries: its id, what it is and its tyre pressure (or why it
    has none: the bare sensor, no wheel)."""
    if pressure_bar is not None:
        tyre = f"tyre at {pressure_bar:g} bar"
    elif run.kind == RunKind.HAMMER:
        tyre = "bare sensor, no tyre"
    elif run.kind == RunKind.FREE_RUN:
        tyre = "no wheel on the bench"
    else:
        tyre = "tyre pressure not recorded"
    return f"{run.run_id} ({run.kind}: {run.name}; {tyre})"


def _flags(analysis: CampaignAnalysis) -> str:
    rows = [(run.run_id, flag.line) for run in analysis.runs for flag in run.flags]
    if not rows:
        return "<p>No flags.</p>"
    return table_html(("run", "flag"), rows).replace("<td>FLAG", '<td class="flag">FLAG')


def _summaries(analysis: CampaignAnalysis) -> str:
    return "".join(
        f"<h3>{escape(run_heading(run, analysis.run_pressures_bar.get(run.run_id)))}</h3>"
        f"<pre>{escape(chr(10).join(run.lines))}</pre>"
        for run in analysis.runs
    )


def _heading(analysis: CampaignAnalysis) -> str:
    """The page's heading: its title and what the campaign is."""
    title = f"wfs-bench report: {analysis.path.name}"
    return (
        f"<h1>{escape(title)}</h1>{metadata_html(analysis.metadata)}"
        f"<p>{escape(str(analysis.path))}: {escape(_sequences_run(analysis))}.</p>"
    )


def report_html(analysis: CampaignAnalysis, figures: Sequence[FigureFile]) -> str:
    """The whole page: heading, summary, flags and figures; the full tables in the appendix."""
    main = [
        ("Summary: tyre, sensor and valid bands", _summary(analysis)),
        ("Flags", _flags(analysis)),
        ("Figures", "".join(figure_html(f) for f in figures) or "<p>No figure: nothing analysed.</p>"),
    ]
    appendix = [
        ("Campaign", _campaign(analysis)),
        ("Sensor", _sensor(analysis)),
        ("Plate masses m_comp", _plate_masses(analysis)),
        ("Identified tyre parameters, every model (95 % intervals)", _parameters(analysis)),
        ("Amplitude dependence (Model 2)", _dependence(analysis)),
        ("Four-post: m_wheel and the quarter car", _four_post(analysis)),
        ("Road replays: rms error against the post's contact force", _road_replays(analysis)),
        ("Valid bands", _bands(analysis)),
        ("Run summaries", _summaries(analysis)),
    ]
    body = "".join(f"<h2>{escape(title)}</h2>{content}" for title, content in main)
    body += '<h1 class="part">Appendix: the full tables</h1>'
    body += "".join(f"<h2>{escape(title)}</h2>{content}" for title, content in appendix)
    title = f"wfs-bench report: {analysis.path.name}"
    return (
        f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>{escape(title)}</title>'
        f"<style>{PAGE_STYLE}</style></head><body>{_heading(analysis)}{body}</body></html>\n"
    )
