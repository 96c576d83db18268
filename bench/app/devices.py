"""Opening the bench: the configured devices, or the simulated lab when the configuration names none.

:func:`open_bench` connects the actuator controller (Modbus TCP or RTU, on a thread of its own:
:mod:`bench.app.actuator_thread`) and the WFS acquisition (serial), brought to a known state (a
stream left running is stopped, then the configured rate set), and chooses who answers the prompts;
on the simulated bench it first starts the simulated lab (:mod:`bench.app.simulated`; a paced one
in a process of its own, :mod:`bench.app.lab_process`) and connects to it over the same
transports. A device that cannot be reached raises :class:`DeviceUnreachableError`, naming the
configuration's keys and the address tried; a device another process holds raises
:class:`DeviceInUseError` (one master per device: :mod:`bench.locks`), a controller found moving
:class:`ControllerStateError`, both before anything is written to a device. This is the one
module of the run that needs the drivers' clients (pymodbus, pyserial) and the simulators; it is
imported only when a bench is opened.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass

from bench import locks
from bench.app.actuator_thread import ThreadedActuator
from bench.app.answers import FileAnswers
from bench.app.lab_process import LabProcess
from bench.app.simulated import SimulatedLab, SimulatedLabSettings, TargetAnswers
from bench.app.terminal import TerminalOperator
from bench.config import BenchConfig
from bench.engine.contracts import Operator
from bench.locks import InUseError
from drivers.actuator import ActuatorClient, ActuatorStatus
from drivers.errors import LinkError
from drivers.register_map import MOVING_STATES
from drivers.wfs_reader import WfsReader


@dataclass
class BenchDevices:
    """The opened devices: the actuator, the acquisition, the person (or simulated operator)."""

    actuator: ThreadedActuator
    acquisition: WfsReader
    operator: Operator
    lab: SimulatedLab | LabProcess | None = None


@contextlib.contextmanager
def open_bench(
    config: BenchConfig,
    operator: Operator | None = None,
    answers: Mapping[str, float | str | bool] | None = None,
) -> Iterator[BenchDevices]:
    """Open the configured devices, or the simulated lab when the configuration names none.

    ``operator``: who answers prompts (default: the simulated operator on the simulated bench, the
    terminal on real hardware; the front ends pass their own). ``answers``: prompt answers checked
    beforehand (:func:`bench.app.answers.load_answers`), given instead of an operator: on the
    simulated bench they are applied to the simulated world."""
    if operator is not None and answers is not None:
        raise ValueError("give an operator or answers, not both")
    transports = {config.actuator.transport, config.wfs.transport}
    if "simulated" in transports and transports != {"simulated"}:
        simulated = [
            f"{device}.transport"
            for device, transport in (("actuator", config.actuator.transport), ("wfs", config.wfs.transport))
            if transport == "simulated"
        ]
        raise ValueError(
            f"{config.source}: {', '.join(simulated)}: a simulated device cannot be mixed with real ones"
            " (the simulated transport is the default: set every device's transport)"
        )
    with contextlib.ExitStack() as stack:
        lab = None
        if config.simulated:
            settings = SimulatedLabSettings(
                kind=config.kind,
                paced=config.simulation.paced,
                flow_control=config.simulation.flow_control,
                wfs_hold_s=config.simulation.wfs_hold_s,
                seed=config.simulation.seed,
                tyre_pressure_bar=config.specimen.tyre_pressure_bar,
                specimen_mounted=config.specimen.wheel_fitted,
                tyre_model=config.specimen.tyre_model,
                nonlinear=config.specimen.nonlinear,
                damper_nonlinear=config.specimen.damper_nonlinear,
                aux_roles=tuple(a.channel.role for a in config.aux),
                register_map=config.actuator.register_map,
            )
            lab_class = LabProcess if config.simulation.in_own_process else SimulatedLab
            lab = stack.enter_context(lab_class(settings))
            host, port = lab.address
            wfs_url = lab.wfs_port
            if answers is not None:
                operator = FileAnswers(answers, lab.operator)
            operator = operator or TargetAnswers(lab.operator)
        else:
            host, port, wfs_url = config.actuator.host, config.actuator.port, config.wfs.device
            _hold_devices(config, stack)  # before anything is opened, sent or read
            if answers is not None:
                operator = FileAnswers(answers)
        operator = operator or TerminalOperator()
        actuator = ThreadedActuator(lambda: _client(config, host, port))
        stack.callback(actuator.close)
        try:
            actuator.connect(
                config.actuator.heartbeat_period_s,
                config.actuator.watchdog_ms,
                check=lambda status: _expect_at_rest(config, host, port, status),
            )
        except ControllerStateError:
            raise
        except (LinkError, OSError) as exc:
            raise DeviceUnreachableError(config, "actuator", host, port, exc) from exc
        reader = WfsReader.serial(wfs_url, baudrate=config.wfs.baudrate)
        stack.enter_context(reader)
        if not reader.wait_connected(config.timing.connect_timeout_s):
            raise DeviceUnreachableError(config, "wfs", wfs_url, None, reader.last_error)
        _known_state(reader, config.wfs.rate_hz)
        yield BenchDevices(actuator, reader, operator, lab)


def _known_state(reader: WfsReader, rate_hz: int) -> None:
    """Bring the WFS acquisition to a known state: not streaming, at the configured rate.

    A stream left running (a run that lost the link before it could stop it, another program) is
    stopped first: STOP is idempotent, its reply comes behind every frame still in flight (no
    subscription takes them, so they are dropped), then RATE, which the device refuses while it
    streams."""
    reader.stop_stream()
    reader.set_rate(rate_hz)


class DeviceUnreachableError(ConnectionError):
    """A device of the bench could not be opened: the message names the configuration file and the
    keys that say where the device is, the address tried and why it failed."""

    def __init__(self, config: BenchConfig, device: str, where: str, port: int | None, cause: object) -> None:
        if device == "wfs":
            keys, what = "wfs.device", f"the WFS acquisition at {where}"
        elif config.actuator.transport == "rtu":
            keys, what = "actuator.device", f"the actuator controller at {config.actuator.device}"
        else:
            keys, what = "actuator.host, actuator.port", f"the actuator controller at {where}:{port}"
        origin = f"{config.source}: {keys}: " if not config.simulated else ""
        super().__init__(f"{origin}cannot reach {what}: {cause}")


class DeviceInUseError(DeviceUnreachableError):
    """A device of the bench is held by another process (its lock, :mod:`bench.locks`): the message
    names the configuration's keys, the device and the holder (pid and command line)."""

    def __init__(self, config: BenchConfig, keys: str, cause: InUseError) -> None:
        self.cause = cause
        ConnectionError.__init__(self, f"{config.source}: {keys}: {cause}")


