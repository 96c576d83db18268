"""MTS RPC III time histories read, written from the format's published description (no maintained
Python library reads them: ``rpc3-file`` on PyPI has pre-releases only), the reader of
:mod:`bench.export.rpc3`'s files and of a lab's drive files (docs/sequences.md, *Road replay*).

The layout read (the writer's, docs/export.md, in general):

- **Header**: key/value records of 128 bytes (a 32-byte key, a 96-byte value, ASCII, ended by a
  NUL), four to a 512-byte block; the first three are ``FORMAT``, ``NUM_HEADER_BLOCKS`` and
  ``NUM_PARAMS``; ``NUM_PARAMS`` records in all.
- **Data**: from byte ``NUM_HEADER_BLOCKS x 512``, in groups of ``PTS_PER_GROUP`` points per channel
  (a whole number of frames of ``PTS_PER_FRAME``), the channels one after the other within a group;
  the last group holds the frames that are left. ``FRAMES x PTS_PER_FRAME`` points per channel.
- **Values**: ``DATA_TYPE`` ``SHORT_INTEGER`` (int16 times ``SCALE.CHAN_n``) or ``FLOATING_POINT``
  (float32 as they are), little-endian (``FORMAT`` ``BINARY_IEEE_LITTLE_END``, or ``BINARY`` as PC
  programs write it: rpc3-file, for one) or big-endian (``BINARY_IEEE_BIG_END``); ``DELTA_T`` the
  sample interval (s).

Not read: half frames (``HALF_FRAMES`` other than 0), ``ASCII`` files.
Every refusal names the file and the record or byte.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

RECORD_BYTES = 128
KEY_BYTES = 32
BLOCK_BYTES = 512
_FORMATS = {"BINARY_IEEE_LITTLE_END": "<", "BINARY": "<", "BINARY_IEEE_BIG_END": ">"}
_DATA_TYPES = {"SHORT_INTEGER": "i2", "FLOATING_POINT": "f4"}
_LEADING = ("FORMAT", "NUM_HEADER_BLOCKS", "NUM_PARAMS")


class Rpc3Error(ValueError):
    """A file that is no readable RPC III time history: the message names the file and where."""


@dataclass(frozen=True)
class Rpc3Channel:
    """One channel: its ``name`` (``DESC.CHAN_n``), ``unit`` (``UNITS.CHAN_n``) and ``values``."""

    name: str
    unit: str
    values: np.ndarray


@dataclass(frozen=True)
class Rpc3File:
    """An RPC III time history: its header records, its channels in order, its sample rate."""

    path: Path
    header: dict[str, str]
    channels: tuple[Rpc3Channel, ...]
    sample_rate_hz: float


def _records(path: Path, data: bytes, first: int, count: int) -> list[tuple[str, str]]:
    out = []
    for k in range(first, first + count):
        raw = data[k * RECORD_BYTES : (k + 1) * RECORD_BYTES]
        if len(raw) < RECORD_BYTES:
            raise Rpc3Error(f"{path}: header record {k + 1} lies beyond the end of the file")
        key, value = raw[:KEY_BYTES], raw[KEY_BYTES:]
        try:
            out.append(
                (key.split(b"\0")[0].decode("ascii").strip(), value.split(b"\0")[0].decode("ascii").strip())
            )
        except UnicodeDecodeError:
            raise Rpc3Error(f"{path}: header record {k + 1} is not ASCII text: not an RPC III file") from None
    return out


def _number(path: Path, header: dict[str, str], key: str, kind: type, low: float) -> float:
    if key not in header:
        raise Rpc3Error(f"{path}: header: no {key} record")
    try:
        value = kind(header[key])
    except ValueError:
        raise Rpc3Error(f"{path}: header: {key} = {header[key]!r} is not a number") from None
    if not value >= low:
        raise Rpc3Error(f"{path}: header: {key} = {header[key]!r} is below {low:g}")
    return value


def read_rpc3(path: str | Path) -> Rpc3File:
    """Read the RPC III time history at ``path`` (see the module docstring); :class:`Rpc3Error`
    naming what is wrong."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise Rpc3Error(f"{path}: cannot be read: {exc.strerror or exc}") from None
    leading = _records(path, data, 0, 3)
    if [key for key, _ in leading] != list(_LEADING):
        raise Rpc3Error(
            f"{path}: the first header records are {[key for key, _ in leading]}, not {list(_LEADING)}:"
            " not an RPC III file"
        )
    header = dict(leading)
    blocks = int(_number(path, header, "NUM_HEADER_BLOCKS", int, 1))
    n_params = int(_number(path, header, "NUM_PARAMS", int, 3))
    if n_params * RECORD_BYTES > blocks * BLOCK_BYTES:
        raise Rpc3Error(f"{path}: header: {n_params} records do not fit {blocks} header blocks")
    header.update(_records(path, data, 3, n_params - 3))
    if header["FORMAT"] not in _FORMATS:
        raise Rpc3Error(f"{path}: header: FORMAT {header['FORMAT']!r} is not one of {sorted(_FORMATS)}")
    data_type = header.get("DATA_TYPE", "SHORT_INTEGER")
    if data_type not in _DATA_TYPES:
        raise Rpc3Error(f"{path}: header: DATA_TYPE {data_type!r} is not one of {sorted(_DATA_TYPES)}")
    if header.get("FILE_TYPE", "TIME_HISTORY") != "TIME_HISTORY":
        raise Rpc3Error(f"{path}: header: FILE_TYPE {header['FILE_TYPE']!r}: only a TIME_HISTORY is read")
    if header.get("HALF_FRAMES", "0") not in ("0", ""):
        raise Rpc3Error(f"{path}: header: HALF_FRAMES {header['HALF_FRAMES']!r}: half frames are not read")
    n_channels = int(_number(path, header, "CHANNELS", int, 1))
    frame = int(_number(path, header, "PTS_PER_FRAME", int, 1))
    group = int(_number(path, header, "PTS_PER_GROUP", int, frame))
    frames = int(_number(path, header, "FRAMES", int, 1))
    delta_t = _number(path, header, "DELTA_T", float, 0.0)
    if group % frame or delta_t <= 0:
        raise Rpc3Error(
            f"{path}: header: PTS_PER_GROUP {group} is no whole number of frames of {frame} points,"
            f" or DELTA_T {delta_t:g} s is not positive"
        )
    dtype = np.dtype(_FORMATS[header["FORMAT"]] + _DATA_TYPES[data_type])
    points = frames * frame
    expected = blocks * BLOCK_BYTES + points * n_channels * dtype.itemsize
    if len(data) < expected:
        raise Rpc3Error(
            f"{path}: {len(data)} bytes, fewer than the {expected} its header describes"
            f" ({n_channels} channels of {frames} frames of {frame} points, {data_type})"
        )
    raw = np.frombuffer(data, dtype=dtype, count=points * n_channels, offset=blocks * BLOCK_BYTES)
    values = np.empty((n_channels, points))
    position = 0
    for start in range(0, points, group):
        n = min(group, points - start)  # the last group holds the frames that are left
        values[:, start : start + n] = raw[position : position + n * n_channels].reshape(n_channels, n)
        position += n * n_channels
    channels = []
    for k in range(1, n_channels + 1):
        scale = (
            _number(path, header, f"SCALE.CHAN_{k}", float, -np.inf) if data_type == "SHORT_INTEGER" else 1.0
        )
        name = header.get(f"DESC.CHAN_{k}", f"channel {k}")
        channels.append(Rpc3Channel(name, header.get(f"UNITS.CHAN_{k}", ""), values[k - 1] * scale))
    return Rpc3File(path, header, tuple(channels), 1.0 / delta_t)
