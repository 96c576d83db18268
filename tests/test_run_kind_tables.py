"""One table per layer where behaviour varies by run kind, each with an entry for every
:class:`~sequences.runs.RunKind`: a new kind fails here until every layer has said what it does with
it (docs/architecture.md, *Adding a run kind*)."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.app.analysis_plan import ANALYSIS_NEEDS
from bench.app.check import RUN_DESCRIPTIONS
from bench.app.run_analysis import ANALYSES, INPUT_READERS, RunAnalyser, RunInputs, initial_knowledge
from bench.app.show import EXCITATIONS
from bench.config import BENCH_KINDS, KIND_DEFAULTS, default_bench_config
from bench.dry_run import PREDICTIONS
from bench.engine import events as ev
from bench.engine.engine import STEP_ACTIONS
from bench.engine.procedures import PROCEDURES
from sequences.runs import EventKind, RigKind, RunKind
from sequences.steps import ACTION_BENCH_KIND, STEP_TYPES

#: Each layer's table keyed by the run kind.
TABLES = {
    "the engine's procedure (bench/engine/procedures PROCEDURES)": PROCEDURES,
    "the dry run (bench/dry_run.py PREDICTIONS)": PREDICTIONS,
    "what the analysis will lack, said by check (bench/app/analysis_plan.py ANALYSIS_NEEDS)": ANALYSIS_NEEDS,
    "the step's line in check (bench/app/check.py RUN_DESCRIPTIONS)": RUN_DESCRIPTIONS,
    "the run's excitation in show (bench/app/show.py EXCITATIONS)": EXCITATIONS,
    "what the analysis reads (bench/app/run_analysis.py INPUT_READERS)": INPUT_READERS,
    "the analysis (bench/app/run_analysis.py ANALYSES)": ANALYSES,
}


@pytest.mark.parametrize("name", sorted(TABLES))
def test_every_run_kind_is_in_the_table(name):
    table = TABLES[name]
    assert set(table) == set(RunKind), f"{name}: missing {set(RunKind) - set(table)}"


def test_every_run_kind_is_recorded_by_a_step():
    """A step says which kind of run it records (an enum member); every kind has a step."""
    made = {cls.run_kind for cls in STEP_TYPES.values()} - {None}
    assert made == set(RunKind)
    assert all(isinstance(cls.run_kind, RunKind | None) for cls in STEP_TYPES.values())


def test_every_step_type_is_an_action_of_the_engine_or_records_a_run():
    """The engine's table of the steps that record no run (a prompt, the hydraulics, a tare, the
    mean position) and the steps that record one (each by its run kind's procedure) are every
    step type, once."""
    actions = set(STEP_ACTIONS)
    measurements = {cls for cls in STEP_TYPES.values() if cls.run_kind is not None}
    assert actions | measurements == set(STEP_TYPES.values()) and not actions & measurements


@pytest.mark.parametrize("kind", list(RunKind))
def test_a_run_of_any_kind_without_its_records_is_flagged_not_raised(kind):
    """Every kind's analysis, given a run whose records were not read, says so in a flag (on the
    four-post bench: a sweep on the shaker is recorded and not analysed)."""
    run = RunInputs(f"r-{kind}", kind, {"bench": "four_post"})
    outcome = RunAnalyser(initial_knowledge(default_bench_config())).analyse(run)
    assert outcome.error and outcome.lines[0].startswith("FLAG analysis failed"), outcome


def test_every_stored_event_kind_is_documented_and_the_engine_stores_only_those():
    """The ``kind`` words of the campaign file's events are one enum, each described in docs/hdf5.md;
    the engine's events that the recorder stores as they are say which of them they are."""
    text = (Path(__file__).resolve().parents[1] / "docs" / "hdf5.md").read_text(encoding="utf-8")
    assert [kind for kind in EventKind if f"`{kind}`" not in text] == []
    stored = [cls for cls in vars(ev).values() if isinstance(cls, type) and "stored_as" in vars(cls)]
    assert stored and all(isinstance(cls.stored_as, EventKind) for cls in stored)


def test_the_rig_is_one_enum_from_the_configuration_to_the_prompts():
    assert tuple(RigKind) == BENCH_KINDS and set(KIND_DEFAULTS) == set(RigKind)
    assert set(ACTION_BENCH_KIND.values()) <= set(RigKind)
    assert default_bench_config("four_post").kind is RigKind.FOUR_POST
