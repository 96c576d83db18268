"""One campaign file as the index's rows (:mod:`bench.archive.columns`): what it is, its runs, the
results stored in it and the identification of the campaign's analysis.

The analysis is :func:`~bench.app.analyze.analyze_campaign`'s, as ``wfsbench analyze`` gives it: the
record the post-run analysis stored beside each run, read back (``source`` ``analysis``), or the
runs fitted again in memory where a run stores none this version reads or ``--reanalyse`` asks;
nothing is written to the file. The few scalars a run's results store by themselves (m_comp, the
hammer's eigenfrequency) are listed beside it as they are (``source`` ``stored``).

Parameter names are the keys of the analysis JSON (docs/analysis-json.md), their units in the
names; docs/index.md lists which each analysis gives.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from datetime import UTC, datetime
from typing import TYPE_CHECKING, Any

from bench.analysis.lsq import Z95
from bench.archive import columns as c
from bench.store import CampaignFile, RunView

if TYPE_CHECKING:
    from bench.analysis.campaign import CampaignAnalysis

Row = dict[str, Any]

#: Keys of the analysis JSON's ``hammer`` object given as values (none has an interval).
HAMMER_VALUES = (
    "eigenfrequency_hz",
    "damped_frequency_hz",
    "damping_ratio_half_power",
    "damping_ratio_log_decrement",
    "stiffness_n_per_m",
    "damping_ns_per_m",
)
#: The four-post quarter car's values that have a 95 % interval of their own: key -> its interval's key.
QUARTER_CAR_MODES = {
    "body_frequency_hz": "body_frequency_ci95_hz",
    "wheel_frequency_hz": "wheel_frequency_ci95_hz",
    "body_damping_ratio": None,
    "wheel_damping_ratio": None,
    "unsprung_mass_above_kg": None,
}


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
        "run_interlocks": sum(1 for event in run.events if event.kind == "interlock"),
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


def hammer_values(hammer: Mapping[str, Any]) -> Iterator[Row]:
    for key in HAMMER_VALUES:
        yield _value(key, hammer[key])


def free_run_values(free_run: Mapping[str, Any]) -> Iterator[Row]:
    """m_comp (its 95 % half-width from its standard uncertainty) and the fit's misfit."""
    sigma = free_run["m_comp_sigma_kg"]
    nominal = free_run["nominal"]
    yield _value(
        "m_comp_kg", free_run["m_comp_kg"], None if sigma is None else Z95 * sigma, determined=not nominal
    )
    yield _value("residual_rms_n_per_m", free_run["residual_rms_n_per_m"])
    yield _value("residual_reduced_chi2", free_run["residual_reduced_chi2"])
    yield from repeat_values(free_run["repeats"])


def band_values(name: str, band: Mapping[str, Any], **extra: Any) -> Iterator[Row]:
    """A valid band as its lowest and upper frequency (``<name>_lowest_hz``, ``<name>_upper_hz``);
    the upper end is null and not determined when the band has no width."""
    yield _value(f"{name}_lowest_hz", band["lowest_hz"], **extra)
    yield _value(f"{name}_upper_hz", band["upper_hz"], determined=band["determined"], **extra)


def repeat_values(repeats: list[Mapping[str, Any]], **extra: Any) -> Iterator[Row]:
    """The repeatability of each point measured more than once: per channel the relative rms
    spread of the repeats (``repeat_spread.<channel>``) and the spread their noise alone gives
    (``repeat_noise.<channel>``), at the point's ``freq_hz``."""
    for repeat in repeats:
        for kind in ("spread", "noise"):
            for channel, value in sorted(repeat[kind].items()):
                yield _value(f"repeat_{kind}.{channel}", value, freq_hz=repeat["freq_hz"], **extra)


