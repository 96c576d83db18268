"""The monitor's server in a process of its own, beside a running bench.

The bench's process keeps the engine, the WFS reader and the recorder; whatever viewers do (many of
them, a flood of requests, malformed ones, one that never reads) is handled in this child, which
never holds the bench's interpreter lock, and runs at the lowest priority the bench can give it
(:data:`SERVER_NICENESS`), so that a busy machine makes the viewers wait, not the bench. The bench
hands it each state as one JSON line on its input (:class:`ServerProcess`); the child numbers it and
serves it (:class:`MonitorServer`). The child ends when its input closes, which happens too when
the bench dies, however it dies (:mod:`bench.app.child_process`).

Protocol: the bench's first line gives where to listen (``host``, ``port``, ``token``: null or the
token); the child answers ``{"port": N}`` once it listens, or ``{"error": "..."}`` and ends. Each
later line is a state. The server (aiohttp) is imported in the child only, when it starts.
"""

from __future__ import annotations

import contextlib
import json
import os
import subprocess
from typing import IO, Any

from bench.app.child_process import start_child
from bench.monitor.listen import Listen, MonitorUnavailableError

#: The server's niceness above the bench's (the most the system allows: 19 steps, capped at 19):
#: on a busy bench PC the viewers wait, never the bench's processes.
SERVER_NICENESS = 19
#: How long the child may take to import its server and listen (s).
START_TIMEOUT_S = 30.0
#: How long the child may take to end once its input closed: its streams send their last states.
END_TIMEOUT_S = 10.0


def child_main(stdin: IO[str], stdout: IO[str]) -> None:
    """In the child: listen as the first line says, then serve every state line until the input ends."""
    os.nice(SERVER_NICENESS)
    from bench.monitor.server import MonitorServer

    settings = json.loads(stdin.readline())
    server = MonitorServer(Listen(settings["host"], settings["port"], settings["token"]))
    try:
        server.start()
    except MonitorUnavailableError as exc:
        stdout.write(json.dumps({"error": str(exc)}) + "\n")
        return
    stdout.write(json.dumps({"port": server.port}) + "\n")
    try:
        for line in stdin:
            server.publish(json.loads(line))
    finally:
        server.close()


class ServerProcess:
    """The monitor's server as a child process at ``listen``: :meth:`start` (or
    :class:`MonitorUnavailableError`), :meth:`publish` a state, :meth:`close`."""

    def __init__(self, listen: Listen) -> None:
        self.listen = listen
        self.port = listen.port
        self._child = None

    @property
    def url(self) -> str:
        host = f"[{self.listen.host}]" if ":" in self.listen.host else self.listen.host
        return f"http://{host}:{self.port}/"

    def start(self) -> None:
        child = start_child(__name__, text=True)
        self._child = child
        settings = {"host": self.listen.host, "port": self.listen.port, "token": self.listen.token}
        child.stdin.write(json.dumps(settings) + "\n")
        answer = _read_answer(child.stdout)
        if "port" not in answer:
            self.close()
            raise MonitorUnavailableError(answer.get("error", "the monitor's server process ended"))
        self.port = int(answer["port"])

    def publish(self, state: dict[str, Any]) -> None:
        """Hand ``state`` to the server (on the caller's thread: the monitor's feed, never the
        engine's); a server that has gone is not written to again."""
        if self._child is None:
            return
        try:
            self._child.stdin.write(json.dumps(state, allow_nan=False, separators=(",", ":")) + "\n")
        except (BrokenPipeError, ValueError):  # the child ended (killed); the bench goes on without it
            self._child = None

    def close(self) -> None:
        child, self._child = self._child, None
        if child is None:
            return
        with contextlib.suppress(BrokenPipeError):
            child.stdin.close()
        try:
            child.wait(END_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            child.kill()
            child.wait(END_TIMEOUT_S)


def _read_answer(stream: IO[str]) -> dict[str, Any]:
    """The child's first line (it ends without one if it could not even start)."""
    line = stream.readline()
    return json.loads(line) if line.strip() else {}
