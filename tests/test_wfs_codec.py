"""WFS frame codec and command set: byte-exact layout, CRC, garbage replies."""

import binascii
import struct

import numpy as np
import pytest

from drivers.errors import MalformedReplyError
from drivers.wfs_commands import Reply, format_command, parse_command, parse_reply
from drivers.wfs_frame import (
    FRAME_SIZE,
    crc16_rows,
    decode,
    encode,
    new_frames,
    valid_at,
)


def test_crc16_ccitt_false_check_value():
    rows = np.frombuffer(b"12345678", dtype=np.uint8).reshape(1, 8)  # the check string, even length
    assert crc16_rows(rows).tolist() == [binascii.crc_hqx(b"12345678", 0xFFFF)]
    assert binascii.crc_hqx(b"123456789", 0xFFFF) == 0x29B1  # the reference is CRC-16/CCITT-FALSE


def test_crc_agrees_with_the_standard_library():
    """binascii.crc_hqx with initial value 0xFFFF is an independent CRC-16/CCITT-FALSE."""
    rows = np.random.default_rng(3).integers(0, 256, (500, 60), dtype=np.uint8)
    reference = [binascii.crc_hqx(r.tobytes(), 0xFFFF) for r in rows]
    assert crc16_rows(rows).tolist() == reference
    frames = new_frames(50)
    frames["seq"] = np.arange(50)
    frames["boot"] = 7
    data = encode(frames)
    offsets = range(0, len(data), FRAME_SIZE)
    stamped = [int.from_bytes(data[i + 62 : i + 64], "little") for i in offsets]
    assert stamped == [binascii.crc_hqx(data[i + 2 : i + 62], 0xFFFF) for i in offsets]


def test_valid_at_checks_frames_at_any_byte_offset():
    frames = new_frames(3)
    frames["seq"] = [5, 6, 7]
    data = bytearray(b"\xa5\x5a\x00" + encode(frames) + b"\xa5")
    data[3 + FRAME_SIZE + 20] ^= 0x10  # break the second frame
    starts = np.array([0, 3, 3 + FRAME_SIZE, 3 + 2 * FRAME_SIZE])
    assert valid_at(np.frombuffer(bytes(data), np.uint8), starts).tolist() == [False, True, False, True]


def test_frame_layout_is_byte_exact():
    f = new_frames(1)
    f["seq"], f["sample"], f["fz"], f["aux2"], f["status"], f["boot"] = 7, 3, 1.5, -2.0, 0x0104, 0x0302
    data = encode(f)
    assert FRAME_SIZE == 64 == len(data)
    assert data[0:2] == b"\xa5\x5a"
    assert data[2:6] == struct.pack("<I", 7)
    assert data[6:10] == struct.pack("<I", 3)
    assert data[18:22] == struct.pack("<f", 1.5)  # fz: third force channel at offset 10 + 8
    assert data[50:54] == struct.pack("<f", -2.0)  # aux2 at 42 + 8
    assert data[58:60] == b"\x04\x01"
    assert data[60:62] == b"\x02\x03"  # boot
    assert data[62:64] == struct.pack("<H", binascii.crc_hqx(data[2:62], 0xFFFF))


def test_encode_decode_round_trip_and_single_bit_errors_detected():
    f = new_frames(200)
    f["seq"] = np.arange(200)
    f["fx"] = np.linspace(-1, 1, 200)
    data = bytearray(encode(f))
    frames, ok = decode(bytes(data))
    assert ok.all()
    assert np.array_equal(frames["fx"], f["fx"])
    rng = np.random.default_rng(1)
    hit = sorted(rng.choice(200, 40, replace=False))
    for i in hit:
        data[i * FRAME_SIZE + int(rng.integers(0, FRAME_SIZE))] ^= 1 << int(rng.integers(0, 8))
    _, ok = decode(bytes(data))
    assert np.flatnonzero(~ok).tolist() == hit


def test_decode_refuses_partial_frames():
    with pytest.raises(ValueError, match="whole number"):
        decode(b"\xa5\x5a" + bytes(10))


def test_command_lines_byte_exact():
    assert format_command("IDENT") == b"IDENT\n"
    assert format_command("RATE", 1000) == b"RATE 1000\n"
    assert format_command("RATE?") == b"RATE?\n"
    with pytest.raises(ValueError, match="unknown WFS command"):
        format_command("FIRE")


def test_device_side_command_parsing():
    assert parse_command(b"rate 500\r\n") == ("RATE", ["500"])
    for garbage in (b"", b"\xff\xfe", b"LAUNCH 3"):
        with pytest.raises(ValueError):
            parse_command(garbage)


def test_reply_byte_exact_and_round_trip():
    line = Reply(True, "RATE", ("1000",)).encode()
    assert line == b"$OK,RATE,1000*07\r\n"
    assert parse_reply(line) == Reply(True, "RATE", ("1000",))


@pytest.mark.parametrize(
    "line",
    [
        b"$OK,RATE,1000*00\r\n",  # wrong checksum
        b"$OK,RATE,1000\r\n",  # no checksum
        b"OK,RATE*1F\r\n",  # no $
        b"$\xff\xfe*00\r\n",
        b"$MAYBE,RATE*" + b"00\r\n",
        b"$OK,RATE*ZZ\r\n",
        b"$OK,RATE,1000* 7\r\n",  # a space for a hex digit (the checksum is 0x07)
        b"$OK,RATE,1000*+7\r\n",
        b"$OK,RATE,1000*7\r\n",
        b"$OK,IDENT*7a\r\n",  # lower-case hex (the checksum is 0x7A)
        b"$" + b"A" * 300 + b"*00\r\n",
    ],
)
def test_garbage_replies_are_malformed(line):
    """Each line is one fault away from a valid reply (``$OK,IDENT*7A``, ``$OK,RATE,1000*07``)."""
    with pytest.raises(MalformedReplyError):
        parse_reply(line)
