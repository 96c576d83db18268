"""Async client of the servo-hydraulic actuator controller, over Modbus TCP or Modbus RTU.

Typed operations on top of the register map. Safety rules kept here:

- every setpoint is checked against the bench's limit envelope before anything is written;
- START is sent only after a configure that completed (a failed configure may leave the controller
  with a half-written setpoint);
- raw register writes are private: every setpoint goes through the checked operations;
- every reply is checked against its request (function code, address, quantity, byte count): a
  reply that belongs to another request (a late reply on an RTU line, which has no transaction
  ids) is drained and the read retried; a write that got one is an unknown outcome;
- reads are retried on timeout; writes are never re-sent (a write that timed out or got a foreign
  reply raises :class:`CommandOutcomeUnknownError`: read the status to learn what happened);
- timeouts, exception replies, foreign or malformed replies and lost connections become the typed
  errors of ``drivers.errors`` (all :class:`LinkError`);
- a heartbeat that can no longer be confirmed sets :attr:`ActuatorClient.heartbeat_lost` and calls
  ``on_link_lost``, so that a run engine learns it at once instead of from a counter.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from functools import partial
from typing import Any, TypeVar

import numpy as np
from pymodbus.client import AsyncModbusSerialClient, AsyncModbusTcpClient
from pymodbus.client.base import ModbusBaseClient
from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException
from pymodbus.pdu import ModbusPDU

from drivers.errors import (
    CommandOutcomeUnknownError,
    CommandRejectedError,
    ConnectionLostError,
    DeviceExceptionError,
    DriveMismatchError,
    LinkError,
    LinkTimeoutError,
    MalformedReplyError,
    MismatchedReplyError,
    NotConfiguredError,
    ProtocolMismatchError,
)
from drivers.register_map import (
    ALL_POSTS,
    FC_READ_HOLDING,
    FC_READ_INPUT,
    FC_WRITE_MULTIPLE,
    MOVING_STATES,
    REFUSAL_CODES,
    Command,
    ControllerState,
    ErrorCode,
    InterlockFlag,
    RegisterMap,
    load_register_map,
)
from drivers.setpoints import (
    NO_NOTCH,
    AmplitudeUpdate,
    DriveSetpoint,
    DwellSetpoint,
    FrequencyUpdate,
    SweepSetpoint,
)
from sequences.limits import BenchLimits

log = logging.getLogger(__name__)
_Code = TypeVar("_Code", ControllerState, ErrorCode)

#: reply timeout of one request (s): a 20-register reply takes 4.6 ms on RTU at 115200 baud and
#: about 1 ms on loopback TCP; the rest is margin for a loaded host
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
        return self.state in MOVING_STATES


class ActuatorClient:
    """Typed operations on the actuator controller.

    Create it with :meth:`tcp` or :meth:`rtu`, then ``await connect()``. ``on_link_lost(reason)``,
    if given, is called once when :attr:`heartbeat_lost` is set.
    """

    def __init__(
        self,
        modbus: ModbusBaseClient,
        register_map: RegisterMap,
        limits: BenchLimits,
        read_attempts: int = DEFAULT_READ_ATTEMPTS,
        timeout_s: float = DEFAULT_TIMEOUT_S,
        *,
        on_link_lost: Callable[[str], None] | None = None,
    ) -> None:
        """``timeout_s`` is the reply timeout ``modbus`` was created with (s): the heartbeat needs it."""
        self._modbus = modbus
        self.map = register_map
        self.limits = limits
        self.read_attempts = read_attempts
        self.timeout_s = timeout_s
        self.on_link_lost = on_link_lost
        self._heartbeat_task: asyncio.Task | None = None
        self.heartbeat_failures = 0
        self._heartbeat_lost = asyncio.Event()
        self._configured = False  # the last configure wrote every register of its setpoint
        self._link = asyncio.Lock()  # one request (and the drain after a foreign reply) at a time

    @classmethod
    def tcp(
        cls,
        host: str,
        port: int,
        *,
        register_map: RegisterMap | None = None,
        limits: BenchLimits | None = None,
        timeout_s: float = DEFAULT_TIMEOUT_S,
        read_attempts: int = DEFAULT_READ_ATTEMPTS,
        on_link_lost: Callable[[str], None] | None = None,
    ) -> ActuatorClient:
        """A client over Modbus TCP (pymodbus' own retries are off: this class decides)."""
        return cls._watching(
            lambda watch: AsyncModbusTcpClient(
                host, port=port, timeout=timeout_s, retries=0, reconnect_delay=0.1, trace_connect=watch
            ),
            register_map=register_map or load_register_map(),
            limits=limits or BenchLimits(),
            read_attempts=read_attempts,
            timeout_s=timeout_s,
            on_link_lost=on_link_lost,
        )

    @classmethod
    def rtu(
        cls,
        port: str,
        *,
        baudrate: int = 115200,
        register_map: RegisterMap | None = None,
        limits: BenchLimits | None = None,
        timeout_s: float = DEFAULT_TIMEOUT_S,
        read_attempts: int = DEFAULT_READ_ATTEMPTS,
        on_link_lost: Callable[[str], None] | None = None,
    ) -> ActuatorClient:
        """A client over Modbus RTU on a serial port (8N1)."""
        return cls._watching(
            lambda watch: AsyncModbusSerialClient(
                port,
                baudrate=baudrate,
                timeout=timeout_s,
                retries=0,
                reconnect_delay=0.1,
                trace_connect=watch,
            ),
            register_map=register_map or load_register_map(),
            limits=limits or BenchLimits(),
            read_attempts=read_attempts,
            timeout_s=timeout_s,
            on_link_lost=on_link_lost,
        )

    @classmethod
    def _watching(
        cls, make_modbus: Callable[[Callable[[bool], None]], ModbusBaseClient], **settings: Any
    ) -> ActuatorClient:
        """A client (``settings``: those of ``__init__``) on the pymodbus client ``make_modbus(watch)``
        makes, which calls ``watch(up)`` at every connection change: see :meth:`_connection_changed`."""
        client: ActuatorClient | None = None

        def watch(up: bool) -> None:
            if client is not None:
                client._connection_changed(up)

        client = cls(make_modbus(watch), **settings)
        return client

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

    async def _call(self, operation: str, function_code: int, request: Callable[[], Awaitable[ModbusPDU]]):
        """Send ``request()`` and turn every pymodbus failure into a typed error (pymodbus raises
        "not connected" when the request is made, before it is awaited); a reply of another function
        code than the request's raises :class:`MismatchedReplyError`."""
        try:
            response = await request()
        except ConnectionException as exc:
            raise ConnectionLostError(f"{operation}: link to the controller is down ({exc})") from exc
        except ModbusIOException as exc:
            if not self._modbus.connected:
                raise ConnectionLostError(f"{operation}: connection dropped ({exc})") from exc
            raise LinkTimeoutError(f"{operation}: no reply ({exc})") from exc
        except ModbusException as exc:
            raise ConnectionLostError(f"{operation}: {exc}") from exc
        if response.function_code & 0x7F != function_code:
            raise MismatchedReplyError(
                f"{operation}: the reply is of function code {response.function_code & 0x7F}, "
                f"the request of {function_code}"
            )
        if response.isError():
            raise DeviceExceptionError(operation, int(response.exception_code))
        return response

    async def _drain(self, deadline: float) -> None:
        """Let the line fall silent until ``deadline`` (event-loop time): replies that arrive with no
        request outstanding are discarded, so the next request sees only its own reply."""
        await asyncio.sleep(max(0.0, deadline - asyncio.get_running_loop().time()))

    async def _read_run(self, table: str, first: int, count: int) -> list[int]:
        """Read ``count`` registers from ``first`` in one request, retrying on a timeout or a foreign
        reply (each attempt holds the link for at most ``timeout_s``)."""
        function_code, read = (
            (FC_READ_HOLDING, self._modbus.read_holding_registers)
            if table == "holding"
            else (FC_READ_INPUT, self._modbus.read_input_registers)
        )
        operation = f"read {table} registers {first}..{first + count - 1}"
        loop = asyncio.get_running_loop()
        for attempt in range(1, self.read_attempts + 1):
            async with self._link:
                deadline = loop.time() + self.timeout_s
                try:
                    response = await self._call(
                        operation,
                        function_code,
                        partial(read, first, count=count, device_id=self.map.device_id),
                    )
                    if len(response.registers) == count:
                        return list(response.registers)
                    raise MismatchedReplyError(
                        f"{operation}: the reply holds {len(response.registers)} registers"
                    )
                except MismatchedReplyError as exc:
                    error: LinkError = exc
                    await self._drain(deadline)
                except LinkTimeoutError as exc:
                    error = exc
            if attempt == self.read_attempts:
                raise error
            log.warning("%s (attempt %d), retrying", error, attempt)
        raise AssertionError("unreachable: read_attempts < 1")

    async def read_table(self, table: str) -> dict[str, float | int]:
        """Read every register of ``table``, one request per run of consecutive registers."""
        values: dict[str, float | int] = {}
        for first, count in self.map.runs(table):
            values.update(self.map.decode_span(table, first, await self._read_run(table, first, count)))
        return values

    async def _write(self, values: dict[str, float]) -> None:
        """Write named holding registers, never re-sending (unchecked: callers check)."""
        for address, words in self.map.encode_many("holding", values):
            operation = f"write registers {address}..{address + len(words) - 1}"
            async with self._link:
                deadline = asyncio.get_running_loop().time() + self.timeout_s
                try:
                    response = await self._call(
                        operation,
                        FC_WRITE_MULTIPLE,
                        partial(self._modbus.write_registers, address, words, device_id=self.map.device_id),
                    )
                    if (response.address, response.count) != (address, len(words)):
                        raise MismatchedReplyError(
                            f"{operation}: the reply acknowledges {response.count} registers "
                            f"from {response.address}"
                        )
                except LinkTimeoutError as exc:
                    raise CommandOutcomeUnknownError(
                        f"{operation}: {exc}; not re-sent, read the status"
                    ) from exc
                except MismatchedReplyError as exc:
                    await self._drain(deadline)
                    raise CommandOutcomeUnknownError(
                        f"{operation}: {exc}; not re-sent, read the status"
                    ) from exc

    async def _refusal(self, exc: DeviceExceptionError, what: str) -> CommandRejectedError:
        """The typed refusal for an ILLEGAL_VALUE or DEVICE_BUSY reply, naming the controller's
        reason; any other exception reply (a device failure, ...) is re-raised as it is."""
        if exc.exception_code not in REFUSAL_CODES:
            raise exc
        raw = await self.read_table("input")
        reason = _enum(ErrorCode, raw["error_code"], "error_code")
        if reason is not ErrorCode.NOT_ALLOWED_IN_STATE:
            return CommandRejectedError(f"controller refused {what}: {reason.name}")
        state = _enum(ControllerState, raw["state"], "state")
        flags = InterlockFlag(raw["interlock_flags"])
        tripped = f" ({', '.join(flag.name.lower() for flag in flags)})" if flags else ""
        return CommandRejectedError(
            f"controller refused {what}: {reason.name}: the controller is in {state.name}{tripped}",
            awaits_reset=state in (ControllerState.INTERLOCK, ControllerState.ESTOP),
        )

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
            state=_enum(ControllerState, raw["state"], "state"),
            interlock=InterlockFlag(raw["interlock_flags"]),
            error=_enum(ErrorCode, raw["error_code"], "error_code"),
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

    async def configure(
        self, setpoint: DwellSetpoint | SweepSetpoint | DriveSetpoint, channel_mask: int = ALL_POSTS
    ) -> None:
        """Check ``setpoint`` against the bench's limits (LimitError before anything is written), then
        write it with the controller's interlock thresholds. A sweep's notch needs a controller whose
        map has the notch registers (CommandRejectedError, nothing written); a sweep without one
        clears the notch of the sweep before it there. A drive plays what the controller's drive
        memory holds: it must hold this drive (:meth:`load_drive`; CommandRejectedError, nothing
        written)."""
        values = setpoint.registers(self.limits)
        if isinstance(setpoint, DriveSetpoint) and not await self.holds_drive(setpoint):
            raise CommandRejectedError(
                "the controller does not hold the drive to play (its length or CRC-32 differ): load it first"
            )
        if isinstance(setpoint, SweepSetpoint) and self.map.sweep_notches:
            values = {**NO_NOTCH, **values}
        elif isinstance(setpoint, SweepSetpoint) and setpoint.notch is not None:
            raise CommandRejectedError(
                f"the register map {self.map.source} has no notch registers: the controller notches no sweep"
            )
        values["channel_mask"] = channel_mask
        values["displacement_limit_mm"] = self.limits.displacement_interlock_mm
        values["force_limit_n"] = self.limits.force_interlock_n
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

    async def holds_drive(self, drive: DriveSetpoint) -> bool:
        """Whether the controller's drive memory holds ``drive`` whole: its rate, length, the samples
        received and their CRC-32 (False for a map without drive registers)."""
        if not self.map.drive_files:
            return False
        held = await self._read_named("holding", ("drive_rate_hz", "drive_length"))
        received = await self._read_named("input", ("drive_loaded", "drive_crc32"))
        return (
            held["drive_rate_hz"] == np.float32(drive.sample_rate_hz)
            and held["drive_length"] == drive.n_samples
            and received["drive_loaded"] == drive.n_samples
            and received["drive_crc32"] == drive.crc32
        )

    async def load_drive(self, drive: DriveSetpoint) -> None:
        """Upload ``drive`` into the controller's drive memory, unless it holds it already
        (docs/protocols.md, *Drive files*): its rate and length, then its samples in blocks, each
        with its offset; then the controller's count and CRC-32 of what it received are checked.
        LimitError (nothing written) outside the bench's limits; CommandRejectedError when the map
        has no drive registers (nothing written) or the controller refuses a request (moving, a
        sample out of order), naming its reason; DriveMismatchError when the controller reports
        another drive than the one sent. A block whose reply came too late is settled by reading how
        many samples the controller has received: it is sent again only if it did not arrive."""
        if not self.map.drive_files:
            raise CommandRejectedError(
                f"the register map {self.map.source} has no drive_* registers: the controller plays no"
                " drive file"
            )
        drive.check(self.limits)
        if await self.holds_drive(drive):
            return
        try:
            await self._write(drive.upload_header())
            for block in drive.upload_blocks():
                await self._write_block(block, drive.n_samples)
        except DeviceExceptionError as exc:
            raise await self._refusal(exc, "the drive upload") from exc
        if not await self.holds_drive(drive):
            received = await self._read_named("input", ("drive_loaded", "drive_crc32"))
            raise DriveMismatchError(
                f"the controller received {received['drive_loaded']} samples with CRC-32"
                f" {received['drive_crc32']:08x}; the drive sent has {drive.n_samples} with {drive.crc32:08x}"
            )

    async def _write_block(self, block: dict[str, object], n_samples: int) -> None:
        """One block of an upload; a reply too late to tell is settled by ``drive_loaded``."""
        offset = int(block["drive_offset"])  # type: ignore[call-overload]
        try:
            await self._write(block)
        except CommandOutcomeUnknownError as exc:
            loaded = (await self._read_named("input", ("drive_loaded",)))["drive_loaded"]
            if loaded == offset:
                log.warning("drive block at %d: %s; it did not arrive: sent again", offset, exc)
                await self._write(block)
            elif loaded != min(offset + len(block["drive_block"]), n_samples):  # type: ignore[arg-type]
                raise

    async def _read_named(self, table: str, names: tuple[str, ...]) -> dict[str, float | int]:
        """The registers ``names`` of ``table``, consecutive in the map, in one read."""
        regs = [self.map.table(table)[name] for name in names]
        first = min(r.address for r in regs)
        count = max(r.address + r.width for r in regs) - first
        return self.map.decode_span(table, first, await self._read_run(table, first, count))

    async def update_amplitude(self, update: AmplitudeUpdate) -> None:
        """Give the sine dwell holding now a new amplitude, ramped (docs/protocols.md, *Amplitude
        held within the dwell*): LimitError (nothing written) outside the bench's limits;
        CommandRejectedError when the map has no such registers (nothing written) or the controller
        refuses it (outside a dwell's hold, beyond its own limits), naming its reason."""
        if not self.map.amplitude_updates:
            raise CommandRejectedError(
                f"the register map {self.map.source} has no amplitude_update_mm: the controller takes no"
                " amplitude update"
            )
        values = update.registers(self.limits)
        try:
            await self._write(values)
        except DeviceExceptionError as exc:
            raise await self._refusal(exc, "the amplitude update") from exc

    async def update_frequency(self, update: FrequencyUpdate) -> None:
        """Glide the sine dwell holding now to a new frequency (docs/protocols.md, *Frequency
        updates*): LimitError (nothing written) outside the bench's limits; CommandRejectedError when
        the map has no such register or the controller refuses it, naming its reason."""
        if not self.map.frequency_updates:
            raise CommandRejectedError(
                f"the register map {self.map.source} has no frequency_update_hz: the controller takes no"
                " frequency update"
            )
        try:
            await self._write(update.registers(self.limits))
        except DeviceExceptionError as exc:
            raise await self._refusal(exc, "the frequency update") from exc

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

    @property
    def heartbeat_lost(self) -> asyncio.Event:
        """Set when the running heartbeat can no longer be confirmed: the link is lost (a heartbeat
        write finds it down), or no heartbeat write has been acknowledged for the watchdog time (the
        controller's watchdog may have expired). Cleared by :meth:`start_heartbeat`.

        With the link closed it is set within one heartbeat period plus one reply timeout; when
        replies merely stop, within the watchdog time plus one period and one reply timeout.
        """
        return self._heartbeat_lost

    def longest_block_s(self, period_s: float) -> float:
        """The longest a heartbeat can be held back (s): requests are serialised on the link, so a
        heartbeat may wait for a read that times out (or drains a foreign reply) on every attempt,
        each attempt holding the link for at most one timeout, plus one heartbeat period."""
        return self.timeout_s * self.read_attempts + period_s

    async def start_heartbeat(
        self, period_s: float = DEFAULT_HEARTBEAT_PERIOD_S, watchdog_ms: int = DEFAULT_WATCHDOG_MS
    ) -> None:
        """Arm the controller's watchdog and keep writing a changing heartbeat every ``period_s``.

        Raises ValueError (nothing written) when ``watchdog_ms`` is not longer than
        :meth:`longest_block_s`: one slow reply would then starve the heartbeat and trip the bench.
        Arming is the one write sent again when its reply came too late to tell: it sets a
        configuration and a first beat, the same whether it lands once or twice (a busy host's late
        reply would otherwise leave the bench unopened).
        """
        longest_ms = self.longest_block_s(period_s) * 1000
        if watchdog_ms <= longest_ms:
            raise ValueError(
                f"a {watchdog_ms} ms watchdog would trip on one slow reply: a request can hold the link "
                f"for {self.timeout_s} s x {self.read_attempts} attempts + the {period_s} s heartbeat "
                f"period = {longest_ms:.0f} ms; lengthen the watchdog or shorten the timeout/attempts"
            )
        await self.stop_heartbeat()
        arm = {"watchdog_ms": watchdog_ms, "heartbeat": 1}
        try:
            await self._write(arm)
        except CommandOutcomeUnknownError as exc:
            log.warning("arming the watchdog: %s; sent again (it lands the same twice)", exc)
            await self._write(arm)
        self._heartbeat_lost.clear()
        self._heartbeat_task = asyncio.create_task(
            self._beat(period_s, watchdog_ms / 1000), name="actuator-heartbeat"
        )

    async def stop_heartbeat(self) -> None:
        """Stop beating; the controller's watchdog then tapers any running excitation to a stop."""
        task, self._heartbeat_task = self._heartbeat_task, None
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task

    async def _beat(self, period_s: float, watchdog_s: float) -> None:
        loop = asyncio.get_running_loop()
        counter = 1
        confirmed_at = loop.time()
        # stop_heartbeat clears the task before cancelling it: a cancellation lost inside a write
        # (Python 3.11's wait_for drops one that arrives with the reply) still ends the loop
        while self._heartbeat_task is asyncio.current_task():
            await asyncio.sleep(period_s)
            if self._heartbeat_lost.is_set():
                return  # lost meanwhile (the connection dropped): see below
            counter = counter % 0xFFFF + 1
            try:
                await self._write({"heartbeat": counter})
                confirmed_at = loop.time()
            except (LinkTimeoutError, ConnectionLostError, DeviceExceptionError) as exc:
                self.heartbeat_failures += 1
                log.warning("heartbeat write failed (%d so far): %s", self.heartbeat_failures, exc)
                unconfirmed_s = loop.time() - confirmed_at
                if isinstance(exc, ConnectionLostError):
                    self._lose_heartbeat(f"link lost: {exc}")
                elif unconfirmed_s >= watchdog_s:
                    self._lose_heartbeat(
                        f"no heartbeat acknowledged for {unconfirmed_s:.2f} s "
                        f"(watchdog {watchdog_s:g} s): {exc}"
                    )
                if self._heartbeat_lost.is_set():
                    # fail safe: a link that comes back must not revive a lost heartbeat, or it
                    # would keep alive an excitation nobody can stop; the controller's watchdog
                    # stops it, and start_heartbeat beats again
                    return

    def _connection_changed(self, up: bool) -> None:
        """A connection that drops while the heartbeat runs loses the heartbeat at once, even if
        pymodbus connects again before the next beat: requests may have been lost with it, and the
        controller may have dropped it for a reason of its own (fail safe, as a lost beat)."""
        beating = self._heartbeat_task is not None and not self._heartbeat_task.done()
        if not up and beating:
            self._lose_heartbeat("link lost: the connection to the controller dropped")

    def _lose_heartbeat(self, reason: str) -> None:
        if self._heartbeat_lost.is_set():
            return
        log.error("heartbeat lost: %s", reason)
        self._heartbeat_lost.set()
        if self.on_link_lost is not None:
            self.on_link_lost(reason)


def _enum(kind: type[_Code], value: float | int, name: str) -> _Code:
    """A protocol code read from the controller; a code the protocol does not define is a link error."""
    try:
        return kind(int(value))
    except ValueError as exc:
        raise MalformedReplyError(
            f"{name}: the controller sent {value!r}, not a {kind.__name__} code"
        ) from exc
