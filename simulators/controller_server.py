"""The simulated actuator controller as a Modbus server (pymodbus 3.16), over TCP or RTU.

It serves only what the register map documents (the same TOML the client reads):

- function codes 3, 4, 6 and 16; any other answers ILLEGAL_FUNCTION (1) and changes nothing;
- read quantities 1..125 and write quantities 1..123 whose byte count matches, else
  ILLEGAL_DATA_VALUE (3), as the Modbus specification prescribes;
- only addresses the map names: the gaps between registers answer ILLEGAL_DATA_ADDRESS (2);
- only its device id: over TCP another unit id answers GATEWAY_TARGET_NO_RESPONSE (0x0B), on the
  RTU line (a bus other devices may share) it stays silent;
- a malformed MBAP header (protocol id not 0, length outside 2..254) closes the TCP connection.

Requests are served one at a time per connection, in order, each reply carrying its own request's
transaction id, as a single-threaded controller does; requests that arrive together (pipelined, in
one TCP segment) are each answered, in order. Both register tables are read from the
controller model's live state, so every server of one model shows the same values (the values in
force from power-up on); writes go through the model, which may refuse them (ILLEGAL_VALUE for an
unknown command or invalid setpoint, DEVICE_BUSY for a command the present state does not allow;
the reason lands in ``error_code``). On the RTU line every reply waits for the time the request and
the reply take on the wire at the configured baud rate (10 bits per byte), as on real hardware.

Faults for tests and dry runs: delayed replies (the client times out), exception replies, and a
dropped connection.
"""

from __future__ import annotations

import asyncio
import logging
import struct
from collections import deque
from dataclasses import dataclass

from pymodbus import FramerType
from pymodbus.constants import ExcCodes
from pymodbus.pdu import DecodePDU, ExceptionResponse, ModbusPDU
from pymodbus.server import ModbusSerialServer, ModbusTcpServer
from pymodbus.server.requesthandler import ServerRequestHandler
from pymodbus.simulator import DataType, SimData, SimDevice

from drivers.register_map import (
    FC_READ_HOLDING,
    FC_READ_INPUT,
    FC_WRITE_MULTIPLE,
    FC_WRITE_SINGLE,
    MAX_READ_QUANTITY,
    MAX_WRITE_QUANTITY,
    REFUSAL_EXCEPTION,
    RegisterMap,
    load_register_map,
)
from simulators.bench_sim import SimulatedBench
from simulators.controller_model import PROTOCOL_VERSION

log = logging.getLogger(__name__)

#: the table each served function code addresses
_TABLE_OF = {
    FC_READ_HOLDING: "holding",
    FC_READ_INPUT: "input",
    FC_WRITE_SINGLE: "holding",
    FC_WRITE_MULTIPLE: "holding",
}
#: MBAP length field (unit id + PDU): at least a function code, at most a 253-byte PDU
_MBAP_LENGTH = range(2, 255)
#: MBAP bytes before the unit id: transaction id, protocol id, length (the length counts from the unit id)
_MBAP_HEADER_BYTES = 6
_BITS_PER_BYTE = 10  # 8N1: start bit, 8 data bits, stop bit


class _Refused(ModbusPDU):
    """A request refused before it reaches the registers: answers ``exception`` and touches nothing."""

    def __init__(self, function_code: int, exception: ExcCodes) -> None:
        super().__init__()
        self.function_code = function_code
        self.exception = exception

    async def datastore_update(self, _context, _device_id: int) -> ModbusPDU:
        return ExceptionResponse(self.function_code, self.exception)


