"""One run of a drive iteration analysed from what the campaign file holds of it: its channels, its
step and its drive's record (docs/analysis.md, *Drive iteration*).

The target is read again from the file the run recorded (``target_file``), checked against the
SHA-256 the run recorded (a target changed since is refused, naming both), cut as the step cuts it;
the response is computed from the run's channels with the plate mass the run's drives were
computed with, over the drive's hold less its settling time, as the engine computed it to decide
whether to stop (:func:`bench.analysis.drive_iteration.analyse_iteration`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from bench.analysis.drive_iteration import (
    RESPONSE_UNITS,
    IterationResult,
    analyse_iteration,
    compared_span,
    stop_rules_met,
)
from bench.analysis.records import DISPLACEMENT, WHEEL_CHANNELS, RoadReplayRecord, record_channels
from bench.engine.run_ids import step_run_id
from bench.store.iteration_target import TargetError, read_target


def analyse_iteration_run(
    run_id: str, record: RoadReplayRecord, step: Mapping[str, Any], drive: Mapping[str, Any]
) -> IterationResult | tuple[list[str], dict[str, Any]]:
    """Iteration 1 on: its :class:`IterationResult`; the identification (iteration 0): its text
    lines and scalars (the drive's and the response's rms)."""
    iteration = int(drive.get("iteration", -1))
    step_id = step_run_id(run_id)
    response = str(step.get("response", "contact_force"))
    fs = float(record.sample_rate_hz)
    channels = record_channels(record, WHEEL_CHANNELS, min_samples=64)
    band = (float(step["error_band_hz"][0]), float(step["error_band_hz"][1]))
    tapers = (float(step["taper_in_s"]), float(step["taper_out_s"]))
    hold = compared_span(int(drive["samples"]), fs, *tapers, float(step["settle_s"]))
    if iteration == 0:
        z = channels[DISPLACEMENT][hold]
        lines = [
            f"drive iteration {step_id}: the rig's identification, {step.get('identification')} drive"
            f" of {drive['samples']} samples (CRC-32 {drive['crc32']}), post displacement"
            f" {1e3 * float(np.std(z)):.3g} mm rms over its hold",
        ]
        return lines, {"iteration": 0, "displacement_rms_mm": 1e3 * float(np.std(z))}
    target, u95, source = _target(step, drive, response, fs)
    errors, traces = analyse_iteration(
        channels,
        target,
        u95,
        fs_hz=fs,
        hold=hold,
        response=response,
        plate_mass_kg=float(drive["plate_mass_kg"]),
        band_hz=band,
        sn_exponent=float(step["sn_exponent"]),
    )
    return IterationResult(
        step_run_id=step_id,
        iteration=iteration,
        response=response,
        unit=RESPONSE_UNITS[response],
        target_source=source,
        drive_crc32=str(drive["crc32"]),
        band_hz=band,
        sn_exponent=float(step["sn_exponent"]),
        rms_error_pct=errors.rms_error_pct,
        octave_error_pct=errors.octave_error_pct,
        in_band_pct=None if errors.in_band_fraction is None else 100 * errors.in_band_fraction,
        damage_ratio=errors.damage_ratio,
        target_rms=errors.target_rms,
        error_rms=errors.error_rms,
        stop_rules_met=stop_rules_met(errors, float(step["rms_error_pct"]), float(step["in_band_pct"])),
        last=iteration == int(step["max_iterations"]),
        traces=traces,
    )


def _target(
    step: Mapping[str, Any], drive: Mapping[str, Any], response: str, fs_hz: float
) -> tuple[np.ndarray, np.ndarray | None, str]:
    path = str(drive.get("target_file", ""))
    try:
        target = read_target(
            path,
            si_unit=RESPONSE_UNITS[response],
            channel=str(step.get("target_channel", "")),
            unit=str(step.get("target_unit", "")),
            time_column=str(step.get("time_column", "")),
        )
    except TargetError as exc:
        raise ValueError(f"the drive iteration's target cannot be read again: {exc}") from None
    if target.sha256 != drive.get("target_sha256"):
        raise ValueError(
            f"the target {path} changed since the run: SHA-256 {target.sha256} now,"
            f" {drive.get('target_sha256')} when it ran"
        )
    values, u95 = target.values, target.u95
    n = int(drive["samples"])
    if values.size < n:
        raise ValueError(f"the target {path} has {values.size} samples, the run's drive {n}")
    return values[:n], (u95[:n] if u95 is not None else None), target.source
