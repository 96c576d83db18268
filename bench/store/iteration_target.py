"""A drive iteration's target read into samples of the matched response at one rate (docs/sequences.md,
*Drive iteration*).

- **A compensated road measurement** (``.h5`` written by ``wfsbench compensate``,
  :mod:`bench.store.compensated`): its contact force ``f_contact_n`` and the 95 % half-width
  ``u95_n`` beside it; the samples where the compensation's filters are defined (the filters' windows
  at the ends are NaN and left out).
- **A channel of a CSV, MDF4 or RPC III file** (:mod:`bench.store.channel_file`): the channel named
  (``channel``; a CSV file's time column ``time_column``, by default its first), in ``unit`` (by
  default the unit the file states), which must be a unit of the response's quantity (N for a
  force, m/s^2 for an acceleration). No band: a raw channel states no uncertainty.

A target that cannot be had is refused naming the file and what is wrong (:class:`TargetError`).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from bench.store.channel_file import (
    CSV_SUFFIXES,
    MDF_SUFFIXES,
    RPC3_SUFFIXES,
    ChannelFileError,
    ChannelKeys,
    read_channel,
)
from bench.store.compensated import SCHEMA_NAME

COMPENSATED_SUFFIXES = (".h5", ".hdf5")
#: A target's channel: named by the step's ``target_channel``, in its ``target_unit`` or the file's.
TARGET_CHANNEL = ChannelKeys("target", "target_channel", "target_unit", mdf=True)


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
    known = (*COMPENSATED_SUFFIXES, *CSV_SUFFIXES, *MDF_SUFFIXES, *RPC3_SUFFIXES)
    if suffix not in known:
        raise TargetError(f"{path}: unknown target file format {suffix!r} (known: {', '.join(known)})")
    if suffix in COMPENSATED_SUFFIXES:
        if channel or unit or time_column:
            raise TargetError(
                f"{path}: a compensated measurement is its contact force in N: it takes no"
                " target_channel, target_unit or time_column"
            )
        values, u95, rate, source = _compensated(path, si_unit)
    else:
        try:
            read = read_channel(
                path, TARGET_CHANNEL, si_unit=si_unit, channel=channel, unit=unit, time_column=time_column
            )
        except ChannelFileError as exc:
            raise TargetError(str(exc)) from None
        values, u95, rate, source = read.values, None, read.sample_rate_hz, read.source
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
