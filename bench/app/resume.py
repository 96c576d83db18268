"""What a campaign file holds already, read before a sequence runs into it: the target check and
the resume plan.

A sequence runs into a new file, or beside the runs of other sequences in an existing one; a file
that holds runs of this very sequence takes it only as a resume. :func:`check_target` refuses a file
that cannot take the sequence before anything is opened and, when resuming, checks that the file
recorded the same sequence and bench (:func:`bench.app.resume_check.check_resume`) and gives the
engine its :class:`ResumeFromFile` plan (the complete runs and points to skip). :func:`held_runs`
lets a front end ask before it starts; :func:`done_in_file` tells the progress display what a
resume has done already.
"""

from __future__ import annotations

from pathlib import Path

from bench.analysis.records import WHEEL_CHANNELS, record_channels
from bench.app.pace import DoneBefore
from bench.app.plan import CampaignPlan
from bench.app.resume_check import check_resume
from bench.engine.contracts import RecordedDrive
from bench.engine.engine import Engine, is_measurement
from bench.engine.run_ids import step_run_id
from bench.store import open_campaign
from bench.store.writer import check_specimen
from sequences.runs import RunKind


class ResumeFromFile:
    """The engine's resume plan, read from the campaign file being resumed."""

    def __init__(self, path: Path) -> None:
        self.path = path
        with open_campaign(path) as campaign:
            self._runs = {
                run.run_id: (run.status, run.completed_point_indices(), run.n_samples)
                for run in campaign.runs
            }

    def recorded_drive(self, run_id: str) -> RecordedDrive | None:
        if not self.run_complete(run_id):
            return None
        with open_campaign(self.path) as campaign:
            (run,) = [r for r in campaign.runs if r.run_id == run_id]
            if run.kind != RunKind.DRIVE_ITERATION:
                return None
            record = run.road_replay_record()
            return RecordedDrive(dict(run.drive), record_channels(record, WHEEL_CHANNELS, min_samples=64))

    def run_complete(self, run_id: str) -> bool:
        return run_id in self._runs and self._runs[run_id][0] == "complete"

    def completed_points(self, run_id: str) -> set[int]:
        return set(self._runs[run_id][1]) if run_id in self._runs else set()

    def recorded_samples(self, run_id: str) -> int:
        return self._runs[run_id][2] if run_id in self._runs else 0


class NothingToResumeError(Exception):
    """A resume of a campaign file that holds every run of the sequence complete: nothing is left to
    run, so nothing is opened, asked or moved (the message says so, naming the file)."""


def check_target(plan: CampaignPlan, out_path: Path, resume: bool) -> ResumeFromFile | None:
    """Refuse a campaign file that cannot take the sequence (before anything is opened): one that
    holds its runs when not resuming, one that records another sensor or tyre than the plan's
    metadata states (:func:`~bench.store.writer.check_specimen`); the resume plan when resuming;
    :class:`NothingToResumeError` when the file holds the sequence complete."""
    existing = _run_ids(out_path)
    if existing is None and resume:
        raise ValueError(f"{out_path}: no campaign file to resume")
    if existing is not None:
        with open_campaign(out_path) as campaign:
            check_specimen(out_path, campaign.metadata, plan.metadata)
    if existing and not resume and {step_run_id(r) for r in existing} & _planned_runs(plan):
        raise ValueError(
            f"{out_path} holds runs of sequence {plan.sequence.name!r} already: resume it (--resume)"
            " or write to another file"
        )
    if not resume:
        return None
    with open_campaign(out_path) as campaign:
        check_resume(campaign, plan.sequence, plan.config, plan.drives)
        if sequence_complete(plan, {run.run_id: run.status for run in campaign.runs}):
            raise NothingToResumeError(
                f"{out_path}: every run of sequence {plan.sequence.name!r} is complete already:"
                " nothing was run (to run it again, write to another file)"
            )
    return ResumeFromFile(out_path)


def sequence_complete(plan: CampaignPlan, statuses: dict[str, str]) -> bool:
    """Whether every run of ``plan``'s sequence is among ``statuses`` (run id -> status of the runs
    a campaign file holds) and complete. A drive iteration's step has no run of its own id (its
    runs are its iterations'): it is never complete here, and a resume lets it find from its runs
    whether it had stopped."""
    return all(statuses.get(run_id) == "complete" for run_id in _planned_runs(plan))


def held_runs(plan: CampaignPlan, out_path: Path) -> set[str]:
    """The runs of ``plan``'s sequence that the campaign file ``out_path`` holds already (none when
    there is no file; StoreError when the file is no campaign file): a new start into it must
    resume them."""
    return {step_run_id(r) for r in _run_ids(Path(out_path)) or set()} & _planned_runs(plan)


def _planned_runs(plan: CampaignPlan) -> set[str]:
    return {
        Engine.run_id(plan.sequence, i) for i, step in enumerate(plan.sequence.steps) if is_measurement(step)
    }


def done_in_file(plan: CampaignPlan, out_path: Path) -> DoneBefore:
    """The points of ``plan``'s sequence that the campaign file ``out_path`` holds done already and
    their estimated duration (a complete sweep or hammer run counts whole); nothing when there is no
    file."""
    if not Path(out_path).exists():
        return DoneBefore()
    steps = {
        Engine.run_id(plan.sequence, i): step
        for i, step in enumerate(plan.sequence.steps)
        if is_measurement(step)
    }
    points, estimated_s = 0, 0.0
    with open_campaign(out_path) as campaign:
        for run in campaign.runs:
            step = steps.get(run.run_id)
            if step is None:
                continue
            done = run.completed_point_indices()
            points += len(done)
            if step.run_kind in (RunKind.DWELL_GRID, RunKind.FREE_RUN):
                dwells = step.dwells()
                # an adaptive grid's added points are beyond its planned dwells and its estimate
                estimated_s += sum(dwells[i].duration_s for i in done if i < len(dwells))
            elif run.status == "complete":
                estimated_s += step.estimated_duration_s
    return DoneBefore(points, estimated_s)


def _run_ids(path: Path) -> set[str] | None:
    """The run ids of the campaign file at ``path``, None when there is no file (StoreError when
    the file is no campaign file)."""
    if not path.exists():
        return None
    with open_campaign(path) as campaign:
        return {run.run_id for run in campaign.runs}
