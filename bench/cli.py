"""The ``wfsbench`` command line: a small front door to the links and the simulated bench.

Each subcommand imports what it needs when it runs, so that the offline commands (``check``,
``analyze``, ``report``, ``import-csv``) and ``--help`` / ``--version`` start without loading the
device clients (pymodbus, pyserial), the simulators or the run engine
(``benchmarks/cli_startup.py`` measures it, ``tests/test_cli_imports.py`` keeps it so).
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import time
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any, NoReturn

from bench.cli_analysis import add_analysis_commands
from bench.cli_archive import add_archive_commands
from bench.cli_compensate import add_compensate_command
from bench.cli_export import add_export_command
from bench.cli_metadata import add_meta_option
from bench.locks import LockDirError
from drivers.errors import LinkError

#: How long ``actuator reset`` waits for an e-stopped controller to taper out of its stop (s).
RESET_TIMEOUT_S = 10.0
#: exit codes of ``wfsbench run`` (docs/cli.md)
EXIT_COMPLETE = 0
EXIT_STOPPED = 1  # aborted (a signal too), e-stopped, interlocked or failed: the file holds the data, marked
EXIT_LINK = 2  # a device could not be reached, or a device or the campaign file is held by another process
EXIT_INVALID = 3  # the sequence, configuration, answers or CSV mapping is invalid: nothing opened or moved
EXIT_REFUSED = 4  # the dry run refused a point: nothing was opened or moved


def _run(args: argparse.Namespace) -> int:
    from bench.app.answers import AnswersError, load_answers
    from bench.app.devices import DeviceUnreachableError
    from bench.app.interrupts import RunInterrupts
    from bench.app.plan import PlanRefusedError, plan_campaign
    from bench.app.progress import DoneBefore, Progress
    from bench.app.resume import NothingToResumeError, done_in_file
    from bench.app.run import hold_campaign_file, run_campaign
    from bench.app.run_log import RunLog
    from bench.app.terminal import TerminalOperator
    from bench.config import ConfigError
    from bench.locks import InUseError
    from sequences import SequenceError

    try:
        bench_config = Path(args.bench) if args.bench else None
        plan = plan_campaign(Path(args.sequence), bench_config, realtime=args.realtime, metadata=args.meta)
        answers = load_answers(Path(args.answers), plan.sequence) if args.answers else None
    except (SequenceError, ConfigError, AnswersError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_INVALID
    except PlanRefusedError as exc:
        print(f"refused by the dry run:\n{exc}", file=sys.stderr)
        return EXIT_REFUSED
    log_path = _log_beside(Path(args.out))
    log_existed = log_path.exists()
    logged_before = log_path.stat().st_size if log_existed else 0
    opened: list = []  # the engine, once the devices are open: from then on the log is the run's
    try:
        with hold_campaign_file(Path(args.out)):  # before the file is read: one writer per file
            done_before = done_in_file(plan, Path(args.out)) if args.resume else DoneBefore()
            progress = Progress(sys.stdout, done_before=done_before)
            with RunInterrupts() as interrupts:
                # at real devices without an answers file, the person at the terminal answers
                asked = answers is None and not plan.config.simulated
                outcome = run_campaign(
                    plan,
                    Path(args.out),
                    resume=args.resume,
                    operator=TerminalOperator(read=interrupts.interruptible(input)) if asked else None,
                    answers=answers,
                    subscribers=(RunLog(progress.line), progress),
                    on_engine=lambda engine: (opened.append(engine), interrupts.attach(engine)),
                )
    except NothingToResumeError as exc:  # nothing opened, asked or moved: the campaign is complete
        print(exc)
        return EXIT_COMPLETE
    except (InUseError, DeviceUnreachableError, ValueError) as exc:
        # a file or device held by another process, a device unreachable: a link problem; else invalid
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_LINK if isinstance(exc, InUseError | DeviceUnreachableError) else EXIT_INVALID
    finally:
        logging.shutdown()  # the log file closed: kept, or removed below
        if not opened and not log_existed:
            log_path.unlink(missing_ok=True)  # nothing ran: the error above says it all, no file left
        elif log_path.exists() and log_path.stat().st_size > logged_before:
            print(f"warnings of the links and libraries: {log_path}", file=sys.stderr)
    why = f": {outcome.reason}" if outcome.reason else ""
    print(f"{plan.sequence.name}: {outcome.status}{why}; file {args.out}")
    return EXIT_COMPLETE if outcome.status == "complete" else EXIT_STOPPED


def _log_beside(out: Path) -> Path:
    """Send log records (the drivers' warnings, pymodbus's raw frames and retries) to ``out.log``
    instead of the terminal, where they would cut into the status line; the file is created only
    when there is a warning to write."""
    path = out.with_name(out.name + ".log")
    handler = logging.FileHandler(path, delay=True)
    handler.setFormatter(logging.Formatter("%(asctime)s %(name)s %(levelname)s: %(message)s"))
    logging.basicConfig(level=logging.WARNING, handlers=[handler], force=True)
    return path


def _tui(args: argparse.Namespace) -> int:
    """The technician's terminal UI; the log goes to a file beside the campaign file, not the screen."""
    from bench.tui.app import WfsBenchApp

    out = Path(args.out or time.strftime("campaign-%Y%m%d-%H%M%S.h5"))
    logging.basicConfig(
        filename=f"{out}.log", level=logging.INFO, format="%(asctime)s %(name)s: %(message)s", force=True
    )
    WfsBenchApp(Path(args.bench) if args.bench else None, out).run()
    return 0