class ControllerStateError(DeviceUnreachableError):
    """The actuator controller is in a state the bench is not opened in: it moves (an excitation
    this program did not start, from another master or a run that ended moments ago)."""

    def __init__(self, config: BenchConfig, where: str, status: ActuatorStatus) -> None:
        self.status = status
        origin = "" if config.simulated else f"{config.source}: "
        state = status.state.name
        ConnectionError.__init__(
            self,
            f"{origin}the actuator controller at {where} is {state}: an excitation runs that this"
            " program did not start (another program drives the controller, or a run that just ended"
            " is tapering out); wait until it is at rest, or stop it at the controller, then open the"
            " bench again. Nothing was written to it",
        )


def _hold_devices(config: BenchConfig, stack: contextlib.ExitStack) -> None:
    """Take the locks of the WFS port and of the controller (its serial port, or its TCP address)
    for the life of ``stack``: a device another process holds is refused (:class:`DeviceInUseError`),
    naming the holder, before this process opens it."""
    a = config.actuator
    if a.transport == "rtu":
        what = f"the actuator controller's port {a.device}"
        controller = (locks.serial_key(a.device), what, "actuator.device")
    else:
        controller = (
            locks.tcp_key(a.host, a.port),
            f"the actuator controller at {a.host}:{a.port}",
            "actuator.host, actuator.port",
        )
    wfs = (locks.serial_key(config.wfs.device), f"the WFS port {config.wfs.device}", "wfs.device")
    for key, what, keys in (wfs, controller):
        try:
            stack.enter_context(locks.holding(key, what))
        except InUseError as exc:
            raise DeviceInUseError(config, keys, exc) from None


def _expect_at_rest(config: BenchConfig, host: str, port: int, status: ActuatorStatus) -> None:
    """Refuse a controller found moving when the bench opens (:class:`ControllerStateError`)."""
    if status.state in MOVING_STATES:
        where = config.actuator.device if config.actuator.transport == "rtu" else f"{host}:{port}"
        raise ControllerStateError(config, where, status)


def _client(config: BenchConfig, host: str, port: int) -> ActuatorClient:
    a = config.actuator
    common = {
        "register_map": a.load_register_map(),
        "limits": config.limits,
        "timeout_s": a.timeout_s,
        "read_attempts": a.read_attempts,
    }
    if a.transport == "rtu":
        return ActuatorClient.rtu(a.device, baudrate=a.baudrate, **common)
    return ActuatorClient.tcp(host, port, **common)
