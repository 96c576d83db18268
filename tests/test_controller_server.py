"""The simulated controller serves only what the register map documents: raw Modbus TCP requests on
127.0.0.1, checked byte for byte against the Modbus application protocol specification."""

from __future__ import annotations

import asyncio
import random
import struct

import pytest
from pymodbus import FramerType

from drivers.register_map import Command, ControllerState, ErrorCode, WaveformCode
from simulators.controller_model import POWER_UP
from simulators.controller_server import ControllerServer

TID = 0x1234


def _mbap(pdu: bytes, unit: int = 1, tid: int = TID, protocol: int = 0) -> bytes:
    return struct.pack(">HHHB", tid, protocol, len(pdu) + 1, unit) + pdu


async def _exchange(controller, frame: bytes, timeout_s: float = 2.0) -> bytes:
    """Send one raw frame on a fresh connection; return the reply's PDU (b"" if the server closed)."""
    reader, writer = await asyncio.open_connection(*controller.address)
    try:
        writer.write(frame)
        await writer.drain()
        header = await asyncio.wait_for(reader.read(7), timeout_s)
        if not header:
            return b""
        tid, protocol, length, _unit = struct.unpack(">HHHB", header)
        assert (tid, protocol) == (TID, 0)
        return await asyncio.wait_for(reader.readexactly(length - 1), timeout_s)
    finally:
        writer.close()


async def _read_holding(controller, address: int, count: int) -> list[int]:
    reply = await _exchange(controller, _mbap(struct.pack(">BHH", 3, address, count)))
    assert reply[:2] == bytes([3, 2 * count]), reply.hex()
    return list(struct.unpack(f">{count}H", reply[2:]))


async def _holding_image(controller) -> list[int]:
    """Every holding register: addresses 0-4, 10-49 and the drive block 50-169 (three reads)."""
    return (
        await _read_holding(controller, 0, 5)
        + await _read_holding(controller, 10, 40)
        + await _read_holding(controller, 50, 120)
    )


@pytest.mark.parametrize(
    ("name", "pdu"),
    [
        ("coil write 0 (hydraulics off)", struct.pack(">BHH", 5, 0, 0xFF00)),
        ("mask write register 0", struct.pack(">BHHH", 22, 0, 0x0000, 0x0004)),
        ("read/write watchdog_ms", struct.pack(">BHHHHBH", 23, 0, 1, 4, 1, 2, 50)),
        ("read coils", struct.pack(">BHH", 1, 0, 8)),
        ("read discrete inputs", struct.pack(">BHH", 2, 0, 8)),
        ("write coils", struct.pack(">BHHBB", 15, 0, 8, 1, 0xFF)),
    ],
)
async def test_only_function_codes_3_4_6_16_are_served(controller, bench, name, pdu):
    with bench.lock:
        assert bench.controller.command(Command.HYDRAULICS_LOW) is None
    before = await _holding_image(controller)
    reply = await _exchange(controller, _mbap(pdu))
    assert reply == bytes([pdu[0] | 0x80, 0x01]), f"{name}: {reply.hex()}"
    assert await _holding_image(controller) == before
    assert bench.controller.state == ControllerState.HYDRAULICS_LOW


@pytest.mark.parametrize(("function", "count"), [(3, 0), (3, 126), (4, 0), (4, 2000)])
async def test_read_quantity_outside_1_to_125_is_illegal_data_value(controller, function, count):
    reply = await _exchange(controller, _mbap(struct.pack(">BHH", function, 0, count)))
    assert reply == bytes([function | 0x80, 0x03])


@pytest.mark.parametrize(
    "pdu",
    [
        struct.pack(">BHHB", 16, 10, 0, 0),  # quantity 0
        struct.pack(">BHHB", 16, 10, 2, 2) + b"\x00\x00",  # byte count disagrees with quantity
    ],
)
async def test_write_multiple_with_a_bad_quantity_is_illegal_data_value(controller, pdu):
    assert await _exchange(controller, _mbap(pdu)) == bytes([0x90, 0x03])


