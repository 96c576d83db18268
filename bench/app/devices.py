"""Opening the bench: the configured devices, or the simulated lab when the configuration names none.

:func:`open_bench` connects the actuator controller (Modbus TCP or RTU, on a thread of its own:
:mod:`bench.app.actuator_thread`) and the WFS acquisition (serial), brought to a known state (a
stream left running is stopped, then the configured rate set), and chooses who answers the prompts;
on the simulated bench it first starts the in-process simulated lab (:mod:`bench.app.simulated`)
and connects to it over the same transports. A device that cannot be
reached raises :class:`DeviceUnreachableError`, naming the configuration's keys and the address
tried. This is the one module of the run that needs the drivers' clients (pymodbus, pyserial) and the
simulators; it is imported only when a bench is opened.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass

from bench.app.actuator_thread import ThreadedActuator
from bench.app.answers import FileAnswers
from bench.app.simulated import SimulatedLab, SimulatedLabSettings, TargetAnswers
from bench.app.terminal import TerminalOperator
from bench.config import BenchConfig
from bench.engine.contracts import Operator
from drivers.actuator import ActuatorClient
from drivers.errors import LinkError
from drivers.wfs_reader import WfsReader


@dataclass
class BenchDevices:
    """The opened devices: the actuator, the acquisition, the person (or simulated operator)."""

    actuator: ThreadedActuator
    acquisition: WfsReader
    operator: Operator
    lab: SimulatedLab | None = None


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
        raise ValueError(f"{config.source}: a simulated device cannot be mixed with real ones")
    with contextlib.ExitStack() as stack:
        lab = None
        if config.simulated:
            lab = stack.enter_context(
                SimulatedLab(
                    SimulatedLabSettings(
                        kind=config.kind,
                        paced=config.simulation.paced,
                        seed=config.simulation.seed,
                        tyre_pressure_bar=config.specimen.tyre_pressure_bar,
                        specimen_mounted=config.specimen.wheel_fitted,
                        tyre_model=config.specimen.tyre_model,
                        nonlinear=config.specimen.nonlinear,
                        aux_roles=tuple(a.channel.role for a in config.aux),
                    )
                )
            )
            host, port = lab.address
            wfs_url = lab.wfs_port
            if answers is not None:
                operator = FileAnswers(answers, lab.operator)
            operator = operator or TargetAnswers(lab.operator)
        else:
            host, port, wfs_url = config.actuator.host, config.actuator.port, config.wfs.device
            if answers is not None:
                operator = FileAnswers(answers)
        operator = operator or TerminalOperator()
        actuator = ThreadedActuator(lambda: _client(config, host, port))
        stack.callback(actuator.close)
        try:
            actuator.connect(config.actuator.heartbeat_period_s, config.actuator.watchdog_ms)
        except (LinkError, OSError) as exc:
            raise DeviceUnreachableError(config, "actuator", host, port, exc) from exc
        reader = WfsReader.serial(wfs_url, baudrate=config.wfs.baudrate)
        stack.enter_context(reader)
        if not reader.wait_connected(5.0):
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

    def __init__(
        self, config: BenchConfig, device: str, where: str, port: int | None, cause: object
    ) -> None:
        if device == "wfs":
            keys, what = "wfs.device", f"the WFS acquisition at {where}"
        elif config.actuator.transport == "rtu":
            keys, what = "actuator.device", f"the actuator controller at {config.actuator.device}"
        else:
            keys, what = "actuator.host, actuator.port", f"the actuator controller at {where}:{port}"
        origin = f"{config.source}: {keys}: " if not config.simulated else ""
        super().__init__(f"{origin}cannot reach {what}: {cause}")


def _client(config: BenchConfig, host: str, port: int) -> ActuatorClient:
    a = config.actuator
    common = {
        "register_map": a.load_register_map(),
        "limits": config.soft_limits,
        "timeout_s": a.timeout_s,
        "read_attempts": a.read_attempts,
    }
    if a.transport == "rtu":
        return ActuatorClient.rtu(a.device, baudrate=a.baudrate, **common)
    return ActuatorClient.tcp(host, port, **common)
