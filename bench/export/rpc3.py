"""A run's measured channels as an MTS RPC III time-history file, written from the format's
published description (no maintained library on PyPI writes it; ``rpc3-file`` reads the files
back in the tests).

The layout, as this writer lays it (docs/export.md):

- **Header**: key/value records of :data:`RECORD_BYTES` bytes, a key of :data:`KEY_BYTES` and a
  value of :data:`VALUE_BYTES`, ASCII, each NUL-padded (at least one NUL ends each); four records
  make a :data:`BLOCK_BYTES`-byte header block, the last block's unused records all NUL. The first
  three records are ``FORMAT``, ``NUM_HEADER_BLOCKS`` and ``NUM_PARAMS``, in that order.
- **Data**: from byte ``NUM_HEADER_BLOCKS * 512``, groups of ``PTS_PER_GROUP`` points per channel,
  the channels one after the other within a group (demultiplexed), each point a little-endian
  ``int16``; here one frame per group (``PTS_PER_GROUP = PTS_PER_FRAME``). The last frame is
  filled up with each channel's last value.
- **Scale**: a channel's physical value is its integer times ``SCALE.CHAN_n``; the scale is the
  channel's largest magnitude over ``INT_FULL_SCALE`` (32752), so each channel uses the whole
  integer range and is resolved to half its scale.

Only the run's physical channels (float32) are written; the integer link counters and status bits
(``seq``, ``sample``, ``status``) are not measured quantities and have no place in a time history.
"""

from __future__ import annotations

import math
from datetime import datetime
from pathlib import Path

import numpy as np

from bench.export.common import ExportError, output_folder
from bench.store import RunView

RECORD_BYTES = 128
KEY_BYTES = 32
VALUE_BYTES = RECORD_BYTES - KEY_BYTES
BLOCK_BYTES = 512
RECORDS_PER_BLOCK = BLOCK_BYTES // RECORD_BYTES
#: The integer full scale RPC III programs use (2^15 - 16).
INT_FULL_SCALE = 32752
#: Points per frame (and per group: one frame per group).
PTS_PER_FRAME = 2048
#: The file name's suffix: a response time history.
SUFFIX = ".rsp"
#: A scale's margin over the largest magnitude: ten times the relative rounding of its text.
SCALE_MARGIN = 1 + 5e-9
#: How numbers are written into the header (a real number in E format, as the format's examples).
_NUMBER = "{:.9E}"


def _field(text: str, size: int, what: str) -> bytes:
    data = text.encode("ascii", errors="replace")
    if len(data) >= size:
        raise ExportError(f"RPC III header: {what} {text!r} is longer than {size - 1} characters")
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


def _date(started: str) -> str:
    """The run's start as the format's DATE (``22-Feb-2000 10:20:11``); empty if unknown."""
    try:
        return datetime.fromisoformat(started).strftime("%d-%b-%Y %H:%M:%S")
    except ValueError:
        return ""


def rpc3_bytes(run: RunView) -> bytes:
    """The whole RPC III file of ``run``'s physical channels."""
    specs = [spec for spec in run.channel_specs if spec.dtype == "f4"]
    if not specs:
        raise ExportError(f"{run.path}: run {run.run_id}: no physical (float) channel to write")
    n = run.n_samples
    if n == 0:
        raise ExportError(f"{run.path}: run {run.run_id}: no samples")
    frames = math.ceil(n / PTS_PER_FRAME)
    params = [
        ("FILE_TYPE", "TIME_HISTORY"),
        ("TIME_TYPE", "RESPONSE"),
        ("DELTA_T", _NUMBER.format(1.0 / run.sample_rate_hz)),
        ("CHANNELS", str(len(specs))),
        ("DATE", _date(run.started)),
        ("OPERATION", "wfsbench export"),
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
        ("PART.NCHAN_1", str(len(specs))),
    ]
    data = np.empty((len(specs), frames * PTS_PER_FRAME), dtype="<i2")
    for i, spec in enumerate(specs, start=1):
        values = np.asarray(run.channels[spec.name], dtype=np.float64)
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise ExportError(
                f"{run.path}: run {run.run_id}: channel {spec.name}: sample {bad[0]} is {values[bad[0]]}:"
                " RPC III holds finite values only"
            )
        text, scale = channel_scale(values)
        data[i - 1, :n] = np.rint(values / scale)
        data[i - 1, n:] = data[i - 1, n - 1]
        params += [
            (f"DESC.CHAN_{i}", spec.name),
            (f"UNITS.CHAN_{i}", spec.unit),
            (f"SCALE.CHAN_{i}", text),
            (f"LOWER_LIMIT.CHAN_{i}", _NUMBER.format(float(values.min()))),
            (f"UPPER_LIMIT.CHAN_{i}", _NUMBER.format(float(values.max()))),
            (f"MAP.CHAN_{i}", str(i)),
        ]
    # frames become groups (one frame each): channel after channel within each
    groups = data.reshape(len(specs), frames, PTS_PER_FRAME).transpose(1, 0, 2)
    return header_bytes(params) + groups.tobytes()


def write_rpc3(runs: tuple[RunView, ...], out: Path) -> list[Path]:
    """One ``<run_id>.rsp`` per run in the new folder ``out`` (refused if it exists)."""
    written = []
    with output_folder(out) as folder:
        for run in runs:
            (folder / f"{run.run_id}{SUFFIX}").write_bytes(rpc3_bytes(run))
            written.append(out / f"{run.run_id}{SUFFIX}")
    return written
