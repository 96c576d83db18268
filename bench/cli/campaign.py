"""The commands that run a campaign: ``demo``, ``run``, ``check``, ``import-csv`` and ``tui``."""

from __future__ import annotations

import argparse
import contextlib
import logging
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from bench.cli.exit_codes import ExitCode
from bench.cli.metadata import add_meta_option
from bench.cli.monitor import add_monitor_options

if TYPE_CHECKING:
    from bench.app.library_log import LibraryLog
    from bench.app.plan import CampaignPlan
    from bench.app.run import CampaignOutcome
    from bench.engine.engine import Engine
    from bench.monitor.feed import BenchMonitor


def _run(args: argparse.Namespace) -> int:
    from bench.app.answers import AnswersError, load_answers
    from bench.app.devices import DeviceUnreachableError
    from bench.app.library_log import library_log, log_beside
    from bench.app.plan import PlanRefusedError, plan_campaign
    from bench.app.resume import NothingToResumeError
    from bench.cli.monitor import monitor_listen, start_bench_monitor
    from bench.config import ConfigError
    from bench.locks import InUseError
    from bench.monitor.listen import MonitorSettingsError, MonitorUnavailableError
    from sequences import SequenceError

    try:
        listen = monitor_listen(args, args.monitor, "--monitor")
        bench_config = Path(args.bench) if args.bench else None
        plan = plan_campaign(Path(args.sequence), bench_config, realtime=args.realtime, metadata=args.meta)
        answers = load_answers(Path(args.answers), plan.sequence) if args.answers else None
    except (SequenceError, ConfigError, AnswersError, OSError, MonitorSettingsError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return ExitCode.INVALID
    except PlanRefusedError as exc:
        print(f"refused by the dry run:\n{exc}", file=sys.stderr)
        return ExitCode.REFUSED
    log_path = log_beside(Path(args.out))
    log_existed = log_path.exists()
    opened: list = []  # the engine, once the devices are open: from then on the log is the run's
    with library_log(log_path) as log, contextlib.ExitStack() as stack:
        try:
            monitor = stack.enter_context(start_bench_monitor(listen)) if listen is not None else None
            outcome = _run_plan(args, plan, answers, opened, monitor)
        except NothingToResumeError as exc:  # nothing opened, asked or moved: the campaign is complete
            print(exc)
            return ExitCode.OK
        except (InUseError, DeviceUnreachableError, MonitorUnavailableError, ValueError) as exc:
            # a file or device held by another process, a device unreachable, the monitor's address
            # taken: unavailable; else invalid
            print(f"error: {exc}", file=sys.stderr)
            held = isinstance(exc, InUseError | DeviceUnreachableError | MonitorUnavailableError)
            return ExitCode.UNAVAILABLE if held else ExitCode.INVALID
        finally:
            _said_of(log, kept=bool(opened) or log_existed)
    return _ended(plan.sequence.name, outcome, args.out)


def _ended(name: str, outcome: CampaignOutcome, out: str) -> ExitCode:
    """How the sequence ended, and each run whose analysis did not give all it is for."""
    why = f": {outcome.reason}" if outcome.reason else ""
    print(f"{name}: {outcome.status}{why}; file {out}")
    if outcome.status != "complete":
        return ExitCode.STOPPED
    incomplete = [a for a in outcome.analyses if not a.complete]
    for analysis in incomplete:  # the sequence ran, but not every run gave what it is for
        print(f"analysis of run {analysis.run_id} {analysis.status}: {analysis.why}")
    return ExitCode.INCOMPLETE if incomplete else ExitCode.OK


def _run_plan(
    args: argparse.Namespace,
    plan: CampaignPlan,
    answers: dict[str, float | str | bool] | None,
    opened: list,
    monitor: BenchMonitor | None,
) -> CampaignOutcome:
    """Run the plan into ``args.out``, holding the file, with the progress on standard output and the
    signals taken over; the engine goes into ``opened`` once the devices are open, and to the web
    ``monitor`` (if any)."""
    from bench.app.interrupts import RunInterrupts
    from bench.app.pace import DoneBefore
    from bench.app.progress import Progress
    from bench.app.resume import done_in_file
    from bench.app.run import hold_campaign_file, run_campaign
    from bench.app.run_log import RunLog
    from bench.app.terminal import TerminalOperator

    with hold_campaign_file(Path(args.out)):  # before the file is read: one writer per file
        done_before = done_in_file(plan, Path(args.out)) if args.resume else DoneBefore()
        with Progress(sys.stdout, done_before=done_before) as progress, RunInterrupts() as interrupts:
            # at real devices without an answers file, the person at the terminal answers
            asked = answers is None and not plan.config.simulated

            def on_engine(engine: Engine) -> None:
                opened.append(engine)
                interrupts.attach(engine)
                if monitor is not None:
                    monitor.feed.attach(engine, plan.config)
                    monitor.feed.launched(done_before)

            return run_campaign(
                plan,
                Path(args.out),
                resume=args.resume,
                operator=TerminalOperator(read=interrupts.interruptible(input)) if asked else None,
                answers=answers,
                subscribers=(RunLog(progress.line), progress),
                on_engine=on_engine,
            )


def _said_of(log: LibraryLog, *, kept: bool) -> None:
    """Where the links' and libraries' warnings went; the log of a command that opened nothing is
    removed (the error printed says it all)."""
    if not kept:
        log.path.unlink(missing_ok=True)
    elif log.written:
        print(f"warnings of the links and libraries: {log.path}", file=sys.stderr)


def _tui(args: argparse.Namespace) -> int:
    """The technician's terminal UI; the log goes to a file beside the campaign file, not the screen."""
    from bench.cli.monitor import monitor_listen, start_bench_monitor
    from bench.monitor.listen import MonitorSettingsError, MonitorUnavailableError
    from bench.tui.app import WfsBenchApp

    try:
        listen = monitor_listen(args, args.monitor, "--monitor")
    except MonitorSettingsError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return ExitCode.INVALID
    out = Path(args.out or time.strftime("campaign-%Y%m%d-%H%M%S.h5"))
    logging.basicConfig(
        filename=f"{out}.log", level=logging.INFO, format="%(asctime)s %(name)s: %(message)s", force=True
    )
    with contextlib.ExitStack() as stack:
        try:
            monitor = stack.enter_context(start_bench_monitor(listen)) if listen is not None else None
        except MonitorUnavailableError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return ExitCode.UNAVAILABLE
        feed, url = (monitor.feed, monitor.server.url) if monitor is not None else (None, None)
        if url is not None:
            logging.getLogger("bench.tui.run").info("web monitor: %s (read-only)", url)
        WfsBenchApp(Path(args.bench) if args.bench else None, out, feed, url).run()
    return ExitCode.OK


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
        return ExitCode.INVALID
    dry = dry_run(sequence, config, drives)
    for line in check_lines(sequence, config, dry):
        print(line)
    return ExitCode.REFUSED if dry.refusals else ExitCode.OK


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
        return ExitCode.UNAVAILABLE
    except (MappingError, CsvError, ConfigError, SequenceError, StoreError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return ExitCode.INVALID
    print(f"imported {'; '.join(map(import_summary, runs))}; file {args.out}")
    return ExitCode.OK


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
    return ExitCode.OK


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



def add_campaign_commands(sub: argparse._SubParsersAction) -> None:
    """Add ``demo``, ``run``, ``check``, ``import-csv`` and ``tui`` to the ``wfsbench`` subcommands."""
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
    add_monitor_options(run)
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
    add_monitor_options(tui)
    tui.set_defaults(run=_tui)