@pytest.mark.parametrize(
    ("pdu", "function"),
    [
        (struct.pack(">BHH", 3, 5, 1), 3),  # holding gap 5-9
        (struct.pack(">BHH", 3, 0, 6), 3),  # a read running into the gap
        (struct.pack(">BHH", 3, 170, 1), 3),  # past the last holding register
        (struct.pack(">BHH", 4, 7, 2), 4),  # input gap 7-9
        (struct.pack(">BHH", 6, 7, 1), 6),
        (struct.pack(">BHHBHH", 16, 8, 2, 4, 0, 0), 16),
    ],
)
async def test_map_gaps_are_illegal_addresses(controller, pdu, function):
    before = await _holding_image(controller)
    assert await _exchange(controller, _mbap(pdu)) == bytes([function | 0x80, 0x02])
    assert await _holding_image(controller) == before


async def test_command_zero_is_refused_as_unknown(controller, bench):
    reply = await _exchange(controller, _mbap(struct.pack(">BHH", 6, 0, 0)))
    assert reply == bytes([0x86, 0x03])
    assert bench.controller.error == ErrorCode.UNKNOWN_COMMAND


async def test_power_up_registers_show_the_values_in_force(controller, bench):
    words = await _holding_image(controller)
    regs = controller.map.holding
    values = {
        name: controller.map.decode(reg, _words_of(words, reg.address, reg.width))
        for name, reg in regs.items()
        if name != "command"
    }
    # the drive memory at power-up: empty, its rate the default 1 kHz
    names = ("drive_rate_hz", "drive_length", "drive_offset", "drive_block")
    drive = {name: values.pop(name) for name in names}
    assert drive == dict(zip(names, (1000.0, 0, 0, (0.0,) * 60), strict=True))
    assert values == pytest.approx(POWER_UP)
    assert values["watchdog_ms"] > 0  # the watchdog is armed at power-up
    assert values == pytest.approx(bench.controller.setpoints)


def _words_of(image: list[int], address: int, width: int) -> list[int]:
    """Words of the holding image read as addresses 0-4 then 10-169."""
    offset = address if address < 5 else address - 5
    return image[offset : offset + width]


async def test_a_write_over_one_server_reads_back_over_another(controller, bench):
    """Two servers on one controller (TCP and RTU in ``sim serve``) show the same holding registers."""
    other = ControllerServer(bench)
    host, port = await other.serve_tcp("127.0.0.1", 0)
    other.address = (host, port)
    try:
        reply = await _exchange(controller, _mbap(struct.pack(">BHH", 6, 4, 900)))
        assert reply == bytes([6, 0, 4, 0x03, 0x84])
        assert (await _read_holding(other, 4, 1)) == [900]
    finally:
        await other.close()


@pytest.mark.parametrize(
    "header",
    [
        struct.pack(">HHHB", TID, 7, 6, 1) + struct.pack(">BHH", 3, 0, 1),  # protocol id 7
        struct.pack(">HHHB", TID, 0, 0, 1),  # length 0
        struct.pack(">HHHB", TID, 0, 300, 1) + b"\x03" * 20,  # length beyond 254
        struct.pack(">HHHB", TID, 0, 300, 1) + b"\x03" * 299,  # ... with all its bytes following
    ],
)
async def test_malformed_mbap_header_closes_the_connection(controller, header):
    reader, writer = await asyncio.open_connection(*controller.address)
    try:
        writer.write(header)
        await writer.drain()
        assert await asyncio.wait_for(reader.read(100), 2.0) == b""  # EOF: the server closed it
    finally:
        writer.close()


