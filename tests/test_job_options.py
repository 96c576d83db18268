"""The options of a job over many files (``index``, ``compensate`` over folders): a number of
workers that is none is refused by both commands before anything is read or written; each runs its
linear algebra on one thread."""

from __future__ import annotations

import argparse
import os
import subprocess
import sys

import pytest

from bench.cli.exit_codes import ExitCode
from bench.cli.job_options import ONE_THREAD_ENVIRONMENT, job_executor
from bench.cli.main import main
from bench.cluster import InProcess, OnDask
from tests.documented import ROOT


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


def _numpy_threads(environment: dict[str, str], call_first: bool) -> tuple[str, int]:
    """In a fresh interpreter: the OpenBLAS setting and the process's threads once numpy is loaded,
    with :func:`one_numerical_thread` called first or not."""
    code = (
        "import os\n"
        "from bench.cli.job_options import one_numerical_thread\n"
        + ("one_numerical_thread()\n" if call_first else "")
        + "import numpy\n"
        "print(os.environ.get('OPENBLAS_NUM_THREADS'), len(os.listdir('/proc/self/task')))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, env=environment, capture_output=True, text=True, check=True
    )
    setting, threads = done.stdout.split()
    return setting, int(threads)


def test_a_jobs_process_loads_its_linear_algebra_on_one_thread_unless_told_otherwise():
    """The library starts a thread per core when numpy loads (2 on this machine); called first, the
    process has its main thread alone; a value the environment holds is kept."""
    plain = {k: v for k, v in os.environ.items() if k not in ONE_THREAD_ENVIRONMENT}
    assert _numpy_threads(plain, call_first=True) == ("1", 1)
    assert _numpy_threads({**plain, "OPENBLAS_NUM_THREADS": "2"}, call_first=True)[0] == "2"


@pytest.mark.parametrize("command", [["index"], ["compensate", "campaign.h5"]])
def test_both_jobs_set_one_numerical_thread_before_anything_else(tmp_path, monkeypatch, command):
    """Each command's first act (the setting acts only before numpy loads)."""
    import bench.cli.archive
    import bench.cli.compensate

    called = []
    for module in (bench.cli.archive, bench.cli.compensate):
        monkeypatch.setattr(module, "one_numerical_thread", lambda: called.append(True))
    main([*command, str(tmp_path / "nothing"), "--out", str(tmp_path / "out"), "--workers", "0"])
    assert called == [True]
