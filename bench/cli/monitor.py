"""The web monitor on the command line: ``--monitor HOST:PORT`` of ``run`` and ``tui``, and
``wfsbench monitor FILE --listen HOST:PORT`` of a campaign file (docs/monitor.md).

The server and its dependencies are imported only when a monitor is asked for, so that ``--help``
and the commands without one start as light as before (``tests/test_cli_imports.py``).
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from pathlib import Path
from typing import TYPE_CHECKING

from bench.cli.exit_codes import ExitCode, unreadable_file_code

if TYPE_CHECKING:
    from bench.monitor.feed import BenchMonitor
    from bench.monitor.listen import Listen

TOKEN_HELP = (
    "the token a viewer must give (required for an address other than loopback; at least 16"
    " characters; it shows in the process list: prefer --monitor-token-file)"
)
TOKEN_FILE_HELP = "read the token from the first line of FILE"


def add_token_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--monitor-token", metavar="TOKEN", help=TOKEN_HELP)
    parser.add_argument("--monitor-token-file", metavar="FILE", help=TOKEN_FILE_HELP)


def add_monitor_options(parser: argparse.ArgumentParser) -> None:
    """``--monitor HOST:PORT`` and its token options, for ``run`` and ``tui``."""
    parser.add_argument(
        "--monitor",
        metavar="HOST:PORT",
        help="serve a read-only web page of the bench at HOST:PORT (127.0.0.1 unless a token is given;"
        " port 0: a free one; docs/monitor.md)",
    )
    add_token_options(parser)


def monitor_listen(args: argparse.Namespace, address: str | None, option: str) -> Listen | None:
    """The monitor's settings from the command line (None when no monitor is asked for);
    :class:`~bench.monitor.listen.MonitorSettingsError` names the option and why."""
    if address is None:
        if args.monitor_token is not None or args.monitor_token_file is not None:
            from bench.monitor.listen import MonitorSettingsError

            raise MonitorSettingsError(f"--monitor-token: given without {option}")
        return None
    from bench.monitor.listen import listen_settings

    token_file = Path(args.monitor_token_file) if args.monitor_token_file else None
    return listen_settings(address, option, token=args.monitor_token, token_file=token_file)


def start_bench_monitor(listen: Listen) -> BenchMonitor:
    """The monitor of a bench, its server in a process of its own; listening (or
    :class:`~bench.monitor.listen.MonitorUnavailableError`), and said where."""
    from bench.monitor.feed import BenchMonitor
    from bench.monitor.server_process import ServerProcess

    server = ServerProcess(listen)
    server.start()
    print(f"monitor: {server.url} (read-only)", flush=True)
    return BenchMonitor(server)


def _monitor(args: argparse.Namespace) -> int:
    """Serve the state of a campaign file until Ctrl-C, SIGTERM or SIGHUP."""
    from bench.monitor.file_view import FileWatch
    from bench.monitor.listen import MonitorSettingsError, MonitorUnavailableError
    from bench.monitor.server import MonitorServer
    from bench.store import StoreError

    try:
        listen = monitor_listen(args, args.listen, "--listen")
    except MonitorSettingsError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return ExitCode.INVALID
    server = MonitorServer(listen)
    watch = FileWatch(Path(args.file), server.publish)
    try:
        watch.start()
    except StoreError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return unreadable_file_code(exc)
    try:
        server.start()
    except MonitorUnavailableError as exc:
        watch.close()
        print(f"error: --listen {args.listen}: {exc}", file=sys.stderr)
        return ExitCode.UNAVAILABLE
    print(f"monitor: {server.url} (read-only) of {args.file}; Ctrl-C ends it", flush=True)
    ended = threading.Event()
    for number in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(number, lambda *_: ended.set())
    try:
        ended.wait()
    except KeyboardInterrupt:
        pass
    finally:
        watch.close()
        server.close()
    print("monitor ended", flush=True)
    return ExitCode.OK


def add_monitor_command(sub: argparse._SubParsersAction) -> None:
    """Add ``monitor`` to the ``wfsbench`` subcommands."""
    monitor = sub.add_parser(
        "monitor",
        help="a read-only web page of a campaign file, being recorded or finished (docs/monitor.md)",
        description="Serve a read-only web page and /api/state of a campaign file: its runs, points"
        " done, analyses with their flags and events, read again every second while a run records it."
        " Runs until Ctrl-C (exit 0). A file that is no campaign file exits 3; an address that cannot"
        " be listened on exits 2 (docs/cli.md).",
    )
    monitor.add_argument("file", help="campaign file (HDF5, docs/hdf5.md)")
    monitor.add_argument(
        "--listen",
        default="127.0.0.1:8080",
        metavar="HOST:PORT",
        help="where to serve (default: %(default)s; another address than loopback needs a token)",
    )
    add_token_options(monitor)
    monitor.set_defaults(run=_monitor)
