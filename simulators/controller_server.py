"""The simulated actuator controller as a Modbus server (pymodbus 3.16), over TCP or RTU.

The register tables follow the register map (the same TOML the client reads). Reads of the input
registers are answered from the controller model's live state; writes to the holding registers go
through the model, which may refuse them (ILLEGAL_VALUE for an unknown command or invalid setpoint,
DEVICE_BUSY for a command the present state does not allow; the reason lands in ``error_code``).

Faults for tests and dry runs: delayed replies (the client times out), exception replies, and a
dropped connection.
"""

from __future__ import annotations

import asyncio
from dataclasses import dataclass

from pymodbus import FramerType
from pymodbus.constants import ExcCodes
from pymodbus.server import ModbusSerialServer, ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from drivers.register_map import ErrorCode, RegisterMap, load_register_map
from simulators.bench_sim import SimulatedBench
from simulators.controller_model import PROTOCOL_VERSION

_FC_READ_INPUT = 4
_REFUSAL = {
    ErrorCode.UNKNOWN_COMMAND: ExcCodes.ILLEGAL_VALUE,
    ErrorCode.INVALID_SETPOINT: ExcCodes.ILLEGAL_VALUE,
    ErrorCode.NOT_ALLOWED_IN_STATE: ExcCodes.DEVICE_BUSY,
}


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

    async def serve_tcp(self, host: str = "127.0.0.1", port: int = 0) -> tuple[str, int]:
        """Listen on TCP (loopback unless told otherwise); returns the bound address (port 0 allowed)."""
        self.server = ModbusTcpServer(self._device(), address=(host, port))
        await self.server.serve_forever(background=True)
        return self.server.transport.sockets[0].getsockname()[:2]

    async def serve_rtu(self, port: str, baudrate: int = 115200) -> None:
        """Serve Modbus RTU on a serial port (a pty slave in dry runs), 8N1."""
        self.server = ModbusSerialServer(self._device(), framer=FramerType.RTU, port=port, baudrate=baudrate)
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
        if function_code == _FC_READ_INPUT:
            self._refresh_inputs(start_address, registers)
            return None
        if set_values is None:
            return None
        self.writes_received += 1
        return self._apply_write(start_address, address, registers, [int(v) for v in set_values])

    def _refresh_inputs(self, start_address: int, registers: list[int]) -> None:
        with self.bench.lock:
            ctrl = self.bench.controller
            rb = ctrl.readback
            values = {
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
            }
        for address, words in self.map.encode_many("input", values):
            registers[address - start_address : address - start_address + len(words)] = words

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
            refused = ctrl.write_setpoints(touched) if touched else None
            if refused is None and command is not None and command != 0:
                refused = ctrl.command(int(command))
        if refused is not None:
            return _REFUSAL[refused]
        return None
