"""The commands that talk to the devices without a sequence: ``sim serve``, ``wfs monitor``,
``actuator status`` and ``actuator reset``."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Awaitable, Callable
from typing import Any

from bench.cli.exit_codes import ExitCode
from drivers.errors import LinkError

#: How long ``actuator reset`` waits for an e-stopped controller to taper out of its stop (s).
RESET_TIMEOUT_S = 10.0


def _sim_serve(args: argparse.Namespace) -> int:
    import asyncio

    from simulators.serve import serve  # the CLI is a composition root: it may know the simulators

    asyncio.run(serve(args.host, args.port, paced=not args.fast, seed=args.seed, ready=_announce))
    return ExitCode.OK


def _announce(line: str) -> None:
    print(line, flush=True)


def _wfs_monitor(args: argparse.Namespace) -> int:
    """Live values and link counters, one line per ``--interval`` seconds of samples; with
    ``--duration``, ``duration / interval`` lines (rounded), so exactly that much of the stream. The
    intervals are counted in frames at the rate the device reports, not by the wall clock."""
    from bench import locks

    try:
        with locks.holding(locks.serial_key(args.port), f"the WFS port {args.port}"):
            return _monitor(args)
    except locks.InUseError as exc:  # one master per device: a run, or another monitor, has it
        print(f"error: {exc}", file=sys.stderr)
        return ExitCode.UNAVAILABLE


def _monitor(args: argparse.Namespace) -> int:
    import numpy as np

    from drivers.wfs_reader import WfsReader

    with WfsReader.serial(args.port, baudrate=args.baudrate) as reader:
        if not reader.wait_connected(5):
            print(f"error: cannot open the WFS port {args.port}: {reader.last_error}", file=sys.stderr)
            return ExitCode.UNAVAILABLE
        print("identity:", ",".join(reader.identify()))
        frames_per_line = max(1, round(args.interval * reader.rate_hz()))
        lines = max(1, round(args.duration / args.interval)) if args.duration else None
        view = reader.subscribe(lossless=False, max_frames=10_000)  # a live view never slows the reader
        reader.start_stream()
        try:
            shown = 0
            pending = None  # frames read beyond the last line's, the next line's first
            while lines is None or shown < lines:
                have = 0 if pending is None else len(pending)
                if have < frames_per_line:
                    block = view.read_frames(frames_per_line - have, timeout_s=args.interval + 5)
                    pending = block.frames if pending is None else np.concatenate([pending, block.frames])
                # a line each interval of frames, whatever the blocks the port's reads made
                f, pending = pending[frames_per_line - 1], pending[frames_per_line:]
                c = reader.counters
                print(
                    f"sample {f['sample']:>9}  Fz {f['fz']:9.1f} N  z {f['aux0'] * 1000:7.3f} mm  "
                    f"F_plate {f['aux1']:9.1f} N  a_hub {f['aux2']:7.2f} m/s2  | ok {c.frames_ok} "
                    f"missing {c.frames_missing} crc {c.crc_rejects} reconnects {c.reconnects}",
                    flush=True,
                )
                shown += 1
        except KeyboardInterrupt:
            pass
        finally:
            view.close()
            reader.stop_stream()
    return ExitCode.OK


def _actuator_status(args: argparse.Namespace) -> int:
    import asyncio

    return asyncio.run(_read_actuator_status(args))


async def _read_actuator_status(args: argparse.Namespace) -> int:
    return await _holding_actuator(args, _print_actuator_status)


async def _holding_actuator(args: argparse.Namespace, act: Callable[[Any, Any], Awaitable[int]]) -> int:
    """``act(client, status)`` on the controller that ``args`` names, holding its lock (one master per
    device: a run that drives it is neither disturbed nor overruled), connected for it alone."""
    from bench import locks
    from drivers.actuator import ActuatorClient

    if args.serial:
        key, what = locks.serial_key(args.serial), f"the actuator controller's port {args.serial}"
        client = ActuatorClient.rtu(args.serial, baudrate=args.baudrate)
    else:
        key, what = locks.tcp_key(args.host, args.port), f"the actuator controller at {args.host}:{args.port}"
        client = ActuatorClient.tcp(args.host, args.port)
    try:
        with locks.holding(key, what):
            try:
                return await act(client, await client.connect())
            finally:
                await client.close()
    except (locks.InUseError, LinkError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return ExitCode.UNAVAILABLE


async def _print_actuator_status(_client: Any, status: Any) -> int:
    for name, value in vars(status).items():
        shown = f"{value:.6g}" if isinstance(value, float) else getattr(value, "name", value)
        print(f"{name:24} {shown}")
    return ExitCode.OK


def _actuator_reset(args: argparse.Namespace) -> int:
    import asyncio

    return asyncio.run(_holding_actuator(args, lambda client, status: _reset_actuator(args, client, status)))


async def _reset_actuator(args: argparse.Namespace, client: Any, status: Any) -> int:
    """Reset an interlocked or e-stopped controller once the operator confirms (``--yes``: without
    asking): it returns to hydraulics low, at rest. Anything else needs no reset (exit 0)."""
    import asyncio

    from drivers.register_map import ControllerState

    tripped = ", ".join(flag.name.lower() for flag in status.interlock) or "no interlock flag"
    if status.state not in (ControllerState.INTERLOCK, ControllerState.ESTOP):
        print(f"the controller is in {status.state.name} ({tripped}): nothing to reset")
        return ExitCode.OK
    print(f"the controller is in {status.state.name} ({tripped})")
    if not args.yes:
        print("reset it (it returns to hydraulics low, at rest)? [y/N] ", end="", flush=True)
        if sys.stdin.readline().strip().lower() not in ("y", "yes"):
            print("not reset")
            return ExitCode.STOPPED
    await client.reset_interlock()
    deadline = time.monotonic() + RESET_TIMEOUT_S
    while (status := await client.read_status()).state in (ControllerState.ESTOP, ControllerState.TAPERING):
        if time.monotonic() > deadline:  # an e-stop's reset tapers out first
            print(f"error: {status.state.name} {RESET_TIMEOUT_S:g} s after the reset", file=sys.stderr)
            return ExitCode.STOPPED
        await asyncio.sleep(0.1)  # a poll of the controller's state, not a wait for a race
    print(f"reset: the controller is in {status.state.name}")
    return ExitCode.OK if status.state is not ControllerState.INTERLOCK else ExitCode.STOPPED


def _controller_address(parser: argparse.ArgumentParser) -> None:
    """The options that name the controller: Modbus TCP (--port, --host) or RTU (--serial)."""
    link = parser.add_mutually_exclusive_group(required=True)
    link.add_argument("--port", type=int, help="Modbus TCP port on --host")
    link.add_argument("--serial", metavar="DEV", help="Modbus RTU on this serial device or pty (8N1)")
    parser.add_argument("--host", default="127.0.0.1")
    parser.add_argument("--baudrate", type=int, default=115200, help="RTU baud rate")


def add_device_commands(sub: argparse._SubParsersAction) -> None:
    """``sim serve``, ``wfs monitor`` and ``actuator status``: the devices, without a sequence."""
    sim = sub.add_parser("sim", help="simulated devices").add_subparsers(dest="action", required=True)
    serve = sim.add_parser(
        "serve",
        help="serve the simulated controller (TCP, RTU on a pty) and WFS (pty)",
        description="Serve the simulated shaker bench: the controller on Modbus TCP and on Modbus RTU"
        " over a pty, the WFS on a pty. The operator's actions are typed on standard input, one per"
        " line: remove_wheel, fit_wheel, set_tyre_pressure BAR, set_damper SETTING,"
        " strike_hammer [PEAK_N] (docs/cli.md).",
    )
    serve.add_argument("--host", default="127.0.0.1")
    serve.add_argument("--port", type=int, default=0, help="TCP port (0: any free port)")
    serve.add_argument("--seed", type=int, default=1)
    serve.add_argument("--fast", action="store_true", help="as fast as the reader drains, not real time")
    serve.set_defaults(run=_sim_serve)
    wfs = sub.add_parser("wfs", help="WFS acquisition").add_subparsers(dest="action", required=True)
    monitor = wfs.add_parser("monitor", help="show live values and link counters")
    monitor.add_argument("--port", required=True, help="serial device or pty path")
    monitor.add_argument("--baudrate", type=int, default=921600)
    monitor.add_argument("--interval", type=float, default=1.0, help="seconds per line")
    monitor.add_argument("--duration", type=float, default=0.0, help="seconds (0: until Ctrl-C)")
    monitor.set_defaults(run=_wfs_monitor)
    act = sub.add_parser("actuator", help="actuator controller").add_subparsers(dest="action", required=True)
    status = act.add_parser("status", help="read the controller state (Modbus TCP, or RTU with --serial)")
    _controller_address(status)
    status.set_defaults(run=_actuator_status)
    reset = act.add_parser(
        "reset", help="reset an interlocked or e-stopped controller, once asked to (--yes: without asking)"
    )
    _controller_address(reset)
    reset.add_argument("--yes", action="store_true", help="reset without asking")
    reset.set_defaults(run=_actuator_reset)


