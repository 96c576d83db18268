"""The asynchronous Modbus client behind the engine's blocking actuator contract.

:class:`drivers.actuator.ActuatorClient` is asyncio code (pymodbus); the engine is a plain loop on
its own thread. :class:`ThreadedActuator` owns an event loop on a thread of its own, where the client
lives with its heartbeat task, and turns each contract call into a coroutine run there. Any thread
may call it: an e-stop from a front end's thread reaches the controller without waiting for the
engine's loop.

A hydraulics, start or stop command whose reply came too late (:class:`CommandOutcomeUnknownError`:
the client never re-sends a write) is settled by reading the status, as docs/protocols.md asks: the
controller in the state the command leads to means it took effect; any other state raises the
error, naming it. One slow reply on a loaded host therefore does not end a sequence. (A setpoint's
configure is not settled so: its several writes leave START refused until it is configured again.)
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import logging
import threading
from collections.abc import Callable, Coroutine
from dataclasses import dataclass
from typing import Any, TypeVar

from drivers.actuator import DEFAULT_HEARTBEAT_PERIOD_S, DEFAULT_WATCHDOG_MS, ActuatorClient, ActuatorStatus
from drivers.errors import CommandOutcomeUnknownError, ConnectionLostError, LinkTimeoutError
from drivers.register_map import MOVING_STATES, ControllerState, InterlockFlag
from drivers.setpoints import (
    DRIVE_BLOCK_SAMPLES,
    AmplitudeUpdate,
    DriveSetpoint,
    DwellSetpoint,
    FrequencyUpdate,
    SweepSetpoint,
)
from sequences.steps import HydraulicLevel

T = TypeVar("T")
log = logging.getLogger(__name__)

#: Longest a single contract call may take (s): a request's attempts with their timeouts and margin.
CALL_TIMEOUT_S = 5.0
#: The controller state each hydraulics level of the contract commands.
HYDRAULICS_STATES = {
    HydraulicLevel.OFF: ControllerState.OFF,
    HydraulicLevel.LOW: ControllerState.HYDRAULICS_LOW,
    HydraulicLevel.HIGH: ControllerState.HYDRAULICS_HIGH,
}


@dataclass(frozen=True)
class ControllerReadback:
    """The controller's status as the engine's contract states it."""

    status: ActuatorStatus

    @property
    def moving(self) -> bool:
        return self.status.moving

    @property
    def sample_count(self) -> int:
        return self.status.sample_count

    @property
    def interlock_reason(self) -> str | None:
        """What holds the controller in its interlock or e-stop: its interlock flags by name
        ("watchdog", "displacement, force"; "estop" in an e-stop, "no flag set" when it names
        none), None when it holds neither. The words name the cause only: the engine's interlock
        names the controller ("controller interlock: watchdog") and the UI its state."""
        tripped = self.status.state in (ControllerState.INTERLOCK, ControllerState.ESTOP)
        if not tripped and not self.status.interlock:
            return None
        names = [flag.name.lower() for flag in InterlockFlag if flag in self.status.interlock]
        if self.status.state is ControllerState.ESTOP and InterlockFlag.ESTOP not in self.status.interlock:
            names.insert(0, InterlockFlag.ESTOP.name.lower())
        return ", ".join(names) or "no flag set"


class ThreadedActuator:
    """The engine's :class:`bench.engine.contracts.Actuator` on an :class:`ActuatorClient`."""

    def __init__(self, make_client: Callable[[], ActuatorClient], *, heartbeat: bool = True) -> None:
        """``make_client()`` builds the client (it must be created inside the loop's thread)."""
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, name="actuator-link", daemon=True)
        self._thread.start()
        self._client: ActuatorClient = self._call(self._create(make_client))
        self._heartbeat = heartbeat
        self._beat = (DEFAULT_HEARTBEAT_PERIOD_S, DEFAULT_WATCHDOG_MS)

    async def _create(self, make_client: Callable[[], ActuatorClient]) -> ActuatorClient:
        return make_client()

    def _call(self, coro: Coroutine[Any, Any, T], timeout_s: float = CALL_TIMEOUT_S) -> T:
        """Run ``coro`` on the client's loop; what it raises is raised as it is (a
        :class:`LinkTimeoutError` of the client is a TimeoutError too, so only the wait itself
        running out is reported as this call taking too long)."""
        future = asyncio.run_coroutine_threadsafe(coro, self._loop)
        done, _ = concurrent.futures.wait((future,), timeout_s)
        if not done:
            future.cancel()
            raise LinkTimeoutError(f"actuator call took longer than {timeout_s} s")
        return future.result()

    # -- life cycle ---------------------------------------------------------------------------

    def connect(
        self,
        heartbeat_period_s: float = DEFAULT_HEARTBEAT_PERIOD_S,
        watchdog_ms: int = DEFAULT_WATCHDOG_MS,
        *,
        check: Callable[[ActuatorStatus], None] | None = None,
    ) -> ActuatorStatus:
        """Connect; with the heartbeat on, beat every ``heartbeat_period_s`` and arm the
        controller's watchdog with ``watchdog_ms``. ``check(status)`` sees the first status before
        anything is written (the heartbeat included) and may refuse the controller by raising."""
        self._beat = (heartbeat_period_s, watchdog_ms)
        status = self._call(self._client.connect())
        if check is not None:
            check(status)
        if self._heartbeat:
            self._call(self._client.start_heartbeat(*self._beat))
        return status

    def close(self) -> None:
        try:
            self._call(self._client.close())
        finally:
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join(timeout=5)
            self._loop.close()

    @property
    def client(self) -> ActuatorClient:
        return self._client

    # -- the contract -------------------------------------------------------------------------

    def read_status(self) -> ControllerReadback:
        return ControllerReadback(self._call(self._client.read_status()))

    def configure(self, setpoint: DwellSetpoint | SweepSetpoint | DriveSetpoint) -> None:
        """Write the setpoint; when a reply came too late to tell whether its writes took effect,
        write the whole setpoint once more. Unlike a command, a setpoint is a set of register
        values written while the actuator is at rest: writing the same values again leaves the
        controller as one write would, and only a completed write lets START through."""
        try:
            self._call(self._client.configure(setpoint))
        except CommandOutcomeUnknownError as exc:
            log.warning("setpoint: %s; written again", exc)
            # the late reply is still on its way: a status read (its retries drain a reply that is
            # not its own) waits it out, so the second write's reply is not queued behind it
            self.read_status()
            self._call(self._client.configure(setpoint))

    @property
    def amplitude_updates(self) -> bool:
        """Whether the controller takes amplitude updates (its register map names the registers)."""
        return self._client.map.amplitude_updates

    @property
    def sweep_notches(self) -> bool:
        """Whether the controller lowers a sweep's amplitude over a notch (its map has the registers)."""
        return self._client.map.sweep_notches

    @property
    def frequency_updates(self) -> bool:
        """Whether the controller takes frequency updates (its register map names the register)."""
        return self._client.map.frequency_updates

    @property
    def drive_files(self) -> bool:
        """Whether the controller plays drive files (its register map names the drive registers)."""
        return self._client.map.drive_files

    def load_drive(self, drive: DriveSetpoint) -> None:
        """Upload the drive unless the controller holds it: one request per block, each within the
        client's reply timeout, so the call may take that long for every block."""
        requests = drive.n_samples // DRIVE_BLOCK_SAMPLES + 4  # the blocks, the header, the checks
        self._call(self._client.load_drive(drive), CALL_TIMEOUT_S + requests * self._client.timeout_s)

    def update_frequency(self, update: FrequencyUpdate) -> None:
        """A new frequency for the dwell holding now; a late reply is told by the hold sync output."""
        self._call(self._client.update_frequency(update))

    def update_amplitude(self, update: AmplitudeUpdate) -> None:
        """A new amplitude for the dwell holding now. A reply too late to tell is not settled here:
        the hold sync output in the frames shows whether the ramp came (the engine looks there)."""
        self._call(self._client.update_amplitude(update))

    def start(self) -> None:
        self._settled("start", self._client.start(), lambda state: state in MOVING_STATES)

    def stop(self) -> None:
        self._settled("stop", self._client.stop(), lambda state: state is not ControllerState.RUNNING)

    def estop(self) -> None:
        self._call(self._client.estop())

    def set_hydraulics(self, level: str) -> None:
        operation = {
            HydraulicLevel.OFF: self._client.hydraulics_off,
            HydraulicLevel.LOW: self._client.hydraulics_low,
            HydraulicLevel.HIGH: self._client.hydraulics_high,
        }[level]
        wanted = HYDRAULICS_STATES[level]
        self._settled(f"hydraulics {level}", operation(), lambda state: state is wanted)

    def _settled(
        self, what: str, command: Coroutine[Any, Any, None], took_effect: Callable[[ControllerState], bool]
    ) -> None:
        """Send ``command``; when its reply came too late to tell whether it took effect
        (:class:`CommandOutcomeUnknownError`), the status read after it decides: a state for which
        ``took_effect`` holds means it did; any other state raises the error, naming the state.
        Requests are answered in order, so the read sees the command if it arrived at all."""
        try:
            self._call(command)
        except CommandOutcomeUnknownError as exc:
            state = self._call(self._client.read_status()).state
            if not took_effect(state):
                raise CommandOutcomeUnknownError(
                    f"{what}: {exc}; the controller reads {state.name.lower()} after it"
                ) from exc
            log.warning("%s: %s; the controller reads %s: done", what, exc, state.name.lower())

    def reset_interlock(self) -> None:
        """Reset the controller; after a lost link, reconnect and beat again first (the lost
        heartbeat stays stopped until then, so that the controller's watchdog keeps its word). A
        reset whose reply came too late to tell (:class:`CommandOutcomeUnknownError`) is settled by
        the status read after it: still interlocked or e-stopped, it is sent once more."""
        if self.link_fault() is not None:
            self._call(self._client.connect())
            if self._heartbeat:
                self._call(self._client.start_heartbeat(*self._beat))
        try:
            self._call(self._client.reset_interlock())
        except CommandOutcomeUnknownError as exc:  # a starved host's late reply: read what it did
            state = self._call(self._client.read_status()).state
            if state not in (ControllerState.INTERLOCK, ControllerState.ESTOP):
                log.warning("reset: %s; the controller reads %s: done", exc, state.name.lower())
                return
            # not taken: a reset releases a latch and moves nothing, so it is sent once more
            log.warning("reset: %s; the controller still reads %s: sent again", exc, state.name.lower())
            self._call(self._client.reset_interlock())

    def link_fault(self) -> str | None:
        """Set from the moment the connection dropped or the heartbeat could no longer be confirmed
        (a single slow reply is not a fault) until :meth:`reset_interlock` restores the link."""
        if not self._client.connected:
            return str(ConnectionLostError("the Modbus connection to the controller is down"))
        if self._heartbeat and self._client.heartbeat_lost.is_set():
            return f"the heartbeat could not be confirmed ({self._client.heartbeat_failures} writes failed)"
        return None
