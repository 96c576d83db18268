"""The options of a job over many files (``index``, ``compensate`` over folders): a number of
workers that is none is refused by both commands before anything is read or written."""

from __future__ import annotations

import argparse

import pytest

from bench.cli.exit_codes import ExitCode
from bench.cli.job_options import job_executor
from bench.cli.main import main
from bench.cluster import InProcess, OnDask


@pytest.mark.parametrize("command", [["index"], ["compensate", "campaign.h5"]])
@pytest.mark.parametrize("workers", ["-2", "two", "1.5", "", "1e3"])
def test_workers_that_are_no_whole_number_of_processes_are_refused(tmp_path, capsys, command, workers):
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as refused:
        main([*command, str(tmp_path), "--out", str(out), f"--workers={workers}"])
    assert refused.value.code == ExitCode.INVALID
    said = f"argument --workers: a whole number of processes, 0 or more, not {workers!r}"
    assert said in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize(
    ("scheduler", "workers", "kind"),
    [(None, 0, InProcess), (None, 3, OnDask), (None, None, OnDask), ("tcp://127.0.0.1:8786", 0, OnDask)],
)
def test_the_options_name_where_the_job_runs(scheduler, workers, kind):
    assert isinstance(job_executor(argparse.Namespace(scheduler=scheduler, workers=workers)), kind)
