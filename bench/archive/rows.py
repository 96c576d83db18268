"""One campaign file as the index's rows (:mod:`bench.archive.columns`): what it is, its runs, the
results stored in it and the identification of the campaign's analysis.

The analysis is :func:`~bench.app.analyze.analyze_campaign`'s, as ``wfsbench analyze`` gives it: the
record the post-run analysis stored beside each run, read back (``source`` ``analysis``), or the
runs fitted again in memory where a run stores none this version reads or ``--reanalyse`` asks;
nothing is written to the file. The few scalars a run's results store by themselves (m_comp, the
hammer's eigenfrequency) are listed beside it as they are (``source`` ``stored``).

The values are read from the analysis document's types (:mod:`bench.report.analysis_document`);
parameter names are the keys of the analysis JSON (docs/analysis-json.md), their units in the names;
docs/index.md lists which each analysis gives.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator, Mapping
from datetime import UTC, datetime
from typing import TYPE_CHECKING, Any

from bench.analysis.campaign import AnalysisKind
from bench.analysis.lsq import Z95
from bench.archive import columns as c
from bench.store import CampaignFile, RunView
from sequences.runs import EventKind

if TYPE_CHECKING:
    from bench.analysis.campaign import CampaignAnalysis
    from bench.report.analysis_document import (
        AmplitudeDoc,
        AmplitudeRowDoc,
        BandDoc,
        FlagDoc,
        FourPostDoc,
        FreeRunDoc,
        HammerDoc,
        ModelFitDoc,
        QuarterCarDoc,
        RatiosOnlyDoc,
        RepeatDoc,
        ShakerPressureDoc,
    )

Row = dict[str, Any]


def timestamp(text: str) -> datetime | None:
    """An ISO 8601 time of the file (``2026-05-04T10:00:00.000+00:00``); one without a zone is
    taken as UTC; empty or unreadable text gives None."""
    try:
        moment = datetime.fromisoformat(text)
    except ValueError:
        return None
    return moment if moment.tzinfo else moment.replace(tzinfo=UTC)


def campaign_columns(campaign: CampaignFile) -> Row:
    """The file columns a readable campaign file fills: its versions, names, creation and the
    test's metadata (the root attributes :data:`~bench.store.schema.METADATA_FIELDS`)."""
    return {
        "schema_version": campaign.schema_version,
        "software_version": campaign.software_version,
        "created": timestamp(campaign.created),
        "config_name": campaign.config_name,
        "sequence_name": campaign.sequence_name,
        **campaign.metadata,
    }


def run_columns(run: RunView) -> Row:
    """The run's columns; the bench, operator and notes it records itself (the session that ran it)
    replace the campaign's."""
    pressure = run.conditions.get("tyre_pressure_bar")
    return {
        **{name: value for name, value in run.metadata.items() if value},
        "run_id": run.run_id,
        "run_kind": run.kind,
        "run_status": run.status,
        "run_reason": run.reason,
        "run_started": timestamp(run.started),
        "run_finished": timestamp(run.finished),
        "run_interlocks": sum(1 for event in run.events if event.kind == EventKind.INTERLOCK),
        "tyre_pressure_bar": float(pressure) if isinstance(pressure, int | float) else None,
    }


def stored_values(run: RunView) -> Iterator[Row]:
    """Every number stored in the run's results groups, one row each (``parameter``: its key, a
    nested key joined with dots); texts and arrays are left out."""
    for name in run.result_names:
        for parameter, value in _numbers(run.results(name)):
            yield {
                "entry": c.VALUE,
                "source": "stored",
                "result_name": name,
                "parameter": parameter,
                "value": value,
            }


def _numbers(tree: Mapping[str, Any], prefix: str = "") -> Iterator[tuple[str, float]]:
    for key, value in tree.items():
        if isinstance(value, Mapping):
            yield from _numbers(value, f"{prefix}{key}.")
        elif isinstance(value, int | float) and not isinstance(value, bool):
            yield f"{prefix}{key}", float(value)


def _value(parameter: str, value: float | None, ci95: float | None = None, **extra: Any) -> Row:
    finite = value is not None and math.isfinite(value)
    return {
        "entry": c.VALUE,
        "source": "analysis",
        "parameter": parameter,
        "value": float(value) if finite else None,
        "ci95": float(ci95) if ci95 is not None and math.isfinite(ci95) else None,
        "determined": extra.pop("determined", finite),
        **extra,
    }


