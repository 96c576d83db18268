"""Planning a campaign: a sequence checked against the bench before anything is opened.

:func:`plan_campaign` loads the bench configuration and the sequence file, validates the sequence
against the bench's limits and dry-runs it on the bench model (:mod:`bench.dry_run`);
:func:`plan_sequence` does the same for a sequence built in Python. The resulting
:class:`CampaignPlan` is what every run takes (:mod:`bench.app.run`): a plan that does not stand is
refused here, so nothing is opened or moved for it. Planning needs neither the devices nor the
engine, so ``wfsbench check`` and the front ends can plan without loading them.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path

from bench.config import BenchConfig, load_bench_config
from bench.dry_run import dry_run
from bench.engine.contracts import PlannedDrive, PlannedIteration
from bench.iteration_plan import load_iterations, with_checks
from bench.replay_drive import load_drives
from sequences import Sequence, dump_sequence, load_sequence, validate
from sequences.metadata import merged


class PlanRefusedError(ValueError):
    """The dry run refused the sequence on this bench; nothing was opened or moved."""


@dataclass(frozen=True)
class CampaignPlan:
    """A validated sequence on a configured bench, with the texts that produced them and the test
    metadata its campaign is recorded with (every field: the configuration's, the sequence's and
    the command line's merged, each key from the last that gives it); ``drives``: each road
    replay's drive as it was loaded and dry-run, and each drive iteration's target with its drives'
    check, by its step's index (what the engine plays)."""

    config: BenchConfig
    config_text: str
    sequence: Sequence
    sequence_text: str
    metadata: Mapping[str, str] = field(default_factory=merged)
    drives: Mapping[int, PlannedDrive | PlannedIteration] = field(default_factory=dict)

    def with_metadata(self, given: Mapping[str, str]) -> CampaignPlan:
        """This plan with the fields of ``given`` replacing its own (a front end's operator and
        notes, as ``--meta`` does)."""
        return replace(self, metadata=merged(self.metadata, given))


def plan_campaign(
    sequence_path: Path,
    config_path: Path | None = None,
    *,
    realtime: bool = False,
    metadata: Mapping[str, str] | None = None,
) -> CampaignPlan:
    """Load and check everything before anything is opened: SequenceError / ConfigError name the
    file and the key; PlanRefusedError lists every point the dry run refuses. ``realtime`` paces the
    simulated bench in real time (the configuration's ``simulation.paced``; no effect on hardware).
    ``metadata``: test metadata fields given on the command line, winning over the files'."""
    config = load_bench_config(config_path)
    if realtime:
        config = replace(config, simulation=replace(config.simulation, paced=True))
    sequence = load_sequence(sequence_path, config.limits)
    config_text = Path(config_path).read_text() if config_path else config.to_toml()
    plan = plan_sequence(sequence, config, Path(sequence_path).read_text(), config_text)
    return plan.with_metadata(metadata or {})


def plan_sequence(
    sequence: Sequence, config: BenchConfig, sequence_text: str | None = None, config_text: str | None = None
) -> CampaignPlan:
    """Check a sequence built in Python (or loaded) against ``config``: the same validation as a
    sequence file gets, then the dry run. The texts recorded with the campaign default to the
    sequence and configuration written out as TOML. Road replays' drives and drive iterations'
    targets are loaded here, once (SequenceError when one cannot be had): the drive dry-run is the
    drive played, and each drive an iteration computes is dry-run by the check the dry run gives."""
    validate(sequence, config.limits, config.channels)
    targets = load_iterations(sequence, config.wfs.rate_hz, config.masses.plate_kg)
    drives = {**load_drives(sequence), **targets}
    checked = dry_run(sequence, config, drives)
    if checked.refusals:
        raise PlanRefusedError("\n".join(str(r) for r in checked.refusals))
    drives = with_checks(drives, checked.drive_checks)
    return CampaignPlan(
        config,
        config_text if config_text is not None else config.to_toml(),
        sequence,
        sequence_text if sequence_text is not None else dump_sequence(sequence),
        merged(config.metadata, sequence.metadata),
        drives,
    )
