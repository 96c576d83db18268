"""The command's exit codes mean one thing each, one table for every command (docs/cli.md, "Exit
codes", :mod:`bench.cli.exit_codes`): a command line argparse cannot use is invalid input (3, the
usage then ``error: ...``), never the unavailable-device code 2, which every command that opens a
device gives, with ``error:``, when the device cannot be reached; a complete sequence whose analysis
is not complete is INCOMPLETE (5), as ``analyze`` says of the same file."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from bench.cli.exit_codes import ExitCode
from bench.cli.main import main
from tests.commands import wfsbench
from tests.sequence_texts import sequence_text

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize(
    ("args", "error"),
    [
        ((), "error: the following arguments are required: COMMAND"),
        (("run",), "error: the following arguments are required: sequence, --out"),
        (("run", "x.toml", "--out", "x.h5", "--bogus"), "error: unrecognized arguments: --bogus"),
        (("check", "x.toml", "--bench"), "error: argument --bench: expected one argument"),
        (
            ("wfs", "monitor", "--port", "p", "--duration", "soon"),
            "error: argument --duration: invalid float value: 'soon'",
        ),
        (("frobnicate",), "error: argument COMMAND: invalid choice: 'frobnicate'"),
    ],
)
def test_a_command_line_that_cannot_be_used_is_invalid_input(args, error):
    result = wfsbench(*args)
    assert result.returncode == ExitCode.INVALID, result.stderr
    usage, *_, last = result.stderr.splitlines()
    assert usage.startswith("usage: wfsbench")
    assert last.startswith(error), last


def test_a_wfs_port_that_cannot_be_opened_is_a_link_error_naming_the_port(tmp_path):
    port = tmp_path / "nonexist"
    result = wfsbench("wfs", "monitor", "--port", str(port), "--duration", "1")
    assert result.returncode == ExitCode.UNAVAILABLE, result.stdout + result.stderr
    assert result.stderr.startswith(f"error: cannot open the WFS port {port}: "), result.stderr
    assert result.stdout == ""


def test_version_and_help_are_plain_text():
    from importlib.metadata import version

    shown = wfsbench("--version")
    assert (shown.returncode, shown.stdout) == (0, f"wfsbench {version('wfs-bench')}\n")
    helped = wfsbench("--help")
    assert helped.returncode == 0
    assert "``" not in helped.stdout and "--version" in helped.stdout
    assert "The wfsbench command line: run and check test sequences" in " ".join(helped.stdout.split())


GRID_OF_THREE = """
[[steps]]
type = "dwell_grid"
label = "three dwells, no pressure asked"
freqs_hz = [10, 25, 40]
amplitudes_mm = [2]
settle_cycles = 2
settle_min_s = 0.1
measure_cycles = 2
measure_min_s = 0.5
taper_in_s = 0.2
taper_out_s = 0.2
"""


def test_a_run_whose_analysis_is_not_complete_exits_incomplete_naming_the_run(tmp_path, capsys):
    """The sequence completes, but its grid ran without a tyre pressure asked: the command says which
    run's analysis failed and why, last, and exits INCOMPLETE (5), as ``analyze`` of the file does."""
    sequence = tmp_path / "three.toml"
    sequence.write_text(sequence_text("three", GRID_OF_THREE))
    out = tmp_path / "three.h5"
    assert main(["run", str(sequence), "--out", str(out)]) == ExitCode.INCOMPLETE
    lines = capsys.readouterr().out.splitlines()
    assert lines[-2] == f"three: complete; file {out}"
    assert lines[-1] == (
        "analysis of run three-s002-dwell_grid failed: no tyre pressure was answered before this grid"
    )
    assert main(["analyze", str(out), "--no-store"]) == ExitCode.INCOMPLETE


def test_the_documented_table_is_the_code_s_table():
    """docs/cli.md's table of exit codes lists every code of :class:`ExitCode` with its number, and no
    command module keeps codes of its own."""
    doc = (ROOT / "docs" / "cli.md").read_text()
    table = doc[doc.index("### Exit codes") :]
    rows = re.findall(r"^\| (\d) \| `([A-Z_]+)` \|", table, flags=re.M)
    assert [(int(n), name) for n, name in rows] == [(code.value, code.name) for code in ExitCode]
    for module in (ROOT / "bench").rglob("*.py"):
        assert not re.search(r"^EXIT_\w+ = \d", module.read_text(), flags=re.M), module
