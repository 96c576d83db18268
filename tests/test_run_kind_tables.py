"""One table per layer where behaviour varies by run kind, each with an entry for every
:class:`~sequences.runs.RunKind`: a new kind fails here until every layer has said what it does with
it (docs/architecture.md, *Adding a run kind*)."""

from __future__ import annotations

import pytest

from bench.app.run_analysis import ANALYSES, INPUT_READERS, RunAnalyser, RunInputs, initial_knowledge
from bench.config import default_bench_config
from bench.engine.procedures import PROCEDURES
from sequences.runs import RunKind
from sequences.steps import MEASUREMENT_TYPES

#: Each layer's table keyed by the run kind.
TABLES = {
    "the engine's procedure (bench/engine/procedures PROCEDURES)": PROCEDURES,
    "what the analysis reads (bench/app/run_analysis.py INPUT_READERS)": INPUT_READERS,
    "the analysis (bench/app/run_analysis.py ANALYSES)": ANALYSES,
}


@pytest.mark.parametrize("name", sorted(TABLES))
def test_every_run_kind_is_in_the_table(name):
    table = TABLES[name]
    assert set(table) == set(RunKind), f"{name}: missing {set(RunKind) - set(table)}"


@pytest.mark.parametrize("step_type", MEASUREMENT_TYPES, ids=lambda t: t.kind)
def test_every_measurement_step_is_run_by_a_procedure(step_type):
    """A measurement step is run by its run kind's procedure: a new step type needs a kind the
    engine has a procedure for."""
    assert RunKind.of_step(step_type.kind) in PROCEDURES


@pytest.mark.parametrize("kind", list(RunKind))
def test_a_run_of_any_kind_without_its_records_is_flagged_not_raised(kind):
    """Every kind's analysis, given a run whose records were not read, says so in a flag (on the
    four-post bench: a sweep on the shaker is recorded and not analysed)."""
    run = RunInputs(f"r-{kind}", kind, {"bench": "four_post"})
    outcome = RunAnalyser(initial_knowledge(default_bench_config())).analyse(run)
    assert outcome.error and outcome.lines[0].startswith("FLAG analysis failed"), outcome
