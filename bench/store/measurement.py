"""A measurement to compensate, read from an MDF4 file, a CSV file or a campaign file's run: the WFS
Fz and the hub acceleration in SI units at one sample rate (docs/compensate.md).

- **MDF4** (``.mf4``, ``.mdf``, ``.mdf4``; read with asammdf): the channels named by the mapping's
  ``channels`` table (``column`` is the MDF channel's name), by default ``fz_wfs_n`` and
  ``a_hub_m_s2``; the unit is the mapping's, else the channel's own (``kN``, ``g``, ...), which
  must be one of the quantity's (docs/import.md's units); both channels on one time base.
- **CSV**: the import's conventions (docs/import.md): the mapping's ``csv``, ``time`` and
  ``channels`` tables; without a mapping, a comma-separated file whose header names the channels
  and a time column ``t_s`` (or ``time_s``) in seconds, with a units row under it or none: a CSV
  file ``wfsbench export --format csv`` wrote is read as it is.
- **A campaign file's run** (``.h5``, with ``run_id``): the run's Fz and hub acceleration by their
  roles, and the tyre pressure its conditions record.

What the measurement states of its own chain (its hub accelerometer's lag, its logger's bandwidth)
comes with it: the mapping's ``measurement`` table (:mod:`bench.store.measurement_chain`).

A file that lacks a channel is refused naming the channel and what the file has.

An MDF4 or CSV file is read front to back once, block by block, into channels kept on disk
(:mod:`bench.store.spool`); what follows reads them by slice, so the memory a measurement takes
does not grow with its length (a campaign file's run, a bench run, is read whole).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from bench.analysis.blockwise import Record, blocks
from bench.analysis.records import HUB_ACCELERATION, WFS_FORCE
from bench.store.channel_file import MDF_SUFFIXES, ChannelFileError, csv_header
from bench.store.csv_mapping import ChannelColumn, ChannelMapping, Dialect, Timing
from bench.store.csv_read import LARGEST_SI_VALUE, TIME_STEP_TOLERANCE, CsvError, read_csv
from bench.store.csv_units import UNITS, channel_si_unit, known_units, unit_named
from bench.store.measurement_chain import MeasurementChain
from bench.store.reader import open_campaign
from bench.store.spool import SpooledChannel
from sequences.runs import RunKind

#: Bytes of an MDF file asammdf reads at a time (its fragments): a few blocks of samples.
MDF_FRAGMENT_BYTES = 4 << 20
#: The channels a compensation reads.
MEASUREMENT_CHANNELS = (WFS_FORCE, HUB_ACCELERATION)
#: The time columns a CSV measurement read without a mapping may have, in s: the first the header
#: names is the time (``time_s``: as ``wfsbench export --format csv`` writes it).
DEFAULT_TIME_COLUMNS = ("t_s", "time_s")
#: What an error on a CSV read without a mapping adds: what such a file must be, and the way out.
_WITHOUT_MAPPING = (
    f" (read without --mapping: a comma-separated file whose header names a time column"
    f" {' or '.join(map(repr, DEFAULT_TIME_COLUMNS))} in s and the columns"
    f" {', '.join(map(repr, MEASUREMENT_CHANNELS))}, a units row under it or none;"
    " --mapping names the file's own columns, units and layout: docs/import.md)"
)
CAMPAIGN_SUFFIXES = (".h5", ".hdf5")


class MeasurementError(ValueError):
    """A measurement that cannot be read: the message names the file and what is wrong."""


class MissingChannelError(MeasurementError):
    """The measurement lacks a channel the compensation needs: the message names it and what the
    file has."""


class NotOnTheTyreError(MeasurementError):
    """The measurement was recorded without a tyre on the sensor (a free run): refused like a
    measurement the campaign does not cover."""


@dataclass(frozen=True)
class Measurement:
    """``channels`` (``fz_wfs_n`` in N, ``a_hub_m_s2`` in m/s^2) at ``sample_rate_hz`` from
    ``source`` (the file, and the run): arrays, or channels kept on disk read by slice
    (:class:`~bench.analysis.blockwise.Record`); ``tyre_pressure_bar`` when the source records it;
    ``start_s``: the time of the first sample in the source's own time (a CSV's time column, an MDF
    file's time stamps; 0 where the source has none), so that a part cut from a longer record keeps
    its place in it; ``chain``: what the source states of its hub accelerometer and logger;
    ``campaign_file``: the campaign file the measurement is a run of (None: another source)."""

    source: str
    sample_rate_hz: float
    channels: dict[str, Record]
    tyre_pressure_bar: float | None = None
    start_s: float = 0.0
    chain: MeasurementChain = field(default_factory=MeasurementChain)
    campaign_file: Path | None = None

    @property
    def n_samples(self) -> int:
        return self.channels[WFS_FORCE].size


def _default_columns() -> tuple[ChannelColumn, ...]:
    """The channels under their own names, in their SI units."""
    columns = []
    for name in MEASUREMENT_CHANNELS:
        si_unit = channel_si_unit(name) or ""
        columns.append(ChannelColumn(name, si_unit, name, si_unit))
    return tuple(columns)


def _wanted(mapping: ChannelMapping | None, path: Path) -> tuple[ChannelColumn, ...]:
    """The mapping's columns of the measurement's channels (the defaults without a mapping); a
    mapping that names neither is refused."""
    if mapping is None:
        return _default_columns()
    columns = tuple(c for c in mapping.channels if c.channel in MEASUREMENT_CHANNELS)
    missing = [name for name in MEASUREMENT_CHANNELS if name not in {c.channel for c in columns}]
    if missing:
        raise MissingChannelError(
            f"{mapping.path}: channels: no column mapped to {', '.join(missing)}, which a compensation"
            f" of {path.name} needs"
        )
    return columns


def read_measurement(
    path: str | Path, *, run_id: str | None = None, mapping: ChannelMapping | None = None
) -> Measurement:
    """The measurement at ``path``: an MDF4 file, a CSV file, or ``run_id`` of a campaign file (by
    the file's suffix)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix in CAMPAIGN_SUFFIXES:
        if mapping is not None:
            raise MeasurementError(f"{path}: a campaign file's channels have their roles: no --mapping")
        return _checked(_campaign_run(path, run_id))
    if run_id is not None:
        raise MeasurementError(f"{path}: --run names a run of a campaign file (.h5), not of a {suffix} file")
    chain = mapping.chain if mapping is not None else MeasurementChain()
    if suffix in MDF_SUFFIXES:
        return replace(_checked(_mdf(path, _wanted(mapping, path))), chain=chain)
    if suffix == ".csv":
        # the CSV reader refuses a value that is not a finite number
        return replace(_csv(path, mapping), chain=chain)
    raise MeasurementError(
        f"{path}: unknown measurement format {suffix!r}: MDF4 (.mf4, .mdf, .mdf4), CSV (.csv) or a campaign"
        " file's run (.h5 with --run)"
    )


def _checked(measurement: Measurement) -> Measurement:
    """``measurement``, refused when a channel holds a sample that is not a finite number (a gap,
    an overload marked NaN) or one beyond any measured value (:data:`LARGEST_SI_VALUE`: a damaged
    value, a wrong unit or scale): naming the channel, how many, and the first (read block by
    block)."""
    for name, x in measurement.channels.items():
        for test, what in (
            (lambda b: ~np.isfinite(b), "that are not finite numbers"),
            (lambda b: np.abs(b) > LARGEST_SI_VALUE, f"beyond +/-{LARGEST_SI_VALUE:g} (SI units)"),
        ):
            count, first = 0, None
            for start, block in blocks(x):
                bad = np.flatnonzero(test(block))
                if bad.size and first is None:
                    first = start + int(bad[0])
                count += bad.size
            if first is not None:
                t_s = measurement.start_s + first / measurement.sample_rate_hz
                raise MeasurementError(
                    f"{measurement.source}: {name} has {count} samples {what}, the first at sample"
                    f" {first} (t = {t_s:g} s): cut the measurement around them"
                )
    return measurement


def _campaign_run(path: Path, run_id: str | None) -> Measurement:
    with open_campaign(path) as campaign:
        runs = ", ".join(run.run_id for run in campaign.runs)
        if run_id is None:
            raise MeasurementError(f"{path}: which run? give --run (the file holds {runs})")
        if run_id not in {run.run_id for run in campaign.runs}:
            raise MeasurementError(f"{path}: no run {run_id!r} (the file holds {runs})")
        run = campaign.run(run_id)
        channels = run.channels.slice(0, run.n_samples)
        missing = [name for name in MEASUREMENT_CHANNELS if name not in channels]
        if missing:
            raise MissingChannelError(
                f"{path}: run {run_id}: no {', '.join(missing)} channel (it has {', '.join(channels)})"
            )
        if run.kind == RunKind.FREE_RUN or run.conditions.get("wheel_fitted") is False:
            raise NotOnTheTyreError(
                f"{path}: run {run_id} ({run.kind}) was recorded without the wheel on the bench: its WFS"
                " measured no tyre's contact force, there is nothing to compensate"
            )
        pressure = run.conditions.get("tyre_pressure_bar")
        return Measurement(
            f"{path} run {run_id}",
            run.sample_rate_hz,
            {name: np.asarray(channels[name], dtype=float) for name in MEASUREMENT_CHANNELS},
            float(pressure) if pressure is not None else None,
            campaign_file=path,
        )


def _csv(path: Path, mapping: ChannelMapping | None) -> Measurement:
    columns = _wanted(mapping, path)
    if mapping is None:
        try:
            header, units_row = csv_header(path)
        except ChannelFileError as exc:
            raise MeasurementError(str(exc)) from None
        time_column = next((name for name in DEFAULT_TIME_COLUMNS if name in header), DEFAULT_TIME_COLUMNS[0])
        dialect, timing = Dialect(units_row=units_row), Timing(column=time_column, unit="s")
    else:
        dialect, timing = mapping.dialect, mapping.timing
        if timing is None:
            raise MeasurementError(f"{mapping.path}: time: missing (a CSV measurement needs its sample rate)")
    hint = "" if mapping is not None else _WITHOUT_MAPPING
    try:
        table = read_csv(path, dialect, timing, columns, sink=_Spool)
    except CsvError as exc:
        raise MeasurementError(f"{exc}{hint}") from None
    for column in columns:
        if column.channel not in table.columns:
            raise MissingChannelError(
                str(table.missing(column, f": the compensation needs {column.channel}")) + hint
            )
    channels = {c.channel: table.columns[c.channel] for c in columns}
    return Measurement(str(path), table.sample_rate_hz, channels, start_s=table.start_s)


class _Spool:
    """The CSV reader's columns kept on disk (:class:`SpooledChannel`)."""

    def __init__(self) -> None:
        self._columns: dict[str, SpooledChannel] = {}

    def add(self, channel: str, values: np.ndarray) -> None:
        self._columns.setdefault(channel, SpooledChannel()).append(values)

    def column(self, channel: str) -> SpooledChannel:
        return self._columns[channel]


def _mdf(path: Path, columns: tuple[ChannelColumn, ...]) -> Measurement:
    """The MDF file's channels, read fragment by fragment (:data:`MDF_FRAGMENT_BYTES`) into
    spooled channels in SI units, their time stamps checked to be one time base of one rate."""
    from asammdf import MDF  # only here: it takes a second to import

    try:
        mdf = MDF(path)
    except Exception as exc:  # asammdf raises many kinds for a file it cannot read
        raise MeasurementError(f"{path}: not a readable MDF file: {exc}") from None
    with mdf:
        mdf.configure(read_fragment_size=MDF_FRAGMENT_BYTES)
        names = sorted(name for name in mdf.channels_db if not name.startswith("$"))
        for column in columns:
            if column.column not in mdf.channels_db:
                raise MissingChannelError(
                    f"{path}: no channel {column.column!r} for {column.channel} (the file has"
                    f" {', '.join(names)})"
                )
            if len(mdf.channels_db[column.column]) > 1:
                raise MeasurementError(
                    f"{path}: channel {column.column!r} is in {len(mdf.channels_db[column.column])}"
                    " groups: which one is the measurement's is ambiguous (a file of one measurement"
                    " is needed; of a campaign's MDF4 export: `wfsbench export --run ID` writes one run)"
                )
        try:
            return _mdf_spooled(path, mdf, columns)
        except MeasurementError:
            raise
        except Exception as exc:  # a data block asammdf cannot decode: a damaged file
            raise MeasurementError(f"{path}: its samples cannot be read: {exc}") from None


def _mdf_spooled(path: Path, mdf, columns: tuple[ChannelColumn, ...]) -> Measurement:
    """The channels of ``columns`` of the open ``mdf``, fragment by fragment, spooled in SI units."""
    time_s, spooled, factors = SpooledChannel(), {c.channel: SpooledChannel() for c in columns}, {}
    fragments = zip(*(mdf.iter_get(c.column) for c in columns), strict=True)
    for signals in fragments:
        stamps = signals[0].timestamps
        for column, signal in zip(columns, signals, strict=True):
            if signal.timestamps.size != stamps.size or not np.allclose(
                signal.timestamps, stamps, rtol=0, atol=1e-9
            ):
                raise MeasurementError(
                    f"{path}: {' and '.join(c.column for c in columns)} are not on one time base"
                    " (resample them to one rate first)"
                )
            if column.channel not in factors:
                factors[column.channel] = _factor(path, column, signal.unit) * column.scale
            spooled[column.channel].append(np.asarray(signal.samples, dtype=float) * factors[column.channel])
        time_s.append(stamps)
    rate = _rate(path, time_s)
    start_s = float(time_s[0:1][0])
    time_s.close()
    return Measurement(str(path), rate, dict(spooled), start_s=start_s)


def _rate(path: Path, t: SpooledChannel) -> float:
    """The sample rate of the time stamps ``t``, which must step evenly (read block by block)."""
    if t.size < 2:
        raise MeasurementError(f"{path}: fewer than two samples")
    step = (t[t.size - 1 : t.size][0] - t[0:1][0]) / (t.size - 1)
    uneven = step <= 0
    for start, block in blocks(t):
        steps = np.diff(np.concatenate([t[start - 1 : start], block]))
        uneven = uneven or bool(np.any(np.abs(steps - step) > TIME_STEP_TOLERANCE * step))
    if uneven:
        raise MeasurementError(
            f"{path}: the time stamps step unevenly (mean step {step:g} s): not one sample rate"
        )
    return 1.0 / step


def _factor(path: Path, column: ChannelColumn, stated: str) -> float:
    """The factor from the channel's unit (the mapping's, else the MDF channel's own) to SI."""
    unit = column.unit
    known = unit_named(stated) if stated.strip() else None
    if unit is None:
        if known is None:
            raise MeasurementError(
                f"{path}: channel {column.column!r}: unit {stated!r} is not one of {known_units()}"
                " (give the unit in the mapping)"
            )
        unit = known
    elif known is not None and known != unit:
        raise MeasurementError(
            f"{path}: channel {column.column!r}: the file gives the unit {stated}, the mapping {unit}"
        )
    si_unit, factor = UNITS[unit]
    if si_unit != column.si_unit:
        raise MeasurementError(
            f"{path}: channel {column.column!r}: {stated or unit} is not a unit of {column.si_unit}"
        )
    return factor
