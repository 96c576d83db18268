"""The simulated bench in this process, behind the same transports as real hardware.

The controller model is served by a real Modbus TCP server on 127.0.0.1 (on an event loop of its
own thread) and the WFS device streams over a pseudo-terminal, so the engine talks to them through
the real clients exactly as it would to a lab's devices. The simulated world (what is mounted, the
tyre pressure, the car on the posts, a hammer blow) is changed only by the simulated operator when a
prompt is answered; the engine never sees it.
"""

from __future__ import annotations

import asyncio
import threading
from dataclasses import dataclass
from pathlib import Path

from bench.app.answers import WorldOperator
from bench.models.benches import TyreModel
from bench.models.setup import BenchSetup
from drivers.register_map import load_register_map
from sequences import Prompt
from sequences.channels import DEFAULT_AUX_INPUTS, Role, standard_name
from sequences.runs import RigKind
from simulators.bench_sim import UNPACED_BLOCK_S, BenchRunner, SimulatedBench
from simulators.controller_server import ControllerServer
from simulators.plant import PlantSimulator, SensorRealism
from simulators.ports import TTY_RX_BUFFER_BYTES, PtyLink
from simulators.wfs_device import BACKPRESSURE_S, WfsDevice
from simulators.world import SimulatedOperator, SimulatedWorld

#: How far (s of samples) the unpaced bench may run ahead of the engine (``EngineTiming.backlog_s``):
#: it waits for its host, so one block is enough; more would only be rest recorded between points.
UNPACED_BACKLOG_S = UNPACED_BLOCK_S
#: The shortest WFS silence (s) taken as a lost link on the unpaced bench. Its devices run on threads
#: of the bench's process and write only as fast as the engine drains them, so their link falls
#: silent whenever that process waits for the processor: on a busy PC for longer than a real link's
#: limit (``[timing] wfs_silence_s``, 0.5 s). Their silence is the host's, not a link's.
UNPACED_WFS_SILENCE_S = 5.0


def default_hold_s(paced: bool) -> float:
    """How long the simulated WFS holds frames for a host that stops reading, when the configuration
    does not say: paced, the device's own buffer; unpaced (its devices on threads of the bench's
    process, starved with it), as long as the engine takes the link's silence for its host's."""
    return BACKPRESSURE_S if paced else UNPACED_WFS_SILENCE_S


@dataclass(frozen=True)
class SimulatedLabSettings:
    """``kind``: "shaker" or "four_post"; ``paced``: real time (a dry run one can watch) or as fast
    as the engine drains the WFS; ``seed``: sensor noise; what stands on the bench at power-up: the
    tyre pressure, whether the wheel (car) is mounted, the tyre model (1-3, None: the world's
    default) and its non-linearity; ``wheel_speed_rad_s``: the wheel's rotation (0: standing);
    ``flow_control``: the paced WFS link holds the device back when the host stops reading (up to
    ``wfs_hold_s`` of frames, None: :data:`~simulators.wfs_device.BACKPRESSURE_S`; the unpaced link
    always does, by default as long as the engine takes its silence for its host's,
    :data:`UNPACED_WFS_SILENCE_S`) instead of overrunning the port's buffer; ``aux_roles``: the role
    of what each aux input of the WFS is wired to (the configuration's); ``register_map``: the map
    the controller serves (the configuration's; None: the drivers'), so that a map without the
    optional registers serves a controller without what they do."""

    kind: RigKind = RigKind.SHAKER
    paced: bool = False
    flow_control: bool = False
    wfs_hold_s: float | None = None
    seed: int = 1
    tyre_pressure_bar: float = 2.5
    specimen_mounted: bool = True
    tyre_model: int | None = None
    nonlinear: bool = True
    damper_nonlinear: bool = False
    wheel_speed_rad_s: float = 0.0
    aux_roles: tuple[Role, ...] = tuple(a.channel.role for a in DEFAULT_AUX_INPUTS)
    register_map: Path | None = None


#: The bench signals the simulated plant gives the WFS's aux inputs, by role.
SIMULATED_SIGNALS = (Role.BENCH_DISPLACEMENT, Role.PLATE_FORCE, Role.HUB_ACCELERATION)


class SimulatedLab:
    """Controller on Modbus TCP (``address``), WFS on a pty (``wfs_port``), the world and its operator.

    Use as a context manager; everything runs on background threads until the exit."""

    def __init__(self, settings: SimulatedLabSettings | None = None) -> None:
        self.settings = settings or SimulatedLabSettings()
        s = self.settings
        plant = PlantSimulator(BenchSetup.paper_hammer(), SensorRealism(seed=s.seed))
        self.bench = SimulatedBench(plant)
        self.world = SimulatedWorld(
            self.bench,
            kind=s.kind,
            pressure_bar=s.tyre_pressure_bar,
            specimen_mounted=s.specimen_mounted,
            model=TyreModel(s.tyre_model) if s.tyre_model is not None else None,
            nonlinear=s.nonlinear,
            damper_nonlinear=s.damper_nonlinear,
        )
        self.operator = SimulatedOperator(self.world)
        # paced, the link stands in for real hardware: a host that stops reading overruns the
        # port's receive buffer and loses frames (with flow control, it holds the device back, which
        # drops frames once its own buffer is full); unpaced, the bench waits for its host instead
        overruns = s.paced and not s.flow_control
        self.link = PtyLink(rx_buffer_bytes=TTY_RX_BUFFER_BYTES if overruns else None)
        wiring = tuple(standard_name(role) if role in SIMULATED_SIGNALS else None for role in s.aux_roles)
        self.device = WfsDevice(
            self.link,
            self.bench,
            seed=s.seed,
            speed_rad_s=s.wheel_speed_rad_s,
            aux_wiring=wiring,
            hold_s=s.wfs_hold_s if s.wfs_hold_s is not None else default_hold_s(s.paced),
        )
        self.runner = BenchRunner(self.bench, paced=s.paced)
        self.runner.sinks.append(self.device)
        self.server = ControllerServer(self.bench, load_register_map(s.register_map))
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, name="sim-controller", daemon=True)
        self.address: tuple[str, int] = ("", 0)

    @property
    def wfs_port(self) -> str:
        return self.link.path

    def __enter__(self) -> SimulatedLab:
        self._thread.start()
        self.device.start()
        self.runner.start()
        if not self.runner.delivering.wait(10):  # the devices are powered up: the WFS has samples
            raise RuntimeError(f"the simulated bench produced no samples: {self.runner.error}")
        future = asyncio.run_coroutine_threadsafe(self.server.serve_tcp("127.0.0.1", 0), self._loop)
        self.address = future.result(10)
        return self

    def __exit__(self, *exc: object) -> None:
        asyncio.run_coroutine_threadsafe(self.server.close(), self._loop).result(10)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout=5)
        self.runner.stop()
        self.device.stop()
        self.link.close()
        if self.runner.error is not None:
            raise RuntimeError(f"the simulated bench failed: {self.runner.error}") from self.runner.error

    def drop_controller_link(self) -> None:
        """Pull the Modbus cable: every client connection is closed by the controller's side."""
        self._loop.call_soon_threadsafe(self.server.drop_connections)


class TargetAnswers:
    """The simulated technician: answers each prompt with the value it asks for (confirms the
    others) and applies the answer to the simulated world."""

    def __init__(self, operator: WorldOperator) -> None:
        self.operator = operator

    def answer(self, prompt: Prompt) -> object:
        value = prompt.check_answer(prompt.target if prompt.target is not None else True)
        if prompt.action is not None:
            self.operator.apply(prompt.action, value)
        return value
