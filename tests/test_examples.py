"""The scripted campaign in examples/ runs as an engineer would run it, end to end."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from bench.store import open_campaign

EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "scripted_campaign.py"


@pytest.mark.validation
@pytest.mark.slow
def test_the_scripted_campaign_runs_and_records_every_point(tmp_path):
    out = tmp_path / "scripted.h5"
    result = subprocess.run(
        [sys.executable, str(EXAMPLE), str(out)], capture_output=True, text=True, timeout=300, check=False
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert f"complete; campaign file {out}" in result.stdout
    with open_campaign(out) as campaign:
        runs = {run.run_id: run for run in campaign.runs}
        assert [run.kind for run in runs.values()] == ["free_run", "dwell_grid", "dwell_grid"]
        assert all(run.status == "complete" for run in runs.values())
        pressures = [run.conditions["tyre_pressure_bar"] for run in runs.values() if run.kind == "dwell_grid"]
        assert pressures == [1.5, 2.5]
        assert all(
            sorted(run.completed_point_indices()) == list(range(len(run.step["freqs_hz"])))
            for run in runs.values()
        )
    assert "stiffness_n_per_m" in result.stdout  # the identification was printed after each pressure's grid


@pytest.mark.parametrize(
    ("args", "code", "words"), [(["--help"], 0, "usage:"), (["--out", "x.h5"], 2, "usage:")]
)
def test_the_example_takes_its_arguments_like_a_command(tmp_path, args, code, words):
    """--help prints the usage and runs nothing; an option it does not take is refused."""
    result = subprocess.run(
        [sys.executable, str(EXAMPLE), *args],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=tmp_path,
        check=False,
    )
    assert result.returncode == code, result.stderr
    assert words in result.stdout + result.stderr
    assert list(tmp_path.iterdir()) == []  # no campaign file, not even one named --help