def hammer_values(hammer: HammerDoc) -> Iterator[Row]:
    """The bare sensor's frequencies, damping ratios, stiffness and damping (none has an interval)."""
    yield _value("eigenfrequency_hz", hammer.eigenfrequency_hz)
    yield _value("damped_frequency_hz", hammer.damped_frequency_hz)
    yield _value("damping_ratio_half_power", hammer.damping_ratio_half_power)
    yield _value("damping_ratio_log_decrement", hammer.damping_ratio_log_decrement)
    yield _value("stiffness_n_per_m", hammer.stiffness_n_per_m)
    yield _value("damping_ns_per_m", hammer.damping_ns_per_m)


def free_run_values(free_run: FreeRunDoc) -> Iterator[Row]:
    """m_comp (its 95 % half-width from its standard uncertainty) and the fit's misfit."""
    sigma = free_run.m_comp_sigma_kg
    ci95 = None if sigma is None else Z95 * sigma
    yield _value("m_comp_kg", free_run.m_comp_kg, ci95, determined=not free_run.nominal)
    yield _value("residual_rms_n_per_m", free_run.residual_rms_n_per_m)
    yield _value("residual_reduced_chi2", free_run.residual_reduced_chi2)
    yield from repeat_values(free_run.repeats)


def band_values(name: str, band: BandDoc, **extra: Any) -> Iterator[Row]:
    """A valid band as its lowest and upper frequency (``<name>_lowest_hz``, ``<name>_upper_hz``);
    the upper end is null and not determined when the band has no width."""
    yield _value(f"{name}_lowest_hz", band.lowest_hz, **extra)
    yield _value(f"{name}_upper_hz", band.upper_hz, determined=band.determined, **extra)


def repeat_values(repeats: tuple[RepeatDoc, ...], **extra: Any) -> Iterator[Row]:
    """The repeatability of each point measured more than once: per channel the relative rms
    spread of the repeats (``repeat_spread.<channel>``) and the spread their noise alone gives
    (``repeat_noise.<channel>``), at the point's ``freq_hz``."""
    for repeat in repeats:
        for kind, by_channel in (("spread", repeat.spread), ("noise", repeat.noise)):
            for channel, value in sorted(by_channel.items()):
                yield _value(f"repeat_{kind}.{channel}", value, freq_hz=repeat.freq_hz, **extra)


def fitted_values(fit: ModelFitDoc | QuarterCarDoc, **extra: Any) -> Iterator[Row]:
    """A fit's parameters by name with their 95 % half-widths; those it names undetermined are
    marked so, whatever their number."""
    for name, value in fit.values.items():
        yield _value(name, value, fit.ci95.get(name), determined=name not in fit.undetermined, **extra)


def model_values(fit: ModelFitDoc, **extra: Any) -> Iterator[Row]:
    """A tyre model's parameters, its BIC and its rms error against the measured ratio."""
    yield from fitted_values(fit, **extra)
    yield _value("bic", fit.bic, **extra)
    yield _value("ratio_relative_rms", fit.ratio_relative_rms, **extra)


def amplitude_values(amp: AmplitudeDoc) -> Iterator[Row]:
    """One amplitude with a tyre fit: every model (the selected one marked), the selected model's
    peak, the valid bands and the repeatability."""
    at = {"amplitude_m": amp.amplitude_m}
    for fit in amp.models:
        yield from model_values(fit, **at, model=fit.model, selected=fit.model == amp.selected_model)
    if (peak := amp.model_peak) is not None:
        selected = {**at, "model": amp.selected_model, "selected": True}
        yield _value("peak_freq_hz", peak.freq_hz, peak.freq_ci95_hz, **selected)
        yield _value("peak_ratio", peak.ratio, peak.ratio_ci95, **selected)
    yield from band_values("valid_band_raw", amp.valid_band_raw, **at)
    yield from band_values("valid_band_compensated", amp.valid_band_compensated, **at)
    yield from repeat_values(amp.repeats, **at)


def ratios_only_values(amp: RatiosOnlyDoc) -> Iterator[Row]:
    """An amplitude without a tyre fit: its raw valid band and the repeatability."""
    at = {"amplitude_m": amp.amplitude_m}
    yield from band_values("valid_band_raw", amp.valid_band_raw, **at)
    yield from repeat_values(amp.repeats, **at)


def amplitude_dependence_values(rows: tuple[AmplitudeRowDoc, ...]) -> Iterator[Row]:
    """Model 2 per amplitude: its stiffness's and damping's change against the smallest amplitude."""
    for row in rows:
        at = {"amplitude_m": row.amplitude_m, "model": 2}
        yield _value("stiffness_change", row.stiffness_change, **at)
        yield _value("equivalent_damping_ns_per_m", row.equivalent_damping_ns_per_m, **at)
        yield _value("damping_change", row.damping_change, **at)


