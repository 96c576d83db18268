"""``wfsbench analyze`` says whether every analysis completed: exit code 0 and ``status`` complete
only then; a run whose analysis failed (a channel it needs deleted from the file) gives exit code 5
(``ExitCode.INCOMPLETE``), ``status`` partial, the run's own status and why, in the text and the JSON."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import pytest

from bench.cli.exit_codes import ExitCode
from bench.models.setup import BenchSetup
from bench.simulated_campaign import FREE_RUN_GRID_HZ, SHAKER_GRID_HZ, simulate_dwells
from tests.campaign_files import StoredRun, write_campaign
from tests.commands import wfsbench


@pytest.fixture(scope="module")
def campaign(tmp_path_factory) -> Path:
    free = simulate_dwells(BenchSetup.paper_free_run(), FREE_RUN_GRID_HZ[::3], 2e-3, seed=21)
    grid = simulate_dwells(BenchSetup.paper_shaker(2.5, nonlinear=False), SHAKER_GRID_HZ[4:], 2e-3, seed=22)
    runs = [
        StoredRun("free", "free_run", tuple(free), {"wheel_fitted": False}),
        StoredRun("grid", "dwell_grid", tuple(grid), {"tyre_pressure_bar": 2.5}),
    ]
    return write_campaign(tmp_path_factory.mktemp("status") / "campaign.h5", runs)


def _json(path: Path, *options: str) -> tuple[int, dict]:
    run = wfsbench("analyze", str(path), "--json", "--no-store", *options)
    return run.returncode, json.loads(run.stdout)


def test_a_complete_analysis_exits_0_and_says_so(campaign):
    text = wfsbench("analyze", str(campaign), "--no-store")  # the module's file is left as it is
    assert text.returncode == ExitCode.OK, text.stderr
    assert text.stdout.splitlines()[-1] == "== analysis complete: 2 runs analysed"
    code, doc = _json(campaign)
    assert code == ExitCode.OK and doc["status"] == "complete"
    assert [(r["run_id"], r["status"], r["error"], r["omitted"]) for r in doc["runs"]] == [
        ("free", "complete", None, []),
        ("grid", "complete", None, []),
    ]


def test_a_channel_deleted_from_the_file_fails_its_analysis_and_the_command(campaign, tmp_path):
    broken = tmp_path / "broken.h5"
    broken.write_bytes(campaign.read_bytes())
    with h5py.File(broken, "r+") as file:
        del file["runs/grid/channels/fz_wfs_n"]
    # fitted again: a stored analysis would be the record of the data as it was analysed
    text = wfsbench("analyze", str(broken), "--reanalyse")
    assert text.returncode == ExitCode.INCOMPLETE, text.stderr
    last = text.stdout.splitlines()[-1]
    assert last.startswith("== analysis partial: 1 of 2 runs not complete (grid failed: ")
    assert "fz_wfs_n" in last and "missing" in last
    code, doc = _json(broken, "--reanalyse")
    assert code == ExitCode.INCOMPLETE and doc["status"] == "partial"
    grid = next(r for r in doc["runs"] if r["run_id"] == "grid")
    assert grid["status"] == "failed" and "fz_wfs_n" in grid["error"]
    assert next(r for r in doc["runs"] if r["run_id"] == "free")["status"] == "complete"