class _MapDecoder(DecodePDU):
    """Decodes requests, refusing what the register map does not document (see the module doc)."""

    def __init__(self, register_map: RegisterMap) -> None:
        super().__init__(is_server=True)
        self._served = {
            table: frozenset(
                a for r in register_map.table(table).values() for a in range(r.address, r.address + r.width)
            )
            for table in ("holding", "input")
        }

    def decode(self, frame: bytes) -> ModbusPDU | None:
        function_code = frame[0]
        refusal = self._refusal(function_code, frame[1:])
        if refusal is not None:
            return _Refused(function_code, refusal)
        return super().decode(frame)

    def _refusal(self, function_code: int, data: bytes) -> ExcCodes | None:
        if function_code not in _TABLE_OF:
            return ExcCodes.ILLEGAL_FUNCTION
        if len(data) < 4:
            return ExcCodes.ILLEGAL_VALUE
        address, quantity = struct.unpack_from(">HH", data)
        if function_code == FC_WRITE_SINGLE:
            quantity = 1
        elif function_code == FC_WRITE_MULTIPLE:
            byte_count = data[4] if len(data) > 4 else -1
            if (
                not 1 <= quantity <= MAX_WRITE_QUANTITY
                or byte_count != 2 * quantity
                or len(data) != 5 + byte_count
            ):
                return ExcCodes.ILLEGAL_VALUE
        elif not 1 <= quantity <= MAX_READ_QUANTITY:
            return ExcCodes.ILLEGAL_VALUE
        served = self._served[_TABLE_OF[function_code]]
        if any(a not in served for a in range(address, address + quantity)):
            return ExcCodes.ILLEGAL_ADDRESS
        return None


class _Connection(ServerRequestHandler):
    """One client connection (or the RTU line): checks MBAP headers, serves requests in order."""

    def __init__(self, owner, *args) -> None:
        super().__init__(owner, *args)
        self._pending: deque[tuple[ModbusPDU, tuple | None, int]] = deque()  # request, sender, bytes
        self._serial = asyncio.Lock()
        self._closing = False  # a malformed header came: nothing more is read
        #: bytes of an ADU whose rest has not come yet: a buffer of its own, since pymodbus empties
        #: ``recv_buffer`` whenever it sends (a reply going out would lose the next request's start)
        self._adu_bytes = b""

    def datagram_received(self, data: bytes, addr: tuple | None) -> None:
        """Over TCP, cut the stream into ADUs by their MBAP length and hand each on alone, so that
        every request of a segment is served (pymodbus decodes one ADU per arrival and drops a
        buffer beyond one ADU's size); a malformed header closes the connection at once, whatever
        follows it. A request split anywhere across segments is put together again, whatever replies
        go out meanwhile. On the RTU line (no MBAP, a single master waiting for each reply) pymodbus
        frames the bytes itself."""
        if not self.server.mbap:
            super().datagram_received(data, addr)
            return
        if self._closing:
            return
        self._adu_bytes += data
        while len(self._adu_bytes) >= _MBAP_HEADER_BYTES:
            protocol_id, length = struct.unpack_from(">2xHH", self._adu_bytes)
            if protocol_id != 0 or length not in _MBAP_LENGTH:
                log.warning("malformed MBAP header %s: closing the connection", self._adu_bytes[:7].hex(" "))
                self._adu_bytes = b""
                self._closing = True  # the requests before it are answered first, nothing after it
                self.loop.call_soon(lambda: self.loop.create_task(self._close_after_replies()))
                return
            size = _MBAP_HEADER_BYTES + length
            if len(self._adu_bytes) < size:
                return  # the rest of this ADU comes in a later segment
            adu, self._adu_bytes = self._adu_bytes[:size], self._adu_bytes[size:]
            self.callback_data(adu, addr)

    def callback_data(self, data: bytes, addr: tuple | None = None) -> int:
        used = super().callback_data(data, addr)
        if self.last_pdu:  # the base class scheduled handle_later for it
            self._pending.append((self.last_pdu, self.last_addr, used))
        return used

    async def _close_after_replies(self) -> None:
        async with self._serial:  # queued behind the requests that came before the bad header
            self.close()

    def handle_later(self) -> None:
        self.loop.create_task(self._serve(*self._pending.popleft()))

    async def _serve(self, pdu: ModbusPDU, addr: tuple | None, request_bytes: int) -> None:
        """Answer one request (``request_bytes`` long on the wire) after the ones before it; the
        reply carries this request's ids."""
        owner = self.server
        async with self._serial:
            if pdu.dev_id != owner.unit_id:
                if not owner.mbap:
                    return  # on a shared line another device's request is not ours to answer
                response: ModbusPDU = ExceptionResponse(pdu.function_code, ExcCodes.GATEWAY_NO_RESPONSE)
            else:
                try:
                    response = await pdu.datastore_update(owner.context, pdu.dev_id)
                except Exception:  # a model failure must answer, not kill the connection
                    log.exception("controller failed to serve %s", pdu)
                    response = ExceptionResponse(pdu.function_code, ExcCodes.DEVICE_FAILURE)
            response.transaction_id, response.dev_id = pdu.transaction_id, pdu.dev_id
            if owner.baudrate:
                wire_bytes = request_bytes + len(self.framer.buildFrame(response))
                await asyncio.sleep(wire_bytes * _BITS_PER_BYTE / owner.baudrate)
            self.server_send(response, addr)