def shaker_values(pressure: Mapping[str, Any]) -> Iterator[Row]:
    """One tyre pressure: per amplitude every model's values with their intervals (the selected
    model marked), the model's peak, the valid bands and the repeatability; the amplitudes without a
    tyre fit (their raw band, repeatability); the amplitude dependence of Model 2."""
    for amp in pressure["amplitudes"]:
        at = {"amplitude_m": amp["amplitude_m"]}
        for fit in amp["models"]:
            model = {**at, "model": fit["model"], "selected": fit["model"] == amp["selected_model"]}
            for name, value in fit["values"].items():
                yield _value(
                    name, value, fit["ci95"].get(name), determined=name not in fit["undetermined"], **model
                )
            yield _value("bic", fit["bic"], **model)
            yield _value("ratio_relative_rms", fit["ratio_relative_rms"], **model)
        if (peak := amp["model_peak"]) is not None:
            selected = {**at, "model": amp["selected_model"], "selected": True}
            yield _value("peak_freq_hz", peak["freq_hz"], peak["freq_ci95_hz"], **selected)
            yield _value("peak_ratio", peak["ratio"], peak["ratio_ci95"], **selected)
        yield from band_values("valid_band_raw", amp["valid_band_raw"], **at)
        yield from band_values("valid_band_compensated", amp["valid_band_compensated"], **at)
        yield from repeat_values(amp["repeats"], **at)
    for amp in pressure["ratios_only"]:
        at = {"amplitude_m": amp["amplitude_m"]}
        yield from band_values("valid_band_raw", amp["valid_band_raw"], **at)
        yield from repeat_values(amp["repeats"], **at)
    for row in pressure["amplitude_dependence"] or ():
        at = {"amplitude_m": row["amplitude_m"], "model": 2}
        for key in ("stiffness_change", "equivalent_damping_ns_per_m", "damping_change"):
            yield _value(key, row[key], **at)


def four_post_values(four_post: Mapping[str, Any]) -> Iterator[Row]:
    """m_wheel, the accelerometer's delay, the quarter car with its modes, the three valid bands."""
    sigma = four_post["m_wheel_sigma_kg"]
    yield _value("m_wheel_kg", four_post["m_wheel_kg"], None if sigma is None else Z95 * sigma)
    yield _value("accelerometer_delay_s", four_post["accelerometer_delay_s"])
    yield _value("measured_amplitude_m", four_post["measured_amplitude_m"])
    car = four_post["quarter_car"]
    for name, value in car["values"].items():
        yield _value(name, value, car["ci95"].get(name), determined=name not in car["undetermined"])
    for name, ci_key in QUARTER_CAR_MODES.items():
        yield _value(name, car[name], car[ci_key] if ci_key else None)
    for band in ("valid_band_raw", "valid_band_hub_compensated", "valid_band_model_compensated"):
        yield from band_values(band, four_post[band])


def analysis_rows(analysis: CampaignAnalysis) -> dict[str, list[Row]]:
    """The analysis's values and flags by the run they belong to: the hammer result to the last
    hammer run, each free run's m_comp to that run, each tyre pressure's identification to the
    dwell grid after which it was made, the four-post result to its sweep."""
    from bench.report.json_out import analysis_json, free_run_json

    doc = analysis_json(analysis)
    out: dict[str, list[Row]] = {}
    succeeded = [run for run in analysis.runs if not run.error]

    def last(name: str, pressure: float | None = None) -> str | None:
        runs = [
            run.run_id
            for run in succeeded
            if run.name == name and (pressure is None or run.results.get("tyre_pressure_bar") == pressure)
        ]
        return runs[-1] if runs else None

    def add(run_id: str | None, rows: Iterator[Row]) -> None:
        if run_id is not None:
            out.setdefault(run_id, []).extend(rows)

    if doc["hammer"] is not None:
        add(last("hammer"), hammer_values(doc["hammer"]))
    for plate in analysis.knowledge.plate_masses:
        add(plate.run_id, free_run_values(free_run_json(plate.result)))
    for pressure in doc["shaker"]:
        add(last("shaker", pressure["tyre_pressure_bar"]), shaker_values(pressure))
    if doc["four_post"] is not None:
        add(last("four_post"), four_post_values(doc["four_post"]))
    for run in analysis.runs:
        flags = (
            {"entry": c.FLAG, "source": "analysis", "parameter": str(flag.code), "text": flag.line}
            for flag in run.flags
        )
        add(run.run_id, flags)
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
