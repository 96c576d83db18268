"""The WFS acquisition's triggered capture: a block of Fz at the converter rate, as one binary message.

The line's frame rate (at most 1.25 kHz at 921600 baud) cannot show the sensor ringing at about
2.2 kHz in a hammer test. ``CAPTURE <trigger_level_n> <pre_trigger_s> <length_s>`` arms the
acquisition: it buffers Fz at its converter rate (10 kHz), triggers when ``|Fz - baseline|``
exceeds the level (the baseline is the mean Fz over the 10 ms before arming), and sends the block
between two frames as one message, little-endian::

    offset  size  field              type  unit
    0       2     sync               u2    0xC33C (bytes 3C C3), distinct from the frame's 0x5AA5
    2       4     n_samples          u4    samples in the block (1 .. MAX_CAPTURE_SAMPLES)
    6       4     pre_trigger        u4    samples before the trigger sample (<= n_samples)
    10      4     rate_hz            f4    Hz     the converter rate
    14      4     trigger_level_n    f4    N      the level armed
    18      4     baseline_n         f4    N      the baseline the level was measured from
    22      2     header_crc         u2    CRC-16/CCITT-FALSE over bytes 2..21
    24      4 n   samples            f4    N      Fz (tare applied), oldest first
    24+4n   2     crc                u2    CRC-16/CCITT-FALSE over the samples

The header's own CRC lets the stream parser tell a capture from binary bytes that happen to hold
the sync word before it waits for ``n_samples``; the CRC is the frames' (``drivers/wfs_frame.py``).
"""

from __future__ import annotations

import binascii
from dataclasses import dataclass

import numpy as np

CAPTURE_SYNC = 0xC33C
CAPTURE_SYNC_BYTES = CAPTURE_SYNC.to_bytes(2, "little")
#: the longest block a capture may hold (10 s at 10 kHz, 400 kB)
MAX_CAPTURE_SAMPLES = 100_000
HEADER_DTYPE = np.dtype(
    [
        ("sync", "<u2"),
        ("n_samples", "<u4"),
        ("pre_trigger", "<u4"),
        ("rate_hz", "<f4"),
        ("trigger_level_n", "<f4"),
        ("baseline_n", "<f4"),
        ("header_crc", "<u2"),
    ]
)
HEADER_SIZE = HEADER_DTYPE.itemsize
_CRC_SIZE = 2


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF), the frames' CRC, computed in C."""
    return binascii.crc_hqx(data, 0xFFFF)


@dataclass(frozen=True)
class Capture:
    """A triggered block of Fz: ``samples_n`` at ``rate_hz``, the trigger at ``pre_trigger_samples``."""

    samples_n: np.ndarray
    rate_hz: float
    pre_trigger_samples: int
    trigger_level_n: float
    baseline_n: float

    def __post_init__(self) -> None:
        n = len(self.samples_n)
        if not 0 < n <= MAX_CAPTURE_SAMPLES or not 0 <= self.pre_trigger_samples <= n or self.rate_hz <= 0:
            raise ValueError(
                f"invalid capture: {n} samples, {self.pre_trigger_samples} before the trigger, "
                f"{self.rate_hz} Hz"
            )

    @property
    def t_s(self) -> np.ndarray:
        """Time of each sample from the trigger sample (negative before it)."""
        return (np.arange(len(self.samples_n)) - self.pre_trigger_samples) / self.rate_hz


def message_size(n_samples: int) -> int:
    return HEADER_SIZE + 4 * n_samples + _CRC_SIZE


def encode_capture(capture: Capture) -> bytes:
    """The message for a capture (samples as float32)."""
    header = np.zeros(1, HEADER_DTYPE)
    header["sync"] = CAPTURE_SYNC
    header["n_samples"] = len(capture.samples_n)
    header["pre_trigger"] = capture.pre_trigger_samples
    header["rate_hz"] = capture.rate_hz
    header["trigger_level_n"] = capture.trigger_level_n
    header["baseline_n"] = capture.baseline_n
    head = header.tobytes()
    header["header_crc"] = crc16(head[2 : HEADER_SIZE - 2])
    samples = np.asarray(capture.samples_n, dtype="<f4").tobytes()
    return header.tobytes() + samples + crc16(samples).to_bytes(2, "little")


def decode_capture(buf: bytes, pos: int = 0) -> tuple[int, Capture | None]:
    """Try the message starting at ``buf[pos]`` (which holds the capture sync word).

    Returns ``(bytes consumed, capture)``: ``(0, None)`` while the message may still be incomplete,
    ``(1, None)`` when these bytes are no capture (bad header CRC or fields, bad data CRC: the
    caller skips one byte and resynchronises).
    """
    if len(buf) - pos < HEADER_SIZE:
        return 0, None
    head = bytes(buf[pos : pos + HEADER_SIZE])
    header = np.frombuffer(head, HEADER_DTYPE)[0]
    if header["sync"] != CAPTURE_SYNC or int(header["header_crc"]) != crc16(head[2 : HEADER_SIZE - 2]):
        return 1, None
    n = int(header["n_samples"])
    pre = int(header["pre_trigger"])
    rate_hz = float(header["rate_hz"])
    if not 0 < n <= MAX_CAPTURE_SAMPLES or pre > n or not rate_hz > 0:
        return 1, None
    size = message_size(n)
    if len(buf) - pos < size:
        return 0, None
    samples = bytes(buf[pos + HEADER_SIZE : pos + size - _CRC_SIZE])
    if int.from_bytes(buf[pos + size - _CRC_SIZE : pos + size], "little") != crc16(samples):
        return 1, None
    values = np.frombuffer(samples, "<f4").astype(float)
    return size, Capture(values, rate_hz, pre, float(header["trigger_level_n"]), float(header["baseline_n"]))
