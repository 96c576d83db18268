"""The ``wfsbench`` command line: its parser and entry point.

Each subcommand imports what it needs when it runs, so that the offline commands (``check``,
``analyze``, ``report``, ``import-csv``) and ``--help`` / ``--version`` start without loading the
device clients (pymodbus, pyserial), the simulators or the run engine
(``benchmarks/cli_startup.py`` measures it, ``tests/test_cli_imports.py`` keeps it so).
"""

from __future__ import annotations

import argparse
import os
import sys
from typing import NoReturn

from bench.cli.analysis import add_analysis_commands
from bench.cli.archive import add_archive_commands
from bench.cli.campaign import add_campaign_commands
from bench.cli.compensate import add_compensate_command
from bench.cli.devices import add_device_commands
from bench.cli.exit_codes import ExitCode
from bench.cli.export import add_export_command
from bench.cli.monitor import add_monitor_command
from bench.locks import LockDirError
from drivers.errors import LinkError


class _Parser(argparse.ArgumentParser):
    """argparse with the documented exit code for a command line it cannot use: invalid input (3),
    not argparse's own 2, which ``wfsbench`` keeps for a device that could not be reached."""

    def error(self, message: str) -> NoReturn:
        self.print_usage(sys.stderr)
        self.exit(ExitCode.INVALID, f"error: {message}\n")


class _Version(argparse.Action):
    """``--version``: the installed package's version (looked up only when asked: it costs imports)."""

    def __init__(self, option_strings: list[str], dest: str, **kwargs: object) -> None:
        super().__init__(option_strings, dest, nargs=0, help="print the version and exit")

    def __call__(self, parser: argparse.ArgumentParser, *args: object) -> None:
        from bench.app.version import software_version

        print(f"wfsbench {software_version()}")
        parser.exit(0)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="wfsbench",
        description="The wfsbench command line: run and check test sequences on a wheel force sensor"
        " bench, analyse and report campaign files, serve and talk to the (simulated) devices."
        " Each command has its own --help; docs/cli.md describes them all.",
    )
    parser.add_argument("--version", action=_Version)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    add_campaign_commands(sub)
    add_device_commands(sub)
    add_analysis_commands(sub)
    add_export_command(sub)
    add_compensate_command(sub)
    add_archive_commands(sub)
    add_monitor_command(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.run(args)
    except LinkError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return ExitCode.UNAVAILABLE
    except LockDirError as exc:  # the environment names no usable lock directory: nothing opened
        print(f"error: {exc}", file=sys.stderr)
        return ExitCode.INVALID
    except KeyboardInterrupt:  # Ctrl-C before a command took it over (a run: before the devices opened)
        print("interrupted: nothing moved", file=sys.stderr)
        return ExitCode.STOPPED
    except BrokenPipeError:  # the reader of a pipe went away (| head): stop writing, quietly
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # the exit's flush goes nowhere
        return ExitCode.OK


if __name__ == "__main__":
    sys.exit(main())
