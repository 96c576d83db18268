"""Async client of the servo-hydraulic actuator controller, over Modbus TCP or Modbus RTU.

Typed operations on top of the register map. Safety rules kept here:

- every setpoint is checked against the bench's soft limits before anything is written;
- START is sent only after a configure that completed (a failed configure may leave the controller
  with a half-written setpoint);
- raw register writes are private: every setpoint goes through the checked operations;
- reads are retried on timeout; writes are never re-sent (a write that timed out raises
  :class:`CommandOutcomeUnknownError`: read the status to learn what happened);
- timeouts, exception replies and lost connections become the typed errors of ``drivers.errors``.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from dataclasses import dataclass

from pymodbus.client import AsyncModbusSerialClient, AsyncModbusTcpClient
from pymodbus.client.base import ModbusBaseClient
from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException

from drivers.errors import (
    CommandOutcomeUnknownError,
    CommandRejectedError,
    ConnectionLostError,
    DeviceExceptionError,
    LinkTimeoutError,
    NotConfiguredError,
    ProtocolMismatchError,
)
from drivers.register_map import (
    Command,
    ControllerState,
    ErrorCode,
    InterlockFlag,
    RegisterMap,
    load_register_map,
)
from drivers.setpoints import DwellSetpoint, SoftLimits, SweepSetpoint

log = logging.getLogger(__name__)

ALL_POSTS = 0x000F
#: Modbus exception codes by which the controller refuses a write: ILLEGAL_VALUE, DEVICE_BUSY
_REFUSAL_CODES = (3, 6)
#: reply timeout of one request (s): a 30-register reply takes a few ms even on RTU at 115200 baud
DEFAULT_TIMEOUT_S = 0.3
#: read attempts before a read timeout is raised
DEFAULT_READ_ATTEMPTS = 3
#: heartbeat write period (s) and controller watchdog (ms); the watchdog exceeds the longest a
#: request can hold the link (timeout x attempts) plus the period: 0.3 x 3 + 0.1 = 1.0 s < 1.5 s
DEFAULT_HEARTBEAT_PERIOD_S = 0.1
DEFAULT_WATCHDOG_MS = 1500


@dataclass(frozen=True)
class ActuatorStatus:
    """A snapshot of the controller's input registers, in engineering units."""

    protocol_version: int
    state: ControllerState
    interlock: InterlockFlag
    error: ErrorCode
    heartbeat_echo: int
    cycle_count: int
    achieved_amplitude_mm: float
    displacement_mm: float
    force_n: float
    frequency_hz: float
    sample_count: int

    @property
    def moving(self) -> bool:
        return self.state in (ControllerState.RUNNING, ControllerState.TAPERING)


