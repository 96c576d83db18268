"""The WFS acquisition's binary frame: a numpy structured dtype, CRC, vectorised encode/decode.

Protocol version 2 (:data:`PROTOCOL_VERSION`). One frame per sample, 64 bytes, little-endian, no
padding::

    offset  size  field          type  unit
    0       2     sync           u2    0x5AA5 (bytes A5 5A)
    2       4     seq            u4    frames sent since power-up (link accounting)
    6       4     sample         u4    sample index since the last START (the acquisition clock)
    10      24    fx fy fz       f4    N      forces in the sensor's rotating frame
                  mx my mz       f4    N m    moments in the sensor's rotating frame
    34      4     angle_rad      f4    rad    wheel angle about the wheel axis y
    38      4     speed_rad_s    f4    rad/s  wheel speed
    42      16    aux0..aux3     f4    aux0 bench displacement m, aux1 plate force N,
                                              aux2 hub acceleration m/s^2, aux3 spare
    58      2     status         u2    Status bits
    60      2     boot           u2    power-ups of the device (wraps at 2^16): a new value is a restart
    62      2     crc            u2    CRC-16/CCITT-FALSE over bytes 2..61

Version 1 had no ``boot`` field (62 bytes), so a restart had to be guessed from ``seq`` going back.
The CRC is computed column by column over a whole block of frames at once, so checking a block
costs a few dozen numpy operations whatever its length.
"""

from __future__ import annotations

import enum

import numpy as np

#: the version of the frame layout and command set; IDENT reports it as its last field
PROTOCOL_VERSION = 2
SYNC = 0x5AA5
SYNC_BYTES = SYNC.to_bytes(2, "little")
FORCE_FIELDS = ("fx", "fy", "fz", "mx", "my", "mz")
AUX_FIELDS = ("aux0", "aux1", "aux2", "aux3")

FRAME_DTYPE = np.dtype(
    [("sync", "<u2"), ("seq", "<u4"), ("sample", "<u4")]
    + [(name, "<f4") for name in FORCE_FIELDS]
    + [("angle_rad", "<f4"), ("speed_rad_s", "<f4")]
    + [(name, "<f4") for name in AUX_FIELDS]
    + [("status", "<u2"), ("boot", "<u2"), ("crc", "<u2")]
)
FRAME_SIZE = FRAME_DTYPE.itemsize
CRC_START, CRC_END = 2, FRAME_SIZE - 2


class Status(enum.IntFlag):
    """Bits of the frame's ``status`` field.

    ``EXCITATION_ACTIVE`` and ``AMPLITUDE_HOLD`` are digital inputs of the acquisition wired to the
    actuator controller's sync outputs, sampled with the analog channels (same delay).
    """

    OVERLOAD_FX = 1 << 0
    OVERLOAD_FY = 1 << 1
    OVERLOAD_FZ = 1 << 2
    OVERLOAD_MX = 1 << 3
    OVERLOAD_MY = 1 << 4
    OVERLOAD_MZ = 1 << 5
    OVERLOAD_AUX = 1 << 6
    ADC_FAULT = 1 << 7
    TARED = 1 << 8
    EXCITATION_ACTIVE = 1 << 9
    AMPLITUDE_HOLD = 1 << 10


def _crc16_table() -> np.ndarray:
    table = np.zeros(256, dtype=np.uint16)
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
        table[byte] = crc & 0xFFFF
    return table


_TABLE = _crc16_table()


def _crc16_word_table() -> np.ndarray:
    """``T[v]``: the CRC state after feeding 16 zero bits from state ``v``, so that one 16-bit word
    ``w`` advances the state ``c`` to ``T[c ^ w]`` (the CRC is linear)."""
    high = _TABLE[np.arange(65536) >> 8]
    low = np.arange(65536, dtype=np.uint16) & 0xFF
    state = (low << 8) ^ high
    return (state << 8) ^ _TABLE[state >> 8]


_WORD_TABLE = _crc16_word_table()


def crc16_rows(rows: np.ndarray) -> np.ndarray:
    """CRC-16/CCITT-FALSE of every row of a 2-D uint8 array with an even number of columns,
    vectorised over the rows and taking two bytes per step."""
    words = np.ascontiguousarray(rows).view(">u2").astype(np.uint16)
    crc = np.full(rows.shape[0], 0xFFFF, dtype=np.uint16)
    for column in words.T:
        crc = _WORD_TABLE[crc ^ column]
    return crc


def _as_bytes(frames: np.ndarray) -> np.ndarray:
    return frames.view(np.uint8).reshape(len(frames), FRAME_SIZE)


def frame_crc(frames: np.ndarray) -> np.ndarray:
    """The CRC each frame of a FRAME_DTYPE array should carry."""
    return crc16_rows(_as_bytes(np.ascontiguousarray(frames))[:, CRC_START:CRC_END])


def valid(frames: np.ndarray) -> np.ndarray:
    """Boolean mask: sync word right and CRC right."""
    return (frames["sync"] == SYNC) & (frames["crc"] == frame_crc(frames))


def valid_at(data: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Boolean mask: whether the frame starting at each byte offset of ``starts`` in ``data`` (a uint8
    array holding every one of these frames whole) has its sync word and CRC right.

    Vectorised over the offsets, which may overlap: the stream parser checks every sync word of a
    stretch of garbage at once.
    """
    rows = np.lib.stride_tricks.sliding_window_view(data, FRAME_SIZE)[starts]
    stored = rows[:, -2].astype(np.uint16) | (rows[:, -1].astype(np.uint16) << 8)
    sync = (rows[:, 0] == SYNC_BYTES[0]) & (rows[:, 1] == SYNC_BYTES[1])
    return sync & (crc16_rows(rows[:, CRC_START:CRC_END]) == stored)


def new_frames(n: int) -> np.ndarray:
    """A zeroed block of ``n`` frames."""
    return np.zeros(n, dtype=FRAME_DTYPE)


def encode(frames: np.ndarray) -> bytes:
    """Stamp sync and CRC on a block of frames and return its bytes."""
    block = np.array(frames, dtype=FRAME_DTYPE, copy=True)
    block["sync"] = SYNC
    block["crc"] = frame_crc(block)
    return block.tobytes()


def decode(data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """Decode back-to-back frames: ``(frames, valid_mask)``; ``len(data)`` must be a multiple of 64."""
    if len(data) % FRAME_SIZE:
        raise ValueError(f"{len(data)} bytes is not a whole number of {FRAME_SIZE}-byte frames")
    frames = np.frombuffer(data, dtype=FRAME_DTYPE)
    return frames, valid(frames)
