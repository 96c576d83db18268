"""The campaign report as one self-contained HTML page: the figures embedded as base64 PNG data
URIs, the style inline, no script, no link, no external reference of any kind, so the page reads
the same offline, mailed or archived. Tables: the campaign and its givens, the sensor, m_comp,
the identified parameters with their 95 % intervals and what is not determined, the amplitude
dependence, m_wheel, the quarter car and its modes, every valid band with the reason it ends,
every flag, and each run's text summary.
"""

from __future__ import annotations

import base64
from collections.abc import Iterable, Sequence
from html import escape

from bench.analysis.campaign import CampaignAnalysis
from bench.analysis.frf import ValidBand
from bench.analysis.lsq import Z95
from bench.report.figures import FigureFile

_STYLE = """
body { font-family: sans-serif; max-width: 60em; margin: 1em auto; padding: 0 1em; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; border-bottom: 1px solid #ccc; margin-top: 2em; }
table { border-collapse: collapse; margin: 0.5em 0 1em; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.2em 0.5em; text-align: left; vertical-align: top; }
th { background: #f0f0f0; } td.num { text-align: right; font-variant-numeric: tabular-nums; }
figure { margin: 1em 0; } figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.9em; color: #444; } .flag { color: #a00; }
pre { background: #f7f7f7; padding: 0.5em; overflow-x: auto; font-size: 0.8em; }
"""


def _table(header: Sequence[str], rows: Iterable[Sequence[object]]) -> str:
    """A table; floats and ints are right-aligned."""

    def cell(value: object) -> str:
        numeric = isinstance(value, int | float) and not isinstance(value, bool)
        return f'<td class="num">{escape(str(value))}</td>' if numeric else f"<td>{escape(str(value))}</td>"

    head = "".join(f"<th>{escape(h)}</th>" for h in header)
    body = "".join(f"<tr>{''.join(cell(v) for v in row)}</tr>" for row in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def _g(value: float, digits: int = 4) -> str:
    return f"{value:.{digits}g}"


def _band_row(what: str, band: ValidBand) -> tuple[str, ...]:
    lowest = _g(band.lowest_hz) if band.n_points else "-"
    upper = _g(band.upper_hz) if band.determined else "not determined"
    skipped = ", ".join(_g(f, 3) for f in band.skipped_hz) or "-"
    return what, lowest, upper, band.starts_at, band.limited_by, skipped


def _figure(fig: FigureFile) -> str:
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
    return _table(
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
    return _table(
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
    return _table(header, rows) if rows else "<p>none</p>"


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
    return _table(("pressure", "amplitude", "model", "parameter", "value", "+/- 95 %", "", "BIC"), rows)


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
    return _table(("pressure", "amplitude", "k (kN/m, 95 %)", "change", "d (Ns/m)", "change"), rows)


def _four_post(analysis: CampaignAnalysis) -> str:
    r = analysis.knowledge.four_post
    if r is None:
        return "<p>No four-post sweep in this file.</p>"
    m, car = r.wheel_mass, r.quarter_car
    mass = _table(
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
    params = _table(
        ("quarter-car parameter", "value", "+/- 95 %", ""),
        (
            (n, _g(v, 6), _g(car.ci95[n], 2), "NOT DETERMINED" if n in car.undetermined else "")
            for n, v in car.values.items()
        ),
    )
    modes = _table(
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
    return tolerance + _table(
        ("ratio", "from (Hz)", "up to (Hz)", "starts", "ends because", "skips (Hz)"), rows
    )


def _flags(analysis: CampaignAnalysis) -> str:
    rows = [(run.run_id, line) for run in analysis.runs for line in run.lines if "FLAG" in line]
    if not rows:
        return "<p>No flags.</p>"
    return _table(("run", "flag"), rows).replace("<td>FLAG", '<td class="flag">FLAG')


def _summaries(analysis: CampaignAnalysis) -> str:
    return "".join(
        f"<h3>{escape(run.run_id)} ({escape(run.kind)}: {escape(run.name)})</h3>"
        f"<pre>{escape(chr(10).join(run.lines))}</pre>"
        for run in analysis.runs
    )


def report_html(analysis: CampaignAnalysis, figures: Sequence[FigureFile]) -> str:
    """The whole page."""
    sections = [
        ("Campaign", _campaign(analysis)),
        ("Sensor", _sensor(analysis)),
        ("Plate masses m_comp", _plate_masses(analysis)),
        ("Identified tyre parameters (95 % intervals)", _parameters(analysis)),
        ("Amplitude dependence (Model 2)", _dependence(analysis)),
        ("Four-post: m_wheel and the quarter car", _four_post(analysis)),
        ("Valid bands", _bands(analysis)),
        ("Flags", _flags(analysis)),
        ("Figures", "".join(_figure(f) for f in figures) or "<p>No figure: nothing analysed.</p>"),
        ("Run summaries", _summaries(analysis)),
    ]
    body = "".join(f"<h2>{escape(title)}</h2>{content}" for title, content in sections)
    title = f"wfs-bench report: {analysis.path.name}"
    return (
        f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>{escape(title)}</title>'
        f"<style>{_STYLE}</style></head><body><h1>{escape(title)}</h1>{body}</body></html>\n"
    )
