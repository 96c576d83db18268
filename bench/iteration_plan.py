"""A drive iteration's target and identification drive, loaded once when the sequence is planned
(docs/sequences.md, *Drive iteration*), as :mod:`bench.replay_drive` loads a road replay's drive.

:func:`load_iterations` gives each drive iteration of a sequence its
:class:`~bench.engine.contracts.PlannedIteration`: the target read
(:func:`bench.store.iteration_target.read_target`) in the matched response's unit, cut to the step's
``duration_s``, at the bench's sample rate (the drive is played and the response recorded at the
WFS's rate, sample for sample), and the broadband identification drive generated from the step
(:func:`bench.analysis.drive_iteration.broadband_drive`). What each run records of it (its
``drive`` attribute's ``target``, ``target_sha256``, ``response``): where the target came from.
The plan's dry run then adds each drive's check (:func:`with_checks`).

A target that cannot be had is refused as a problem of the sequence (:class:`SequenceError`),
naming the step's key and, for a file, the file and what is wrong.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

from bench.analysis.drive_iteration import RESPONSE_UNITS, broadband_drive
from bench.engine.contracts import DriveCheck, PlannedIteration
from bench.replay_drive import drive_folder
from bench.store.iteration_target import TargetError, read_target
from drivers.setpoints import DriveSetpoint
from sequences import DriveIteration, Problem, Sequence, SequenceError


def load_iterations(
    sequence: Sequence, sample_rate_hz: float, plate_mass_kg: float
) -> dict[int, PlannedIteration]:
    """Every drive iteration's target of ``sequence``, by its step's index, for a bench recording at
    ``sample_rate_hz`` whose post's plate is ``plate_mass_kg``; :class:`SequenceError` with every
    target that cannot be had."""
    planned, problems = {}, []
    for index, step in enumerate(sequence.steps):
        if isinstance(step, DriveIteration):
            try:
                planned[index] = planned_iteration(
                    step, drive_folder(sequence), sample_rate_hz, plate_mass_kg
                )
            except _RefusedError as exc:
                problems.append(Problem(sequence.source, f"steps[{index}].{exc.key}", exc.message))
    if problems:
        raise SequenceError.of(problems)
    return planned


class _RefusedError(Exception):
    def __init__(self, key: str, message: str) -> None:
        super().__init__(message)
        self.key, self.message = key, message


def planned_iteration(
    step: DriveIteration, folder: Path, sample_rate_hz: float, plate_mass_kg: float
) -> PlannedIteration:
    """The target of ``step`` (a file relative to ``folder``) and its identification drive."""
    path = (folder / step.target).resolve()
    unit = RESPONSE_UNITS[step.response]
    try:
        target = read_target(
            path,
            si_unit=unit,
            channel=step.target_channel,
            unit=step.target_unit,
            time_column=step.time_column,
        )
    except TargetError as exc:
        raise _RefusedError("target", str(exc)) from None
    if abs(target.sample_rate_hz - sample_rate_hz) > 1e-6 * sample_rate_hz:
        raise _RefusedError(
            "target",
            f"{target.source}: sampled at {target.sample_rate_hz:g} Hz, the bench records at"
            f" {sample_rate_hz:g} Hz: resample the target to the bench's rate",
        )
    values, u95 = target.values, target.u95
    if step.duration_s:
        n = round(step.duration_s * sample_rate_hz) + 1
        if n > values.size:
            raise _RefusedError(
                "duration_s",
                f"{step.duration_s:g} s: the target {target.source} lasts only"
                f" {(values.size - 1) / sample_rate_hz:g} s",
            )
        values, u95 = values[:n], (u95[:n] if u95 is not None else None)
    length_s = (values.size - 1) / sample_rate_hz
    edges_s = step.taper_in_s + step.taper_out_s + 2 * step.settle_s
    if not length_s > edges_s + 2.0:
        raise _RefusedError(
            "duration_s" if step.duration_s else "target",
            f"the target lasts {length_s:g} s: at least 2 s must be compared, between the drive's tapers"
            f" and settling times ({step.taper_in_s:g} + {step.taper_out_s:g} + 2 x {step.settle_s:g} s)",
        )
    identification_mm = broadband_drive(
        step.identification,
        rms_mm=step.identification_rms_mm,
        duration_s=step.identification_s,
        sample_rate_hz=sample_rate_hz,
        band_hz=tuple(step.band_hz),
        seed=step.identification_seed,
        target=values,
    )
    identification = DriveSetpoint(identification_mm, sample_rate_hz, step.taper_in_s, step.taper_out_s)
    record = {
        "target": target.source,
        "target_file": str(path),
        "target_sha256": target.sha256,
        "response": step.response,
        "plate_mass_kg": plate_mass_kg,
    }
    return PlannedIteration(values, u95, sample_rate_hz, identification, plate_mass_kg, record)


def with_checks(planned: Mapping[int, object], checks: Mapping[int, DriveCheck]) -> dict[int, object]:
    """``planned`` (road replays' drives, drive iterations' targets) with each drive iteration's
    dry run of a drive, from the plan's dry run."""
    return {
        index: replace(item, check=checks[index]) if isinstance(item, PlannedIteration) else item
        for index, item in planned.items()
    }
