"""A drive iteration's target read into samples of the matched response at one rate (docs/sequences.md,
*Drive iteration*).

- **A compensated road measurement** (``.h5`` written by ``wfsbench compensate``,
  :mod:`bench.store.compensated`): its contact force ``f_contact_n`` and the 95 % half-width
  ``u95_n`` beside it; the samples where the compensation's filters are defined (the filters' windows
  at the ends are NaN and left out).
- **A channel of a CSV, MDF4 or RPC III file**: the channel named (``channel``; a CSV file's time
  column ``time_column``, by default its first), in ``unit`` (by default the unit the file states),
  which must be a unit of the response's quantity (N for a force, m/s^2 for an acceleration). No
  band: a raw channel states no uncertainty.

A target that cannot be had is refused naming the file and what is wrong (:class:`TargetError`).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from bench.store.compensated import SCHEMA_NAME
from bench.store.csv_mapping import ChannelColumn, Dialect, Timing
from bench.store.csv_read import CsvError, read_csv
from bench.store.csv_units import UNITS, known_units, unit_named
from bench.store.drive_files import csv_header
from bench.store.measurement import MDF_SUFFIXES
from bench.store.rpc3 import Rpc3Error, read_rpc3

COMPENSATED_SUFFIXES = (".h5", ".hdf5")
RPC3_SUFFIXES = (".rsp", ".drv", ".tim", ".rpc")
#: The target's name while it is read.
_TARGET = "target"


class TargetError(ValueError):
    """A target that cannot be iterated on: the message names the file and what is wrong."""


@dataclass(frozen=True)
class TargetSamples:
    """A target as read: ``values`` (SI unit ``si_unit``) at ``sample_rate_hz``, the 95 % half-width
    ``u95`` beside them (None: the file states none), from ``source`` (the file and its channel),
    ``sha256`` of the file's bytes."""

    values: np.ndarray
    u95: np.ndarray | None
    sample_rate_hz: float
    si_unit: str
    source: str
    sha256: str


def read_target(
    path: str | Path, *, si_unit: str, channel: str = "", unit: str = "", time_column: str = ""
) -> TargetSamples:
    """The target in ``path`` (by its suffix: see the module docstring), in ``si_unit``."""
    path = Path(path)
    if not path.is_file():
        raise TargetError(f"{path}: no such file")
    suffix = path.suffix.lower()
    if suffix in COMPENSATED_SUFFIXES:
        if channel or unit or time_column:
            raise TargetError(
                f"{path}: a compensated measurement is its contact force in N: it takes no"
                " target_channel, target_unit or time_column"
            )
        values, u95, rate, source = _compensated(path, si_unit)
    elif suffix == ".csv":
        values, rate, source = _csv(path, si_unit, channel, unit, time_column)
        u95 = None
    elif suffix in RPC3_SUFFIXES or suffix in MDF_SUFFIXES:
        if time_column:
            raise TargetError(f"{path}: time_column names a CSV file's time column; this file has none")
        reader = _rpc3 if suffix in RPC3_SUFFIXES else _mdf
        values, rate, source = reader(path, si_unit, channel, unit)
        u95 = None
    else:
        known = ", ".join((*COMPENSATED_SUFFIXES, ".csv", *MDF_SUFFIXES, *RPC3_SUFFIXES))
        raise TargetError(f"{path}: unknown target format {suffix!r} (known: {known})")
    if values.size < 2 or not np.all(np.isfinite(values)):
        raise TargetError(f"{source}: fewer than two finite samples")
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    return TargetSamples(values, u95, rate, si_unit, source, digest)


def _compensated(path: Path, si_unit: str) -> tuple[np.ndarray, np.ndarray, float, str]:
    if si_unit != "N":
        raise TargetError(f"{path}: a compensated measurement is a force (N), the response is in {si_unit}")
    try:
        with h5py.File(path, "r") as f:
            if f.attrs.get("schema") != SCHEMA_NAME:
                raise TargetError(f"{path}: not a compensated measurement (schema {f.attrs.get('schema')!r})")
            force = np.asarray(f["f_contact_n"][()], dtype=float)
            u95 = np.asarray(f["u95_n"][()], dtype=float)
            rate = float(f.attrs["sample_rate_hz"])
    except OSError as exc:
        raise TargetError(f"{path}: not a readable HDF5 file: {exc}") from None
    defined = np.flatnonzero(np.isfinite(force) & np.isfinite(u95))
    if defined.size == 0:
        raise TargetError(f"{path}: no sample of the contact force is defined")
    span = slice(int(defined[0]), int(defined[-1]) + 1)
    return force[span], u95[span], rate, f"{path} contact force (compensated)"


