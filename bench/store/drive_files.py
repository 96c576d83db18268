"""A road replay's drive file read into displacement samples at one rate (docs/sequences.md,
*Road replay*): the displacement channel of a CSV file or an MTS RPC III time history, in a unit of
length the file states (:mod:`bench.store.channel_file`: the formats and what is refused)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench.store.channel_file import ChannelFileError, ChannelKeys, read_channel

#: A drive's displacement: its channel named by the step's ``channel``, in the file's unit.
DRIVE_CHANNEL = ChannelKeys("displacement", "channel")


class DriveFileError(ValueError):
    """A drive file that cannot be played: the message names the file and where in it."""


@dataclass(frozen=True)
class DriveSamples:
    """A drive as read: ``displacement_m`` at ``sample_rate_hz``, from ``source`` (the file and the
    column or channel)."""

    displacement_m: np.ndarray
    sample_rate_hz: float
    source: str


def read_drive_file(path: str | Path, *, channel: str = "", time_column: str = "") -> DriveSamples:
    """The drive in ``path``; ``channel`` names its displacement column or channel and
    ``time_column`` a CSV file's time column (empty: the defaults). :class:`DriveFileError` naming
    the file and where."""
    try:
        read = read_channel(Path(path), DRIVE_CHANNEL, si_unit="m", channel=channel, time_column=time_column)
    except ChannelFileError as exc:
        raise DriveFileError(str(exc)) from None
    return DriveSamples(read.values, read.sample_rate_hz, read.source)
