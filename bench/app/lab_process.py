"""The simulated lab in a process of its own, as real devices are boxes of their own.

A paced simulated bench stands in for hardware: its WFS streams at the line rate and its controller
keeps its own time whatever the bench PC does. In the bench's process it would share the
interpreter (and its lock) with the engine, the recorder and the analysis, so a busy host would
starve the devices as well as the reader, and a stall of the host would show as a stall of the
devices instead of as lost bytes at the port. :class:`LabProcess` runs :class:`SimulatedLab` in a
child interpreter (``python -m bench.app.lab_process``); the engine reaches it over the same
transports (Modbus TCP on 127.0.0.1, the WFS pty), and the operator's hands (a prompt's action:
remove the wheel, set the pressure) reach its world over the child's standard input and output,
one JSON object per line:

- parent to child: the settings first (``SimulatedLabSettings`` as an object), then requests
  ``{"apply": [action, answer]}``, ``{"drop_controller_link": true}`` or ``{"link": true}`` (the
  WFS link's counters);
- child to parent: ``{"address": [host, port], "wfs_port": path}`` once the devices are up, then
  ``{"ok": true}`` (with ``"bytes_overrun"`` for ``link``) or ``{"error": text}`` for each
  request, and ``{"ended": null}`` or ``{"ended": text}`` (the simulated bench failed) when its
  standard input closes.

The child (:mod:`bench.app.child_process`) runs in a session of its own, so Ctrl-C at the terminal
reaches the bench (which tapers the run out) and not the devices; it ends when its standard input
closes, which a bench process that dies (even by SIGKILL) does too.
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
import threading
import traceback
from typing import IO, Any

from bench.app.child_process import Child, start_child
from bench.app.simulated import SimulatedLabSettings
from sequences.channels import Role

#: How long the child may take to bring the simulated devices up (s): an interpreter start and the
#: imports on a busy host, then the devices' own start (SimulatedLab waits up to 10 s for samples).
START_TIMEOUT_S = 60.0
#: How long the child may take to close its devices once asked (s).
STOP_TIMEOUT_S = 20.0


class LabProcessError(RuntimeError):
    """The simulated lab's process failed to start, to answer, or ended with its bench failed."""


class LabProcess:
    """The simulated lab (:class:`~bench.app.simulated.SimulatedLab`) in a child process, with the
    same face: ``settings``, ``address`` (Modbus TCP), ``wfs_port`` (pty path), ``operator`` (whose
    ``apply(action, answer)`` changes the simulated world) and :meth:`drop_controller_link`.

    Use as a context manager."""

    def __init__(self, settings: SimulatedLabSettings) -> None:
        self.settings = settings
        self.address: tuple[str, int] = ("", 0)
        self.wfs_port = ""
        self.operator = RemoteOperator(self)
        self._process: Child | None = None
        self._lock = threading.Lock()  # one request and its reply at a time

    def __enter__(self) -> LabProcess:
        self._process = start_child("bench.app.lab_process", text=True)
        try:
            self._send(_settings_to_json(self.settings))
            ready = self._receive(START_TIMEOUT_S)
            if "address" not in ready:
                raise LabProcessError(f"the simulated lab did not start: {ready.get('ended') or ready}")
        except BaseException:
            self._kill()
            raise
        host, port = ready["address"]
        self.address, self.wfs_port = (str(host), int(port)), str(ready["wfs_port"])
        return self

    def __exit__(self, *exc: object) -> None:
        process = self._process
        if process is None:
            return
        self._process = None
        try:
            assert process.stdin is not None
            process.stdin.close()  # the child's signal to close its devices
            ended = _read_reply(process.stdout, STOP_TIMEOUT_S)
            process.wait(STOP_TIMEOUT_S)
        except (LabProcessError, OSError, subprocess.TimeoutExpired) as err:
            process.kill()
            process.wait()
            raise LabProcessError(f"the simulated lab did not close: {err}") from None
        if ended.get("ended"):
            raise LabProcessError(f"the simulated bench failed: {ended['ended']}")

    def drop_controller_link(self) -> None:
        """Pull the Modbus cable: every client connection is closed by the controller's side."""
        self.request({"drop_controller_link": True})

    def bytes_overrun(self) -> int:
        """Bytes the WFS link dropped so far because the host's receive buffer was full."""
        return int(self.request({"link": True})["bytes_overrun"])

    def request(self, message: dict[str, Any]) -> dict[str, Any]:
        """Send one request and return its reply; an error reply is raised as ValueError (an
        unknown action, an answer the world cannot take), a child that does not answer as
        :class:`LabProcessError`."""
        with self._lock:
            self._send(message)
            reply = self._receive(STOP_TIMEOUT_S)
        if "error" in reply:
            raise ValueError(reply["error"])
        if not reply.get("ok"):
            raise LabProcessError(f"the simulated lab answered {reply}")
        return reply

    def _send(self, message: dict[str, Any]) -> None:
        process = self._process
        if process is None or process.stdin is None:
            raise LabProcessError("the simulated lab is not running")
        try:
            process.stdin.write(json.dumps(message) + "\n")
            process.stdin.flush()
        except OSError as err:
            raise LabProcessError(f"the simulated lab's process is gone: {err}") from None

    def _receive(self, timeout_s: float) -> dict[str, Any]:
        assert self._process is not None
        return _read_reply(self._process.stdout, timeout_s)

    def _kill(self) -> None:
        if self._process is not None:
            self._process.kill()
            self._process.wait()
            self._process = None


