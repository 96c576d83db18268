"""``wfsbench compensate``: a measurement's WFS force compensated to the contact force with what a
campaign identified (docs/compensate.md); or many measurements, folders of them, as one job into an
output folder (docs/compensate.md, *Many measurements*).

Exit codes of one measurement (:mod:`bench.cli.exit_codes`):

- OK: compensated, the output (and the filters) written;
- UNAVAILABLE: a process is writing the campaign file (or a campaign-file measurement);
- INVALID: an input cannot be used: the campaign file is no campaign file, the measurement or its mapping
  cannot be read, the output exists, the options contradict each other or the measurement (a
  bandwidth above half its rate); nothing was written;
- REFUSED: the campaign does not cover the measurement (no identification at its tyre pressure,
  a sample rate the filters cannot serve, a channel the measurement lacks); the message names what
  is missing; nothing was written.

Exit codes of a job (several measurements, a folder, or ``--scheduler`` / ``--workers``): OK, the
summary is written (every file not compensated listed in it with its error, and printed);
UNAVAILABLE, the scheduler could not be reached or another job writes into the output folder;
INVALID, a path that does not exist, a campaign file that is no campaign, an output folder that
cannot be used, or options of one measurement only.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from bench.cli.analysis import add_reanalyse_option
from bench.cli.exit_codes import ExitCode, unreadable_file_code
from bench.cli.job_options import add_job_options


class _StopError(Exception):
    """The command ends early with ``code`` and ``message`` (on standard error)."""

    def __init__(self, code: int, message: str) -> None:
        super().__init__(message)
        self.code = code


def _measurement(args: argparse.Namespace):
    """The measurement, with what the command line states of its chain, and its tyre pressure (the
    option's, else the one its source records)."""
    from bench.store import StoreError
    from bench.store.csv_mapping import MappingError, load_channel_mapping
    from bench.store.measurement import (
        MeasurementError,
        MissingChannelError,
        NotOnTheTyreError,
        read_measurement,
    )

    try:
        mapping = load_channel_mapping(args.mapping) if args.mapping else None
        measurement = read_measurement(args.measurement[0], run_id=args.run_id, mapping=mapping)
    except (MissingChannelError, NotOnTheTyreError) as exc:
        raise _StopError(ExitCode.REFUSED, f"refused: {exc}") from None
    except (MappingError, MeasurementError, StoreError) as exc:
        raise _StopError(unreadable_file_code(exc), f"error: {exc}") from None
    measurement = _with_stated_chain(measurement, args)
    recorded = measurement.tyre_pressure_bar
    if args.pressure is None:
        return measurement, recorded
    if recorded is not None and abs(recorded - args.pressure) > 1e-9:
        raise _StopError(
            ExitCode.INVALID,
            f"error: --pressure {args.pressure:g} bar contradicts the {recorded:g} bar that"
            f" {measurement.source} records",
        )
    return measurement, args.pressure


def _with_stated_chain(measurement, args: argparse.Namespace):
    """The measurement with the chain the command line states beside the one its mapping states
    (both may state a value only when they agree)."""
    from bench.app.compensate import with_stated_chain

    try:
        return with_stated_chain(measurement, args.hub_lag_ms, args.bandwidth_hz)
    except ValueError as exc:
        raise _StopError(ExitCode.INVALID, f"error: {exc}") from None


def _compensation(args: argparse.Namespace):
    """The compensation of the measurement with the campaign's analysis (refused: what is missing),
    and where that analysis came from (:attr:`~bench.analysis.campaign.CampaignAnalysis.source`)."""
    from bench.app.analyze import CampaignFileError, analyze_campaign
    from bench.app.compensate import prepare_compensation
    from bench.app.compensation_assumptions import CompensationRefusedError, MeasurementChainError
    from bench.store import StoreError

    out = Path(args.out)
    if out.exists():
        raise _StopError(
            ExitCode.INVALID, f"error: {out}: exists; the output is never replaced (choose another --out)"
        )
    if args.filters:
        _check_filters_path(Path(args.filters))
    measurement, pressure = _measurement(args)
    try:
        analysis = analyze_campaign(Path(args.campaign), reanalyse=args.reanalyse)
    except (StoreError, CampaignFileError) as exc:
        raise _StopError(unreadable_file_code(exc), f"error: {exc}") from None
    try:
        return prepare_compensation(analysis, measurement, pressure), analysis.source
    except CompensationRefusedError as exc:
        raise _StopError(ExitCode.REFUSED, f"refused: {exc}") from None
    except MeasurementChainError as exc:
        raise _StopError(ExitCode.INVALID, f"error: {exc}") from None


def _check_filters_path(filters: Path) -> None:
    """The filters' file is checked before anything is computed or written, as ``--out`` is: a
    .json or .csv file in a folder that exists, never over a file."""
    if filters.suffix.lower() not in (".json", ".csv"):
        raise _StopError(ExitCode.INVALID, f"error: --filters {filters}: give a .json or .csv file")
    if filters.exists():
        said = f"error: --filters {filters}: exists; it is never replaced (choose another name)"
        raise _StopError(ExitCode.INVALID, said)
    if not filters.parent.is_dir():
        raise _StopError(ExitCode.INVALID, f"error: --filters {filters}: no folder {filters.parent}")


def _is_job(args: argparse.Namespace) -> bool:
    """Whether the command line asks for a job over many measurements: several, a folder, a cluster,
    or an output that is a folder."""
    return (
        len(args.measurement) > 1
        or any(Path(m).is_dir() for m in args.measurement)
        or args.scheduler is not None
        or args.workers is not None
        or Path(args.out).is_dir()
    )


def _compensate(args: argparse.Namespace) -> int:
    if _is_job(args):
        from bench.cli.compensate_job import run_job

        return run_job(args)
    return _compensate_one(args)


def _compensate_one(args: argparse.Namespace) -> int:
    from bench.app.compensate import write_output
    from bench.report.filters import write_filters
    from bench.store.compensated import OutputExistsError

    filters = Path(args.filters) if args.filters else None
    try:
        compensation, analysis_source = _compensation(args)
        if filters is not None:  # first: a folder that went away meanwhile stops it before the output
            write_filters(filters, compensation.filters, compensation.accelerometer_offset_m_s2)
        try:
            done = write_output(
                compensation, Path(args.out), campaign=Path(args.campaign), campaign_analysis=analysis_source
            )
        except BaseException:
            if filters is not None:
                filters.unlink(missing_ok=True)  # nothing of a failed compensation is left
            raise
    except _StopError as stop:
        print(stop, file=sys.stderr)
        return stop.code
    except (OutputExistsError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return ExitCode.INVALID
    if args.json:
        print(json.dumps(done.to_json(filters), indent=1))
        return ExitCode.OK
    for line in done.lines():
        print(line)
    if filters is not None:
        print(f"filters {filters}")
    print(f"compensated {args.out}")
    return ExitCode.OK


def _pressure_bar(text: str) -> float:
    """A tyre pressure given on the command line: a positive, finite number of bar ("nan", "inf",
    0 and below are refused: a pressure no identification is made at)."""
    value = float(text)  # argparse names the option for a ValueError
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"a tyre pressure must be a positive number of bar, got {text!r}")
    return value


def _hub_lag_ms(text: str) -> float | str:
    """A hub accelerometer lag given on the command line (:func:`bench.store.measurement_chain.
    hub_lag_ms`: a number of ms, 0 or more, or ``campaign``)."""
    from bench.store.measurement_chain import from_text, hub_lag_ms

    try:
        return hub_lag_ms(from_text(text))
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _bandwidth_hz(text: str) -> float:
    """A logger bandwidth given on the command line: a number of Hz above 0."""
    from bench.store.measurement_chain import bandwidth_hz, from_text

    try:
        return bandwidth_hz(from_text(text))
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_compensate_command(sub: argparse._SubParsersAction) -> None:
    """Add ``compensate`` to the ``wfsbench`` subcommands."""
    cmd = sub.add_parser(
        "compensate",
        help="compensate a measurement's WFS force with what a campaign identified (docs/compensate.md)",
        description="Compensate the WFS Fz of a measurement (MDF4, CSV or a campaign file's run) to the"
        " contact force with the tyre, wheel mass and sensor a campaign identified, with a 95 % band per"
        " sample; write it to an HDF5 file. A measurement the campaign does not cover (its tyre pressure,"
        " its sample rate, a channel) is refused, naming what is missing. Exit codes: 0 done, 3 an input"
        " cannot be used, 4 refused. Given several measurements or folders of them (MDF4 and CSV), or"
        " --scheduler / --workers, compensate them as one job into the folder --out: one output per"
        " measurement (HDF5 and MDF4), a Parquet summary of every file, unchanged files not read again,"
        " on a local Dask cluster or the cluster of --scheduler (exit codes: 0 done, 2 the scheduler or"
        " the folder is unavailable, 3 an input cannot be used).",
    )
    cmd.add_argument("campaign", help="campaign file (HDF5) whose analysis gives the compensation")
    cmd.add_argument(
        "measurement",
        nargs="+",
        metavar="MEASUREMENT",
        help="the measurement: MDF4 (.mf4, .mdf), CSV (.csv) or a campaign file (.h5) with --run; or"
        " several, or folders of MDF4 and CSV measurements (searched recursively): a job",
    )
    cmd.add_argument(
        "--out",
        required=True,
        help="output file (HDF5, docs/compensate.md), never replaced; of a job: its output folder",
    )
    add_job_options(
        cmd,
        scheduler_help="a job on this dask.distributed scheduler (tcp://host:8786)",
        workers_help="a job on a local cluster of N processes (default: the machine's cores); 0: in this"
        " process",
    )
    cmd.add_argument("--run", dest="run_id", metavar="ID", help="the run of a campaign-file measurement")
    cmd.add_argument(
        "--pressure",
        type=_pressure_bar,
        metavar="BAR",
        help="the measurement's tyre pressure (a campaign file's run records its own)",
    )
    cmd.add_argument(
        "--mapping",
        metavar="FILE",
        help="TOML: which column or MDF channel is fz_wfs_n and a_hub_m_s2, units, CSV dialect and time"
        " (the import's csv, time and channels tables, docs/import.md)",
    )
    cmd.add_argument(
        "--hub-lag-ms",
        type=_hub_lag_ms,
        metavar="MS|campaign",
        help="the lag of the measurement's hub accelerometer (ms), or 'campaign': the accelerometer the"
        " campaign's four-post run measured; not stated: 0 (or the campaign's for a run of the campaign"
        " file itself), said so",
    )
    cmd.add_argument(
        "--bandwidth-hz",
        type=_bandwidth_hz,
        metavar="HZ",
        help="the frequency up to which the measurement's logger passes Fz and the hub acceleration"
        " unchanged (its anti-alias filter): the valid band ends there",
    )
    cmd.add_argument(
        "--json", action="store_true", help="print what was done as JSON (docs/compensate.md) instead of text"
    )
    cmd.add_argument(
        "--filters",
        metavar="FILE",
        help="also export the filters for a real-time DSP (.json or .csv): taps, latency, rate, band",
    )
    add_reanalyse_option(cmd)
    cmd.set_defaults(run=_compensate)