def _check(args: argparse.Namespace) -> int:
    from bench.app.check import check_lines
    from bench.config import ConfigError, load_bench_config
    from bench.dry_run import dry_run
    from bench.replay_drive import load_drives
    from sequences import SequenceError, load_sequence

    try:
        config = load_bench_config(Path(args.bench) if args.bench else None)
        sequence = load_sequence(Path(args.sequence), config.limits, config.channels)
        drives = load_drives(sequence)
    except (SequenceError, ConfigError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_INVALID
    dry = dry_run(sequence, config, drives)
    for line in check_lines(sequence, config, dry):
        print(line)
    return EXIT_REFUSED if dry.refusals else EXIT_COMPLETE


def _import_csv(args: argparse.Namespace) -> int:
    from bench.app.version import software_version
    from bench.config import ConfigError, default_bench_config, load_bench_config
    from bench.locks import InUseError
    from bench.store import StoreError
    from bench.store.csv_import import ImportLimits, import_campaign, import_summary
    from bench.store.csv_mapping import MappingError, load_mapping
    from bench.store.csv_read import CsvError
    from sequences import SequenceError
    from sequences.limits import TYRE_PRESSURE_RANGE_BAR
    from sequences.metadata import merged

    try:
        mapping = load_mapping(Path(args.mapping))
        config = load_bench_config(Path(args.bench)) if args.bench else default_bench_config(mapping.bench)
        if config.kind != mapping.bench:
            raise ConfigError(
                [f"{args.bench}: kind: a {config.kind} bench; the mapping's source.bench: {mapping.bench}"]
            )
        config_text = Path(args.bench).read_text() if args.bench else config.to_toml()
        limits = ImportLimits(config.limits.min_freq_hz, config.limits.max_freq_hz, *TYRE_PRESSURE_RANGE_BAR)
        out, version = Path(args.out), software_version()
        runs = import_campaign(
            mapping,
            out,
            limits=limits,
            config_toml=config_text,
            software_version=version,
            metadata=merged(config.metadata, args.meta),
        )
    except InUseError as exc:  # another process writes that file
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_LINK
    except (MappingError, CsvError, ConfigError, SequenceError, StoreError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_INVALID
    print(f"imported {'; '.join(map(import_summary, runs))}; file {args.out}")
    return EXIT_COMPLETE


def _demo(args: argparse.Namespace) -> int:
    from bench.demo import run_demo

    earlier = Path(args.out) / "campaign.h5"
    if earlier.exists():  # said before the minute of the demo, while Ctrl-C still keeps it
        print(
            f"replacing {earlier} and {earlier.with_name('report')}/ of an earlier demo: their runs and"
            " analyses are not kept (--out DIR writes elsewhere)",
            flush=True,
        )
    for line in run_demo(Path(args.out), seed=args.seed, metadata=args.meta):
        print(line)
    return 0


def _sim_serve(args: argparse.Namespace) -> int:
    import asyncio

    from simulators.serve import serve  # the CLI is a composition root: it may know the simulators

    asyncio.run(serve(args.host, args.port, paced=not args.fast, seed=args.seed, ready=_announce))
    return 0


def _announce(line: str) -> None:
    print(line, flush=True)


def _wfs_monitor(args: argparse.Namespace) -> int:
    """Live values and link counters, one line per ``--interval`` seconds of samples; with
    ``--duration``, ``duration / interval`` lines (rounded), so exactly that much of the stream. The
    intervals are counted in frames at the rate the device reports, not by the wall clock."""
    from bench import locks

    try:
        with locks.holding(locks.serial_key(args.port), f"the WFS port {args.port}"):
            return _monitor(args)
    except locks.InUseError as exc:  # one master per device: a run, or another monitor, has it
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_LINK


def _monitor(args: argparse.Namespace) -> int:
    import numpy as np

    from drivers.wfs_reader import WfsReader

    with WfsReader.serial(args.port, baudrate=args.baudrate) as reader:
        if not reader.wait_connected(5):
            print(f"error: cannot open the WFS port {args.port}: {reader.last_error}", file=sys.stderr)
            return EXIT_LINK
        print("identity:", ",".join(reader.identify()))
        frames_per_line = max(1, round(args.interval * reader.rate_hz()))
        lines = max(1, round(args.duration / args.interval)) if args.duration else None
        view = reader.subscribe(lossless=False, max_frames=10_000)  # a live view never slows the reader
        reader.start_stream()
        try:
            shown = 0
            pending = None  # frames read beyond the last line's, the next line's first
            while lines is None or shown < lines:
                have = 0 if pending is None else len(pending)
                if have < frames_per_line:
                    block = view.read_frames(frames_per_line - have, timeout_s=args.interval + 5)
                    pending = block.frames if pending is None else np.concatenate([pending, block.frames])
                # a line each interval of frames, whatever the blocks the port's reads made
                f, pending = pending[frames_per_line - 1], pending[frames_per_line:]
                c = reader.counters
                print(
                    f"sample {f['sample']:>9}  Fz {f['fz']:9.1f} N  z {f['aux0'] * 1000:7.3f} mm  "
                    f"F_plate {f['aux1']:9.1f} N  a_hub {f['aux2']:7.2f} m/s2  | ok {c.frames_ok} "
                    f"missing {c.frames_missing} crc {c.crc_rejects} reconnects {c.reconnects}",
                    flush=True,
                )
                shown += 1
        except KeyboardInterrupt:
            pass
        finally:
            view.close()
            reader.stop_stream()
    return 0


def _actuator_status(args: argparse.Namespace) -> int:
    import asyncio

    return asyncio.run(_read_actuator_status(args))


async def _read_actuator_status(args: argparse.Namespace) -> int:
    return await _holding_actuator(args, _print_actuator_status)


async def _holding_actuator(args: argparse.Namespace, act: Callable[[Any, Any], Awaitable[int]]) -> int:
    """``act(client, status)`` on the controller that ``args`` names, holding its lock (one master per
    device: a run that drives it is neither disturbed nor overruled), connected for it alone."""
    from bench import locks
    from drivers.actuator import ActuatorClient

    if args.serial:
        key, what = locks.serial_key(args.serial), f"the actuator controller's port {args.serial}"
        client = ActuatorClient.rtu(args.serial, baudrate=args.baudrate)
    else:
        key, what = locks.tcp_key(args.host, args.port), f"the actuator controller at {args.host}:{args.port}"
        client = ActuatorClient.tcp(args.host, args.port)
    try:
        with locks.holding(key, what):
            try:
                return await act(client, await client.connect())
            finally:
                await client.close()
    except (locks.InUseError, LinkError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_LINK


async def _print_actuator_status(_client: Any, status: Any) -> int:
    for name, value in vars(status).items():
        shown = f"{value:.6g}" if isinstance(value, float) else getattr(value, "name", value)
        print(f"{name:24} {shown}")
    return 0


def _actuator_reset(args: argparse.Namespace) -> int:
    import asyncio

    return asyncio.run(_holding_actuator(args, lambda client, status: _reset_actuator(args, client, status)))


async def _reset_actuator(args: argparse.Namespace, client: Any, status: Any) -> int:
    """Reset an interlocked or e-stopped controller once the operator confirms (``--yes``: without
    asking): it returns to hydraulics low, at rest. Anything else needs no reset (exit 0)."""
    import asyncio

    from drivers.register_map import ControllerState

    tripped = ", ".join(flag.name.lower() for flag in status.interlock) or "no interlock flag"
    if status.state not in (ControllerState.INTERLOCK, ControllerState.ESTOP):
        print(f"the controller is in {status.state.name} ({tripped}): nothing to reset")
        return EXIT_COMPLETE
    print(f"the controller is in {status.state.name} ({tripped})")
    if not args.yes:
        print("reset it (it returns to hydraulics low, at rest)? [y/N] ", end="", flush=True)
        if sys.stdin.readline().strip().lower() not in ("y", "yes"):
            print("not reset")
            return EXIT_STOPPED
    await client.reset_interlock()
    deadline = time.monotonic() + RESET_TIMEOUT_S
    while (status := await client.read_status()).state in (ControllerState.ESTOP, ControllerState.TAPERING):
        if time.monotonic() > deadline:  # an e-stop's reset tapers out first
            print(f"error: {status.state.name} {RESET_TIMEOUT_S:g} s after the reset", file=sys.stderr)
            return EXIT_STOPPED
        await asyncio.sleep(0.1)  # a poll of the controller's state, not a wait for a race
    print(f"reset: the controller is in {status.state.name}")
    return EXIT_COMPLETE if status.state is not ControllerState.INTERLOCK else EXIT_STOPPED


def _controller_address(parser: argparse.ArgumentParser) -> None:
    """The options that name the controller: Modbus TCP (--port, --host) or RTU (--serial)."""
    link = parser.add_mutually_exclusive_group(required=True)
    link.add_argument("--port", type=int, help="Modbus TCP port on --host")
    link.add_argument("--serial", metavar="DEV", help="Modbus RTU on this serial device or pty (8N1)")
    parser.add_argument("--host", default="127.0.0.1")
    parser.add_argument("--baudrate", type=int, default=115200, help="RTU baud rate")


class _Parser(argparse.ArgumentParser):
    """argparse with the documented exit code for a command line it cannot use: invalid input (3),
    not argparse's own 2, which ``wfsbench`` keeps for a device that could not be reached."""

    def error(self, message: str) -> NoReturn:
        self.print_usage(sys.stderr)
        self.exit(EXIT_INVALID, f"error: {message}\n")


class _Version(argparse.Action):
    """``--version``: the installed package's version (looked up only when asked: it costs imports)."""

    def __init__(self, option_strings: list[str], dest: str, **kwargs: object) -> None:
        super().__init__(option_strings, dest, nargs=0, help="print the version and exit")

    def __call__(self, parser: argparse.ArgumentParser, *args: object) -> None:
        from bench.app.version import software_version

        print(f"wfsbench {software_version()}")
        parser.exit(0)


def _add_demo(sub: argparse._SubParsersAction) -> None:
    demo = sub.add_parser(
        "demo",
        help="run the paper's whole campaign through the engine, simulated",
        description="Run the paper's whole campaign on the simulated benches into DIR/campaign.h5 and"
        " its report into DIR/report/. A campaign.h5 and report of an earlier demo in DIR are replaced"
        " (the command says so first): use another --out to keep them.",
    )
    demo.add_argument("--seed", type=int, default=1, help="noise seed of the simulated sensors")
    demo.add_argument(
        "--out",
        default="wfsbench-demo",
        metavar="DIR",
        help="directory for campaign.h5 and report/, replaced if there (default: %(default)s)",
    )
    add_meta_option(demo, "the simulated benches' configurations")
    demo.set_defaults(run=_demo)


def _add_device_commands(sub: argparse._SubParsersAction) -> None:
    """``sim serve``, ``wfs monitor`` and ``actuator status``: the devices, without a sequence."""
    sim = sub.add_parser("sim", help="simulated devices").add_subparsers(dest="action", required=True)
    serve = sim.add_parser(
        "serve",
        help="serve the simulated controller (TCP, RTU on a pty) and WFS (pty)",
        description="Serve the simulated shaker bench: the controller on Modbus TCP and on Modbus RTU"
        " over a pty, the WFS on a pty. The operator's actions are typed on standard input, one per"
        " line: remove_wheel, fit_wheel, set_tyre_pressure BAR, set_damper SETTING,"
        " strike_hammer [PEAK_N] (docs/cli.md).",
    )
    serve.add_argument("--host", default="127.0.0.1")
    serve.add_argument("--port", type=int, default=0, help="TCP port (0: any free port)")
    serve.add_argument("--seed", type=int, default=1)
    serve.add_argument("--fast", action="store_true", help="as fast as the reader drains, not real time")
    serve.set_defaults(run=_sim_serve)
    wfs = sub.add_parser("wfs", help="WFS acquisition").add_subparsers(dest="action", required=True)
    monitor = wfs.add_parser("monitor", help="show live values and link counters")
    monitor.add_argument("--port", required=True, help="serial device or pty path")
    monitor.add_argument("--baudrate", type=int, default=921600)
    monitor.add_argument("--interval", type=float, default=1.0, help="seconds per line")
    monitor.add_argument("--duration", type=float, default=0.0, help="seconds (0: until Ctrl-C)")
    monitor.set_defaults(run=_wfs_monitor)
    act = sub.add_parser("actuator", help="actuator controller").add_subparsers(dest="action", required=True)
    status = act.add_parser("status", help="read the controller state (Modbus TCP, or RTU with --serial)")
    _controller_address(status)
    status.set_defaults(run=_actuator_status)
    reset = act.add_parser(
        "reset", help="reset an interlocked or e-stopped controller, once asked to (--yes: without asking)"
    )
    _controller_address(reset)
    reset.add_argument("--yes", action="store_true", help="reset without asking")
    reset.set_defaults(run=_actuator_reset)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="wfsbench",
        description="The wfsbench command line: run and check test sequences on a wheel force sensor"
        " bench, analyse and report campaign files, serve and talk to the (simulated) devices."
        " Each command has its own --help; docs/cli.md describes them all.",
    )
    parser.add_argument("--version", action=_Version)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    _add_demo(sub)
    run = sub.add_parser("run", help="run a sequence file on the bench into a campaign file")
    run.add_argument("sequence", help="sequence file (TOML, docs/sequences.md)")
    run.add_argument("--out", required=True, help="campaign file (HDF5, docs/hdf5.md)")
    run.add_argument("--bench", help="bench configuration (TOML); default: the simulated shaker bench")
    run.add_argument("--resume", action="store_true", help="continue an interrupted campaign file")
    run.add_argument(
        "--answers", metavar="FILE", help="answers to the prompts by id (TOML, docs/cli.md): unattended run"
    )
    run.add_argument("--realtime", action="store_true", help="pace the simulated bench in real time")
    add_meta_option(run, "the configuration and the sequence")
    run.set_defaults(run=_run)
    check = sub.add_parser("check", help="validate and dry-run a sequence on the bench; nothing moves")
    check.add_argument("sequence", help="sequence file (TOML, docs/sequences.md)")
    check.add_argument("--bench", help="bench configuration (TOML); default: the simulated shaker bench")
    check.set_defaults(run=_check)
    imp = sub.add_parser("import-csv", help="bring CSV exports of another system into a campaign file")
    imp.add_argument("mapping", help="mapping file (TOML, docs/import.md): columns, units, what each file is")
    imp.add_argument("--out", required=True, help="new campaign file (HDF5, docs/hdf5.md)")
    imp.add_argument(
        "--bench",
        help="bench configuration recorded with the campaign (default: the mapping's bench kind)",
    )
    add_meta_option(imp, "the configuration")
    imp.set_defaults(run=_import_csv)
    tui = sub.add_parser("tui", help="the technician's terminal UI (docs/tui.md)")
    tui.add_argument("--bench", help="bench configuration (TOML); default: the simulated shaker bench")
    tui.add_argument("--out", help="campaign file (HDF5); default: campaign-<date>-<time>.h5 here")
    tui.set_defaults(run=_tui)
    _add_device_commands(sub)
    add_analysis_commands(sub)
    add_export_command(sub)
    add_compensate_command(sub)
    add_archive_commands(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.run(args)
    except LinkError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_LINK
    except LockDirError as exc:  # the environment names no usable lock directory: nothing opened
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_INVALID
    except KeyboardInterrupt:  # Ctrl-C before a command took it over (a run: before the devices opened)
        print("interrupted: nothing moved", file=sys.stderr)
        return EXIT_STOPPED
    except BrokenPipeError:  # the reader of a pipe went away (| head): stop writing, quietly
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # the exit's flush goes nowhere
        return EXIT_COMPLETE


if __name__ == "__main__":
    sys.exit(main())
