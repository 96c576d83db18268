"""``wfsbench run --resume`` says what it does when there is nothing to continue: a file that holds
the sequence complete runs nothing (nothing opened, asked or moved; the file untouched) and says so
with exit code 0; a sequence of which the file holds no run is refused with exit code 3, naming the
sequences it does hold (before, it was run afresh into the file)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from bench.cli.exit_codes import ExitCode
from tests.commands import wfsbench
from tests.test_campaign_cli import SMOKE


@pytest.fixture
def smoke_file(smoke_campaign: Path, tmp_path: Path) -> Path:
    """A copy of the smoke sequence's complete campaign file (tests/conftest.py)."""
    return Path(shutil.copyfile(smoke_campaign, tmp_path / "smoke.h5"))


def test_resuming_a_complete_campaign_runs_nothing_and_says_so(smoke_file):
    before = smoke_file.read_bytes()
    run = wfsbench("run", str(SMOKE), "--out", str(smoke_file), "--resume")
    assert run.returncode == ExitCode.OK, run.stderr
    assert run.stdout.strip() == (
        f"{smoke_file}: every run of sequence 'smoke' is complete already: nothing was run"
        " (to run it again, write to another file)"
    )
    assert "progress:" not in run.stdout
    assert smoke_file.read_bytes() == before


def test_resuming_with_a_sequence_the_file_does_not_hold_is_refused(smoke_file):
    before = smoke_file.read_bytes()
    hammer = SMOKE.with_name("hammer.toml")
    run = wfsbench("run", str(hammer), "--out", str(smoke_file), "--resume")
    assert run.returncode == ExitCode.INVALID, run.stdout + run.stderr
    assert run.stderr.strip() == (
        f"error: {smoke_file}: cannot resume: it holds no run of sequence 'hammer' (it holds sequences"
        " smoke): there is nothing of it to continue; to add its runs to this file, run it without --resume"
    )
    assert smoke_file.read_bytes() == before
