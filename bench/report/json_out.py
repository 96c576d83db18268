"""A campaign's analysis as JSON: schema ``wfs-bench-analysis``, version 2 (docs/analysis-json.md
lists every key with its unit). SI units throughout, named in the keys (``_hz``, ``_kg``, ``_m``,
``_n_per_m``, ``_ns_per_m``, ``_s``); ratios and damping ratios are plain numbers. A value the data
does not give is ``null``, never a guess. A version only gains keys; renaming or removing one, or
changing its unit, makes the next (2: the quarter car's tyre loss became a friction force).
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from bench.analysis.campaign import CampaignAnalysis, SensorSource
from bench.analysis.drive_iteration import IterationResult, by_step
from bench.analysis.flags import flags_of
from bench.analysis.frf import ValidBand
from bench.analysis.hammer import HammerResult
from bench.analysis.lsq import Z95
from bench.analysis.repeats import RepeatSpread
from bench.analysis.road_replay import FORCES, RoadReplayResult
from bench.analysis.road_validation import ERROR_BAND_HZ, OCTAVE_CENTRES_HZ
from bench.analysis.runs import (
    FourPostResult,
    FreeRunResult,
    ShakerAmplitudeResult,
    ShakerCampaignResult,
    ShakerRatiosResult,
)
from bench.report.text import free_run_lines
from sequences.metadata import METADATA_FIELDS

SCHEMA = "wfs-bench-analysis"
VERSION = 2


def _number(value: float) -> float | None:
    """A finite float, or None (JSON has no NaN or infinity)."""
    value = float(value)
    return value if np.isfinite(value) else None


def _numbers(values: dict[str, float]) -> dict[str, float | None]:
    return {name: _number(v) for name, v in values.items()}


def band_json(band: ValidBand) -> dict[str, Any]:
    """A valid band: where it starts and ends (Hz), why, and the unreliable points it skips."""
    return {
        "determined": band.determined,
        "lowest_hz": _number(band.lowest_hz) if band.n_points else None,
        "upper_hz": _number(band.upper_hz) if band.determined else None,
        "n_points": band.n_points,
        "starts_at": band.starts_at,
        "limited_by": band.limited_by,
        "skipped_hz": [float(f) for f in band.skipped_hz],
        "amplitude_tolerance": band.amplitude_tolerance,
        "phase_tolerance_deg": band.phase_tolerance_deg,
    }


def hammer_json(result: HammerResult) -> dict[str, Any]:
    return {
        "eigenfrequency_hz": result.eigenfrequency_hz,
        "damped_frequency_hz": result.damped_frequency_hz,
        "damping_ratio_half_power": result.damping_ratio_half_power,
        "damping_ratio_log_decrement": result.damping_ratio_log_decrement,
        "stiffness_n_per_m": result.stiffness_n_per_m,
        "damping_ns_per_m": result.damping_ns_per_m,
        "n_peaks": result.n_peaks,
        "decay_start_s": result.decay_start_s,
        "decay_stop_s": result.decay_stop_s,
    }


def repeats_json(repeats: tuple[RepeatSpread, ...]) -> list[dict[str, Any]]:
    """The dwells measured more than once: per point, how many were combined and their relative rms
    spread over the displacement per channel, against their noise."""
    return [
        {
            "freq_hz": r.freq_hz,
            "n": r.n,
            "spread": r.spread,
            "noise": r.noise,
            "outside_noise": r.outside_noise,
        }
        for r in repeats
    ]


def free_run_json(result: FreeRunResult) -> dict[str, Any]:
    p = result.plate
    return {
        "m_comp_kg": p.mass_kg,
        "m_comp_sigma_kg": None if result.nominal else p.sigma_kg,
        "nominal": result.nominal,
        "residual_rms_n_per_m": _number(p.residual_rms_n_per_m),
        "residual_reduced_chi2": None if result.nominal else p.reduced_chi2,
        "n_points_used": p.n_points,
        "n_dwells": len(result.fits),
        "freq_range_hz": [result.fits[0].freq_hz, result.fits[-1].freq_hz] if result.fits else None,
        "flags": [flag.line for flag in flags_of(free_run_lines(result))],
        "repeats": repeats_json(result.repeats),
    }


def amplitude_json(result: ShakerAmplitudeResult) -> dict[str, Any]:
    ident = result.identification
    peak = result.model_peak
    top_hz, top = result.largest_measured_ratio
    return {
        "amplitude_m": result.amplitude_m,
        "n_dwells": len(result.fits),
        "freq_range_hz": [result.fits[0].freq_hz, result.fits[-1].freq_hz],
        "selected_model": int(ident.best),
        "selection": ident.selection,
        "frequency_dependent_stiffness": ident.frequency_dependent_stiffness,
        "hysteretic_damping": ident.hysteretic_damping,
        "models": [
            {
                "model": int(model),
                "values": _numbers(fit.values),
                "ci95": _numbers(fit.ci95),
                "undetermined": list(fit.undetermined),
                "converged": fit.converged,
                "bic": fit.bic,
                "aic": fit.aic,
                "ratio_relative_rms": fit.ratio_relative_rms,
            }
            for model, fit in ident.fits.items()
        ],
        "findings": list(ident.findings),
        "model_peak": None
        if peak is None
        else {
            "freq_hz": peak.freq_hz,
            "freq_ci95_hz": peak.freq_ci95_hz,
            "ratio": peak.height,
            "ratio_ci95": peak.height_ci95,
        },
        "largest_measured": {"freq_hz": top_hz, "ratio": top},
        "valid_band_raw": band_json(result.valid_band_raw),
        "valid_band_compensated": band_json(result.valid_band_compensated),
        "band_conditions": list(result.band_conditions),
        "plate_mass_tolerance_kg": result.plate_mass_tolerance_kg,
        "compensator_design_error": result.compensator.design_error,
        "compensator_band_hz": result.compensator.band_hz,
        "unsettled": list(result.unsettled),
        "rejected": list(result.rejected),
        "hub_acceleration_recorded": result.hub_acceleration_recorded,
        "repeats": repeats_json(result.repeats),
    }


def ratios_json(result: ShakerRatiosResult) -> dict[str, Any]:
    """An amplitude without a tyre fit: why, and the measured F_wfs/F_contact per dwell with the
    95 % half-widths of its magnitude and phase."""
    raw = result.frfs.wfs_per_contact
    half = Z95 * raw.sigma / np.sqrt(2)
    return {
        "amplitude_m": result.amplitude_m,
        "n_dwells": len(result.fits),
        "freq_range_hz": [result.fits[0].freq_hz, result.fits[-1].freq_hz],
        "why_no_fit": result.why,
        "ratios": [
            {
                "freq_hz": float(f),
                "ratio": float(abs(h)),
                "ratio_ci95": float(c),
                "phase_deg": float(np.degrees(np.angle(h))),
                "phase_ci95_deg": float(np.degrees(c / abs(h))),
                "reliable": bool(ok),
            }
            for f, h, c, ok in zip(raw.freq_hz, raw.value, half, raw.reliable, strict=True)
        ],
        "valid_band_raw": band_json(result.valid_band_raw),
        "unsettled": list(result.unsettled),
        "rejected": list(result.rejected),
        "hub_acceleration_recorded": result.hub_acceleration_recorded,
        "repeats": repeats_json(result.repeats),
    }


def shaker_json(pressure_bar: float, result: ShakerCampaignResult) -> dict[str, Any]:
    dep = result.amplitude_dependence
    return {
        "tyre_pressure_bar": pressure_bar,
        "wheel_mass_kg": result.wheel_mass_kg,
        "sensor_eigenfrequency_hz": result.sensor.eigenfrequency_hz,
        "sensor_damping_ratio": result.sensor.damping_ratio,
        "free_run": free_run_json(result.free_run),
        "amplitudes": [amplitude_json(r) for r in result.amplitudes.values()],
        "ratios_only": [ratios_json(r) for r in result.ratios_only.values()],
        "amplitude_dependence": None
        if dep is None
        else [row._asdict() for row in dep.rows()],
    }


def four_post_json(result: FourPostResult) -> dict[str, Any]:
    m, car = result.wheel_mass, result.quarter_car
    flank_hz, other_hz = result.unreliable_bins_hz
    return {
        "label": result.label,
        "tyre_model": int(result.tyre_model),
        "tyre_source": result.tyre_source,
        "post_free_run": free_run_json(result.post_free_run),
        "m_wheel_kg": m.mass_kg,
        "m_wheel_sigma_kg": m.sigma_kg,
        "m_wheel_band_hz": [float(f) for f in m.band_hz],
        "m_wheel_given_kg": result.wheel_mass_given_kg,
        "accelerometer_delay_s": m.accelerometer_delay_s,
        "valid_band_raw": band_json(result.valid_band_raw),
        "valid_band_hub_compensated": band_json(result.valid_band_hub_compensated),
        "valid_band_model_compensated": band_json(result.valid_band_model_compensated),
        "quarter_car": {
            "values": _numbers(car.values),
            "ci95": _numbers(car.ci95),
            "undetermined": list(car.undetermined),
            "taken_as_given": list(car.taken_as_given),
            "reduced_chi2": car.reduced_chi2,
            "converged": car.converged,
            "band_hz": [float(f) for f in car.band_hz],
            "body_frequency_hz": car.body_frequency_hz,
            "body_frequency_ci95_hz": car.body_frequency_ci95_hz,
            "body_damping_ratio": car.body_damping_ratio,
            "wheel_frequency_hz": car.wheel_frequency_hz,
            "wheel_frequency_ci95_hz": car.wheel_frequency_ci95_hz,
            "wheel_damping_ratio": car.wheel_damping_ratio,
            "unsprung_mass_above_kg": car.suspension.unsprung_mass_above_kg,
        },
        "n_bins": int(result.frfs.wfs_per_z.freq_hz.size),
        "unreliable_bins": result.unreliable_bins,
        "unreliable_flank_hz": [float(f) for f in flank_hz],
        "unreliable_low_excitation_hz": [float(f) for f in other_hz],
        "amplitude_m": result.amplitude_m,
        "measured_amplitude_m": result.measured_amplitude_m,
        "findings": list(result.findings),
    }


def road_replay_json(run_id: str, result: RoadReplayResult) -> dict[str, Any]:
    """A road replay: its drive, the corrections used and each force's rms error against the
    contact force (null for the model-compensated force the campaign gives no model for)."""
    errors = {
        name: None
        if name not in result.errors
        else {"rms_n": result.errors[name].rms_n, "octave_rms_n": list(result.errors[name].octave_rms_n)}
        for name, _ in FORCES
    }
    return {
        "run_id": run_id,
        "drive_source": result.source,
        "span_s": result.span_s,
        "sample_rate_hz": result.sample_rate_hz,
        "m_comp_kg": result.plate_mass_kg,
        "m_wheel_kg": result.wheel_mass_kg,
        "accelerometer_delay_s": result.accelerometer_delay_s,
        "error_band_hz": list(ERROR_BAND_HZ),
        "octave_centres_hz": list(OCTAVE_CENTRES_HZ),
        "contact_rms_n": result.contact_rms_n,
        "errors": errors,
        "identification": result.identification or None,
        "valid_band_hz": None if result.valid_band_hz is None else list(result.valid_band_hz),
        "model_omitted": result.model_omitted or None,
    }


def drive_iterations_json(results: dict[str, IterationResult]) -> list[dict[str, Any]]:
    """Each drive iteration (by its step's run id), its iterations in order: per iteration its run,
    drive checksum and errors; ``rms_error_pct`` again as one list over the iterations."""
    out = []
    for step_run_id, runs in by_step(results).items():
        first = runs[0][1]
        iterations = [
            {
                "run_id": run_id,
                "iteration": r.iteration,
                "drive_crc32": r.drive_crc32,
                "rms_error_pct": r.rms_error_pct,
                "octave_error_pct": list(r.octave_error_pct),
                "in_band_pct": r.in_band_pct,
                "damage_ratio": r.damage_ratio,
                "target_rms": r.target_rms,
                "error_rms": r.error_rms,
                "stop_rules_met": r.stop_rules_met,
            }
            for run_id, r in runs
        ]
        out.append(
            {
                "step_run_id": step_run_id,
                "response": first.response,
                "unit": first.unit,
                "target": first.target_source,
                "error_band_hz": list(first.band_hz),
                "octave_centres_hz": list(OCTAVE_CENTRES_HZ),
                "sn_exponent": first.sn_exponent,
                "rms_error_pct": [i["rms_error_pct"] for i in iterations],
                "iterations": iterations,
            }
        )
    return out


def analysis_json(analysis: CampaignAnalysis, results_names: dict[str, str] | None = None) -> dict[str, Any]:
    """The whole analysis as a JSON-ready mapping; ``results_names``: run id -> the name its
    results were stored under (from :func:`~bench.app.analyze.store_reanalysis`)."""
    k = analysis.knowledge
    names = results_names or {}
    return {
        "schema": SCHEMA,
        "version": VERSION,
        "file": str(analysis.path),
        "software_version": analysis.software_version,
        "sequence_name": analysis.sequence_name,
        "sequences": [{"name": name, "runs": runs} for name, runs in analysis.sequences],
        "config_source": analysis.config_source,
        "analysis_source": analysis.source,
        "metadata": {name: analysis.metadata.get(name, "") for name in METADATA_FIELDS},
        "status": str(analysis.status),
        "given": {"sensor_mass_kg": analysis.sensor_mass_kg, "wheel_mass_kg": analysis.wheel_mass_kg},
        "sensor": {
            "mass_kg": k.sensor.mass_kg,
            "eigenfrequency_hz": k.sensor.eigenfrequency_hz,
            "damping_ratio": k.sensor.damping_ratio,
            "from_hammer_test": k.sensor_source == SensorSource.HAMMER_TEST,
            "source": str(k.sensor_source),
        },
        "hammer": None if k.hammer is None else hammer_json(k.hammer),
        "shaker": [shaker_json(p, r) for p, r in sorted(k.shaker.items())],
        "four_post": None if k.four_post is None else four_post_json(k.four_post),
        "road_replays": [road_replay_json(run_id, r) for run_id, r in k.road_replays.items()],
        "drive_iterations": drive_iterations_json(k.drive_iterations),
        "runs": [
            {
                "run_id": run.run_id,
                "kind": run.kind,
                "analysis": run.name,
                "results_name": names.get(run.run_id),
                "status": str(run.status),
                "error": run.error or None,
                "omitted": list(run.omitted),
                "summary": list(run.lines),
            }
            for run in analysis.runs
        ],
        "not_analysed": [{"run_id": run_id, "status": status} for run_id, status in analysis.skipped],
        "flags": [
            {"run_id": run.run_id, "code": str(flag.code), "flag": flag.line}
            for run in analysis.runs
            for flag in run.flags
        ],
    }


def analysis_json_text(analysis: CampaignAnalysis, results_names: dict[str, str] | None = None) -> str:
    """:func:`analysis_json` as indented JSON text (strict: no NaN)."""
    return json.dumps(analysis_json(analysis, results_names), indent=2, allow_nan=False)
