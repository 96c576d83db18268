"""``wfsbench check``: validation and dry run without opening a device, through the command line."""

from __future__ import annotations

import subprocess
import sys

from sequences import shipped_file
from tests.commands import wfsbench
from tests.test_campaign_cli import ROOT


def check(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "bench.cli", "check", *args],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


def test_a_valid_sequence_lists_its_steps_totals_and_largest_loads():
    result = check(str(shipped_file("smoke.toml")))
    assert result.returncode == 0, result.stderr
    out = result.stdout.splitlines()
    assert sum(line.startswith("  steps[") for line in out) == 12
    assert "steps[3] free_run: 3 dwells 10-60 Hz at 2 mm" in result.stdout
    assert "8 points; about 29 s of bench time, about 3.5 min with the operator's answers" in out
    assert "largest wfs_load_n:" in result.stdout and "(limit 24000 N)" in result.stdout
    assert out[-1] == "every point within the bench's limits: nothing refused"


def test_a_sequence_under_a_minute_gives_its_bench_time_in_seconds():
    result = check(str(shipped_file("hammer.toml")))
    assert result.returncode == 0, result.stderr
    assert "3 points; about 3 s of bench time, about 4.0 min with the operator's answers" in result.stdout


def test_refused_points_are_each_named_with_the_limit_and_exit_4(tmp_path):
    bench = tmp_path / "weak.toml"
    bench.write_text("[limits]\nwfs_force_n = 700\n")
    result = check(str(shipped_file("smoke.toml")), "--bench", str(bench))
    assert result.returncode == 4
    assert "REFUSED (4): steps this bench cannot do, points beyond its limits:" in result.stdout
    assert result.stdout.count("is beyond the limit wfs_force_n = 700 N") == 4


def test_a_sequence_for_another_kind_of_bench_is_refused_by_check_and_by_run(tmp_path):
    four_post = str(shipped_file("paper_four_post.toml"))
    result = check(four_post)  # on the default configuration: the simulated shaker
    assert result.returncode == 4
    assert (
        "  steps[5] prompt 'car_on_posts': car_on_posts is done on a four_post bench, and the configured"
        " bench is a shaker bench (give a four_post bench configuration with --bench: the simulated one is"
        " configs/simulated_four_post.toml)"
    ) in result.stdout.splitlines()
    out = tmp_path / "c.h5"
    run = wfsbench("run", four_post, "--out", str(out))
    assert run.returncode == 4 and "car_on_posts is done on a four_post bench" in run.stderr
    assert not out.exists()  # refused before anything was opened
    named = check(four_post, "--bench", str(ROOT / "configs" / "simulated_four_post.toml"))
    assert named.returncode == 0, named.stdout  # the configuration the refusal names takes it


def test_an_invalid_file_is_named_with_its_key_and_exit_3(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(
        shipped_file("smoke.toml").read_text().replace("freqs_hz = [10, 30, 60]", "freqs_hz = [10, 30, 600]")
    )
    result = check(str(bad))
    assert result.returncode == 3
    assert f"{bad}: steps[3].freqs_hz[2]: 600 Hz is above the bench's highest frequency" in result.stderr
    assert result.stdout == ""