class _StrictServing:
    """What both servers add to pymodbus: the map's decoder and unit id, MBAP checks, RTU pacing."""

    def _strict(self, register_map: RegisterMap, framer: FramerType, baudrate: int) -> None:
        self.decoder = _MapDecoder(register_map)
        self.unit_id = register_map.device_id
        self.mbap = framer == FramerType.SOCKET
        self.baudrate = baudrate
        self.connections_accepted = 0  # clients that connected since the server started (for tests)

    def callback_new_connection(self) -> _Connection:
        self.connections_accepted += 1
        return _Connection(self, self.trace_packet, self.trace_pdu, self.trace_connect)


class _StrictTcpServer(_StrictServing, ModbusTcpServer):
    def __init__(self, device: SimDevice, register_map: RegisterMap, framer: FramerType, **kwargs) -> None:
        super().__init__(device, framer=framer, **kwargs)
        self._strict(register_map, framer, 0)


class _StrictSerialServer(_StrictServing, ModbusSerialServer):
    def __init__(self, device: SimDevice, register_map: RegisterMap, baudrate: int, **kwargs) -> None:
        super().__init__(device, framer=FramerType.RTU, baudrate=baudrate, **kwargs)
        self._strict(register_map, FramerType.RTU, baudrate)


@dataclass
class ModbusFaults:
    """Faults applied to the next requests (counts decrease as they are used)."""

    delay_next: int = 0
    delay_s: float = 0.0
    exception_next: int = 0
    exception_code: ExcCodes = ExcCodes.DEVICE_FAILURE


