"""Running a planned sequence into a campaign file: the composition of a run.

:func:`run_campaign` takes the campaign file's writer lock (one writer per file, :mod:`bench.locks`),
checks the target file (:mod:`bench.app.resume`), opens the bench
(:mod:`bench.app.devices`), builds the engine (:mod:`bench.app.engine_build`), subscribes the
recorder and the post-run analysis, and runs the :class:`~bench.app.plan.CampaignPlan`;
:func:`run_on_engine` does the same on an engine a front end keeps open between sequences. Nothing
here plans: a plan is checked before it reaches a run (:mod:`bench.app.plan`).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

from bench import locks
from bench.analysis.campaign import CampaignKnowledge
from bench.app.collector import collector_frozen
from bench.app.devices import open_bench
from bench.app.engine_build import build_engine
from bench.app.plan import CampaignPlan
from bench.app.post_run import PostRunAnalysis
from bench.app.recorder import Recorder
from bench.app.resume import ResumeFromFile, check_target
from bench.app.run_analysis import initial_knowledge
from bench.app.version import software_version
from bench.engine import events as ev
from bench.engine.contracts import Operator
from bench.engine.engine import Engine
from bench.store import CampaignWriter
from bench.store.schema import CampaignInUseError, campaign_key


@dataclass(frozen=True)
class CampaignOutcome:
    """How the sequence ended, and what the analysis said after each run."""

    status: str
    reason: str
    analyses: list[ev.AnalysisDone]


def run_campaign(
    plan: CampaignPlan,
    out_path: Path,
    *,
    resume: bool = False,
    operator: Operator | None = None,
    answers: Mapping[str, float | str | bool] | None = None,
    subscribers: tuple[Callable[[ev.Event], None], ...] = (),
    on_engine: Callable[[Engine], None] | None = None,
    knowledge: CampaignKnowledge | None = None,
) -> CampaignOutcome:
    """Run ``plan`` into the campaign file ``out_path``.

    A new file is created; an existing campaign file takes the sequence's runs beside its own (the
    four-post sequence after the shaker's), unless it holds runs of this very sequence: then only
    ``resume`` continues it, skipping its complete runs and points. ``on_engine`` receives the
    engine before it runs (a front end keeps it to request pause, abort and e-stop). ``answers``:
    the prompts' answers of an unattended run (see :func:`open_bench`). ``knowledge``:
    what the campaign established so far (sensor, plate masses, tyres), carried from one sequence to
    the next; by default it starts from the configuration and the runs already in the file."""
    out_path = Path(out_path)
    with hold_campaign_file(out_path):
        resume_plan = check_target(plan, out_path, resume)
        with open_bench(plan.config, operator, answers) as devices:
            engine = build_engine(plan.config, devices)
            if on_engine is not None:
                on_engine(engine)
            return _run_on(
                engine, plan, out_path, resume_plan=resume_plan, subscribers=subscribers, knowledge=knowledge
            )


def run_on_engine(
    engine: Engine,
    plan: CampaignPlan,
    out_path: Path,
    *,
    resume: bool = False,
    subscribers: tuple[Callable[[ev.Event], None], ...] = (),
    knowledge: CampaignKnowledge | None = None,
    gate_asks: bool = False,
) -> CampaignOutcome:
    """Like :func:`run_campaign`, on an engine whose bench stays open between sequences (a front
    end that shows and switches the bench between runs). The recorder, the analysis and
    ``subscribers`` are unsubscribed when the sequence ends. ``gate_asks``: a free run not to be
    trusted is put to the operator as a question instead of ending the sequence (``Engine.run``)."""
    out_path = Path(out_path)
    with hold_campaign_file(out_path):
        resume_plan = check_target(plan, out_path, resume)
        return _run_on(
            engine,
            plan,
            out_path,
            resume_plan=resume_plan,
            subscribers=subscribers,
            knowledge=knowledge,
            gate_asks=gate_asks,
        )


@contextlib.contextmanager
def hold_campaign_file(path: Path) -> Iterator[None]:
    """The campaign file's writer lock for the ``with`` block (:mod:`bench.locks`), taken before the
    file is read or a device opened: a file another process writes is refused
    (:class:`~bench.store.schema.CampaignInUseError`, an :class:`~bench.locks.InUseError`) naming it."""
    key = campaign_key(path)
    try:
        locks.acquire(key, f"the campaign file {path}")
    except locks.InUseError as exc:
        advice = "write to another file, or wait until it has finished"
        raise CampaignInUseError(path, exc.holder, advice) from None
    try:
        yield
    finally:
        locks.release(key)


def _run_on(
    engine: Engine,
    plan: CampaignPlan,
    out_path: Path,
    *,
    resume_plan: ResumeFromFile | None,
    subscribers: tuple[Callable[[ev.Event], None], ...],
    knowledge: CampaignKnowledge | None,
    gate_asks: bool = False,
) -> CampaignOutcome:
    analyses: list[ev.AnalysisDone] = []
    knowledge = knowledge or initial_knowledge(plan.config)
    with (
        _campaign_writer(plan, out_path, out_path.exists()) as campaign,
        PostRunAnalysis(out_path, engine.bus.publish, knowledge) as analysis,
        collector_frozen(),
    ):
        own = [
            Recorder(campaign),
            analysis,
            lambda e: analyses.append(e) if isinstance(e, ev.AnalysisDone) else None,
        ]
        engine.bus.subscribe(own[0], critical=True)
        for subscriber in (*own[1:], *subscribers):
            engine.bus.subscribe(subscriber)
        try:
            outcome = engine.run(
                plan.sequence,
                sequence_text=plan.sequence_text,
                config_text=plan.config_text,
                resume=resume_plan,
                gate=analysis.gate,
                gate_asks=gate_asks,
                drives=plan.drives,
            )
        finally:
            for subscriber in (*own, *subscribers):
                engine.bus.unsubscribe(subscriber)
    return CampaignOutcome(outcome.status, outcome.reason, analyses)


def _campaign_writer(plan: CampaignPlan, out_path: Path, exists: bool) -> CampaignWriter:
    if exists:
        return CampaignWriter.open_append(out_path, metadata=plan.metadata)
    return CampaignWriter.create(
        out_path,
        software_version=software_version(),
        config_toml=plan.config_text,
        sequence_toml=plan.sequence_text,
        sequence_name=plan.sequence.name,
        config_name=plan.config.source,
        metadata=plan.metadata,
    )