@pytest.mark.parametrize("count", [2, 20, 40, 100])
async def test_pipelined_requests_in_one_segment_are_all_answered_in_order(controller, count):
    """Heartbeat writes and reads, sent together in one write: each is answered with its own
    transaction id, in order, and each read sees the write just before it (served in order)."""
    requests = []
    for k in range(count // 2):
        requests.append(_mbap(struct.pack(">BHH", 6, 3, 100 + k), tid=2 * k + 1))  # heartbeat = 100 + k
        requests.append(_mbap(struct.pack(">BHH", 3, 3, 1), tid=2 * k + 2))  # read it back
    reader, writer = await asyncio.open_connection(*controller.address)
    try:
        writer.write(b"".join(requests))  # one segment on loopback: the server gets them at once
        await writer.drain()
        replies = await _read_replies_until(reader, count)
    finally:
        writer.close()
    assert [tid for tid, _ in replies] == list(range(1, count + 1)), f"{len(replies)} of {count} answered"
    for k in range(count // 2):
        assert replies[2 * k][1] == struct.pack(">BHH", 6, 3, 100 + k)  # the write's echo
        assert replies[2 * k + 1][1] == struct.pack(">BBH", 3, 2, 100 + k)


async def _read_replies_until(reader: asyncio.StreamReader, wanted: int) -> list[tuple[int, bytes]]:
    """Up to ``wanted`` replies; fewer if the server closes the connection or says nothing for 5 s."""
    replies = []
    for _ in range(wanted):
        try:
            header = await asyncio.wait_for(reader.readexactly(7), 5.0)
        except (asyncio.IncompleteReadError, TimeoutError):
            break
        tid, protocol, length, _unit = struct.unpack(">HHHB", header)
        assert protocol == 0
        replies.append((tid, await asyncio.wait_for(reader.readexactly(length - 1), 5.0)))
    return replies


async def test_a_request_split_over_segments_is_answered_once_whole(controller):
    request = _mbap(struct.pack(">BHH", 4, 0, 1))
    reader, writer = await asyncio.open_connection(*controller.address)
    try:
        for piece in (request[:3], request[3:9], request[9:]):  # header cut before its length, then PDU
            writer.write(piece)
            await writer.drain()
            await asyncio.sleep(0.01)  # separate segments; the answer waits for the whole request
        assert await _read_replies_until(reader, 1) == [(TID, bytes([4, 2, 0, 1]))]
    finally:
        writer.close()


@pytest.mark.parametrize("cut", [3, 9], ids=["inside the next header", "inside the next PDU"])
async def test_a_request_split_after_a_complete_one_is_answered_once_its_rest_comes(controller, cut):
    """A whole request and the start of the next in one segment; the first's reply goes out (it did
    empty the server's buffer, the next request's start with it, before the fix), then the rest."""
    first, second = (_mbap(struct.pack(">BHH", 4, 0, 1), tid=tid) for tid in (1, 2))
    reader, writer = await asyncio.open_connection(*controller.address)
    try:
        writer.write(first + second[:cut])
        await writer.drain()
        assert await _read_replies_until(reader, 1) == [(1, bytes([4, 2, 0, 1]))]  # sent meanwhile
        writer.write(second[cut:])
        await writer.drain()
        assert await _read_replies_until(reader, 1) == [(2, bytes([4, 2, 0, 1]))]
    finally:
        writer.close()


async def test_requests_sent_in_pieces_of_1_to_30_bytes_are_all_answered_in_order(controller):
    """200 requests cut into seeded pieces of 1-30 bytes, each written alone (a lab's client may
    split its writes anywhere): every one answered, with its own transaction id, in order."""
    data = b"".join(_mbap(struct.pack(">BHH", 4, 0, 1), tid=tid) for tid in range(1, 201))
    rng = random.Random(7)
    reader, writer = await asyncio.open_connection(*controller.address)
    try:
        position = 0
        while position < len(data):
            size = rng.randint(1, 30)
            writer.write(data[position : position + size])
            await writer.drain()
            await asyncio.sleep(0)  # let the server's replies go out between pieces
            position += size
        replies = await _read_replies_until(reader, 200)
    finally:
        writer.close()
    assert [tid for tid, _ in replies] == list(range(1, 201)), f"{len(replies)} of 200 answered"


@pytest.mark.parametrize(
    "malformed",
    [
        struct.pack(">HHHB", 2, 0, 300, 1) + bytes(299),  # length beyond 254, its bytes following
        struct.pack(">HHHB", 2, 0, 1, 1) + struct.pack(">BHH", 3, 0, 1),  # length 1, data following
        struct.pack(">HHHB", 2, 0, 0xFFFF, 1) + bytes(1000),
        struct.pack(">HHHB", 2, 5, 6, 1) + struct.pack(">BHH", 3, 0, 1),  # protocol id 5
    ],
    ids=["length 300", "length 1", "length 65535", "protocol id 5"],
)
async def test_a_malformed_length_after_a_request_closes_the_connection(controller, malformed):
    """A good request, then a malformed header with data after it, in one segment: the good one is
    answered, then the connection is closed; what followed the bad header is never served."""
    good = _mbap(struct.pack(">BHH", 4, 0, 1), tid=1)
    after = _mbap(struct.pack(">BHH", 4, 0, 1), tid=3)
    reader, writer = await asyncio.open_connection(*controller.address)
    try:
        writer.write(good + malformed + after)
        await writer.drain()
        assert await _read_replies_until(reader, 3) == [(1, bytes([4, 2, 0, 1]))]
        assert await asyncio.wait_for(reader.read(100), 5.0) == b""  # EOF: closed by the server
    finally:
        writer.close()


async def test_other_unit_ids_get_gateway_target_failed_to_respond(controller):
    reply = await _exchange(controller, _mbap(struct.pack(">BHH", 4, 0, 1), unit=2))
    assert reply == bytes([0x84, 0x0B])


def _modbus_crc(frame: bytes) -> bytes:
    """CRC-16/MODBUS (reflected 0xA001, initial 0xFFFF), low byte first: the RTU frame check."""
    crc = 0xFFFF
    for byte in frame:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return struct.pack("<H", crc)


@pytest.fixture
async def rtu_controller(bench):
    """The controller serving RTU frames over TCP on 127.0.0.1 (a serial-to-Ethernet converter)."""
    server = ControllerServer(bench)
    server.address = await server.serve_tcp("127.0.0.1", 0, framer=FramerType.RTU)
    yield server
    await server.close()


async def _rtu_exchange(controller, adu: bytes) -> bytes:
    reader, writer = await asyncio.open_connection(*controller.address)
    try:
        writer.write(adu + _modbus_crc(adu))
        await writer.drain()
        try:
            return await asyncio.wait_for(reader.read(256), 0.5)
        except TimeoutError:
            return b""  # no answer
    finally:
        writer.close()


@pytest.mark.parametrize(
    ("adu", "reply"),
    [
        (bytes([1, 5, 0, 0, 0xFF, 0]), bytes([1, 0x85, 1])),  # coil write: ILLEGAL_FUNCTION
        (bytes([1, 22, 0, 0, 0, 0, 0, 4]), bytes([1, 0x96, 1])),  # mask write: ILLEGAL_FUNCTION
        (bytes([1, 3, 0, 0, 0, 0]), bytes([1, 0x83, 3])),  # quantity 0: ILLEGAL_DATA_VALUE
        (bytes([1, 3, 0, 5, 0, 1]), bytes([1, 0x83, 2])),  # the gap: ILLEGAL_DATA_ADDRESS
        (bytes([2, 4, 0, 0, 0, 1]), b""),  # another device on the line: not ours to answer
    ],
)
async def test_rtu_frames_get_the_same_refusals_and_other_devices_no_answer(rtu_controller, adu, reply):
    expected = reply + _modbus_crc(reply) if reply else b""
    assert await _rtu_exchange(rtu_controller, adu) == expected


@pytest.mark.parametrize(("command", "exception"), [(0, 0x03), (99, 0x03), (int(Command.START), 0x06)])
async def test_a_refused_command_written_with_setpoints_applies_none_of_them(
    controller, bench, command, exception
):
    """Command, waveform and channel mask in one write (function 16 from address 0): the command is
    refused (unknown, or START with hydraulics off), so the waveform and mask are not applied."""
    before = await _holding_image(controller)
    pdu = struct.pack(">BHHB3H", 16, 0, 3, 6, command, int(WaveformCode.SINE_DWELL), 0x0001)
    assert await _exchange(controller, _mbap(pdu)) == bytes([0x90, exception])
    assert await _holding_image(controller) == before
    assert bench.controller.state == ControllerState.OFF
