"""The post-run analysis in a process of its own (bench/app/analysis_process.py): it gives what the
same analysis gives in this process, run for run, with the campaign's knowledge brought back; an
input it cannot analyse is a flagged analysis and the next run is analysed; a process that dies is
a clear error, and the runs it held are published as flagged analyses, not lost or waited for."""

from __future__ import annotations

import os
import pickle
import signal

import numpy as np
import pytest

from bench.analysis.campaign import CampaignKnowledge
from bench.analysis.flags import FlagCode
from bench.app.analysis_process import (
    SCHEDULING_POLICY,
    AnalysisProcess,
    AnalysisProcessError,
    read_message,
    write_message,
)
from bench.app.post_run import PostRunAnalysis
from bench.app.run_analysis import (
    RunAnalyser,
    RunInputs,
    initial_knowledge,
    replay_campaign,
    run_inputs,
    runs_to_analyse,
)
from bench.config import default_bench_config
from bench.engine import events as ev
from bench.store import open_campaign

RESULT_TIMEOUT_S = 60.0  # wall clock for one analysis to come back, a timeout only


def _fresh() -> CampaignKnowledge:
    return initial_knowledge(default_bench_config())


def test_the_process_analyses_as_this_process_does_and_brings_the_knowledge_back(smoke_campaign):
    """Run for run the same lines and results; the knowledge given to the process ends as the one
    analysed here (only the changes came back: new values, list items appended, dict entries)."""
    here_knowledge = _fresh()
    with open_campaign(smoke_campaign) as campaign:
        here = replay_campaign(campaign, RunAnalyser(here_knowledge))
        inputs = [run_inputs(run, campaign) for run in runs_to_analyse(campaign)]
    with AnalysisProcess(_fresh()) as process:
        for run in inputs:
            process.submit(run)
        there = [process.next_result(RESULT_TIMEOUT_S).outcome for _ in inputs]
        assert process.outstanding == 0 and process.next_result(0) is None
    assert [a.name for a in here] == ["plate_mass", "shaker", "sweep"]
    assert [(a.run_id, a.lines, a.results, a.flags) for a in here] == [
        (a.run_id, a.lines, a.results, a.flags) for a in there
    ]
    knowledge = process.knowledge
    assert list(knowledge.analysed_runs) == list(here_knowledge.analysed_runs) == [a.run_id for a in here]
    assert [p.result.plate.mass_kg for p in knowledge.plate_masses] == [
        p.result.plate.mass_kg for p in here_knowledge.plate_masses
    ]
    assert list(knowledge.shaker) == [2.5] and len(knowledge.shaker_free_run) == 3
    assert list(knowledge.shaker[2.5].amplitudes) == list(here_knowledge.shaker[2.5].amplitudes)


def test_an_input_the_analysis_cannot_take_is_flagged_and_the_next_run_is_analysed(smoke_campaign):
    with open_campaign(smoke_campaign) as campaign:
        free_run = run_inputs(runs_to_analyse(campaign)[0], campaign)
    broken = RunInputs("broken-free_run", "free_run", {}, dwells=("not a record",))  # type: ignore[arg-type]
    with AnalysisProcess(_fresh()) as process:
        process.submit(broken)
        process.submit(free_run)
        flagged = process.next_result(RESULT_TIMEOUT_S).outcome
        analysed = process.next_result(RESULT_TIMEOUT_S).outcome
    assert flagged.error.startswith("AttributeError") and flagged.lines[0].startswith("FLAG analysis failed")
    assert [f.code for f in flagged.flags] == [FlagCode.ANALYSIS_FAILED]  # the flag's code came along
    assert analysed.name == "plate_mass" and not analysed.error
    assert list(process.knowledge.analysed_runs) == ["broken-free_run", free_run.run_id]


def test_an_input_whose_record_cannot_be_made_is_answered_and_the_next_run_is_analysed(smoke_campaign):
    """A value in a run's conditions that has no digest (a set) leaves that run without a record, as
    a result the record cannot hold does; the process answers it and goes on."""
    with open_campaign(smoke_campaign) as campaign:
        free_run = run_inputs(runs_to_analyse(campaign)[0], campaign)
    odd = RunInputs("odd-free_run", "free_run", {"note": {1, 2}})
    with AnalysisProcess(_fresh()) as process:
        process.submit(odd)
        process.submit(free_run)
        first = process.next_result(RESULT_TIMEOUT_S)
        second = process.next_result(RESULT_TIMEOUT_S)
    assert first.outcome.run_id == "odd-free_run" and first.record == ""
    assert second.outcome.name == "plate_mass" and second.record.startswith('{"format":')