class ActuatorClient:
    """Typed operations on the actuator controller.

    Create it with :meth:`tcp` or :meth:`rtu`, then ``await connect()``.
    """

    def __init__(
        self,
        modbus: ModbusBaseClient,
        register_map: RegisterMap,
        limits: SoftLimits,
        read_attempts: int = DEFAULT_READ_ATTEMPTS,
        timeout_s: float = DEFAULT_TIMEOUT_S,
    ) -> None:
        """``timeout_s`` is the reply timeout ``modbus`` was created with (s): the heartbeat needs it."""
        self._modbus = modbus
        self.map = register_map
        self.limits = limits
        self.read_attempts = read_attempts
        self.timeout_s = timeout_s
        self._heartbeat_task: asyncio.Task | None = None
        self.heartbeat_failures = 0
        self._configured = False  # the last configure wrote every register of its setpoint

    @classmethod
    def tcp(
        cls,
        host: str,
        port: int,
        *,
        register_map: RegisterMap | None = None,
        limits: SoftLimits | None = None,
        timeout_s: float = DEFAULT_TIMEOUT_S,
        read_attempts: int = DEFAULT_READ_ATTEMPTS,
    ) -> ActuatorClient:
        """A client over Modbus TCP (pymodbus' own retries are off: this class decides)."""
        modbus = AsyncModbusTcpClient(host, port=port, timeout=timeout_s, retries=0, reconnect_delay=0.1)
        limits = limits or SoftLimits()
        return cls(modbus, register_map or load_register_map(), limits, read_attempts, timeout_s)

    @classmethod
    def rtu(
        cls,
        port: str,
        *,
        baudrate: int = 115200,
        register_map: RegisterMap | None = None,
        limits: SoftLimits | None = None,
        timeout_s: float = DEFAULT_TIMEOUT_S,
        read_attempts: int = DEFAULT_READ_ATTEMPTS,
    ) -> ActuatorClient:
        """A client over Modbus RTU on a serial port (8N1)."""
        modbus = AsyncModbusSerialClient(
            port, baudrate=baudrate, timeout=timeout_s, retries=0, reconnect_delay=0.1
        )
        limits = limits or SoftLimits()
        return cls(modbus, register_map or load_register_map(), limits, read_attempts, timeout_s)

    # -- connection ---------------------------------------------------------------------------

    async def connect(self) -> ActuatorStatus:
        """Open the link, check the protocol version, and return the first status."""
        if not await self._modbus.connect():
            host = self._modbus.comm_params.host
            raise ConnectionLostError(f"cannot connect to the actuator controller at {host}")
        status = await self.read_status()
        if status.protocol_version != self.map.protocol_version:
            raise ProtocolMismatchError(
                f"controller speaks protocol version {status.protocol_version}, "
                f"the register map {self.map.source} expects {self.map.protocol_version}"
            )
        return status

    async def close(self) -> None:
        await self.stop_heartbeat()
        self._modbus.close()

    @property
    def connected(self) -> bool:
        return bool(self._modbus.connected)

    # -- low level ----------------------------------------------------------------------------

    async def _call(self, operation: str, coro):
        """Run one request and turn every pymodbus failure into a typed error."""
        try:
            response = await coro
        except ConnectionException as exc:
            raise ConnectionLostError(f"{operation}: link to the controller is down ({exc})") from exc
        except ModbusIOException as exc:
            if not self._modbus.connected:
                raise ConnectionLostError(f"{operation}: connection dropped ({exc})") from exc
            raise LinkTimeoutError(f"{operation}: no reply ({exc})") from exc
        except ModbusException as exc:
            raise ConnectionLostError(f"{operation}: {exc}") from exc
        if response.isError():
            raise DeviceExceptionError(operation, int(getattr(response, "exception_code", 0)))
        return response

    async def read_table(self, table: str) -> dict[str, float | int]:
        """Read every register of ``table`` in one request, retrying on timeout."""
        first, count = self.map.span(table)
        read = (
            self._modbus.read_holding_registers if table == "holding" else self._modbus.read_input_registers
        )
        for attempt in range(1, self.read_attempts + 1):
            try:
                response = await self._call(
                    f"read {table} registers", read(first, count=count, device_id=self.map.device_id)
                )
                break
            except LinkTimeoutError:
                if attempt == self.read_attempts:
                    raise
                log.warning("read %s registers timed out (attempt %d), retrying", table, attempt)
        if len(response.registers) != count:
            raise DeviceExceptionError(f"read {table} registers: got {len(response.registers)} of {count}", 0)
        return self.map.decode_span(table, first, list(response.registers))

    async def _write(self, values: dict[str, float]) -> None:
        """Write named holding registers, never re-sending on timeout (unchecked: callers check)."""
        for address, words in self.map.encode_many("holding", values):
            operation = f"write registers {address}..{address + len(words) - 1}"
            try:
                await self._call(
                    operation,
                    self._modbus.write_registers(address, words, device_id=self.map.device_id),
                )
            except LinkTimeoutError as exc:
                raise CommandOutcomeUnknownError(f"{operation}: {exc}; not re-sent, read the status") from exc

    async def _refusal(self, exc: DeviceExceptionError, what: str) -> CommandRejectedError:
        """The typed refusal for an ILLEGAL_VALUE or DEVICE_BUSY reply, naming the controller's
        reason; any other exception reply (a device failure, ...) is re-raised as it is."""
        if exc.exception_code not in _REFUSAL_CODES:
            raise exc
        reason = ErrorCode((await self.read_table("input"))["error_code"])
        return CommandRejectedError(f"controller refused {what}: {reason.name}")

    async def command(self, command: Command) -> None:
        """Write a command code; a refusal (ILLEGAL_VALUE, DEVICE_BUSY) raises
        :class:`CommandRejectedError` naming the reason, other exception replies DeviceExceptionError.

        ``Command.START`` goes through :meth:`start`, which checks the last configure completed.
        """
        if command is Command.START and not self._configured:
            raise NotConfiguredError("START not sent: no setpoint was configured completely; configure again")
        try:
            await self._write({"command": int(command)})
        except DeviceExceptionError as exc:
            raise await self._refusal(exc, command.name) from exc

    # -- typed operations ---------------------------------------------------------------------

    async def read_status(self) -> ActuatorStatus:
        raw = await self.read_table("input")
        return ActuatorStatus(
            protocol_version=int(raw["protocol_version"]),
            state=ControllerState(raw["state"]),
            interlock=InterlockFlag(raw["interlock_flags"]),
            error=ErrorCode(raw["error_code"]),
            heartbeat_echo=int(raw["heartbeat_echo"]),
            cycle_count=int(raw["cycle_count"]),
            achieved_amplitude_mm=float(raw["achieved_amplitude_mm"]),
            displacement_mm=float(raw["actual_displacement_mm"]),
            force_n=float(raw["actual_force_n"]),
            frequency_hz=float(raw["frequency_hz"]),
            sample_count=int(raw["sample_count"]),
        )

    async def hydraulics_off(self) -> None:
        await self.command(Command.HYDRAULICS_OFF)

    async def hydraulics_low(self) -> None:
        await self.command(Command.HYDRAULICS_LOW)

    async def hydraulics_high(self) -> None:
        await self.command(Command.HYDRAULICS_HIGH)

    async def configure(self, setpoint: DwellSetpoint | SweepSetpoint, channel_mask: int = ALL_POSTS) -> None:
        """Check ``setpoint`` against the soft limits, then write it with the interlock thresholds."""
        values = setpoint.registers(self.limits)  # raises LimitError before anything is written
        values["channel_mask"] = channel_mask
        values["displacement_limit_mm"] = self.limits.displacement_limit_mm
        values["force_limit_n"] = self.limits.force_limit_n
        self._configured = False
        try:
            await self._write(values)
        except DeviceExceptionError as exc:
            raise await self._refusal(exc, "the setpoint") from exc
        self._configured = True

    @property
    def configured(self) -> bool:
        """Whether the last :meth:`configure` completed (START is refused otherwise)."""
        return self._configured

    async def start(self) -> None:
        """Start the configured excitation; NotConfiguredError (nothing sent) unless the last
        :meth:`configure` completed."""
        await self.command(Command.START)

    async def stop(self) -> None:
        """Stop with the configured taper-out (never an abrupt stop)."""
        await self.command(Command.STOP)

    async def estop(self) -> None:
        await self.command(Command.ESTOP)

    async def reset_interlock(self) -> None:
        await self.command(Command.RESET_INTERLOCK)

    # -- heartbeat ----------------------------------------------------------------------------

    def longest_block_s(self, period_s: float) -> float:
        """The longest a heartbeat can be held back (s): requests are serialised on the link, so a
        heartbeat may wait for a read that times out on every attempt, plus one heartbeat period."""
        return self.timeout_s * self.read_attempts + period_s

    async def start_heartbeat(
        self, period_s: float = DEFAULT_HEARTBEAT_PERIOD_S, watchdog_ms: int = DEFAULT_WATCHDOG_MS
    ) -> None:
        """Arm the controller's watchdog and keep writing a changing heartbeat every ``period_s``.

        Raises ValueError (nothing written) when ``watchdog_ms`` is not longer than
        :meth:`longest_block_s`: one slow reply would then starve the heartbeat and trip the bench.
        """
        longest_ms = self.longest_block_s(period_s) * 1000
        if watchdog_ms <= longest_ms:
            raise ValueError(
                f"a {watchdog_ms} ms watchdog would trip on one slow reply: a request can hold the link "
                f"for {self.timeout_s} s x {self.read_attempts} attempts + the {period_s} s heartbeat "
                f"period = {longest_ms:.0f} ms; lengthen the watchdog or shorten the timeout/attempts"
            )
        await self._write({"watchdog_ms": watchdog_ms, "heartbeat": 1})
        await self.stop_heartbeat()
        self._heartbeat_task = asyncio.create_task(self._beat(period_s), name="actuator-heartbeat")

    async def stop_heartbeat(self) -> None:
        """Stop beating; the controller's watchdog then tapers any running excitation to a stop."""
        task, self._heartbeat_task = self._heartbeat_task, None
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task

    async def _beat(self, period_s: float) -> None:
        counter = 1
        while True:
            await asyncio.sleep(period_s)
            counter = counter % 0xFFFF + 1
            try:
                await self._write({"heartbeat": counter})
            except (LinkTimeoutError, ConnectionLostError, DeviceExceptionError) as exc:
                self.heartbeat_failures += 1
                log.warning("heartbeat write failed (%d so far): %s", self.heartbeat_failures, exc)
