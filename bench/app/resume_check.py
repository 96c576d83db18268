"""Whether a campaign file can be resumed with a sequence and a bench configuration (docs/cli.md,
"Resume").

A resume continues the very campaign the file holds: the sequence must be the one stored with it,
step by step as validated (its name and every step's values; whitespace, comments, the order of
keys and the description do not count), and the bench the same as measured (everything in the
configuration except how the devices are reached and whether the simulated bench is paced). Either
difference is refused before anything is opened, naming the first differing step or key, so that
one campaign never mixes amplitudes, limits or calibrations.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

from bench.app.analyze import sequences_run
from bench.config import BenchConfig, ConfigError, measured_bench, parse_bench_config
from bench.engine.contracts import PlannedDrive, PlannedIteration
from bench.engine.engine import Engine, is_measurement
from bench.engine.run_ids import step_run_id
from bench.store import CampaignFile
from sequences import Sequence, SequenceError, parse_sequence, step_fields


class ResumeMismatchError(ValueError):
    """The campaign file holds another sequence or another bench than the one given to resume it."""


def check_resume(
    campaign: CampaignFile,
    sequence: Sequence,
    config: BenchConfig,
    drives: Mapping[int, PlannedDrive | PlannedIteration] | None = None,
) -> None:
    """Refuse (:class:`ResumeMismatchError`) to resume ``campaign`` with ``sequence`` on ``config``
    when either differs from what the file recorded (relative paths of the stored configuration are
    taken from the directory of ``config``'s file, as they were when it was recorded), or when a
    road replay's drive or a drive iteration's target (``drives``, as planned) is not the one its
    runs recorded (its SHA-256: the file changed since).

    The file records the configuration and the sequence text of the campaign's first sequence; a
    sequence added to it later (the four-post's after the shaker's) is compared run by run with the
    steps its runs recorded, and its bench is not compared. A sequence of which the file holds no
    run has nothing to continue: refused too (it is added to a file without ``--resume``)."""
    problem = _drives_difference(campaign, sequence, drives or {})
    if problem:
        raise _mismatch(campaign, problem)
    if campaign.sequence_name != sequence.name:
        if not _holds_runs_of(campaign, sequence):
            held = ", ".join(name for name, _ in sequences_run(run.run_id for run in campaign.runs))
            raise _mismatch(
                campaign,
                f"it holds no run of sequence {sequence.name!r} (it holds sequences {held or 'none'}):"
                " there is nothing of it to continue; to add its runs to this file, run it without"
                " --resume",
            )
        problem = _runs_difference(campaign, sequence)
        if problem:
            raise _mismatch(campaign, f"the sequence in {sequence.source} differs from its runs: {problem}")
        return
    config_dir = Path(config.source).parent if config.source != "<default>" else None
    try:
        stored_config = parse_bench_config(campaign.config_toml, f"{campaign.path}:/config_toml", config_dir)
        stored = parse_sequence(
            campaign.sequence_toml, f"{campaign.path}:/sequence_toml", stored_config.limits
        )
    except (ConfigError, SequenceError) as exc:
        raise _mismatch(campaign, f"what the file recorded cannot be read back to compare: {exc}") from None
    problem = _sequence_difference(sequence, stored)
    if problem:
        raise _mismatch(
            campaign, f"the sequence in {sequence.source} differs from the one the file holds: {problem}"
        )
    problem = _first_difference(measured_bench(config), measured_bench(stored_config))
    if problem:
        raise _mismatch(
            campaign,
            f"the bench configuration {config.source} differs from the one the file holds: {problem}",
        )


#: What a planned drive's record names its checksum by: a road replay's drive, a drive iteration's
#: target (each of whose runs, ``<step run id>-iNN``, records it).
CHECKSUMS = (("sha256", "drive", "played"), ("target_sha256", "target", "iterated on"))


def _drives_difference(
    campaign: CampaignFile, sequence: Sequence, drives: Mapping[int, PlannedDrive | PlannedIteration]
) -> str:
    """The first road replay whose planned drive, or drive iteration whose target, differs from the
    one its runs recorded (a file changed since)."""
    for index, planned in drives.items():
        run_id = Engine.run_id(sequence, index)
        runs = [run for run in campaign.runs if step_run_id(run.run_id) == run_id]
        for key, what, done in CHECKSUMS:
            now = planned.record.get(key)
            old = next((run.drive[key] for run in runs if key in run.drive), None)
            if now is not None and old is not None and old != now:
                source = planned.record.get("source" if what == "drive" else "target")
                return (
                    f"steps[{index}]: the {what} ({source}) is not the one run {run_id} {done}: SHA-256"
                    f" {now} now, {old} in the file"
                )
    return ""


def _mismatch(campaign: CampaignFile, text: str) -> ResumeMismatchError:
    return ResumeMismatchError(f"{campaign.path}: cannot resume: {text}")


def _sequence_difference(sequence: Sequence, stored: Sequence) -> str:
    if len(stored.steps) != len(sequence.steps):
        return f"steps: {len(sequence.steps)} steps now, {len(stored.steps)} in the file"
    for index, (new, old) in enumerate(zip(sequence.steps, stored.steps, strict=True)):
        problem = _first_difference(_normal(step_fields(new)), _normal(step_fields(old)), f"steps[{index}].")
        if problem:
            return problem
    return ""


def _holds_runs_of(campaign: CampaignFile, sequence: Sequence) -> bool:
    """Whether the file holds any run of ``sequence`` (by the run ids its steps would record)."""
    held = {run.run_id for run in campaign.runs}
    return any(
        Engine.run_id(sequence, index) in held
        for index, step in enumerate(sequence.steps)
        if is_measurement(step)
    )


def _runs_difference(campaign: CampaignFile, sequence: Sequence) -> str:
    recorded = {run.run_id: run.step for run in campaign.runs}
    for index, step in enumerate(sequence.steps):
        run_id = Engine.run_id(sequence, index)
        if is_measurement(step) and run_id in recorded:
            problem = _first_difference(
                _normal(step_fields(step)), _normal(recorded[run_id]), f"steps[{index}]."
            )
            if problem:
                return f"{problem} (run {run_id})"
    return ""


def _first_difference(new: dict[str, object], old: dict[str, object], prefix: str = "") -> str:
    """The first key whose value differs, with both values; empty when none does."""
    for key in (*new, *(k for k in old if k not in new)):
        if new.get(key) != old.get(key):
            return f"{prefix}{key}: {_shown(new.get(key))} now, {_shown(old.get(key))} in the file"
    return ""


def _normal(fields: dict[str, object]) -> dict[str, object]:
    """Values as the campaign file stores them (JSON: tuples become lists, 2 equals 2.0)."""
    return json.loads(json.dumps(fields, default=str))


def _shown(value: object) -> str:
    return "(absent)" if value is None else json.dumps(value)