def test_the_analysis_process_runs_as_batch_work_at_the_benchs_priority():
    """Batch: a waking thread of the bench comes first; the same priority: the bench waits for some
    of its results, and a lower one starves it on a busy host."""
    with AnalysisProcess(_fresh()) as process:
        process.submit(RunInputs("r", "free_run", {}))
        assert process.next_result(RESULT_TIMEOUT_S).outcome.error  # answered: it has set its policy
        pid = process._process.pid
        policy, child = os.sched_getscheduler(pid), os.getpriority(os.PRIO_PROCESS, pid)
    assert policy == SCHEDULING_POLICY == os.SCHED_BATCH
    assert child == os.getpriority(os.PRIO_PROCESS, 0)


def test_a_killed_analysis_process_is_a_clear_error():
    with AnalysisProcess(_fresh()) as process:
        os.kill(process._process.pid, signal.SIGKILL)
        process._process.wait(10)
        with pytest.raises(AnalysisProcessError, match="analysis process"):
            process.submit(RunInputs("r", "free_run", {}))
            process.next_result(RESULT_TIMEOUT_S)


def test_runs_held_by_a_dead_analysis_process_are_published_flagged_at_the_sequences_end(smoke_campaign):
    """The subscriber sends the smoke file's free run as the engine's events say it completed; the
    process dies before answering; the sequence's end publishes it as a flagged analysis (the
    replay of the file's runs, never published, is not either)."""
    published: list[ev.Event] = []
    with open_campaign(smoke_campaign) as campaign:
        free_run = runs_to_analyse(campaign)[0]
    with PostRunAnalysis(smoke_campaign, published.append, _fresh()) as analysis:  # replays the file first
        child = analysis._process._process
        os.kill(child.pid, signal.SIGSTOP)  # it cannot answer before it dies
        try:
            analysis(ev.RunStarted(free_run.run_id, "free_run", {}, {}, (), 1000.0))
            analysis(ev.RunFinished(free_run.run_id, "complete", ""))
        finally:
            os.kill(child.pid, signal.SIGKILL)  # a stopped process left behind would never end
            child.wait(10)
        analysis(ev.SequenceFinished("complete", ""))
    (done,) = [e for e in published if isinstance(e, ev.AnalysisDone)]
    assert done.run_id == free_run.run_id and done.name == "analysis"
    assert done.summary[0].startswith("FLAG analysis failed: the analysis process ended")



def test_a_message_keeps_its_arrays_beside_its_pickle_and_a_cut_stream_is_the_end(tmp_path):
    """The framing: arrays come back equal and writable (the analysis may work on them in place);
    a stream cut anywhere inside a frame, or garbage in its place, is an error, never a hang."""
    message = {"x": np.arange(100_000, dtype=np.float64), "view": np.arange(10)[::2], "text": "ok"}
    path = tmp_path / "frames.bin"
    with path.open("wb") as stream:
        write_message(stream, message)
        write_message(stream, ("second", np.ones(3, np.float32)))
    with path.open("rb") as stream:
        first, second = read_message(stream), read_message(stream)
        with pytest.raises(EOFError):
            read_message(stream)
    np.testing.assert_array_equal(first["x"], message["x"])
    np.testing.assert_array_equal(first["view"], [0, 2, 4, 6, 8])
    assert first["x"].flags.writeable and first["text"] == "ok" and second[0] == "second"
    whole = path.read_bytes()
    for cut in (0, 5, 12, 40, len(whole) // 2):
        path.write_bytes(whole[:cut])
        with path.open("rb") as stream, pytest.raises(EOFError):
            read_message(stream)
    for garbage in (b"\x05" + bytes(11) + b"garbage", b"\xff" * 12 + b"garbage", bytes(8) + b"\xff" * 4):
        path.write_bytes(garbage)
        with path.open("rb") as stream, pytest.raises(pickle.UnpicklingError):
            read_message(stream)
