"""A drive iteration on the simulated four-post bench against a simulated road: the road's targets
written as a lab would have them, the iteration run over the bench's real transports, and what the
rig then reproduces of the road's true contact force (the validation test of
tests/test_drive_iteration.py and benchmarks/drive_iteration.py).

A composition root like :mod:`bench.simulated_road`: the road is driven by the simulated bench's
own car (:func:`rig_car`: the configuration's tyre and digressive damper), read by the bench's
sensors and compensated with a campaign's identification as ``wfsbench compensate`` does
(:func:`write_targets`: the compensated contact force, and the raw WFS force and the true contact
force as CSV columns). :func:`iterate` runs a sequence of one drive iteration on one of them and
reads back per iteration the rms error against the target and, from the rig's own contact force
(the post's force less its plate's inertia), the rms error against the road's true contact force.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench.analysis.campaign import AnalysisKind, CampaignAnalysis
from bench.analysis.drive_iteration import compared_span, rig_response
from bench.analysis.records import WFS_FORCE, WHEEL_CHANNELS, record_channels
from bench.analysis.road_validation import band_rms
from bench.app.compensate import prepare_compensation, write_output
from bench.app.plan import plan_campaign
from bench.app.run import run_campaign
from bench.config import BenchConfig
from bench.models.benches import TyreModel
from bench.models.parameters import DamperNonlinearity, Rig, Suspension, TyreNonlinearity, tyre_at_pressure
from bench.models.road import road_drive
from bench.models.setup import BenchKind, BenchSetup
from bench.simulated_campaign import TRUTH_CHANNEL
from bench.simulated_road import BENCH_CHAIN, simulate_road
from bench.store import open_campaign
from bench.store.measurement import MEASUREMENT_CHANNELS, Measurement
from sequences.runs import RunKind

#: The CSV columns :func:`write_targets` writes beside the time: the road's raw WFS force and its
#: true contact force.
RAW_COLUMN = "Fz WFS [N]"
TRUTH_COLUMN = "F contact [N]"


def rig_car(config: BenchConfig) -> BenchSetup:
    """The car on the simulated four-post bench of ``config`` (as the simulated world mounts it)."""
    specimen = config.specimen
    return BenchSetup(
        BenchKind.QUARTER_CAR,
        TyreModel(specimen.tyre_model),
        tyre_at_pressure(specimen.tyre_pressure_bar),
        suspension=Suspension(damper=DamperNonlinearity() if specimen.damper_nonlinear else None),
        rig=Rig(plate_mass_kg=config.masses.plate_kg),
        nonlinearity=TyreNonlinearity() if specimen.nonlinear else None,
    )


@dataclass(frozen=True)
class RoadTargets:
    """A simulated road's targets: the compensated measurement (``compensated``, HDF5) and the CSV
    file (``csv``) of the raw WFS force and the true contact force (``truth_n``, N)."""

    compensated: Path
    csv: Path
    truth_n: np.ndarray


def write_targets(
    folder: Path,
    analysis: CampaignAnalysis,
    config: BenchConfig,
    *,
    road_class: str,
    speed_km_h: float,
    duration_s: float,
    seed: int,
) -> RoadTargets:
    """Drive the rig's car over an ISO 8608 road, compensate what its sensors read with the
    campaign ``analysis`` and write the targets into ``folder``."""
    rate = float(config.wfs.rate_hz)
    drive = road_drive(
        road_class, speed_km_h=speed_km_h, duration_s=duration_s, sample_rate_hz=rate, seed=seed
    )
    record = simulate_road(rig_car(config), drive, seed=seed + 1)
    channels = {name: record.channels[name] for name in MEASUREMENT_CHANNELS}
    measurement = Measurement(f"road {road_class} at {speed_km_h:g} km/h", rate, channels, chain=BENCH_CHAIN)
    compensation = prepare_compensation(analysis, measurement, config.specimen.tyre_pressure_bar)
    stem = f"road_{road_class}_{speed_km_h:g}"
    compensated = write_output(compensation, folder / f"{stem}_compensated.h5", campaign=analysis.path).out
    truth = record.channels[TRUTH_CHANNEL]
    csv = folder / f"{stem}.csv"
    rows = np.column_stack([np.arange(truth.size) / rate, record.channels[WFS_FORCE], truth])
    header = f"t [s],{RAW_COLUMN},{TRUTH_COLUMN}"
    np.savetxt(csv, rows, delimiter=",", header=header, comments="", fmt="%.17g")
    return RoadTargets(compensated, csv, truth)


@dataclass(frozen=True)
class IterationFigures:
    """Per iteration: the rms error against the target (% of its rms), the share inside its band (%
    or None), the damage ratio, and the rms error of the rig's contact force against the road's true
    contact force (% of its rms), all in the step's error band over the compared span; how the
    sequence ended
    (``status``, ``reason``)."""

    rms_error_pct: tuple[float, ...]
    in_band_pct: tuple[float | None, ...]
    damage_ratio: tuple[float, ...]
    contact_error_pct: tuple[float, ...]
    status: str
    reason: str


def iterate(
    folder: Path, config_path: Path, targets: RoadTargets, *, raw: bool, name: str, lines: str = ""
) -> IterationFigures:
    """A sequence of one drive iteration on the compensated target (``raw`` False: the contact
    force matched) or on the raw WFS force (``raw``: the WFS force matched), with the step's extra
    TOML ``lines``, run into ``folder/<name>.h5``."""
    if raw:
        step = f'target = "{targets.csv.name}"\ntarget_channel = "{RAW_COLUMN}"\nresponse = "wfs_force"\n'
        offset = 0
    else:
        step = f'target = "{targets.compensated.name}"\n'
        offset = _compensated_start(targets)
    sequence = folder / f"{name}.toml"
    sequence.write_text(
        f'[sequence]\nname = "{name}"\ndescription = "drive iteration"\n\n'
        '[[steps]]\ntype = "hydraulics"\nlevel = "low"\n\n[[steps]]\ntype = "hydraulics"\nlevel = "high"\n\n'
        f'[[steps]]\ntype = "drive_iteration"\n{step}{lines}'
    )
    plan = plan_campaign(sequence, config_path)
    path = folder / f"{name}.h5"
    outcome = run_campaign(plan, path)
    results = [a.results for a in outcome.analyses if a.name == AnalysisKind.DRIVE_ITERATION]
    (step_,) = [s for s in plan.sequence.steps if s.kind == RunKind.DRIVE_ITERATION]
    contact = []
    with open_campaign(path) as campaign:
        for run in campaign.runs[1:]:
            record = run.road_replay_record()
            fs = record.sample_rate_hz
            channels = record_channels(record, WHEEL_CHANNELS, min_samples=64)
            force = rig_response("contact_force", channels, fs, plan.config.masses.plate_kg)
            n = int(run.drive["samples"])
            span = compared_span(n, fs, step_.taper_in_s, step_.taper_out_s, step_.settle_s)
            truth = targets.truth_n[offset : offset + n][span]
            error = force[span] - np.mean(force[span]) - (truth - np.mean(truth))
            band = (float(step_.error_band_hz[0]), float(step_.error_band_hz[1]))
            contact.append(100 * band_rms(error, fs, band) / band_rms(truth - truth.mean(), fs, band))
    return IterationFigures(
        tuple(r["rms_error_pct"] for r in results),
        tuple(r["in_band_pct"] for r in results),
        tuple(r["damage_ratio"] for r in results),
        tuple(contact),
        outcome.status,
        outcome.reason,
    )


def _compensated_start(targets: RoadTargets) -> int:
    """The sample of the road where the compensated target starts (its filters' window before)."""
    import h5py

    with h5py.File(targets.compensated, "r") as f:
        force = f["f_contact_n"][()]
    return int(np.flatnonzero(np.isfinite(force))[0])
