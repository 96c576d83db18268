"""``wfsbench tui`` in a real terminal (tmux): the documented script (docs/tui_smoke_tmux.sh) types
the keys a person would and runs the smoke sequence to its results screen."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from bench.store import open_campaign

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.validation
def test_documented_tmux_script_runs_smoke_to_results(tmp_path: Path) -> None:
    out = tmp_path / "smoke.h5"
    wfsbench = Path(sys.executable).with_name("wfsbench")
    done = subprocess.run(
        ["bash", str(ROOT / "docs" / "tui_smoke_tmux.sh"), str(out)],
        env={**os.environ, "WFSBENCH": str(wfsbench)},
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    screen = done.stdout
    assert "F5 Results" in screen and "runs of the open file" in screen
    assert "Model 2 selected" in screen and "valid band 2 mm compensated" in screen
    with open_campaign(out) as campaign:
        assert [(r.run_id, r.status) for r in campaign.runs] == [
            ("smoke-s003-free_run", "complete"),
            ("smoke-s009-dwell_grid", "complete"),
            ("smoke-s010-sweep", "complete"),
        ]
        assert campaign.run("smoke-s009-dwell_grid").conditions["tyre_pressure_bar"] == 2.5
    # the UI's log beside the file tells the run's events in the run log's lines
    log = Path(f"{out}.log").read_text()
    for line in (
        "bench.tui.run: starting sequence smoke into",
        "bench.tui.run: prompt remove_wheel: Remove the wheel from the bench -> True",
        "bench.tui.run: run smoke-s003-free_run (free_run)",
        "bench.tui.run:   point 0 at 10 Hz: done, commanded 2.000 mm",
        "bench.tui.run: prompt pressure: Set the tyre pressure to 2.5 bar and enter the pressure read",
        "bench.tui.run: run smoke-s009-dwell_grid: complete",
        "bench.tui.run: sequence complete",
    ):
        assert line in log, line