class ControllerServer:
    """Serves the controller model of ``bench`` with the register map ``register_map``."""

    def __init__(self, bench: SimulatedBench, register_map: RegisterMap | None = None) -> None:
        self.bench = bench
        self.map = register_map or load_register_map()
        self.faults = ModbusFaults()
        self.writes_received = 0  # write requests that reached the controller (for tests)
        self.server: ModbusTcpServer | ModbusSerialServer | None = None
        self._holding_first, self._holding_count = self.map.span("holding")
        self._input_first, self._input_count = self.map.span("input")

    def _device(self) -> SimDevice:
        holding = [SimData(self._holding_first, count=self._holding_count, datatype=DataType.REGISTERS)]
        inputs = [SimData(self._input_first, count=self._input_count, datatype=DataType.REGISTERS)]
        bits = [SimData(0, count=16, values=False, datatype=DataType.BITS)]
        return SimDevice(self.map.device_id, simdata=(bits, bits, holding, inputs), action=self._action)

    # -- serving --------------------------------------------------------------------------------

    async def serve_tcp(
        self, host: str = "127.0.0.1", port: int = 0, framer: FramerType = FramerType.SOCKET
    ) -> tuple[str, int]:
        """Listen on TCP (loopback unless told otherwise); returns the bound address (port 0 allowed).

        ``framer`` RTU serves RTU frames over TCP (a serial-to-Ethernet converter), for tests.
        """
        self.server = _StrictTcpServer(self._device(), self.map, framer, address=(host, port))
        await self.server.serve_forever(background=True)
        return self.server.transport.sockets[0].getsockname()[:2]

    async def serve_rtu(self, port: str, baudrate: int = 115200) -> None:
        """Serve Modbus RTU on a serial port (a pty slave in dry runs), 8N1, paced at ``baudrate``."""
        self.server = _StrictSerialServer(self._device(), self.map, baudrate, port=port)
        await self.server.serve_forever(background=True)

    async def close(self) -> None:
        if self.server is not None:
            await self.server.shutdown()
            self.server = None

    def drop_connections(self) -> None:
        """Close every client connection, as a cable pulled on the controller's side."""
        if self.server is not None:
            for connection in list(self.server.active_connections.values()):
                connection.close()

    # -- register access ------------------------------------------------------------------------

    async def _action(  # noqa: PLR0917 - the signature pymodbus calls
        self,
        function_code: int,
        start_address: int,
        address: int,
        count: int,
        registers: list[int],
        set_values: list[int] | list[bool] | None,
    ) -> ExcCodes | None:
        if self.faults.delay_next > 0:
            self.faults.delay_next -= 1
            await asyncio.sleep(self.faults.delay_s)
        if self.faults.exception_next > 0:
            self.faults.exception_next -= 1
            return self.faults.exception_code
        if function_code == FC_READ_INPUT:
            self._refresh(registers, start_address, "input", self._input_values())
            return None
        if function_code == FC_READ_HOLDING:
            self._refresh(registers, start_address, "holding", self._holding_values())
            return None
        if set_values is None:
            return None
        self.writes_received += 1
        return self._apply_write(start_address, address, registers, [int(v) for v in set_values])

    def _refresh(
        self, registers: list[int], start_address: int, table: str, values: dict[str, float]
    ) -> None:
        for address, words in self.map.encode_many(table, values):
            registers[address - start_address : address - start_address + len(words)] = words

    def _holding_values(self) -> dict[str, float]:
        """The setpoints in force that the map names (``command`` reads 0: a command acts, it is not
        stored; a map without the optional registers serves a controller without them)."""
        with self.bench.lock:
            setpoints = self.bench.controller.setpoints
            values = {"command": 0, **setpoints, **self.bench.controller.drive.registers()}
            return {name: value for name, value in values.items() if name in self.map.holding}

    def _input_values(self) -> dict[str, float]:
        with self.bench.lock:
            ctrl = self.bench.controller
            rb = ctrl.readback
            drive = {"drive_loaded": ctrl.drive.loaded, "drive_crc32": ctrl.drive.crc32}
            return {
                "protocol_version": PROTOCOL_VERSION,
                "state": int(ctrl.state),
                "interlock_flags": int(ctrl.flags),
                "error_code": int(ctrl.error),
                "heartbeat_echo": int(ctrl.setpoints["heartbeat"]),
                "cycle_count": rb.cycle_count % (1 << 32),
                "achieved_amplitude_mm": rb.achieved_amplitude_mm,
                "actual_displacement_mm": rb.displacement_mm,
                "actual_force_n": rb.force_n,
                "frequency_hz": rb.frequency_hz,
                "sample_count": rb.sample_count % (1 << 32),
                **{
                    name: value
                    for name, value in drive.items()
                    if name in self.map.input
                },
            }

    def _apply_write(
        self, start_address: int, address: int, registers: list[int], values: list[int]
    ) -> ExcCodes | None:
        """Decode the registers a write touches and hand them to the controller model."""
        lo, hi = address, address + len(values)
        image = list(registers)
        image[lo - start_address : hi - start_address] = values
        touched: dict[str, float] = {}
        for reg in self.map.holding.values():
            if reg.address < hi and reg.address + reg.width > lo:
                if reg.address < lo or reg.address + reg.width > hi:
                    return ExcCodes.ILLEGAL_ADDRESS  # half of a 32-bit value
                offset = reg.address - start_address
                touched[reg.name] = self.map.decode(reg, image[offset : offset + reg.width])
        command = touched.pop("command", None)
        with self.bench.lock:
            ctrl = self.bench.controller
            if command is not None and ctrl.command_refusal(int(command)) is not None:
                refused = ctrl.command(int(command))  # records the reason; the setpoints stay as they are
            else:
                refused = ctrl.write_setpoints(touched) if touched else None
                if refused is None and command is not None:
                    refused = ctrl.command(int(command))
        if refused is not None:
            return ExcCodes(REFUSAL_EXCEPTION[refused])
        return None
