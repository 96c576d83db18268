"""Run the simulated bench as a standalone process: the controller on Modbus TCP and on Modbus RTU
over a pseudo-terminal, the WFS on another pseudo-terminal, and the operator's hands on its world
taken from standard input.

The operator's actions (what a sequence's prompt asks a person to do: remove the wheel, set the
pressure) reach the program that asks only as answers; the served bench's world changes when the
same actions are typed on this process's standard input, one per line: ``ACTION [VALUE]``
(``remove_wheel``, ``set_tyre_pressure 1.5``, ``strike_hammer 1500``, ``fit_wheel``; a confirmation
given ``no`` is declined). Each line is answered on standard output (``operator: remove_wheel:
done`` or ``operator: refused: ...``).
"""

from __future__ import annotations

import asyncio
import contextlib
import signal
import sys
import threading
from collections.abc import Callable, Iterable

from simulators.bench_sim import BenchRunner, SimulatedBench
from simulators.controller_server import ControllerServer
from simulators.faults import ByteFaults
from simulators.ports import TTY_RX_BUFFER_BYTES, PtyBridge, PtyLink
from simulators.wfs_device import WfsDevice
from simulators.world import SimulatedOperator, SimulatedWorld


async def serve(
    host: str = "127.0.0.1",
    port: int = 0,
    *,
    paced: bool = True,
    seed: int = 1,
    bit_error_rate: float = 0.0,
    ready: Callable[[str], None] = print,
) -> None:
    """Serve until SIGINT/SIGTERM; ``ready`` receives the lines announcing the addresses."""
    bench = SimulatedBench.paper_shaker(seed=seed)
    operator = SimulatedOperator(SimulatedWorld(bench, kind="shaker"))
    link = PtyLink(rx_buffer_bytes=TTY_RX_BUFFER_BYTES if paced else None)  # paced: overruns as a UART
    rtu_line = PtyBridge("actuator")
    device = WfsDevice(link, bench, seed=seed, faults=ByteFaults(seed=seed, bit_error_rate=bit_error_rate))
    runner = BenchRunner(bench, paced=paced)
    runner.sinks.append(device)
    tcp, rtu = ControllerServer(bench), ControllerServer(bench)
    device.start()
    runner.start()
    try:
        bound_host, bound_port = await tcp.serve_tcp(host, port)
        await rtu.serve_rtu(rtu_line.device_path)
        ready(f"actuator controller: modbus tcp {bound_host}:{bound_port}")
        ready(f"actuator controller: modbus rtu {rtu_line.host_path} (8N1)")
        ready(f"wfs acquisition: serial {link.path}")
        hands = threading.Thread(target=_operator_lines, args=(operator, sys.stdin, ready), daemon=True)
        hands.start()
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            with contextlib.suppress(NotImplementedError):
                loop.add_signal_handler(sig, stop.set)
        await stop.wait()
    finally:
        await tcp.close()
        await rtu.close()
        runner.stop()
        device.stop()
        link.close()
        rtu_line.close()


def _operator_lines(operator: SimulatedOperator, lines: Iterable[str], say: Callable[[str], None]) -> None:
    """Apply each line of ``lines`` (``ACTION [VALUE]``) to the world; say what came of it."""
    for line in lines:
        words = line.split()
        if not words:
            continue
        action, value = words[0], " ".join(words[1:])
        try:
            operator.apply(action, _answer(value))
        except (ValueError, RuntimeError) as exc:
            say(f"operator: refused: {exc}")
        else:
            say(f"operator: {line.strip()}: done")


def _answer(text: str) -> float | str | bool:
    """A typed value: nothing or yes is a confirmation, no declines it, a number is a number."""
    if text.lower() in ("", "yes", "true"):
        return True
    if text.lower() in ("no", "false"):
        return False
    try:
        return float(text)
    except ValueError:
        return text
