"""A road replay's drive, loaded once when the sequence is planned: from its drive file or generated
as an ISO 8608 road (docs/sequences.md, *Road replay*).

The drive the dry run checks is the drive the controller plays: :func:`load_drives` gives each road
replay of a sequence its :class:`~bench.engine.contracts.PlannedDrive`, which the plan keeps and the
engine uploads. What the run records of it (its ``drive`` attribute, docs/hdf5.md): where it came
from (``source``: the file and its column or channel, or the road's class, speed, length, band and
seed), ``sha256`` (of the file's bytes; of a generated road, of its samples as played), the samples
as played (``samples``, ``sample_rate_hz``) and their ``crc32`` (what the controller confirms).

A drive that cannot be had is refused as a problem of the sequence (:class:`SequenceError`),
naming the step's key and, for a file, the file, line and column.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from bench.engine.contracts import PlannedDrive
from bench.models.road import road_drive
from bench.store.drive_files import DriveFileError, DriveSamples, read_drive_file
from drivers.setpoints import DriveSetpoint
from sequences import Problem, RoadReplay, Sequence, SequenceError


class _RefusedError(Exception):
    """A drive that cannot be had: the step's ``key`` at fault and why."""

    def __init__(self, key: str, message: str) -> None:
        super().__init__(message)
        self.key, self.message = key, message


def drive_folder(sequence: Sequence) -> Path:
    """Where a road replay's drive file is looked for: the sequence file's folder (a sequence built
    in Python: the working directory)."""
    source = Path(sequence.source)
    return source.parent if source.suffix.lower() == ".toml" else Path.cwd()


def load_drives(sequence: Sequence) -> dict[int, PlannedDrive]:
    """Every road replay's drive of ``sequence``, by its step's index; :class:`SequenceError` with
    every drive that cannot be had."""
    drives, problems = {}, []
    for index, step in enumerate(sequence.steps):
        if isinstance(step, RoadReplay):
            try:
                drives[index] = planned_drive(step, drive_folder(sequence))
            except _RefusedError as exc:
                problems.append(Problem(sequence.source, f"steps[{index}].{exc.key}", exc.message))
    if problems:
        raise SequenceError.of(problems)
    return drives


def planned_drive(step: RoadReplay, folder: Path) -> PlannedDrive:
    """The drive of ``step`` (a drive file relative to ``folder``, or a generated road); refused
    naming the step's field at fault."""
    if step.generated:
        samples, record = _generated(step)
    else:
        samples, record = _from_file(step, folder)
    setpoint = DriveSetpoint(
        1e3 * samples.displacement_m, samples.sample_rate_hz, step.taper_in_s, step.taper_out_s
    )
    if not setpoint.duration_s > step.taper_in_s + step.taper_out_s:
        raise _RefusedError(
            "duration_s" if step.duration_s else "file",
            f"the drive lasts {setpoint.duration_s:g} s: nothing between its tapers"
            f" ({step.taper_in_s:g} + {step.taper_out_s:g} s)",
        )
    record = {
        **record,
        "samples": setpoint.n_samples,
        "sample_rate_hz": setpoint.sample_rate_hz,
        "crc32": f"{setpoint.crc32:08x}",
    }
    return PlannedDrive(setpoint, record)


def _generated(step: RoadReplay) -> tuple[DriveSamples, dict[str, object]]:
    low, high = step.band_cycles_per_m
    try:
        road = road_drive(
            step.road_class,
            speed_km_h=step.speed_km_h,
            duration_s=step.duration_s,
            sample_rate_hz=step.sample_rate_hz,
            seed=step.seed,
            band_cycles_per_m=(low, high),
        )
    except ValueError as exc:
        raise _RefusedError("band_cycles_per_m", str(exc)) from None
    source = (
        f"ISO 8608 class {road.road_class} road at {step.speed_km_h:g} km/h, {step.duration_s:g} s at"
        f" {step.sample_rate_hz:g} Hz, {low:g}-{high:g} cycles/m, seed {step.seed}"
    )
    samples = DriveSamples(road.displacement_m, road.sample_rate_hz, source)
    played = np.asarray(1e3 * road.displacement_m, dtype="<f4")
    return samples, {"source": source, "sha256": hashlib.sha256(played.tobytes()).hexdigest()}


def _from_file(step: RoadReplay, folder: Path) -> tuple[DriveSamples, dict[str, object]]:
    path = (folder / step.file).resolve()
    try:
        samples = read_drive_file(path, channel=step.channel, time_column=step.time_column)
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
    except DriveFileError as exc:
        raise _RefusedError("file", str(exc)) from None
    source = samples.source
    if step.duration_s:
        n = round(step.duration_s * samples.sample_rate_hz) + 1
        if n > samples.displacement_m.size:
            length_s = (samples.displacement_m.size - 1) / samples.sample_rate_hz
            raise _RefusedError(
                "duration_s", f"{step.duration_s:g} s: the drive in {path} lasts only {length_s:g} s"
            )
        samples = DriveSamples(samples.displacement_m[:n], samples.sample_rate_hz, source)
        source += f", its first {step.duration_s:g} s"
    return samples, {"source": source, "sha256": digest, "file": str(path)}
