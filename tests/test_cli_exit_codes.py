"""The command's exit codes mean one thing each (docs/cli.md, "Exit codes"): a command line argparse
cannot use is invalid input (3, the usage then ``error: ...``), never the link-error code 2, which
every command that opens a device gives, with ``error:``, when the device cannot be reached."""

from __future__ import annotations

import pytest

from bench.cli import EXIT_INVALID, EXIT_LINK
from tests.test_campaign_cli import wfsbench


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
    assert result.returncode == EXIT_INVALID, result.stderr
    usage, *_, last = result.stderr.splitlines()
    assert usage.startswith("usage: wfsbench")
    assert last.startswith(error), last


def test_a_wfs_port_that_cannot_be_opened_is_a_link_error_naming_the_port(tmp_path):
    port = tmp_path / "nonexist"
    result = wfsbench("wfs", "monitor", "--port", str(port), "--duration", "1")
    assert result.returncode == EXIT_LINK, result.stdout + result.stderr
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
