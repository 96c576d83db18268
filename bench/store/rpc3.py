"""The MTS RPC III time-history codec, written from the format's published description (no
maintained Python library reads or writes it: ``rpc3-file`` on PyPI has pre-releases only; the
tests read this codec's files back with it): the writer of ``wfsbench export --format rpc3``
(:mod:`bench.export.rpc3`) and the reader of those files and of a lab's drive files
(docs/sequences.md, *Road replay*). One layout, below, for both directions.

The layout (what the writer lays out: int16 data, one frame per group, little-endian; what the
reader takes, in general):

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

The writer's scale: a channel's ``SCALE.CHAN_n`` is its largest magnitude over ``INT_FULL_SCALE``
(32752), so each channel uses the whole integer range and is resolved to half its scale; its last
frame is filled up with its last value.

Not read: half frames (``HALF_FRAMES`` other than 0), ``ASCII`` files.
Every refusal names the file and the record or byte.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

RECORD_BYTES = 128
KEY_BYTES = 32
VALUE_BYTES = RECORD_BYTES - KEY_BYTES
BLOCK_BYTES = 512
RECORDS_PER_BLOCK = BLOCK_BYTES // RECORD_BYTES
#: The integer full scale RPC III programs use (2^15 - 16).
INT_FULL_SCALE = 32752
#: Points per frame the writer lays out (and per group: one frame per group).
PTS_PER_FRAME = 2048
#: A scale's margin over the largest magnitude: ten times the relative rounding of its text.
SCALE_MARGIN = 1 + 5e-9
#: How numbers are written into the header (a real number in E format, as the format's examples).
_NUMBER = "{:.9E}"
_FORMATS = {"BINARY_IEEE_LITTLE_END": "<", "BINARY": "<", "BINARY_IEEE_BIG_END": ">"}
_DATA_TYPES = {"SHORT_INTEGER": "i2", "FLOATING_POINT": "f4"}
_LEADING = ("FORMAT", "NUM_HEADER_BLOCKS", "NUM_PARAMS")


class Rpc3Error(ValueError):
    """A file that is no readable RPC III time history, or values that cannot be written as one:
    the message names the file (or the channel) and where."""


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


# -- writing ------------------------------------------------------------------------------------


def _field(text: str, size: int, what: str) -> bytes:
    data = text.encode("ascii", errors="replace")
    if len(data) >= size:
        raise Rpc3Error(f"RPC III header: {what} {text!r} is longer than {size - 1} characters")
    return data.ljust(size, b"\0")


def header_bytes(params: list[tuple[str, str]]) -> bytes:
    """The header of ``params`` (after the three leading records, which this adds): whole blocks."""
    n_params = len(params) + 3
    n_blocks = math.ceil(n_params / RECORDS_PER_BLOCK)
    records = [
        ("FORMAT", "BINARY_IEEE_LITTLE_END"),
        ("NUM_HEADER_BLOCKS", str(n_blocks)),
        ("NUM_PARAMS", str(n_params)),
        *params,
    ]
    body = b"".join(_field(k, KEY_BYTES, "key") + _field(v, VALUE_BYTES, f"value of {k}") for k, v in records)
    return body.ljust(n_blocks * BLOCK_BYTES, b"\0")


def channel_scale(values: np.ndarray) -> tuple[str, float]:
    """The channel's ``SCALE`` as written (text) and as read back (the number the data are
    quantised with, so writer and reader agree): its largest magnitude over the full scale, raised
    by :data:`SCALE_MARGIN` so that the text's rounding never puts the largest value beyond it."""
    largest = float(np.max(np.abs(values))) if values.size else 0.0
    text = _NUMBER.format(largest * SCALE_MARGIN / INT_FULL_SCALE if largest > 0 else 1.0 / INT_FULL_SCALE)
    return text, float(text)


def time_history_bytes(
    channels: Sequence[Rpc3Channel], sample_rate_hz: float, *, date: str = "", operation: str = ""
) -> bytes:
    """The whole RPC III response time history of ``channels`` (of equal length, finite values)
    at ``sample_rate_hz``; ``date`` as the format writes it (``22-Feb-2000 10:20:11``)."""
    n = channels[0].values.size if channels else 0
    if not channels or n == 0 or any(c.values.size != n for c in channels):
        raise Rpc3Error("RPC III: channels of one length and at least one sample are needed")
    frames = math.ceil(n / PTS_PER_FRAME)
    params = [
        ("FILE_TYPE", "TIME_HISTORY"),
        ("TIME_TYPE", "RESPONSE"),
        ("DELTA_T", _NUMBER.format(1.0 / sample_rate_hz)),
        ("CHANNELS", str(len(channels))),
        ("DATE", date),
        ("OPERATION", operation),
        ("PTS_PER_FRAME", str(PTS_PER_FRAME)),
        ("PTS_PER_GROUP", str(PTS_PER_FRAME)),
        ("FRAMES", str(frames)),
        ("HALF_FRAMES", "0"),
        ("REPEATS", "1"),
        ("DATA_TYPE", "SHORT_INTEGER"),
        ("INT_FULL_SCALE", str(INT_FULL_SCALE)),
        ("BYPASS_FILTER", "0"),
        ("PARTITIONS", "1"),
        ("PART.CHAN_1", "1"),
        ("PART.NCHAN_1", str(len(channels))),
    ]
    data = np.empty((len(channels), frames * PTS_PER_FRAME), dtype="<i2")
    for i, channel in enumerate(channels, start=1):
        values = np.asarray(channel.values, dtype=np.float64)
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise Rpc3Error(
                f"channel {channel.name}: sample {bad[0]} is {values[bad[0]]}:"
                " RPC III holds finite values only"
            )
        text, scale = channel_scale(values)
        data[i - 1, :n] = np.rint(values / scale)
        data[i - 1, n:] = data[i - 1, n - 1]
        params += [
            (f"DESC.CHAN_{i}", channel.name),
            (f"UNITS.CHAN_{i}", channel.unit),
            (f"SCALE.CHAN_{i}", text),
            (f"LOWER_LIMIT.CHAN_{i}", _NUMBER.format(float(values.min()))),
            (f"UPPER_LIMIT.CHAN_{i}", _NUMBER.format(float(values.max()))),
            (f"MAP.CHAN_{i}", str(i)),
        ]
    # frames become groups (one frame each): channel after channel within each
    groups = data.reshape(len(channels), frames, PTS_PER_FRAME).transpose(1, 0, 2)
    return header_bytes(params) + groups.tobytes()