def shaker_values(pressure: ShakerPressureDoc) -> Iterator[Row]:
    """One tyre pressure: each amplitude with a tyre fit, each without one, and the amplitude
    dependence of Model 2."""
    for amp in pressure.amplitudes:
        yield from amplitude_values(amp)
    for ratios in pressure.ratios_only:
        yield from ratios_only_values(ratios)
    yield from amplitude_dependence_values(pressure.amplitude_dependence or ())


def quarter_car_values(car: QuarterCarDoc) -> Iterator[Row]:
    """The quarter car's parameters, and its modes (the frequencies with their intervals)."""
    yield from fitted_values(car)
    yield _value("body_frequency_hz", car.body_frequency_hz, car.body_frequency_ci95_hz)
    yield _value("wheel_frequency_hz", car.wheel_frequency_hz, car.wheel_frequency_ci95_hz)
    yield _value("body_damping_ratio", car.body_damping_ratio)
    yield _value("wheel_damping_ratio", car.wheel_damping_ratio)
    yield _value("unsprung_mass_above_kg", car.unsprung_mass_above_kg)


def four_post_values(four_post: FourPostDoc) -> Iterator[Row]:
    """m_wheel, the accelerometer's delay, the quarter car with its modes, the three valid bands."""
    sigma = four_post.m_wheel_sigma_kg
    yield _value("m_wheel_kg", four_post.m_wheel_kg, None if sigma is None else Z95 * sigma)
    yield _value("accelerometer_delay_s", four_post.accelerometer_delay_s)
    yield _value("measured_amplitude_m", four_post.measured_amplitude_m)
    yield from quarter_car_values(four_post.quarter_car)
    yield from band_values("valid_band_raw", four_post.valid_band_raw)
    yield from band_values("valid_band_hub_compensated", four_post.valid_band_hub_compensated)
    yield from band_values("valid_band_model_compensated", four_post.valid_band_model_compensated)


def flag_row(flag: FlagDoc) -> Row:
    """A flag of a run's analysis: its code as the parameter, its line as the text."""
    return {"entry": c.FLAG, "source": "analysis", "parameter": flag.code, "text": flag.flag}


def analysis_rows(analysis: CampaignAnalysis) -> dict[str, list[Row]]:
    """The analysis's values and flags by the run they belong to: the hammer result to the last
    hammer run, each free run's m_comp to that run, each tyre pressure's identification to the
    dwell grid after which it was made, the four-post result to its sweep."""
    from bench.report.analysis_document import AnalysisDocument, FreeRunDoc

    doc = AnalysisDocument.of(analysis)
    out: dict[str, list[Row]] = {}
    succeeded = [run for run in analysis.runs if not run.error]

    def last(name: str, pressure: float | None = None) -> str | None:
        runs = [
            run.run_id
            for run in succeeded
            if run.name == name and (pressure is None or run.results.get("tyre_pressure_bar") == pressure)
        ]
        return runs[-1] if runs else None

    def add(run_id: str | None, rows: Iterable[Row]) -> None:
        if run_id is not None:
            out.setdefault(run_id, []).extend(rows)

    if doc.hammer is not None:
        add(last(AnalysisKind.HAMMER), hammer_values(doc.hammer))
    for plate in analysis.knowledge.plate_masses:
        add(plate.run_id, free_run_values(FreeRunDoc.of(plate.result)))
    for pressure in doc.shaker:
        add(last(AnalysisKind.SHAKER, pressure.tyre_pressure_bar), shaker_values(pressure))
    if doc.four_post is not None:
        add(last(AnalysisKind.FOUR_POST), four_post_values(doc.four_post))
    for flag in doc.flags:
        add(flag.run_id, [flag_row(flag)])
    return out


def campaign_rows(campaign: CampaignFile, analysis: CampaignAnalysis | None) -> list[Row]:
    """Per run of ``campaign`` (in the order they began): its run row, the values stored in it and
    the values and flags of ``analysis`` (None: not analysed) that belong to it; each row carries
    its run's columns and, once the run was analysed, what its analysis is."""
    analysed = {run.run_id: run for run in analysis.runs} if analysis is not None else {}
    values = analysis_rows(analysis) if analysis is not None else {}
    rows = []
    for run in campaign.runs:
        columns = run_columns(run)
        if (done := analysed.get(run.run_id)) is not None:
            columns["analysis"] = done.name
            why = done.error or "; ".join(done.omitted)
            run_row = {"analysis_status": str(done.status), "analysis_error": why or None}
        else:
            run_row = {}
        rows.append({"entry": c.RUN, **columns, **run_row})
        rows.extend({**columns, **row} for row in stored_values(run))
        rows.extend({**columns, **row} for row in values.get(run.run_id, ()))
    return rows
