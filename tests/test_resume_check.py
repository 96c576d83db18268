"""``wfsbench run --resume`` continues the campaign the file holds, nothing else: a sequence whose
steps differ from the stored one, or a bench that measures differently, is refused with exit code 3
naming the file and the first differing step or key; a copy that differs only in comments,
whitespace or key order, or in how the devices are reached, resumes."""

from __future__ import annotations

from pathlib import Path

from bench.cli.exit_codes import ExitCode
from bench.store import open_campaign
from tests.commands import wfsbench
from tests.test_campaign_cli import SMOKE


def _copy(src: Path, tmp_path: Path) -> Path:
    out = tmp_path / "campaign.h5"
    out.write_bytes(src.read_bytes())
    return out


def test_a_sequence_with_another_amplitude_is_refused_naming_the_step_and_key(tmp_path, smoke_campaign):
    out = _copy(smoke_campaign, tmp_path)
    changed = tmp_path / "smoke_mod.toml"
    changed.write_text(SMOKE.read_text().replace("amplitudes_mm = [2]", "amplitudes_mm = [3]", 1))
    before = out.read_bytes()
    run = wfsbench("run", str(changed), "--out", str(out), "--resume")
    assert run.returncode == ExitCode.INVALID, run.stdout + run.stderr
    assert run.stderr.strip() == (
        f"error: {out}: cannot resume: the sequence in {changed} differs from the one the file holds:"
        " steps[3].amplitudes_mm: [3] now, [2] in the file"
    )
    assert out.read_bytes() == before  # nothing written
    with open_campaign(out) as campaign:
        assert "amplitudes_mm = [2]" in campaign.sequence_toml


def test_a_copy_differing_in_comments_whitespace_and_key_order_resumes(tmp_path, smoke_campaign):
    out = _copy(smoke_campaign, tmp_path)
    lines = SMOKE.read_text().splitlines()
    grid = lines.index("amplitudes_mm = [2]")
    lines[grid - 1], lines[grid] = lines[grid], lines[grid - 1]  # two keys of one step swapped
    same = tmp_path / "smoke_same.toml"
    same.write_text("# the same campaign, re-typed\n\n" + "\n".join(f"{line}   " for line in lines) + "\n")
    run = wfsbench("run", str(same), "--out", str(out), "--resume")
    assert run.returncode == ExitCode.OK, run.stdout + run.stderr


def test_a_bench_that_measures_differently_is_refused_and_connection_settings_may_change(
    tmp_path, smoke_campaign
):
    out = _copy(smoke_campaign, tmp_path)
    heavy = tmp_path / "heavy.toml"
    heavy.write_text('kind = "shaker"\n[masses]\nsensor_kg = 4.0\n')
    run = wfsbench("run", str(SMOKE), "--out", str(out), "--resume", "--bench", str(heavy))
    assert run.returncode == ExitCode.INVALID, run.stdout + run.stderr
    assert run.stderr.strip() == (
        f"error: {out}: cannot resume: the bench configuration {heavy} differs from the one the file"
        " holds: masses.sensor_kg: 4.0 now, 3.82 in the file"
    )
    # the pacing of the simulated bench and the controller's address are no part of the measurement
    moved = tmp_path / "moved.toml"
    moved.write_text('kind = "shaker"\n[actuator]\nport = 1502\n[simulation]\npaced = false\n')
    run = wfsbench("run", str(SMOKE), "--out", str(out), "--resume", "--bench", str(moved), "--realtime")
    assert run.returncode == ExitCode.OK, run.stdout + run.stderr