class RemoteOperator:
    """The operator's hands on the world of a :class:`LabProcess`
    (a :class:`~bench.app.answers.WorldOperator`)."""

    def __init__(self, lab: LabProcess) -> None:
        self._lab = lab

    def apply(self, action: str, answer: float | str | bool | None) -> None:
        """Do what the operator was asked in the lab's world; ValueError for an unknown action."""
        self._lab.request({"apply": [action, answer]})


def _read_reply(stream: IO[str] | None, timeout_s: float) -> dict[str, Any]:
    """One JSON line from the child within ``timeout_s``; LabProcessError if none comes."""
    assert stream is not None
    line: list[str] = []
    reader = threading.Thread(target=lambda: line.append(stream.readline()), daemon=True)
    reader.start()
    reader.join(timeout_s)
    if reader.is_alive():
        raise LabProcessError(f"the simulated lab did not answer within {timeout_s:g} s")
    if not line or not line[0]:
        raise LabProcessError("the simulated lab's process ended without a word")
    try:
        reply = json.loads(line[0])
    except json.JSONDecodeError:
        raise LabProcessError(f"the simulated lab answered garbage: {line[0][:200]!r}") from None
    if not isinstance(reply, dict):
        raise LabProcessError(f"the simulated lab answered {reply!r}")
    return reply


def _settings_to_json(settings: SimulatedLabSettings) -> dict[str, Any]:
    data = dataclasses.asdict(settings)
    data["aux_roles"] = [role.value for role in settings.aux_roles]
    return data


def _settings_from_json(data: dict[str, Any]) -> SimulatedLabSettings:
    return SimulatedLabSettings(**{**data, "aux_roles": tuple(Role(value) for value in data["aux_roles"])})


def _serve(stdin: IO[str], stdout: IO[str]) -> None:
    """The child's side: the lab up, then requests until standard input closes."""
    from bench.app.simulated import SimulatedLab  # the child alone loads the simulators

    def send(message: dict[str, Any]) -> None:
        stdout.write(json.dumps(message) + "\n")
        stdout.flush()

    try:
        lab = SimulatedLab(_settings_from_json(json.loads(stdin.readline())))
        with lab:
            send({"address": list(lab.address), "wfs_port": lab.wfs_port})
            for line in stdin:
                try:
                    request = json.loads(line)
                    reply: dict[str, Any] = {"ok": True}
                    if "apply" in request:
                        action, answer = request["apply"]
                        lab.operator.apply(action, answer)
                    elif request.get("drop_controller_link"):
                        lab.drop_controller_link()
                    elif request.get("link"):
                        reply["bytes_overrun"] = lab.link.bytes_overrun
                    else:
                        raise ValueError("neither apply, drop_controller_link nor link")
                except (ValueError, TypeError, KeyError, AttributeError) as exc:
                    send({"error": f"request {line.strip()[:200]!r} refused: {exc}"})
                else:
                    send(reply)
    except Exception as exc:  # told to the bench, which raises it
        send({"ended": f"{exc or type(exc).__name__}\n{traceback.format_exc(limit=8)}"})
    else:
        send({"ended": None})


def child_main(stdin: IO[str], stdout: IO[str]) -> None:
    """The child's side (:mod:`bench.app.child_process`): the lab's protocol."""
    _serve(stdin, stdout)