def _csv(
    path: Path, si_unit: str, channel: str, unit: str, time_column: str
) -> tuple[np.ndarray, float, str]:
    from bench.store.drive_files import DriveFileError

    try:
        header, units_row = csv_header(path)
    except DriveFileError as exc:
        raise TargetError(str(exc)) from None
    time_column = time_column or header[0]
    if time_column not in header:
        raise TargetError(
            f"{path}: line 1: no time column {time_column!r} (the header has: {', '.join(header)})"
        )
    others = [name for name in header if name != time_column]
    channel = channel or _the_only(others, f"{path}: line 1", "columns besides the time column")
    column = ChannelColumn(_TARGET, si_unit, channel, _unit(path, unit, si_unit) if unit else None)
    try:
        table = read_csv(path, Dialect(units_row=units_row), Timing(column=time_column), (column,))
    except CsvError as exc:
        raise TargetError(str(exc)) from None
    if _TARGET not in table.columns:
        raise TargetError(str(table.missing(column)))
    return table.columns[_TARGET], table.sample_rate_hz, f"{path} column {channel!r}"


def _rpc3(path: Path, si_unit: str, channel: str, unit: str) -> tuple[np.ndarray, float, str]:
    try:
        rpc = read_rpc3(path)
    except Rpc3Error as exc:
        raise TargetError(str(exc)) from None
    names = [c.name for c in rpc.channels]
    channel = channel or _the_only(names, str(path), "channels")
    if channel not in names:
        raise TargetError(f"{path}: no channel {channel!r} (DESC.CHAN_n: {', '.join(names)})")
    found = rpc.channels[names.index(channel)]
    factor = _factor(path, channel, unit or found.unit, si_unit)
    return found.values * factor, rpc.sample_rate_hz, f"{path} channel {channel!r}"


def _mdf(path: Path, si_unit: str, channel: str, unit: str) -> tuple[np.ndarray, float, str]:
    from asammdf import MDF  # only here: it takes a second to import

    try:
        mdf = MDF(path)
    except Exception as exc:  # asammdf raises many kinds for a file it cannot read
        raise TargetError(f"{path}: not a readable MDF file: {exc}") from None
    with mdf:
        names = sorted(name for name in mdf.channels_db if not name.startswith("$"))
        channel = channel or _the_only(
            [n for n in names if n.lower() not in ("t", "time")], str(path), "channels"
        )
        if channel not in mdf.channels_db:
            raise TargetError(f"{path}: no channel {channel!r} (the file has {', '.join(names)})")
        signal = mdf.get(channel)
    t = np.asarray(signal.timestamps, dtype=float)
    if t.size < 2 or not np.all(np.diff(t) > 0):
        raise TargetError(f"{path}: channel {channel!r}: its time stamps do not step forward")
    step = (t[-1] - t[0]) / (t.size - 1)
    if np.any(np.abs(np.diff(t) - step) > 1e-3 * step):
        raise TargetError(f"{path}: channel {channel!r}: the time stamps step unevenly: not one sample rate")
    factor = _factor(path, channel, unit or str(signal.unit), si_unit)
    return np.asarray(signal.samples, dtype=float) * factor, 1.0 / step, f"{path} channel {channel!r}"


def _the_only(names: list[str], where: str, what: str) -> str:
    if len(names) != 1:
        raise TargetError(
            f"{where}: which is the target? {len(names)} {what}: name one as the step's target_channel"
            f" ({', '.join(names)})"
        )
    return names[0]


def _unit(path: Path, spelled: str, si_unit: str) -> str:
    known = unit_named(spelled.strip("[]() ")) if spelled.strip() else None
    if known is None:
        raise TargetError(f"{path}: unit {spelled!r} is not one of {known_units()}")
    if UNITS[known][0] != si_unit:
        raise TargetError(f"{path}: {spelled} is not a unit of {si_unit}, the response's")
    return known


def _factor(path: Path, channel: str, spelled: str, si_unit: str) -> float:
    """The factor from ``spelled`` (the step's unit, else the file's) to ``si_unit``."""
    try:
        return UNITS[_unit(path, spelled, si_unit)][1]
    except TargetError as exc:
        raise TargetError(f"{exc} (channel {channel!r}; give its unit as the step's target_unit)") from None
